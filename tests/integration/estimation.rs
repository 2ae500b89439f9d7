//! Properties of the estimator core: P stays SPD (c), the consensus update reduces to the Kalman update (d), and
//! channel inflation equals dropping the row for a diagonal R (e).
#![allow(non_snake_case)]

use crate::common;
use nalgebra::{DMatrix, DVector};
use proptest::prelude::*;
use simnet::estimate::{
    consensus_update, guarded_update, is_spd, kalman_update, Gaussian, MissingChannels, Observation, Source,
};

fn observation(H: DMatrix<f64>, R: DMatrix<f64>) -> Observation {
    let m = H.nrows();
    Observation {
        H,
        R,
        angle_rows: vec![false; m],
        channel_of_row: (0..m).collect(),
    }
}

fn spd_from(v: &[f64], n: usize, floor: f64) -> DMatrix<f64> {
    let L = DMatrix::from_fn(n, n, |i, j| if j <= i { v[i * n + j] } else { 0.0 });
    &L * L.transpose() + DMatrix::identity(n, n) * floor
}

/// A random system, protocol and arrival pattern.
#[derive(Debug, Clone)]
struct Case {
    n: usize,
    m: usize,
    a: Vec<f64>,
    c: Vec<f64>,
    q: Vec<f64>,
    r: Vec<f64>,
    beta0: f64,
    betas: Vec<f64>,
    /// Per step, per source, per row: did it arrive?
    arrivals: Vec<Vec<Vec<bool>>>,
    noise: Vec<f64>,
}

fn case() -> impl Strategy<Value = Case> {
    (1usize..=4, 1usize..=3, 1usize..=4).prop_flat_map(|(n, m, sources)| {
        (
            Just(n),
            Just(m),
            prop::collection::vec(-1.3f64..1.3, n * n),
            prop::collection::vec(-2.0f64..2.0, m * n),
            prop::collection::vec(-1.0f64..1.0, n * n),
            prop::collection::vec(-1.0f64..1.0, m * m),
            0.0f64..0.5,
            prop::collection::vec(0.0f64..1.0, sources),
            prop::collection::vec(
                prop::collection::vec(prop::collection::vec(any::<bool>(), m), sources),
                25,
            ),
            prop::collection::vec(-3.0f64..3.0, 25 * sources * m),
        )
            .prop_map(|(n, m, a, c, q, r, beta0, betas, arrivals, noise)| Case {
                n,
                m,
                a,
                c,
                q,
                r,
                beta0,
                betas,
                arrivals,
                noise,
            })
    })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, rng_seed: proptest::test_runner::RngSeed::Fixed(20261122), ..ProptestConfig::default() })]

    /// (c) With the LMI guard, P_{k|k} is symmetric positive definite after every update, whatever the system, the β
    /// protocol (weights summing above 1 included) and the arrival pattern. Without the guard the same holds when
    /// Σβ ≤ 1 (then P̄ ⪰ 0).
    #[test]
    fn covariance_stays_spd(c in case()) {
        let (n, m) = (c.n, c.m);
        // ρ(A) ≤ ‖A‖_F ≤ 1.2: an unstable, unobserved mode would otherwise grow P past what doubles can factorise,
        // which says nothing about the update. (Not via eigenvalues: nalgebra's Schur loops on degenerate input.)
        let mut A = DMatrix::from_row_slice(n, n, &c.a);
        let frob = A.norm();
        if frob > 1.2 {
            A *= 1.2 / frob;
        }
        let H = DMatrix::from_row_slice(m, n, &c.c);
        let Q = spd_from(&c.q, n, 1e-3);
        let R = spd_from(&c.r, m, 0.1);
        let obs = observation(H, R.clone());
        let policy = MissingChannels::for_noise(&R, 1e3);
        let total: f64 = c.betas.iter().sum();
        let scaled: Vec<f64> = c.betas.iter().map(|b| if total > 1.0 { b / total } else { *b }).collect();
        let mut guarded = Gaussian { x: DVector::zeros(n), P: DMatrix::identity(n, n) };
        let mut plain = guarded.clone();
        for (k, arrivals) in c.arrivals.iter().enumerate() {
            guarded = simnet::estimate::predict(&guarded, &A, &Q);
            plain = simnet::estimate::predict(&plain, &A, &Q);
            let zs: Vec<DVector<f64>> = (0..arrivals.len())
                .map(|s| DVector::from_fn(m, |i, _| c.noise[(k * arrivals.len() + s) * m + i]))
                .collect();
            let srcs = |w: &[f64]| -> Vec<Source<'_>> {
                (0..arrivals.len()).map(|s| Source { beta: w[s], z: &zs[s], present: &arrivals[s] }).collect()
            };
            let raw = srcs(&c.betas);
            let fallback = raw.first().cloned();
            let (post, _) = guarded_update(&guarded, &obs, c.beta0, &raw, fallback.as_ref(), policy, k as u64, Some((1000.0, 1e-5)));
            guarded = post.unwrap();
            prop_assert!(is_spd(&guarded.P), "guarded P not SPD at step {k}: {}", guarded.P);
            let sc = srcs(&scaled);
            plain = consensus_update(&plain, &obs, c.beta0, &sc, policy, k as u64, 1000.0, 1e-5).unwrap().posterior;
            prop_assert!(is_spd(&plain.P), "P not SPD at step {k} with Σβ ≤ 1: {}", plain.P);
        }
    }
}

