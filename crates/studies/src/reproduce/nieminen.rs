//! `simnet reproduce nieminen`: the rate-table example of the boundary-value paper (Nieminen et al. (2010), §6, Table 1). An
//! accelerometer on a turntable measures the tangential acceleration r·α(t); the table spins `spins` times with the
//! rate profile ω = ω_max sin²(π τ/T_s), at rest before and after. Three methods give velocity and position along the
//! arc: I, double integration by the trapezoid rule (known start); II, FEM with Dirichlet conditions (known positions
//! at both ends); III, FEM with Dirichlet conditions and the sensor-error model a = s·a_m + b fitted from the known
//! velocities at both ends (additional Neumann conditions). I and II remove the bias averaged over the initial rest,
//! as the paper does. The paper does not give its profile or sensor figures; these are stated here.

use rand::Rng as _;
use rand_distr::StandardNormal;
use serde::Serialize;

use super::Claim;
use simnet_engine::estimate::bvp::{fit_error_model, solve, trapezoid, velocity, Constraint, End};
use simnet_engine::report::plot;
use simnet_engine::rng;

#[derive(Debug, Clone, Serialize)]
pub struct Test {
    pub name: &'static str,
    pub spins: usize,
    pub revolutions: f64,
    pub spin_s: f64,
}

/// Test 1: ten spins, seven revolutions; test 2: the same form scaled to a longer run.
pub fn tests() -> [Test; 2] {
    [
        Test {
            name: "test 1",
            spins: 10,
            revolutions: 7.0,
            spin_s: 2.0,
        },
        Test {
            name: "test 2",
            spins: 10,
            revolutions: 10.0,
            spin_s: 6.0,
        },
    ]
}

#[derive(Debug, Clone)]
pub struct Sensor {
    pub rate_hz: f64,
    /// Radius of the accelerometer on the table, m.
    pub radius: f64,
    pub bias: f64,
    pub scale: f64,
    /// White noise per sample, m/s².
    pub noise: f64,
    /// Rest before and after the spins, s.
    pub rest_s: f64,
    pub seed: u64,
}

impl Default for Sensor {
    fn default() -> Self {
        // A consumer-grade MEMS accelerometer: 10 mg bias, 2 % scale error, 1 mg noise per sample.
        Sensor {
            rate_hz: 100.0,
            radius: 0.25,
            bias: 0.098,
            scale: 1.02,
            noise: 0.0098,
            rest_s: 2.0,
            seed: 1,
        }
    }
}

/// Sample times, true arc position, velocity, acceleration, and the measurement.
pub struct Record {
    pub t: Vec<f64>,
    pub x: Vec<f64>,
    pub v: Vec<f64>,
    pub measured: Vec<f64>,
}

pub fn record(test: &Test, s: &Sensor) -> Record {
    let w_max = 2.0 * std::f64::consts::PI * test.revolutions * 2.0 / (test.spins as f64 * test.spin_s);
    let spin_total = test.spins as f64 * test.spin_s;
    let duration = spin_total + 2.0 * s.rest_s;
    let n = (duration * s.rate_hz).round() as usize + 1;
    let mut noise = rng::stream(s.seed, "nieminen", test.spins as u64, test.spin_s.to_bits());
    let (mut t, mut x, mut v, mut m) = (vec![], vec![], vec![], vec![]);
    let pi = std::f64::consts::PI;
    for k in 0..n {
        let tk = k as f64 / s.rate_hz;
        let tau = (tk - s.rest_s).clamp(0.0, spin_total);
        let spins_done = (tau / test.spin_s).floor().min(test.spins as f64 - 1.0);
        let u = tau - spins_done * test.spin_s;
        let active = tk > s.rest_s && tk < s.rest_s + spin_total;
        // ω = ω_max sin²(πu/T), θ = ω_max (u/2 − T sin(2πu/T)/(4π)) per spin; α = ω_max (π/T) sin(2πu/T).
        let theta = spins_done * w_max * test.spin_s / 2.0
            + w_max * (u / 2.0 - test.spin_s * (2.0 * pi * u / test.spin_s).sin() / (4.0 * pi));
        let omega = if active {
            w_max * (pi * u / test.spin_s).sin().powi(2)
        } else {
            0.0
        };
        let alpha = if active {
            w_max * pi / test.spin_s * (2.0 * pi * u / test.spin_s).sin()
        } else {
            0.0
        };
        let a = s.radius * alpha;
        t.push(tk);
        x.push(s.radius * theta);
        v.push(s.radius * omega);
        m.push(s.scale * a + s.bias + noise.sample::<f64, _>(StandardNormal) * s.noise);
    }
    Record { t, x, v, measured: m }
}

