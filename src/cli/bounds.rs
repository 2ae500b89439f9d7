//! `simnet bounds`: the covariance bounds of a linear model under intermittent observations.

use super::*;
use crate::analysis::bounds::BoundsError;

#[derive(Args, Debug, Clone)]
pub struct BoundsArgs {
    /// A topology with a linear model (its A, C, Q, R; --measure runs it).
    #[arg(long, short = 't')]
    pub topology: Option<String>,
    /// A as a TOML array, e.g. '[[-1.25]]' (instead of a topology).
    #[arg(long, allow_hyphen_values = true)]
    pub a: Option<String>,
    /// C (outputs × states) as a TOML array, with --a.
    #[arg(long)]
    pub c: Option<String>,
    /// Q, the process noise covariance, as a TOML array, with --a.
    #[arg(long)]
    pub q: Option<String>,
    /// R, the measurement noise covariance, as a TOML array, with --a.
    #[arg(long)]
    pub r: Option<String>,
    /// Arrival rate λ at which to give S̄ and V̄ (default: 1 − the topology's link loss, or 0.5).
    #[arg(allow_hyphen_values = true, long, value_parser = probability)]
    pub lambda: Option<f64>,
    /// Also run the topology at that arrival rate and print the measured mean trace P_{k|k−1}.
    #[arg(long)]
    pub measure: bool,
    /// Bounds (and measurements, with --measure) over a grid of arrival rates, with a plot.
    #[arg(long)]
    pub sweep: bool,
    /// Where --sweep writes bounds.csv and bounds.svg (default out/bounds).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Simulated duration of each --measure run, s.
    #[arg(allow_hyphen_values = true, long, value_parser = positive)]
    pub duration: Option<f64>,
    /// Seed of each --measure run (default: the topology's).
    #[arg(allow_hyphen_values = true, long)]
    pub seed: Option<u64>,
}

pub(super) fn matrix_arg(name: &str, text: &str) -> Result<nalgebra::DMatrix<f64>, UsageError> {
    #[derive(serde::Deserialize)]
    struct M {
        m: Vec<Vec<f64>>,
    }
    let rows = toml::from_str::<M>(&format!("m = {text}"))
        .map_err(|e| {
            UsageError::Option(format!(
                "--{name}: expected a TOML array of rows such as [[1.0, 0.1], [0.0, 1.0]]: {e}"
            ))
        })?
        .m;
    let c = rows.first().map_or(0, |r| r.len());
    if rows.is_empty() || c == 0 || rows.iter().any(|r| r.len() != c) {
        return Err(UsageError::Option(format!(
            "--{name}: rows must be non-empty and of equal length"
        )));
    }
    Ok(nalgebra::DMatrix::from_fn(rows.len(), c, |i, j| rows[i][j]))
}

#[allow(non_snake_case)] // the textbook names A, C, Q, R
/// A study error the user caused (a topology that is not linear, nothing to measure, a bad matrix) exits 2.
fn usage(e: BoundsError) -> anyhow::Error {
    match e {
        BoundsError::Scenario(e) => UsageError::Scenario(e).into(),
        e @ (BoundsError::NotLinear { .. } | BoundsError::NoEstimator(_)) => UsageError::Option(e.to_string()).into(),
        e => e.into(),
    }
}

