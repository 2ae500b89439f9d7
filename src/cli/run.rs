//! `simnet run`: one scenario on this machine, over UDP.

use super::*;

pub(super) fn run(args: &RunArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    let parquet = args.format.check()? == Format::Parquet;
    if args.capture && args.out.is_none() {
        return Err(UsageError::Option("--capture: writes capture.csv, so it needs --out DIR".into()).into());
    }
    let topo = Arc::new(args.topology()?);
    // A bad --out fails now, not after the run.
    let out_dir = args
        .out
        .as_deref()
        .map(|d| RunDir::open(d, &inputs_of(&topo)))
        .transpose()?;
    let steps = topo.sim().steps();
    tracing::info!(topology = %topo.name(), seed = topo.sim().seed, steps, "starting");
    let progress = (!quiet && !args.json).then(|| progress_bar(steps));
    let capture = args.capture.then(crate::medium::CaptureLog::new);
    let opts = RunOptions {
        capture: capture.clone(),
        clock: if args.realtime { Clock::Realtime } else { Clock::Virtual },
        trace: out_dir
            .as_ref()
            .map(|d| -> Result<TraceWriter, UsageError> {
                let obs = topo.model().get().observation();
                let t = d
                    .trace(&topo)?
                    .with_imu(d.imu_opener())
                    .with_measurements(d.create(MEASUREMENTS)?, obs);
                Ok(if topo.estimators().run.is_empty() {
                    t
                } else {
                    t.with_estimators(d.create(ESTIMATORS)?)
                })
            })
            .transpose()?,
        progress: progress
            .clone()
            .map(|pb| -> net::Progress { Arc::new(move |d, _| pb.set_position(d)) }),
        ..Default::default()
    };
    let rt = tokio::runtime::Builder::new_multi_thread().enable_all().build()?;
    let mut out = rt.block_on(net::run(topo.clone(), opts, shutdown_signal()))?;
    if let Some(pb) = progress {
        pb.finish_and_clear();
    }
    let s = out.summary_beside_clean()?;
    // Files first: a reader that closes stdout early (`| head`) loses nothing.
    let mut wrote = Vec::new();
    let mut shown = None;
    let mut failed = None;
    if let Some(d) = out_dir {
        shown = Some(d.dir.clone());
        match write_run(d, &mut out, &s, &topo, parquet, capture.as_ref()) {
            Ok(w) => wrote = w,
            // The table is still printed: a full disk loses the files, not the result (the directory is as it was).
            Err(e) => failed = Some(e),
        }
    }
    if let Some(e) = failed {
        print_summary(&s, args.json, None)?;
        return Err(e.context(format!(
            "the run's files were not written ({} is as it was)",
            shown.map(|d| d.display().to_string()).unwrap_or_default()
        )));
    }
    print_summary(&s, args.json, None)?;
    if let (Some(dir), false) = (&shown, args.json) {
        outln!("\nwrote {}/{{{}}}", dir.display(), wrote.join(", "));
    }
    Ok(exit_code(s.interrupted))
}

/// Every file of a whole run into `d`'s staging directory, then moved into place as a set; the names written.
fn write_run(
    d: RunDir,
    out: &mut net::RunResults,
    s: &summary::Summary,
    topo: &Scenario,
    parquet: bool,
    capture: Option<&crate::medium::CaptureLog>,
) -> anyhow::Result<Vec<String>> {
    // Each sensing node's IMU samples with the true pose (input for `simnet reconstruct`), streamed too.
    let imu = out.trace.as_ref().map(|t| t.imu_nodes()).unwrap_or_default();
    let (rows, fused) = d.finish_trace(out.trace.take())?;
    let schemes = out.observer.as_ref().and_then(|o| o.schemes()).map(|s| s.rows());
    let mut extra = Vec::new();
    if let Some(rows) = schemes {
        let title = format!(
            "{} — every estimator's error ({})",
            s.topology,
            super::out::conditions(s)
        );
        extra.push((
            "estimators.svg",
            "every estimator's median-over-nodes error, the centralized reference in black".to_string(),
            plot::estimators(rows, topo.sim().dt(), s.model, &title)?,
        ));
    }
    let world = topo.world();
    let at: Vec<(u32, f64, f64)> = topo
        .nodes()
        .iter()
        .enumerate()
        .map(|(i, n)| {
            let p = world.position(i, simnet_core::time::Time::ZERO);
            (n.id, p.x, p.y)
        })
        .collect();
    let title = format!("{} — where the nodes stand ({})", s.topology, super::out::conditions(s));
    if let Some(svg) = plot::map(&at, &s.links, &title)? {
        extra.push((
            "map.svg",
            "where the nodes stand, each link coloured by the datagrams it delivered".to_string(),
            svg,
        ));
    }
    let mut wrote = write_files(&d.stage, s, topo.sim().dt(), &rows, &fused, extra)?;
    wrote.extend(imu.into_iter().map(|id| format!("imu-{id}.csv")));
    wrote.push(MEASUREMENTS.into());
    if schemes.is_some() {
        wrote.push(ESTIMATORS.into());
    }
    if let Some(log) = capture {
        std::fs::write(d.stage.join(CAPTURE), crate::report::capture::csv(&log.take(), topo))?;
        wrote.push(CAPTURE.into());
    }
    if parquet {
        let copies = parquet_copies(&d.stage, &wrote)?;
        wrote.extend(copies);
    }
    d.commit(&wrote)?;
    Ok(wrote)
}

/// The files a run reads, each with what names it: the topology file, the recordings its nodes replay, its key.
pub(super) fn inputs_of(topo: &Scenario) -> Vec<(String, PathBuf)> {
    let mut v = vec![("the topology".to_string(), PathBuf::from(topo.source()))];
    for (i, n) in topo.nodes().iter().enumerate() {
        if let Some(r) = &n.recording {
            v.push((format!("node[{i}].imu_csv"), PathBuf::from(&r.path)));
        }
    }
    if let Some(k) = &topo.security().key_source {
        v.push(("the key file".to_string(), PathBuf::from(k)));
    }
    v
}