/// Errors of one method at the three check points (¼, ½, ¾ of the record).
#[derive(Debug, Clone, Serialize)]
pub struct MethodErrors {
    pub method: &'static str,
    pub velocity: [f64; 3],
    pub position: [f64; 3],
    /// Largest position error over the record.
    pub max_position: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct TestResult {
    pub test: Test,
    pub duration_s: f64,
    pub distance_m: f64,
    pub methods: [MethodErrors; 3],
    /// Method III's fitted scale and bias.
    pub fitted_scale: f64,
    pub fitted_bias: f64,
}

/// Position errors over the record of methods I, II and III: (t, [I, II, III]).
pub type Tracks = Vec<(f64, [f64; 3])>;

pub fn run_test(test: &Test, s: &Sensor) -> Result<(TestResult, Tracks), simnet_engine::estimate::bvp::BvpError> {
    let r = record(test, s);
    let n = r.t.len();
    let rest = (s.rest_s * s.rate_hz) as usize;
    let bias_est = r.measured[..rest.max(1)].iter().sum::<f64>() / rest.max(1) as f64;
    let debiased: Vec<f64> = r.measured.iter().map(|m| m - bias_est).collect();
    let (x0, xn) = (r.x[0], r.x[n - 1]);
    let m1 = trapezoid(&r.t, &debiased, x0, 0.0);
    let m2 = solve(&r.t, &debiased, End::Position(x0), End::Position(xn))?;
    // III: a = s·a_m + b; the velocities at both ends (the table is at rest) are the additional constraints.
    let zeros = vec![0.0; n];
    let ones = vec![1.0; n];
    let (theta, m3) = fit_error_model(
        &r.t,
        &zeros,
        &[r.measured.clone(), ones],
        End::Position(x0),
        End::Position(xn),
        &[
            Constraint::Velocity { t: r.t[0], value: 0.0 },
            Constraint::Velocity {
                t: r.t[n - 1],
                value: 0.0,
            },
        ],
    )?;
    let points = [n / 4, n / 2, 3 * n / 4];
    let errors = |method: &'static str, x: &[f64]| {
        let v = velocity(&r.t, x);
        MethodErrors {
            method,
            velocity: points.map(|i| v[i] - r.v[i]),
            position: points.map(|i| x[i] - r.x[i]),
            max_position: x.iter().zip(&r.x).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max),
        }
    };
    let tracks = (0..n)
        .map(|i| (r.t[i], [m1[i] - r.x[i], m2[i] - r.x[i], m3[i] - r.x[i]]))
        .collect();
    // With a = s·a_m + b the measurement model a_m = (a − b)/s: the sensor's scale is 1/θ₀, its bias −θ₁/θ₀.
    let result = TestResult {
        test: test.clone(),
        duration_s: r.t[n - 1],
        distance_m: xn - x0,
        methods: [errors("I", &m1), errors("II", &m2), errors("III", &m3)],
        fitted_scale: 1.0 / theta[0],
        fitted_bias: -theta[1] / theta[0],
    };
    Ok((result, tracks))
}

pub struct Output {
    pub results: Vec<TestResult>,
    pub table: String,
    pub claims: Vec<Claim>,
    pub plots: Vec<(String, String)>,
}

/// A claim counts as reproduced when it holds on at least this fraction of the seeds.
pub const HOLDS_ON: f64 = 0.9;

/// Identification counts as done when the fitted scale and bias leave less than this fraction of the injected
/// errors (s − 1 and b).
pub const IDENTIFIED: f64 = 0.25;

