//! `simnet reconstruct FILE`: position from a recorded IMU file by FEM with boundary conditions, beside the trapezoid
//! rule, with the optional sensor-error model.

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;
use nalgebra::Vector3;

use super::{write_atomic, UsageError};
use crate::imu_csv::layout;
use crate::reconstruct::{self, reference_velocity, Known, Options};
use crate::report::plot;

#[derive(Args, Debug, Clone)]
pub struct ReconstructArgs {
    /// The IMU file: `t,ax,ay,az,gx,gy,gz[,mx,my,mz][,x,y,z][,roll,pitch,yaw]` (the book: docs/src/recordings.md), or a
    /// maker's export as `simnet attitude` reads it.
    pub file: PathBuf,
    #[command(flatten)]
    pub read: super::args::ReadFlags,
    /// Take the positions at both ends and the start velocity from the file's reference columns.
    #[arg(long)]
    pub from_reference: bool,
    /// Position at the first sample (a Dirichlet condition), m.
    #[arg(allow_hyphen_values = true, long, value_name = "X,Y,Z", value_parser = vec3)]
    pub start_position: Option<Vector3<f64>>,
    /// Position at the last sample (a Dirichlet condition), m.
    #[arg(allow_hyphen_values = true, long, value_name = "X,Y,Z", value_parser = vec3)]
    pub end_position: Option<Vector3<f64>>,
    /// Velocity at the first sample (a Neumann condition), m/s.
    #[arg(allow_hyphen_values = true, long, value_name = "X,Y,Z", value_parser = vec3)]
    pub start_velocity: Option<Vector3<f64>>,
    /// Velocity at the last sample (a Neumann condition), m/s.
    #[arg(allow_hyphen_values = true, long, value_name = "X,Y,Z", value_parser = vec3)]
    pub end_velocity: Option<Vector3<f64>>,
    /// A known velocity at a time (an additional constraint). Repeatable.
    #[arg(allow_hyphen_values = true, long = "velocity-at", value_name = "T:X,Y,Z", value_parser = timed)]
    pub velocity_at: Vec<(f64, Vector3<f64>)>,
    /// A known position at a time (an additional constraint). Repeatable.
    #[arg(allow_hyphen_values = true, long = "position-at", value_name = "T:X,Y,Z", value_parser = timed)]
    pub position_at: Vec<(f64, Vector3<f64>)>,
    /// With --from-reference: add the reference velocity at this many evenly spaced times as constraints.
    #[arg(allow_hyphen_values = true, long, default_value_t = 0)]
    pub reference_constraints: usize,
    /// Fit scale and bias per axis and a gravity correction from the additional constraints.
    #[arg(long)]
    pub error_model: bool,
    /// Where to write reconstruction.csv and the error plot.
    #[arg(long, default_value = "out/reconstruct")]
    pub out: PathBuf,
}

fn vec3(s: &str) -> Result<Vector3<f64>, String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>().map_err(|_| format!("`{x}` is not a number")))
        .collect::<Result<_, _>>()?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok(Vector3::new(x, y, z)),
        _ => Err(format!("expected X,Y,Z (three finite numbers), got `{s}`")),
    }
}

fn timed(s: &str) -> Result<(f64, Vector3<f64>), String> {
    let (t, v) = s
        .split_once(':')
        .ok_or_else(|| format!("expected T:X,Y,Z, got `{s}`"))?;
    let t = t.trim().parse::<f64>().map_err(|_| format!("`{t}` is not a time"))?;
    Ok((t, vec3(v)?))
}

