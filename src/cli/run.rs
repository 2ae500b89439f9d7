//! `simnet run`: one scenario on this machine, over UDP.

use super::*;

pub(super) fn run(args: &RunArgs, quiet: bool) -> anyhow::Result<ExitCode> {
    let parquet = args.format.check()? == Format::Parquet;
    let topo = Arc::new(args.topology()?);
    // A bad --out fails now, not after the run.
    let out_dir = args.out.as_deref().map(OutDir::prepare).transpose()?;
    let steps = topo.sim().steps();
    tracing::info!(topology = %topo.name(), seed = topo.sim().seed, steps, "starting");
    let progress = (!quiet && !args.json).then(|| progress_bar(steps));
    let opts = RunOptions {
        clock: if args.realtime { Clock::Realtime } else { Clock::Virtual },
        trace: out_dir
            .as_ref()
            .map(|d| -> Result<TraceWriter, UsageError> {
                let obs = topo.model().get().observation();
                let t = d
                    .trace(&topo)?
                    .with_imu(d.imu_opener())
                    .with_measurements(d.measurements()?, obs);
                Ok(if topo.estimators().run.is_empty() {
                    t
                } else {
                    t.with_estimators(d.tmp(ESTIMATORS)?)
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
    if let Some(d) = &out_dir {
        // Each sensing node's IMU samples with the true pose (input for `simnet reconstruct`), streamed too.
        let imu = out.trace.as_ref().map(|t| t.imu_nodes()).unwrap_or_default();
        let (rows, fused) = d.finish_trace(out.trace.take())?;
        let schemes = out.observer.as_ref().and_then(|o| o.schemes()).map(|s| s.rows());
        let mut extra = Vec::new();
        if let Some(rows) = schemes {
            let title = format!("{} — every estimator's error (seed {})", s.topology, s.seed);
            extra.push((
                "estimators.svg",
                "every estimator's median-over-nodes error, the centralized reference in black".to_string(),
                plot::estimators(rows, topo.sim().dt(), s.model, &title)?,
            ));
        }
        wrote = write_files(&d.dir, &s, topo.sim().dt(), &rows, &fused, extra)?;
        for id in imu {
            let name = format!("imu-{id}.csv");
            d.rename_tmp(&name)?;
            wrote.push(name);
        }
        d.rename_tmp(MEASUREMENTS)?;
        wrote.push(MEASUREMENTS.into());
        if schemes.is_some() {
            d.rename_tmp(ESTIMATORS)?;
            wrote.push(ESTIMATORS.into());
        }
        if parquet {
            let copies = parquet_copies(&d.dir, &wrote)?;
            wrote.extend(copies);
        }
        d.remove_stale(&wrote)?;
    }
    print_summary(&s, args.json, None)?;
    if let (Some(d), false) = (&out_dir, args.json) {
        println!("\nwrote {}/{{{}}}", d.dir.display(), wrote.join(", "));
    }
    Ok(exit_code(s.interrupted))
}
