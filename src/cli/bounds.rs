//! `simnet bounds`: the covariance bounds of a linear model under intermittent observations.

use super::*;

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
    /// Where --sweep writes bounds.csv and bounds.svg.
    #[arg(long, default_value = "out/bounds")]
    pub out: PathBuf,
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
pub(super) fn bounds(args: &BoundsArgs) -> anyhow::Result<ExitCode> {
    use crate::estimate::bounds::{
        critical_upper, lambda_min, lower_bound, markov_condition, spectral_radius, upper_bound,
    };
    use crate::link::LossModel;
    let topo = match &args.topology {
        Some(t) => {
            let topo = Scenario::resolve(t)
                .and_then(|t| {
                    t.with(&Overrides {
                        duration_s: args.duration,
                        seed: args.seed,
                        ..Default::default()
                    })
                })
                .map_err(UsageError::from)?;
            Some(topo)
        }
        None => None,
    };
    let (A, C, Q, R) = match (&topo, &args.a, &args.c, &args.q, &args.r) {
        (Some(t), None, None, None, None) => match t.model().as_linear() {
            Some(m) => (m.A().clone(), m.C().clone(), m.Q().clone(), m.R().clone()),
            None => {
                return Err(UsageError::Option(format!(
                    "`{}` has a {} model: bounds need kind = \"linear\"",
                    t.name(),
                    t.model().get().kind()
                ))
                .into())
            }
        },
        (None, Some(a), Some(c), Some(q), Some(r)) => (
            matrix_arg("a", a)?,
            matrix_arg("c", c)?,
            matrix_arg("q", q)?,
            matrix_arg("r", r)?,
        ),
        _ => return Err(UsageError::Option("give --topology (linear model), or all of --a --c --q --r".into()).into()),
    };
    // The same checks as a topology's [model].
    let text = format!(
        "[model]\nkind = \"linear\"\na = {}\nc = {}\nq = {}\nr = {}\n[[node]]\nid = 0\n",
        toml_matrix(&A),
        toml_matrix(&C),
        toml_matrix(&Q),
        toml_matrix(&R)
    );
    Scenario::from_toml(&text, "--a/--c/--q/--r").map_err(UsageError::from)?;
    if args.sweep {
        check_out(&args.out)?;
    }
    if args.measure && topo.is_none() {
        return Err(UsageError::Option("--measure runs a topology: give --topology".into()).into());
    }
    let link_loss = topo.as_ref().and_then(|t| t.links().first().map(|l| l.config.loss));
    let lambda = args
        .lambda
        .unwrap_or_else(|| link_loss.map_or(0.5, |l| 1.0 - l.stationary_loss()));
    let rho = spectral_radius(&A).ok_or_else(|| anyhow::anyhow!("the eigenvalues of A did not converge"))?;
    let lmin = lambda_min(&A).unwrap_or(f64::NAN);
    let crit = critical_upper(&A, &C, &Q, &R, 1e-6)?;
    let lbar = crit.value();
    println!("system: {} states, {} outputs; ρ(A) = {rho:.6}", A.nrows(), C.nrows());
    println!("λ_min = {lmin:.6}   (1 − 1/ρ(A)²: below it the expected covariance diverges)");
    if !lbar.is_finite() {
        println!("λ̄     = ∞   (even without loss the filter is unstable: an undetectable unstable mode)");
    } else if crit.lo == crit.hi {
        println!("λ̄     = {lbar:.6}   (C is invertible: λ̄ = λ_min exactly, Sinopoli et al. Thm. 6)");
    } else if crit.to_tolerance {
        println!(
            "λ̄     ∈ ({:.7}, {:.7}]   (bisection: the MARE iteration from 0 diverges at the left end, converges at the right)",
            crit.lo, crit.hi
        );
    } else {
        println!(
            "λ̄     ∈ ({:.7}, {:.7}]   (bisection stopped where the MARE iteration neither converged nor diverged in {:.0e} steps: this is the precision reached)",
            crit.lo, crit.hi, crate::estimate::bounds::MAX_ITER as f64
        );
    }
    let measure = |l: f64| -> anyhow::Result<Option<f64>> {
        let Some(t) = &topo else { return Ok(None) };
        let t = t.with(&Overrides {
            loss: Some(LossModel::Bernoulli { p: 1.0 - l }),
            ..Default::default()
        })?;
        let estimators: Vec<u32> = t
            .nodes()
            .iter()
            .filter(|n| n.role == crate::scenario::Role::Estimator)
            .map(|n| n.id)
            .collect();
        if estimators.is_empty() {
            return Err(UsageError::Option(format!(
                "--measure: `{}` has no estimator node fed over the network",
                t.name()
            ))
            .into());
        }
        // In memory: the same figures as the virtual clock over sockets.
        let s = crate::sim::Sim::new(&t)?.run()?.summary();
        let v: Vec<f64> = s
            .nodes
            .iter()
            .filter(|n| estimators.contains(&n.id))
            .filter_map(|n| n.networked.as_ref().and_then(|f| f.mean_trace_p_prior))
            .collect();
        Ok((!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64))
    };
    use crate::estimate::bounds::FixedPoint;
    let at = |l: f64| -> anyhow::Result<(FixedPoint, FixedPoint)> {
        Ok((lower_bound(&A, &Q, l)?, upper_bound(&A, &C, &Q, &R, l)?))
    };
    let fmt = |v: Option<f64>| v.map_or("—".to_string(), |x| format!("{x:.4}"));
    let fmt_fp = |v: &FixedPoint| match v {
        FixedPoint::Converged(m) => format!("{:.4}", m.trace()),
        FixedPoint::Diverged => "∞ (no fixed point)".into(),
        FixedPoint::Undecided => "not reached (the iteration still creeps: at the edge of stability)".into(),
    };
    let trace_of = |v: &FixedPoint| v.matrix().map(|m| m.trace());
    let (sf, vf) = at(lambda)?;
    let (s, v) = (trace_of(&sf), trace_of(&vf));
    let bursty = matches!(link_loss, Some(LossModel::GilbertElliott { .. }));
    print!(
        "λ = {lambda}{}: trace S̄ = {}, trace V̄ = {}",
        if bursty {
            " (i.i.d. arrivals at the link's mean rate: NOT bounds for its bursty loss)"
        } else {
            ""
        },
        fmt_fp(&sf),
        fmt_fp(&vf)
    );
    if args.measure && !args.sweep {
        let m = measure(lambda)?;
        print!(", measured mean trace P_(k|k−1) = {}", fmt(m));
        if let (Some(s), Some(v), Some(m), false) = (s, v, m, bursty) {
            print!(
                " ({})",
                if s <= m && m <= v {
                    "within the bounds"
                } else {
                    "OUTSIDE the bounds"
                }
            );
        }
    }
    println!();
    if let Some(LossModel::GilbertElliott {
        p,
        r,
        one_minus_h,
        one_minus_k,
    }) = link_loss
    {
        if let Some((lhs, decay, ok)) = markov_condition(&A, p, r, one_minus_h, one_minus_k) {
            let exact = A.nrows() == 1 || (C.is_square() && C.clone().try_inverse().is_some());
            println!(
                "Gilbert–Elliott link (p = {p}, r = {r}, 1−h = {one_minus_h}, 1−k = {one_minus_k}): loss runs decay at ρ(T·diag(1−k, 1−h)) = {decay:.4} per step; ρ(A)²·{decay:.4} = {lhs:.4} {} 1 → {}",
                if ok { "<" } else { "≥" },
                match (ok, exact) {
                    (true, true) => "satisfied: the expected covariance stays bounded (necessary and sufficient here: scalar or C invertible; You, Fu & Xie 2011)",
                    (true, false) => "satisfied, but only necessary for this system (Huang & Dey 2007): boundedness is not shown",
                    (false, _) => "NOT satisfied: the expected covariance diverges (Huang & Dey 2007)",
                }
            );
        }
    }
    if args.sweep {
        use anyhow::Context;
        let start = if lbar.is_finite() { lbar } else { lmin };
        let grid: Vec<f64> = (1..=12)
            .map(|i| start + (1.0 - start) * i as f64 / 12.0)
            .filter(|l| *l < 1.0 + 1e-12)
            .collect();
        let mut rows = Vec::new();
        println!("\n{:>8} {:>12} {:>12} {:>12}", "λ", "trace S̄", "trace V̄", "measured");
        for l in grid {
            let (sf, vf) = at(l)?;
            let (s, v) = (trace_of(&sf), trace_of(&vf));
            let m = if args.measure { measure(l)? } else { None };
            let cell = |f: &FixedPoint| match f {
                FixedPoint::Converged(m) => format!("{:.4}", m.trace()),
                FixedPoint::Diverged => "∞".into(),
                FixedPoint::Undecided => "not reached".into(),
            };
            println!(
                "{:>8.4} {:>12} {:>12} {:>12}",
                l,
                cell(&sf),
                cell(&vf),
                m.map_or("—".into(), |x| format!("{x:.4}"))
            );
            rows.push((l, s, v, m));
        }
        std::fs::create_dir_all(&args.out).with_context(|| format!("cannot create {}", args.out.display()))?;
        let mut csv = String::from("lambda,trace_s_bar,trace_v_bar,measured_trace_p_prior\n");
        let o = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x}"));
        for (l, s, v, m) in &rows {
            csv += &format!("{l},{},{},{}\n", o(*s), o(*v), o(*m));
        }
        write_atomic(&args.out.join("bounds.csv"), csv.as_bytes())?;
        let svg = plot::covariance_bounds(
            &rows,
            lmin,
            lbar,
            &format!(
                "covariance bounds against the arrival rate{}",
                topo.as_ref().map_or(String::new(), |t| format!(" — {}", t.name()))
            ),
        )?;
        write_atomic(&args.out.join("bounds.svg"), svg.as_bytes())?;
        println!("\nwrote {}/{{bounds.csv, bounds.svg}}", args.out.display());
    }
    Ok(ExitCode::SUCCESS)
}

pub(super) fn toml_matrix(m: &nalgebra::DMatrix<f64>) -> String {
    let rows: Vec<String> = (0..m.nrows())
        .map(|i| {
            format!(
                "[{}]",
                (0..m.ncols())
                    .map(|j| format!("{:?}", m[(i, j)]))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })
        .collect();
    format!("[{}]", rows.join(", "))
}
