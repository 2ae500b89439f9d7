//! `simnet attitude FILE`: a recording as its maker wrote it, the EKF, Madgwick and Mahony run on it with the noise
//! levels and field estimated from the recording, each scored against the file's reference orientation.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;

use super::out::write_atomic;
use super::UsageError;
use crate::analysis::attitude::{calibrate, compare_with, error_angles, Comparison, Errors, Gates, GATES};
use crate::imu_csv::layout::{self, ReadOptions};
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
    #[command(flatten)]
    pub read: super::args::ReadFlags,
    /// Calibrate the magnetometer's hard and soft iron from the recording (an ellipsoid fit) before the filters run;
    /// refused, with the reason, when the recording does not turn the sensor enough.
    #[arg(long)]
    pub calibrate_mag: bool,
    /// The gates: `off`, or `accel=F,field=F,dip=DEG` (fractions of |g| and |h|, degrees of dip; default
    /// accel=0.1,field=0.1,dip=5.7).
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
    let shown = args.file.display().to_string();
    let text = crate::input::read_text(&args.file, crate::input::MAX_TABLE)
        .map_err(|e| UsageError::Option(format!("{shown}: cannot read: {e}")))?;
    let o = args.read.options();
    let mut reading = layout::read_any(&text, &shown, &o).map_err(|e| UsageError::Option(e.to_string()))?;
    if let Some(path) = &args.reference {
        let rshown = path.display().to_string();
        let rtext = crate::input::read_text(path, crate::input::MAX_TABLE)
            .map_err(|e| UsageError::Option(format!("{rshown}: cannot read: {e}")))?;
        let ro = ReadOptions {
            columns: Vec::new(),
            ..o.clone()
        };
        let r = layout::read_reference(&rtext, &rshown, &ro).map_err(|e| UsageError::Option(e.to_string()))?;
        let q: Vec<_> = match (&r.recording.quat, &r.recording.euler) {
            (Some(q), _) => q.clone(),
            (_, Some(e)) => e.iter().map(crate::estimate::attitude::from_euler).collect(),
            _ => unreachable!("read_reference returns a reference or an error"),
        };
        let dropped = crate::imu_csv::join_reference(&mut reading.recording, &r.recording.t, &q);
        if reading.recording.t.len() < 3 {
            return Err(UsageError::Option(format!(
                "{rshown}: its times ({:.3}–{:.3} s) hardly overlap the recording's",
                r.recording.t[0],
                r.recording.t.last().copied().unwrap_or(0.0)
            ))
            .into());
        }
        reading.notes.push(format!(
            "reference: {rshown} ({} samples at {:.4} Hz), interpolated at the recording's times{}",
            r.recording.t.len(),
            r.rate_hz,
            if dropped > 0 {
                format!("; {dropped} samples outside its time span left out")
            } else {
                String::new()
            }
        ));
        reading.columns.extend(r.columns.into_iter().filter(|(t, _)| t != "t"));
    }
    let mut calibration = None;
    if args.calibrate_mag {
        let Some(mag) = reading.recording.mag.as_mut() else {
            return Err(
                UsageError::Option(format!("{shown}: --calibrate-mag: the recording has no magnetometer")).into(),
            );
        };
        calibration = Some(calibrate::fit(mag).inspect(|c| {
            for m in mag.iter_mut() {
                *m = c.apply(m);
            }
        }));
    }
    let gates = args.gates.unwrap_or(GATES);
    let c = compare_with(&reading.recording, reading.rate_hz, &gates)
        .map_err(|e| UsageError::Option(format!("{shown}: {e}")))?;
    if let Some(dir) = &args.out {
        let name = args
            .file
            .file_name()
            .map_or(shown.clone(), |n| n.to_string_lossy().to_string());
        write_out(dir, &name, &reading.recording.t, &c)?;
    }
    let mut out = std::io::stdout().lock();
    let e = &c.characterised;
    let t = &reading.recording.t;
    let still_s = e.still.map(|(a, b)| [t[a] - t[0], t[b] - t[0]]);
    if args.json {
        let v = serde_json::json!({
            "file": shown,
            "columns": reading.columns,
            "read": reading.notes,
            "rate_hz": reading.rate_hz,
            "estimated": {
                "still_s": still_s,
                "gyro_bias": e.gyro_bias.as_slice(),
                "gyro_sd": e.gyro_var.sqrt(),
                "accel_sd": e.accel_var.sqrt(),
                "mag_sd": e.mag_var.map(f64::sqrt),
                "g": e.g,
                "accel_motion_sd": e.accel_motion_var.sqrt(),
                "accel_motion_tau": e.accel_motion_tau,
                "accel_passed": e.accel_passed,
                "field": e.field.map(|f| serde_json::json!({
                    "magnitude": f.magnitude,
                    "dip_deg": f.dip.to_degrees(),
                    "passed": f.passed,
                    "disturbance_sd": e.mag_disturbance_var.map(f64::sqrt),
                    "disturbance_tau": e.mag_disturbance_tau,
                })),
            },
            "reference_z_down": c.reference_z_down,
            "gates": { "accel": finite(gates.accel), "field": finite(gates.field), "dip_deg": finite(gates.dip.to_degrees()) },
            "mag_calibration": calibration.as_ref().map(|r| match r {
                Ok(c) => serde_json::json!({
                    "offset": c.offset.as_slice(),
                    "matrix": c.matrix.transpose().as_slice(),
                    "spread_before": c.spread_before,
                    "spread_after": c.spread_after,
                }),
                Err(e) => serde_json::json!({ "refused": e.to_string() }),
            }),
            "scores": c.scores,
        });
        writeln!(out, "{}", serde_json::to_string_pretty(&v)?)?;
        return Ok(ExitCode::SUCCESS);
    }
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
        "  accelerometer gate ({}) passes {:.1} % of samples; linear acceleration it lets through: sd {:.3} m/s², \
         correlation time {:.1} samples",
        if g.accel.is_finite() {
            format!("|a| within {:.0} % of |g|", 100.0 * g.accel)
        } else {
            "open".into()
        },
        100.0 * e.accel_passed,
        e.accel_motion_var.sqrt(),
        e.accel_motion_tau
    )?;
    match &calibration {
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
            "  field {:.4} (file unit), dip {:.1}°; field gate ({}) passes {:.1} % of samples; disturbance it lets \
             through: sd {:.3}, correlation time {:.1} samples",
            f.magnitude,
            f.dip.to_degrees(),
            match (g.field.is_finite(), g.dip.is_finite()) {
                (false, false) => "open".to_string(),
                _ => format!(
                    "|m| within {:.0} %, dip within {:.1}°",
                    100.0 * g.field,
                    g.dip.to_degrees()
                ),
            },
            100.0 * f.passed,
            e.mag_disturbance_var.unwrap_or(0.0).sqrt(),
            e.mag_disturbance_tau.unwrap_or(1.0)
        )?;
    }
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
    writeln!(
        out,
        "\nekf: Lesecq's quaternion EKF; madgwick: β = {} (Madgwick et al. 2011); mahony: k_P = {}, k_I = {} (Mahony et \
         al. 2008)",
        if c.h.is_some() {
            crate::estimate::ahrs::MADGWICK_BETA_MARG
        } else {
            crate::estimate::ahrs::MADGWICK_BETA_IMU
        },
        crate::estimate::ahrs::MAHONY_KP,
        crate::estimate::ahrs::MAHONY_KI
    )?;
    if let Some(dir) = &args.out {
        writeln!(out, "wrote {0}/attitude.csv and {0}/attitude.svg", dir.display())?;
    }
    Ok(ExitCode::SUCCESS)
}

