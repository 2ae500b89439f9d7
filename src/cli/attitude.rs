//! `simnet attitude FILE`: a recording as its maker wrote it, the EKFs, Madgwick, Mahony and VQF run on it with the noise
//! levels and field estimated from the recording, each scored against the file's reference orientation.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;

use super::out::write_atomic;
use super::UsageError;
use crate::analysis::attitude::study::{study, Outside, Source, Study};
use crate::analysis::attitude::{error_angles, Errors, Gates, GATES};
use crate::report::plot;

#[derive(Args, Debug, Clone)]
pub struct AttitudeArgs {
    /// The recording: simnet's CSV or a maker's export (tab, comma, semicolon or space separated; `#`, `//` or `%`
    /// comments), with a reference orientation (quaternion or roll, pitch, yaw).
    pub file: PathBuf,
    /// The reference orientation from a file of its own (a maker's `quaternion.csv` beside `sensors.csv`), matched
    /// to the recording by time (interpolated; samples outside its time span are left out).
    #[arg(long, value_name = "FILE")]
    pub reference: Option<PathBuf>,
    /// A filter run elsewhere, scored beside simnet's: NAME=FILE, FILE holding its attitude (quaternion or roll,
    /// pitch, yaw) with a time column matched to the recording's, or a row per sample; repeatable.
    #[arg(long, value_name = "NAME=FILE", value_parser = parse_compare)]
    pub compare: Vec<(String, PathBuf)>,
    #[command(flatten)]
    pub read: super::args::ReadFlags,
    /// Calibrate the magnetometer's hard and soft iron from the recording (an ellipsoid fit) before the filters run;
    /// refused, with the reason, when the recording does not turn the sensor enough.
    #[arg(long)]
    pub calibrate_mag: bool,
    /// The gates: `off`, or `accel=F,field=F,dip=DEG,settle=S` (fractions of |g| and |h|, degrees of dip, seconds the
    /// field must pass on end before it corrects; default accel=0.1,field=0.1,dip=5.7,settle=0.5).
    #[arg(long, value_parser = Gates::parse)]
    pub gates: Option<Gates>,
    /// Write `attitude.csv` (every filter's attitude and error per sample, the gates' verdicts) and `attitude.svg`
    /// (error against time) into this directory.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the comparison as JSON.
    #[arg(long)]
    pub json: bool,
}