pub(super) fn bounds(args: &BoundsArgs) -> anyhow::Result<ExitCode> {
    use crate::analysis::bounds::{self as study, System};
    use crate::estimate::bounds::FixedPoint;
    use crate::link::LossModel;
    let topo = match &args.topology {
        Some(t) => {
            let o = Overrides {
                duration_s: args.duration,
                seed: args.seed,
                ..Default::default()
            };
            Some(
                Scenario::resolve(t)
                    .and_then(|t| t.with(&o))
                    .map_err(UsageError::from)?,
            )
        }
        None => None,
    };
    let sys = match (&topo, &args.a, &args.c, &args.q, &args.r) {
        (Some(t), None, None, None, None) => System::of(t).map_err(usage)?,
        (None, Some(a), Some(c), Some(q), Some(r)) => System::new(
            matrix_arg("a", a)?,
            matrix_arg("c", c)?,
            matrix_arg("q", q)?,
            matrix_arg("r", r)?,
            "--a/--c/--q/--r",
        )
        .map_err(usage)?,
        _ => return Err(UsageError::Option("give --topology (linear model), or all of --a --c --q --r".into()).into()),
    };
    let out = args.out.clone().unwrap_or_else(|| PathBuf::from("out/bounds"));
    match (args.sweep, &args.out) {
        (true, _) => check_out(&out)?,
        (false, Some(_)) => {
            return Err(UsageError::Option(
                "--out is where --sweep writes: add --sweep (nothing else is written)".into(),
            )
            .into())
        }
        (false, None) => {}
    }
    if args.measure && topo.is_none() {
        return Err(UsageError::Option("--measure runs a topology: give --topology".into()).into());
    }
    let link_loss = topo.as_ref().and_then(|t| t.links().first().map(|l| l.config.loss));
    let lambda = args
        .lambda
        .unwrap_or_else(|| link_loss.map_or(0.5, |l| 1.0 - l.stationary_loss()));
    let st = study::stability(&sys).map_err(usage)?;
    let (crit, lbar, lmin) = (st.critical, st.critical.value(), st.lambda_min);
    outln!(
        "system: {} states, {} outputs; ρ(A) = {:.6}",
        sys.A.nrows(),
        sys.C.nrows(),
        st.rho
    );
    outln!("λ_min = {lmin:.6}   (1 − 1/ρ(A)²: below it the expected covariance diverges)");
    if !lbar.is_finite() {
        outln!("λ̄     = ∞   (even without loss the filter is unstable: an undetectable unstable mode)");
    } else if crit.lo == crit.hi {
        outln!("λ̄     = {lbar:.6}   (C is invertible: λ̄ = λ_min exactly, Sinopoli et al. Thm. 6)");
    } else if crit.to_tolerance {
        outln!(
            "λ̄     ∈ ({:.7}, {:.7}]   (bisection: the MARE iteration from 0 diverges at the left end, converges at the right)",
            crit.lo, crit.hi
        );
    } else {
        outln!(
            "λ̄     ∈ ({:.7}, {:.7}]   (bisection stopped where the MARE iteration neither converged nor diverged in {:.0e} steps: this is the precision reached)",
            crit.lo, crit.hi, crate::estimate::bounds::MAX_ITER as f64
        );
    }
    let fmt = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.4}"));
    let fmt_fp = |v: &FixedPoint| match v {
        FixedPoint::Converged(m) => format!("{:.4}", m.trace()),
        FixedPoint::Diverged => "∞ (no fixed point)".into(),
        FixedPoint::Undecided => "not reached (the iteration still creeps: at the edge of stability)".into(),
    };
    let trace_of = |v: &FixedPoint| v.matrix().map(|m| m.trace());
    let (sf, vf) = study::at(&sys, lambda).map_err(usage)?;
    let (s, v) = (trace_of(&sf), trace_of(&vf));
    let bursty = matches!(link_loss, Some(LossModel::GilbertElliott { .. }));
    out!(
        "λ = {lambda}{}: trace S̄ = {}, trace V̄ = {}",
        if bursty {
            " (i.i.d. arrivals at the link's mean rate: NOT bounds for its bursty loss)"
        } else {
            ""
        },
        fmt_fp(&sf),
        fmt_fp(&vf)
    );
    let measured_on = topo.as_ref().filter(|_| args.measure);
    if let (Some(t), false) = (measured_on, args.sweep) {
        let m = study::measure(t, lambda).map_err(usage)?;
        out!(", measured mean trace P_(k|k−1) = {}", fmt(m));
        if let (Some(s), Some(v), Some(m), false) = (s, v, m, bursty) {
            out!(
                " ({})",
                if s <= m && m <= v {
                    "within the bounds"
                } else {
                    "OUTSIDE the bounds"
                }
            );
        }
    }
    outln!();
    if let Some(((lhs, decay, ok), exact)) = link_loss.as_ref().and_then(|l| study::markov(&sys, l)) {
        let Some(LossModel::GilbertElliott {
            p,
            r,
            one_minus_h,
            one_minus_k,
        }) = link_loss
        else {
            unreachable!("markov() is Some only for Gilbert–Elliott loss")
        };
        outln!(
            "Gilbert–Elliott link (p = {p}, r = {r}, 1−h = {one_minus_h}, 1−k = {one_minus_k}): loss runs decay at ρ(T·diag(1−k, 1−h)) = {decay:.4} per step; ρ(A)²·{decay:.4} = {lhs:.4} {} 1 → {}",
            if ok { "<" } else { "≥" },
            match (ok, exact) {
                (true, true) => "satisfied: the expected covariance stays bounded (necessary and sufficient here: scalar or C invertible; You, Fu & Xie 2011)",
                (true, false) => "satisfied, but only necessary for this system (Huang & Dey 2007): boundedness is not shown",
                (false, _) => "NOT satisfied: the expected covariance diverges (Huang & Dey 2007)",
            }
        );
    }
    if args.sweep {
        use anyhow::Context;
        let cell = |f: &FixedPoint| match f {
            FixedPoint::Converged(m) => format!("{:.4}", m.trace()),
            FixedPoint::Diverged => "∞".into(),
            FixedPoint::Undecided => "not reached".into(),
        };
        outln!("\n{:>8} {:>12} {:>12} {:>12}", "λ", "trace S̄", "trace V̄", "measured");
        let rows = study::sweep(&sys, &study::grid(&st), measured_on, &mut |r| {
            // A closed stdout stops the printing, not the sweep: its files are still written, and the next line
            // printed after it returns the error.
            use std::io::Write as _;
            let _ = writeln!(
                std::io::stdout(),
                "{:>8.4} {:>12} {:>12} {:>12}",
                r.lambda,
                cell(&r.lower),
                cell(&r.upper),
                r.measured.map_or("—".into(), |x| format!("{x:.4}"))
            );
        })
        .map_err(usage)?;
        std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
        write_atomic(&out.join("bounds.csv"), study::csv(&rows).as_bytes())?;
        let points: Vec<plot::BoundsRow> = rows
            .iter()
            .map(|r| (r.lambda, trace_of(&r.lower), trace_of(&r.upper), r.measured))
            .collect();
        let svg = plot::covariance_bounds(
            &points,
            lmin,
            lbar,
            &format!(
                "covariance bounds against the arrival rate{}",
                topo.as_ref().map_or(String::new(), |t| format!(" — {}", t.name()))
            ),
        )?;
        write_atomic(&out.join("bounds.svg"), svg.as_bytes())?;
        outln!("\nwrote {}/{{bounds.csv, bounds.svg}}", out.display());
    }
    Ok(ExitCode::SUCCESS)
}