/// Both tests on `seeds` seeds from `s.seed`; the table shows the first seed, the claims are judged on every seed.
pub fn run(s: &Sensor, seeds: u64) -> Result<Output, super::ReproduceError> {
    let seeds = seeds.max(1);
    let mut per_seed: Vec<Vec<TestResult>> = Vec::new();
    let mut tracks: Vec<Tracks> = Vec::new();
    for i in 0..seeds {
        let sensor = Sensor {
            seed: s.seed + i,
            ..s.clone()
        };
        let (results, tr): (Vec<TestResult>, Vec<Tracks>) = tests()
            .iter()
            .map(|t| run_test(t, &sensor))
            .collect::<Result<Vec<_>, _>>()?
            .into_iter()
            .unzip();
        if i == 0 {
            tracks = tr;
        }
        per_seed.push(results);
    }
    let results = per_seed[0].clone();
    let mut table = String::from(
        "| test | method | Δv at P1, P2, P3 (m/s) | Δx at P1, P2, P3 (m) | max ‖Δx‖ (m) |\n|---|---|---|---|---|\n",
    );
    for r in &results {
        for m in &r.methods {
            table.push_str(&format!(
                "| {} ({:.0} s, {:.1} m) | {} | {:+.4}, {:+.4}, {:+.4} | {:+.4}, {:+.4}, {:+.4} | {:.4} |\n",
                r.test.name,
                r.duration_s,
                r.distance_m,
                m.method,
                m.velocity[0],
                m.velocity[1],
                m.velocity[2],
                m.position[0],
                m.position[1],
                m.position[2],
                m.max_position
            ));
        }
    }
    let abs_max = |a: &[f64; 3]| a.iter().map(|v| v.abs()).fold(0.0, f64::max);
    let n = per_seed.len();
    // Per seed: (holds, figures) of each claim.
    let count = |f: &dyn Fn(&[TestResult]) -> bool| per_seed.iter().filter(|r| f(r)).count();
    let verdict = |k: usize| (k as f64 >= HOLDS_ON * n as f64, format!("holds on {k}/{n} seeds"));
    let med = |f: &dyn Fn(&[TestResult]) -> f64| {
        simnet_engine::stats::median(&per_seed.iter().map(|r| f(r)).collect::<Vec<_>>())
    };

    let grows = |r: &[TestResult]| {
        r.iter()
            .all(|t| t.methods[0].position[2].abs() > t.methods[0].position[0].abs())
    };
    let fem_beats = |r: &[TestResult]| {
        let long = &r[1];
        abs_max(&long.methods[1].position) < abs_max(&long.methods[0].position)
            && abs_max(&long.methods[1].velocity) < abs_max(&long.methods[0].velocity)
    };
    let iii_best = |r: &[TestResult]| {
        r.iter().all(|t| {
            (0..2).all(|k| {
                abs_max(&t.methods[2].position) < abs_max(&t.methods[k].position)
                    && abs_max(&t.methods[2].velocity) < abs_max(&t.methods[k].velocity)
            })
        })
    };
    // Left over of the injected errors after the fit: |ŝ − s| / |s − 1| and |b̂ − b| / |b|.
    let left = |t: &TestResult| {
        (
            (t.fitted_scale - s.scale).abs() / (s.scale - 1.0).abs(),
            (t.fitted_bias - s.bias).abs() / s.bias.abs(),
        )
    };
    let identified = |r: &[TestResult]| {
        r.iter().all(|t| {
            let (a, b) = left(t);
            a < IDENTIFIED && b < IDENTIFIED
        })
    };
    let claim = |id, source, claim, k: usize, figures: String| {
        let (holds, v) = verdict(k);
        Claim {
            id,
            source,
            claim,
            figures: format!("{v}; median over seeds: {figures}"),
            holds,
        }
    };
    let claims = vec![
        claim(
            "1",
            "§6, Table 1",
            "Time stepping (method I) increases the error with time",
            count(&grows),
            (0..2)
                .map(|t| {
                    format!(
                        "{}: ‖Δx‖ {:.4} m at P1, {:.4} m at P3",
                        results[t].test.name,
                        med(&|r| r[t].methods[0].position[0].abs()),
                        med(&|r| r[t].methods[0].position[2].abs())
                    )
                })
                .collect::<Vec<_>>()
                .join("; "),
        ),
        claim(
            "2",
            "§6, Table 1",
            "FEM with Dirichlet conditions (II) gives much better estimates than I in the longer test",
            count(&fem_beats),
            format!(
                "test 2: largest ‖Δx‖ at the points {:.4} m (II) against {:.4} m (I); ‖Δv‖ {:.4} against {:.4} m/s",
                med(&|r| abs_max(&r[1].methods[1].position)),
                med(&|r| abs_max(&r[1].methods[0].position)),
                med(&|r| abs_max(&r[1].methods[1].velocity)),
                med(&|r| abs_max(&r[1].methods[0].velocity))
            ),
        ),
        claim(
            "3",
            "§6, Table 1",
            "FEM with the sensor-error model (III) clearly outperforms I and II in each test",
            count(&iii_best),
            (0..2)
                .map(|t| {
                    format!(
                        "{}: largest ‖Δx‖ {:.5} m (III), {:.4} (II), {:.4} (I)",
                        results[t].test.name,
                        med(&|r| abs_max(&r[t].methods[2].position)),
                        med(&|r| abs_max(&r[t].methods[1].position)),
                        med(&|r| abs_max(&r[t].methods[0].position))
                    )
                })
                .collect::<Vec<_>>()
                .join("; "),
        ),
        claim(
            "4",
            "§5.2",
            "The additional constraints identify the sensor's bias and scale",
            count(&identified),
            format!(
                "{}; identified = less than {:.0} % of each injected error (scale {:+.2}, bias {} m/s²) left",
                (0..2)
                    .map(|t| {
                        format!(
                            "{}: {:.0} % of the scale error and {:.0} % of the bias left",
                            results[t].test.name,
                            100.0 * med(&|r| left(&r[t]).0),
                            100.0 * med(&|r| left(&r[t]).1)
                        )
                    })
                    .collect::<Vec<_>>()
                    .join("; "),
                100.0 * IDENTIFIED,
                s.scale - 1.0,
                s.bias
            ),
        ),
    ];
    // Position error over time in test 1 for the three methods.
    let series: Vec<(String, Vec<(f64, f64)>)> = ["I: trapezoid", "II: FEM, Dirichlet", "III: FEM + error model"]
        .iter()
        .enumerate()
        .map(|(m, name)| (name.to_string(), tracks[0].iter().map(|(t, e)| (*t, e[m])).collect()))
        .collect();
    let plots = vec![(
        "nieminen_position_error.svg".to_string(),
        plot::lines(
            &series,
            "t (s)",
            "position error (m)",
            false,
            "Nieminen, test 1: position error of methods I, II and III",
        )?,
    )];
    Ok(Output {
        results,
        table,
        claims,
        plots,
    })
}