pub(super) fn attitude(args: &AttitudeArgs) -> anyhow::Result<ExitCode> {
    if let Some(dir) = &args.out {
        super::out::check_out(dir)?;
    }
    let shown = args.file.display().to_string();
    let read = |p: &std::path::Path, shown: &str| {
        crate::input::read_text(p, crate::input::MAX_TABLE)
            .map_err(|e| UsageError::Option(format!("{shown}: cannot read: {e}")))
    };
    let text = read(&args.file, &shown)?;
    let reference = match &args.reference {
        Some(p) => Some((read(p, &p.display().to_string())?, p.display().to_string())),
        None => None,
    };
    let gates = args.gates.unwrap_or(GATES);
    let mut compared = Vec::new();
    for (name, p) in &args.compare {
        compared.push((
            name.as_str(),
            read(p, &p.display().to_string())?,
            p.display().to_string(),
        ));
    }
    let outside: Vec<Outside> = compared
        .iter()
        .map(|(name, text, file)| Outside {
            name,
            source: Source { text, name: file },
        })
        .collect();
    let st = study(
        Source {
            text: &text,
            name: &shown,
        },
        reference.as_ref().map(|(text, name)| Source { text, name }),
        &outside,
        &args.read.options(),
        args.calibrate_mag,
        gates,
    )
    .map_err(|e| UsageError::Option(e.to_string()))?;
    if let Some(dir) = &args.out {
        let name = args
            .file
            .file_name()
            .map_or(shown.clone(), |n| n.to_string_lossy().to_string());
        write_out(dir, &name, &st)?;
    }
    let mut out = std::io::stdout().lock();
    if args.json {
        writeln!(out, "{}", serde_json::to_string_pretty(&st.json())?)?;
        return Ok(ExitCode::SUCCESS);
    }
    let (reading, c, calibration) = (&st.reading, &st.comparison, &st.calibration);
    let e = &c.characterised;
    let still_s = st.still_s();
    writeln!(out, "{shown}: read as")?;
    for n in &reading.notes {
        writeln!(out, "  {n}")?;
    }
    let cols: Vec<String> = reading.columns.iter().map(|(t, c)| format!("{t}={c}")).collect();
    writeln!(out, "  columns: {}", cols.join(","))?;
    let g = &gates;
    writeln!(out, "estimated from the recording:")?;
    writeln!(
        out,
        "  white noise ({}): gyro sd {:.2e} rad/s, accelerometer sd {:.2e} m/s²{}",
        if e.still.is_some() {
            "at rest"
        } else {
            "second differences"
        },
        e.gyro_var.sqrt(),
        e.accel_var.sqrt(),
        e.mag_var
            .map_or(String::new(), |v| format!(", magnetometer sd {:.2e}", v.sqrt()))
    )?;
    match still_s {
        Some([a, b]) => writeln!(
            out,
            "  at rest {a:.2}–{b:.2} s: gyro bias [{:.4}, {:.4}, {:.4}] rad/s, |g| {:.4} m/s²",
            e.gyro_bias[0], e.gyro_bias[1], e.gyro_bias[2], e.g
        )?,
        None => writeln!(
            out,
            "  no second at rest: gyro bias taken as zero; |g| {:.4} m/s² (median |a|)",
            e.g
        )?,
    }
    writeln!(
        out,
        "  accelerometer gate ({}) passes {:.1} % of samples; linear acceleration (|a| − |g|, every sample): \
         sd {:.3} m/s², correlation time {:.1} samples",
        if g.accel.is_finite() {
            format!("|a| within {:.0} % of |g|", 100.0 * g.accel)
        } else {
            "open".into()
        },
        100.0 * e.accel_passed,
        e.accel_motion_var.sqrt(),
        e.accel_motion_tau
    )?;
    match calibration {
        Some(Ok(c)) => writeln!(
            out,
            "  magnetometer calibrated (ellipsoid fit): hard iron [{:.4}, {:.4}, {:.4}], |m| spread {:.1} % → {:.1} %",
            c.offset[0],
            c.offset[1],
            c.offset[2],
            100.0 * c.spread_before,
            100.0 * c.spread_after
        )?,
        Some(Err(r)) => writeln!(
            out,
            "  magnetometer not calibrated: {r}; the readings are used as recorded"
        )?,
        None => {}
    }
    if let Some(f) = e.field {
        writeln!(
            out,
            "  field {:.4} (file unit), dip {:.1}°; field gate ({}) passes {:.1} % of samples; disturbance (|m| − |h|, every \
             sample): sd {:.3}, correlation time {:.1} samples",
            f.magnitude,
            f.dip.to_degrees(),
            match (g.field.is_finite(), g.dip.is_finite()) {
                (false, false) => "open".to_string(),
                _ => format!(
                    "|m| within {:.0} %, dip within {:.1}°{}",
                    100.0 * g.field,
                    g.dip.to_degrees(),
                    if g.settle > 0.0 {
                        format!(", for {} s on end", g.settle)
                    } else {
                        String::new()
                    }
                ),
            },
            100.0 * f.passed,
            e.mag_disturbance_var.unwrap_or(0.0).sqrt(),
            e.mag_disturbance_tau.unwrap_or(1.0)
        )?;
    }
    match &e.across {
        Some(x) => writeln!(
            out,
            "  across g and the field, the gyro linking the samples (fitted gyro bias [{:.4}, {:.4}, {:.4}] rad/s \
             more): horizontal specific force sd {} m/s², τ {:.1} → R {}{}",
            x.bias_correction[0],
            x.bias_correction[1],
            x.bias_correction[2],
            sig3(x.accel.var.sqrt()),
            x.accel.tau,
            sig3(x.accel.white_equivalent),
            x.field.map_or(String::new(), |f| format!(
                "; field across, horizontal sd {}, τ {:.1} → R {}",
                sig3(f.var.sqrt()),
                f.tau,
                sig3(f.white_equivalent)
            ))
        )?,
        None => writeln!(
            out,
            "  across g and the field: the gyro-aided fit failed; R from |a| − |g| and |m| − |h| instead"
        )?,
    }
    let m = &c.mekf_model;
    writeln!(
        out,
        "  the MEKF's disturbances (less the white noise): horizontal linear acceleration sd {} m/s², τ {:.2} s; \
         vertical sd {} m/s²{}",
        sig3(m.accel_horizontal.var.sqrt()),
        m.accel_horizontal.tau,
        sig3(m.accel_vertical.var.sqrt()),
        c.h.map_or(String::new(), |_| format!(
            "; field across, horizontal sd {}, τ {:.2} s",
            sig3(m.field.var.sqrt()),
            m.field.tau
        ))
    )?;
    writeln!(
        out,
        "reference: {}; filters start from the first accelerometer{} sample\n",
        if c.reference_z_down {
            "z down (NED-like), turned z-up for the comparison"
        } else {
            "z up"
        },
        if c.h.is_some() { " and magnetometer" } else { "" }
    )?;
    writeln!(
        out,
        "{:<10} │ {:>8} {:>8} {:>8} {:>9} {:>8} │ {:>8} {:>8} {:>8} {:>9} {:>8} │ {:>8} │ {:>13}",
        "filter",
        "mean °",
        "rms °",
        "max °",
        "heading °",
        "tilt °",
        "mean °",
        "rms °",
        "max °",
        "heading °",
        "tilt °",
        "offset °",
        "gated a / m"
    )?;
    writeln!(
        out,
        "{:<10} │ {:^45} │ {:^45} │",
        "", "as recorded", "constant heading offset removed"
    )?;
    let row = |e: &Errors| {
        format!(
            "{:>8.2} {:>8.2} {:>8.2} {:>9.2} {:>8.2}",
            e.mean, e.rms, e.max, e.heading_mean, e.tilt_mean
        )
    };
    for s in &c.scores {
        writeln!(
            out,
            "{:<10} │ {} │ {} │ {:>8.1} │ {:>13}",
            s.filter,
            row(&s.as_recorded),
            row(&s.offset_removed),
            s.heading_offset_deg,
            s.gated
                .map_or("-".to_string(), |g| format!("{} / {}", g.accel, g.field))
        )?;
    }
    if let (Some(a), Some(b)) = (c.closest(false), c.closest(true)) {
        writeln!(
            out,
            "closest to the reference: {} ({:.2}°) as recorded, {} ({:.2}°) with the offset removed",
            a.filter, a.as_recorded.mean, b.filter, b.offset_removed.mean
        )?;
    }
    writeln!(
        out,
        "\nekf: Lesecq's quaternion EKF; mekf: the multiplicative EKF with Gauss–Markov linear acceleration and field \
         disturbance (Markley 2003; Roetenberg et al. 2005); madgwick: β = {} (Madgwick et al. 2011); mahony: k_P = \
         {}, k_I = {} (Mahony et al. 2008); gyro: the gyro alone, bias removed; vqf: VQF with its published defaults \
         (Laidig & Seel 2023), which starts from its own first samples",
        if c.h.is_some() {
            crate::estimate::ahrs::MADGWICK_BETA_MARG
        } else {
            crate::estimate::ahrs::MADGWICK_BETA_IMU
        },
        crate::estimate::ahrs::MAHONY_KP,
        crate::estimate::ahrs::MAHONY_KI
    )?;
    for (name, p) in &args.compare {
        writeln!(
            out,
            "{name}: run outside simnet, read from {} (its north need not be the reference's: compare the errors with \
             the offset removed)",
            p.display()
        )?;
    }
    let nis = |n: &Option<crate::analysis::attitude::Nis>| {
        n.map_or("-".to_string(), |n| {
            let verdict = if n.per_dof < n.band[0] {
                "model too wide"
            } else if n.per_dof > n.band[1] {
                "model too narrow"
            } else {
                "consistent"
            };
            format!(
                "{:.2} ({verdict}; 99 % band {:.2}–{:.2})",
                n.per_dof, n.band[0], n.band[1]
            )
        })
    };
    writeln!(
        out,
        "\nnormalised innovation squared per degree of freedom, accelerometer / magnetometer:"
    )?;
    for s in &c.scores {
        if let Some(k) = &s.consistency {
            writeln!(out, "  {:<8} {} / {}", s.filter, nis(&k.accel), nis(&k.field))?;
        }
    }
    let nc = &c.noise_check;
    let part = |p: &crate::analysis::attitude::sensor::Part, model: f64| {
        format!(
            "sd {}, τ {:.1} → R {} ({:.2}× the model's)",
            sig3(p.var.sqrt()),
            p.tau,
            sig3(p.white_equivalent),
            p.white_equivalent / model
        )
    };
    writeln!(
        out,
        "
the EKF's noise model against the reference (per axis; R = mean square over the samples the gates pass × \
         their correlation time):\n  linear acceleration across g: {}; the model's R {}",
        part(&nc.accel_across, nc.accel_model),
        sig3(nc.accel_model)
    )?;
    if let Some(f) = &nc.field {
        writeln!(
            out,
            "  field disturbance across the field, horizontal (turns heading): {}\n  across, vertical (dip): {}\n  \
             along (|m|): {}; the model's R {}",
            part(&f.across_horizontal, f.model),
            part(&f.across_vertical, f.model),
            part(&f.along, f.model),
            sig3(f.model)
        )?;
    }
    if let Some(dir) = &args.out {
        writeln!(out, "wrote {0}/attitude.csv and {0}/attitude.svg", dir.display())?;
    }
    Ok(ExitCode::SUCCESS)
}