fn random_system(seed: u64) -> (Gaussian, Observation, DVector<f64>) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let (n, m) = (4, 3);
    let v: Vec<f64> = (0..n * n).map(|_| rng.gen_range(-1.0..1.0)).collect();
    let P = spd_from(&v, n, 0.2);
    let H = DMatrix::from_fn(m, n, |_, _| rng.gen_range(-1.0..1.0));
    let R = DMatrix::from_diagonal(&DVector::from_fn(m, |_, _| rng.gen_range(0.1..2.0)));
    let x = DVector::from_fn(n, |_, _| rng.gen_range(-1.0..1.0));
    let z = DVector::from_fn(m, |_, _| rng.gen_range(-2.0..2.0));
    (Gaussian { x, P }, observation(H, R), z)
}

/// (d) β₀ = 0 and a single measurement of weight 1: the consensus update is the Kalman update (1e-12).
#[test]
fn consensus_reduces_to_kalman() {
    for seed in 0..50 {
        let (prior, obs, z) = random_system(seed);
        let present = vec![true; z.len()];
        let kf = kalman_update(&prior, &obs, &z, &present, MissingChannels::Drop).unwrap();
        let src = [Source {
            beta: 1.0,
            z: &z,
            present: &present,
        }];
        let cu = consensus_update(&prior, &obs, 0.0, &src, MissingChannels::Drop, 10, 1000.0, 1e-5).unwrap();
        let dx = (&cu.posterior.x - &kf.x).amax();
        let dp = (&cu.posterior.P - &kf.P).amax();
        assert!(dx < 1e-12 && dp < 1e-12, "seed {seed}: |Δx| = {dx:e}, |ΔP| = {dp:e}");
    }
}

/// (e) With a diagonal R, inflating a missing channel by λ = 1e3 matches dropping its row (1e-5 relative), for the
/// Kalman and the consensus update.
#[test]
fn inflation_matches_dropping_the_row() {
    for seed in 0..50 {
        let (prior, obs, z) = random_system(seed);
        let present = vec![true, false, true];
        let inflate = kalman_update(&prior, &obs, &z, &present, MissingChannels::Inflate(1e3)).unwrap();
        let drop = kalman_update(&prior, &obs, &z, &present, MissingChannels::Drop).unwrap();
        let rel = |a: &DMatrix<f64>, b: &DMatrix<f64>| (a - b).amax() / b.amax();
        assert!(
            rel(&inflate.P, &drop.P) < 1e-5,
            "seed {seed}: P differs by {:e}",
            rel(&inflate.P, &drop.P)
        );
        assert!(
            (&inflate.x - &drop.x).amax() / drop.x.amax().max(1e-12) < 1e-5,
            "seed {seed}: x differs"
        );

        let z2 = &z * 0.5;
        let p2 = vec![false, false, true];
        let src = [
            Source {
                beta: 0.6,
                z: &z,
                present: &present,
            },
            Source {
                beta: 0.4,
                z: &z2,
                present: &p2,
            },
        ];
        let a = consensus_update(&prior, &obs, 0.01, &src, MissingChannels::Inflate(1e3), 1, 1e3, 1e-5).unwrap();
        let b = consensus_update(&prior, &obs, 0.01, &src, MissingChannels::Drop, 1, 1e3, 1e-5).unwrap();
        assert!(rel(&a.posterior.P, &b.posterior.P) < 1e-5, "consensus, seed {seed}");
    }
}

/// The missing-channel policy follows R: inflation only for a diagonal R.
#[test]
fn correlated_noise_drops_rows() {
    let R = DMatrix::from_row_slice(2, 2, &[1.0, 0.3, 0.3, 1.0]);
    assert_eq!(MissingChannels::for_noise(&R, 1e3), MissingChannels::Drop);
    assert_eq!(
        MissingChannels::for_noise(&DMatrix::identity(2, 2), 1e3),
        MissingChannels::Inflate(1e3)
    );
}

/// (f) At 20 % loss every node's networked mean error is below its independent mean error, for the two-node protocol,
/// the alternative three-node protocol and ring3, over 5 seeds (the claim of Sequeira's §5). In memory: the
/// same runs as over sockets (`golden.rs` holds them equal). For the
/// 0.7/0.01/0.01 protocol the ratio is reported, not forced.
#[test]
#[ignore = "long suite: statistics over 5 seeds and 3 topologies (.ci/run runs it)"]
fn networked_beats_independent_at_20_percent_loss() {
    for name in ["pair2-paper", "tri3-alt", "ring3"] {
        for seed in 1..=5 {
            let s = common::simulate(common::topology(name, common::bernoulli(0.2, seed)));
            for n in &s.nodes {
                let r = n.error_ratio.expect("both filters report a mean error");
                println!("{name} seed {seed} node {}: networked/independent = {r:.3}", n.id);
                assert!(r < 1.0, "{name} seed {seed} node {}: ratio {r}", n.id);
                assert!(!n.networked.as_ref().unwrap().diverged);
            }
        }
    }
    let mut ratios = Vec::new();
    for seed in 1..=5 {
        let s = common::simulate(common::topology("tri3-paper", common::bernoulli(0.2, seed)));
        ratios.extend(s.nodes.iter().filter_map(|n| n.error_ratio));
    }
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    println!("tri3-paper (β = 0.7/0.01/0.01) at 20 % loss: mean networked/independent ratio {mean:.3} over 5 seeds");
}
