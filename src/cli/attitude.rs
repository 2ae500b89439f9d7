//! `simnet attitude FILE`: a recording as its maker wrote it, the EKF, Madgwick and Mahony run on it with the noise
//! levels and field estimated from the recording, each scored against the file's reference orientation.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use super::UsageError;
use crate::analysis::attitude::{compare, Errors};
use crate::imu_csv::layout::{self, ReadOptions, Units};

#[derive(Args, Debug, Clone)]
pub struct AttitudeArgs {
    /// The recording: simnet's CSV or a maker's export (tab, comma, semicolon or space separated; `#`, `//` or `%`
    /// comments), with a reference orientation (quaternion or roll, pitch, yaw).
    pub file: PathBuf,
    /// Columns the usual names miss: TARGET=COLUMN pairs, e.g. `t=Counter/rate,ax=Acc_X,qw=Quat_w` (COLUMN/K,
    /// COLUMN*K scale; /rate divides by --rate).
    #[arg(long, value_parser = layout::parse_columns)]
    pub columns: Option<Vec<(String, String)>>,
    /// Units the header does not give: accel=g|m/s2, gyro=deg/s|rad/s, time=s|ms|us, angle=deg|rad (comma-separated).
    #[arg(long, value_parser = units)]
    pub units: Option<Units>,
    /// Samples per second, for a file whose time column counts samples (or that has none).
    #[arg(long, value_parser = super::args::positive)]
    pub rate: Option<f64>,
    /// Print the comparison as JSON.
    #[arg(long)]
    pub json: bool,
}

fn units(s: &str) -> Result<Units, String> {
    let mut u = Units::default();
    for part in s.split(',').filter(|p| !p.trim().is_empty()) {
        let (k, v) = part
            .split_once('=')
            .ok_or_else(|| format!("`{part}`: write WHAT=UNIT, e.g. gyro=deg/s"))?;
        let k = k.trim();
        let f = layout::unit_factor(k, v).ok_or_else(|| format!("`{}` is not a unit of {k}", v.trim()))?;
        match k {
            "accel" => u.accel = Some(f),
            "gyro" => u.gyro = Some(f),
            "time" => u.time = Some(f),
            "angle" => u.angle = Some(f),
            _ => unreachable!("unit_factor knows no other quantity"),
        }
    }
    Ok(u)
}

pub(super) fn attitude(args: &AttitudeArgs) -> anyhow::Result<ExitCode> {
    let shown = args.file.display().to_string();
    let text = crate::input::read_text(&args.file, crate::input::MAX_TABLE)
        .map_err(|e| UsageError::Option(format!("{shown}: cannot read: {e}")))?;
    let o = ReadOptions {
        columns: args.columns.clone().unwrap_or_default(),
        units: args.units.clone().unwrap_or_default(),
        rate_hz: args.rate,
    };
    let reading = layout::read(&text, &shown, &o).map_err(|e| UsageError::Option(e.to_string()))?;
    let c = compare(&reading.recording, reading.rate_hz).map_err(|e| UsageError::Option(format!("{shown}: {e}")))?;
    let mut out = std::io::stdout().lock();
    if args.json {
        let v = serde_json::json!({
            "file": shown,
            "columns": reading.columns,
            "read": reading.notes,
            "rate_hz": reading.rate_hz,
            "estimated": {
                "window_s": [reading.recording.t[c.estimated.window.0] - reading.recording.t[0],
                             reading.recording.t[c.estimated.window.1] - reading.recording.t[0]],
                "gyro_bias": c.estimated.gyro_bias.as_slice(),
                "gyro_sd": c.estimated.gyro_var.sqrt(),
                "accel_sd": c.estimated.accel_var.sqrt(),
                "g": c.estimated.g,
                "mag_sd": c.estimated.mag_var.map(f64::sqrt),
                "field": c.estimated.field.map(|(m, d)| serde_json::json!({"magnitude": m, "dip_deg": d.to_degrees()})),
            },
            "reference_z_down": c.reference_z_down,
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
    let e = &c.estimated;
    let t = &reading.recording.t;
    writeln!(
        out,
        "estimated from its quietest second ({:.2}–{:.2} s): gyro noise sd {:.2e} rad/s, bias [{:.4}, {:.4}, {:.4}] \
         rad/s; accelerometer noise sd {:.2e} m/s², |g| {:.4} m/s²{}",
        t[e.window.0] - t[0],
        t[e.window.1] - t[0],
        e.gyro_var.sqrt(),
        e.gyro_bias[0],
        e.gyro_bias[1],
        e.gyro_bias[2],
        e.accel_var.sqrt(),
        e.g,
        match (e.mag_var, e.field) {
            (Some(v), Some((m, d))) => format!(
                "; magnetometer noise sd {:.2e}, field {m:.4} (file unit), dip {:.1}°",
                v.sqrt(),
                d.to_degrees()
            ),
            _ => String::new(),
        }
    )?;
    writeln!(
        out,
        "reference: {} (turned z-up for the comparison); filters start from the first accelerometer{} sample\n",
        if c.reference_z_down {
            "z down (NED-like)"
        } else {
            "z up"
        },
        if c.h.is_some() { " and magnetometer" } else { "" }
    )?;
    writeln!(
        out,
        "{:<10} │ {:>8} {:>8} {:>8} {:>9} {:>8} │ {:>8} {:>8} {:>8} {:>9} {:>8} │ {:>8}",
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
        "offset °"
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
            "{:<10} │ {} │ {} │ {:>8.1}",
            s.filter,
            row(&s.as_recorded),
            row(&s.offset_removed),
            s.heading_offset_deg
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
    Ok(ExitCode::SUCCESS)
}