/// `NAME=FILE` of `--compare`.
fn parse_compare(s: &str) -> Result<(String, PathBuf), String> {
    match s.split_once('=') {
        Some((name, file)) if !file.is_empty() => Ok((name.to_string(), PathBuf::from(file))),
        _ => Err(format!("`{s}`: expected NAME=FILE, e.g. vqf=vqf.csv")),
    }
}

/// `attitude.csv` and `attitude.svg`.
fn write_out(dir: &std::path::Path, title: &str, st: &Study) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    write_atomic(&dir.join("attitude.csv"), st.csv().as_bytes())?;
    let (c, t) = (&st.comparison, &st.reading.recording.t);
    let series: Vec<(String, Vec<(f64, f64)>)> = c
        .attitudes
        .iter()
        .zip(st.error_angles())
        .zip(&c.scores)
        .map(|(((name, q), e), s)| {
            // A filter run outside has a north of its own: its curve is drawn with its heading offset removed.
            let e = if s.outside {
                error_angles(q, &c.reference, s.heading_offset_deg.to_radians())
            } else {
                e
            };
            let pts = t.iter().zip(e).map(|(t0, e)| (t0 - t[0], e[0].to_degrees())).collect();
            let label = if s.outside {
                format!(
                    "{name}: mean {:.2}° ({:.0}° heading offset removed)",
                    s.offset_removed.mean, s.heading_offset_deg
                )
            } else {
                format!("{name}: mean {:.2}°", s.as_recorded.mean)
            };
            (label, pts)
        })
        .collect();
    let title = format!("attitude error against the on-board orientation, {title}");
    let svg = plot::lines(&series, "t (s)", "error (°)", false, &title)?;
    write_atomic(&dir.join("attitude.svg"), svg.as_bytes())?;
    Ok(())
}

/// Three significant digits, fixed point.
fn sig3(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let decimals = (2 - x.abs().log10().floor() as i64).clamp(0, 12) as usize;
    format!("{x:.decimals$}")
}