/// An open gate (∞) as JSON null.
fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

/// `attitude.csv` and `attitude.svg`.
fn write_out(dir: &std::path::Path, title: &str, t: &[f64], c: &Comparison) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let errors: Vec<Vec<[f64; 3]>> = c
        .attitudes
        .iter()
        .map(|(_, q)| error_angles(q, &c.reference, 0.0))
        .collect();
    let mut csv = String::from("t,ref_qw,ref_qx,ref_qy,ref_qz,accel_passed,field_passed");
    for (name, _) in &c.attitudes {
        csv.push_str(&format!(
            ",{name}_qw,{name}_qx,{name}_qy,{name}_qz,{name}_error_deg,{name}_heading_deg,{name}_tilt_deg"
        ));
    }
    csv.push('\n');
    for k in 0..t.len() {
        let r = &c.reference[k];
        let (a, f) = c.passed[k];
        csv.push_str(&format!(
            "{},{},{},{},{},{},{}",
            t[k] - t[0],
            r[0],
            r[1],
            r[2],
            r[3],
            u8::from(a),
            u8::from(f)
        ));
        for ((_, q), e) in c.attitudes.iter().zip(&errors) {
            let (q, e) = (q[k], e[k]);
            csv.push_str(&format!(
                ",{},{},{},{},{},{},{}",
                q[0],
                q[1],
                q[2],
                q[3],
                e[0].to_degrees(),
                e[1].to_degrees(),
                e[2].to_degrees()
            ));
        }
        csv.push('\n');
    }
    write_atomic(&dir.join("attitude.csv"), csv.as_bytes())?;
    let series: Vec<(String, Vec<(f64, f64)>)> = c
        .attitudes
        .iter()
        .zip(&errors)
        .zip(&c.scores)
        .map(|(((name, _), e), s)| {
            let pts = t.iter().zip(e).map(|(t0, e)| (t0 - t[0], e[0].to_degrees())).collect();
            (format!("{name}: mean {:.2}°", s.as_recorded.mean), pts)
        })
        .collect();
    let title = format!("attitude error against the on-board orientation, {title}");
    let svg = plot::lines(&series, "t (s)", "error (°)", false, &title)?;
    write_atomic(&dir.join("attitude.svg"), svg.as_bytes())?;
    Ok(())
}