pub fn reconstruct(args: &ReconstructArgs) -> anyhow::Result<ExitCode> {
    super::check_out(&args.out)?;
    let constrained = !args.velocity_at.is_empty() || !args.position_at.is_empty();
    if constrained && !args.error_model {
        return Err(UsageError::Option(
            "--velocity-at/--position-at constrain the error model's fit: add --error-model (without it they change nothing)"
                .into(),
        )
        .into());
    }
    let text = crate::input::read_text(&args.file, crate::input::MAX_TABLE)
        .map_err(|e| UsageError::Option(format!("cannot read {}: {e}", args.file.display())))?;
    let mut rec = layout::read_any(&text, &args.file.display().to_string(), &args.read.options())
        .map_err(|e| UsageError::Option(e.to_string()))?
        .recording;
    if rec.quat.is_some() && rec.euler.is_none() {
        // A maker's quaternion may be z down (NED): reconstruction integrates in simnet's z-up frame.
        rec.quat = crate::analysis::attitude::reference_up(&rec).ok().map(|(q, _)| q);
    }
    let n = rec.t.len();
    let mut o = Options {
        start: args
            .start_position
            .map(Known::Position)
            .or(args.start_velocity.map(Known::Velocity)),
        end: args
            .end_position
            .map(Known::Position)
            .or(args.end_velocity.map(Known::Velocity)),
        start_velocity: args.start_velocity,
        error_model: args.error_model,
        ..Default::default()
    };
    o.constraints
        .extend(args.velocity_at.iter().map(|(t, v)| (*t, Known::Velocity(*v))));
    o.constraints
        .extend(args.position_at.iter().map(|(t, p)| (*t, Known::Position(*p))));
    if args.from_reference {
        let p = rec
            .position
            .as_ref()
            .ok_or_else(|| UsageError::Option("--from-reference: the file has no x,y,z reference columns".into()))?;
        let v = reference_velocity(&rec.t, p);
        o.start = Some(Known::Position(p[0]));
        o.end = Some(Known::Position(p[n - 1]));
        o.start_velocity = Some(v[0]);
        let m = args.reference_constraints;
        for j in 0..m {
            let i = (j + 1) * (n - 1) / (m + 1);
            o.constraints.push((rec.t[i], Known::Velocity(v[i])));
        }
    }
    let r = reconstruct::reconstruct(&rec, &o).map_err(|e| match e {
        reconstruct::ReconstructError::Bvp(b) => anyhow::anyhow!(b),
        other => anyhow::Error::new(UsageError::Option(other.to_string())),
    })?;

    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "{}: {n} samples over {:.2} s; attitude from {}",
        args.file.display(),
        rec.t[n - 1] - rec.t[0],
        if rec.euler.is_some() || rec.quat.is_some() {
            "the reference columns"
        } else {
            "the integrated gyro"
        }
    )?;
    let mut methods: Vec<(&str, &Vec<Vector3<f64>>)> = Vec::new();
    if let Some(tr) = &r.trapezoid {
        methods.push(("trapezoid rule (initial values)", tr));
    }
    methods.push(("FEM (boundary values)", &r.fem));
    if let Some((m, _)) = &r.model {
        methods.push(("FEM + error model", m));
    }
    if let Some(p) = &rec.position {
        writeln!(
            out,
            "\n| method | max error (m) | mean error (m) | error at the middle (m) |\n|---|---|---|---|"
        )?;
        for (name, x) in &methods {
            let e: Vec<f64> = x.iter().zip(p).map(|(a, b)| (a - b).norm()).collect();
            writeln!(
                out,
                "| {name} | {:.4} | {:.4} | {:.4} |",
                e.iter().copied().fold(0.0, f64::max),
                e.iter().sum::<f64>() / n as f64,
                e[n / 2]
            )?;
        }
    }
    if let Some((_, th)) = &r.model {
        writeln!(
            out,
            "\nerror model: scale corrections {:+.4} {:+.4} {:+.4}; biases {:+.4} {:+.4} {:+.4} m/s²; gravity correction {:+.4} {:+.4} {:+.4} m/s²",
            th[0], th[1], th[2], th[3], th[4], th[5], th[6], th[7], th[8]
        )?;
    }
    std::fs::create_dir_all(&args.out)?;
    let mut csv = String::from("t");
    for (name, _) in &methods {
        let key = name.split_whitespace().next().unwrap_or("m").to_lowercase();
        csv.push_str(&format!(",{key}_x,{key}_y,{key}_z"));
    }
    csv.push('\n');
    for i in 0..n {
        csv.push_str(&rec.t[i].to_string());
        for (_, x) in &methods {
            csv.push_str(&format!(",{},{},{}", x[i][0], x[i][1], x[i][2]));
        }
        csv.push('\n');
    }
    write_atomic(&args.out.join("reconstruction.csv"), csv.as_bytes())?;
    if let Some(p) = &rec.position {
        let series: Vec<(String, Vec<(f64, f64)>)> = methods
            .iter()
            .map(|(name, x)| {
                (
                    name.to_string(),
                    rec.t
                        .iter()
                        .zip(x.iter().zip(p))
                        .map(|(t, (a, b))| (*t, (a - b).norm()))
                        .collect(),
                )
            })
            .collect();
        let svg = plot::lines(&series, "t (s)", "position error (m)", true, "reconstruction error")?;
        write_atomic(&args.out.join("reconstruction.svg"), svg.as_bytes())?;
        writeln!(
            out,
            "\nwrote {}/{{reconstruction.csv, reconstruction.svg}}",
            args.out.display()
        )?;
    } else {
        // Without a reference position there is no error to plot.
        writeln!(out, "\nwrote {}/reconstruction.csv", args.out.display())?;
    }
    Ok(ExitCode::SUCCESS)
}
