//! Covariance intersection: consistent whatever the (unknown) correlation between the estimates, and the
//! trace-optimal ω never does worse on the trace than the paper's ω = 0.5.
#![allow(non_snake_case)]

use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use simnet::estimate::fusion::{cascade, intersect, trace_optimal_omega, Omega};
use simnet::estimate::Gaussian;

fn random_spd(rng: &mut rand_chacha::ChaCha8Rng, n: usize) -> DMatrix<f64> {
    let L = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0));
    &L * L.transpose() + DMatrix::identity(n, n) * 0.1
}

/// Monte Carlo: two (or three) estimates whose errors are strongly correlated in a way the fusion does not know; the
/// fused P bounds the empirical covariance of the fused error in every direction (up to sampling error, 4σ).
#[test]
fn covariance_intersection_is_consistent() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let n = 3;
    let samples = 20_000;
    for trial in 0..6 {
        // Joint covariance of the stacked errors (e1, e2, e3): random SPD, so cross-correlations are arbitrary.
        let J = random_spd(&mut rng, 3 * n);
        let Lj = J.clone().cholesky().unwrap().l();
        let block = |i: usize| J.view((i * n, i * n), (n, n)).into_owned();
        let parts: Vec<Gaussian> = (0..3)
            .map(|i| Gaussian {
                x: DVector::zeros(n),
                P: block(i),
            })
            .collect();
        for (omega, k) in [
            (Omega::Fixed(0.5), 2),
            (Omega::TraceOptimal, 2),
            (Omega::Fixed(0.5), 3),
            (Omega::TraceOptimal, 3),
        ] {
            let fused_P = cascade(&parts[..k], omega, &[false; 3]).unwrap().P;
            let mut emp = DMatrix::<f64>::zeros(n, n);
            let mut rng2 = rand_chacha::ChaCha8Rng::seed_from_u64(100 + trial);
            for _ in 0..samples {
                let z = DVector::from_fn(3 * n, |_, _| rng2.sample::<f64, _>(StandardNormal));
                let e = &Lj * z;
                let est: Vec<Gaussian> = (0..k)
                    .map(|i| Gaussian {
                        x: e.rows(i * n, n).into_owned(),
                        P: block(i),
                    })
                    .collect();
                let f = cascade(&est, omega, &[false; 3]).unwrap();
                emp += &f.x * f.x.transpose();
            }
            emp /= samples as f64;
            // In every direction u: uᵀ Σ u ≤ uᵀ P u, allowing the sampling error of a variance (√(2/N) relative).
            let slack = 1.0 + 4.0 * (2.0 / samples as f64).sqrt();
            let w = fused_P.clone().cholesky().unwrap().l().try_inverse().unwrap();
            let ratio = (&w * &emp * w.transpose()).symmetric_eigenvalues().max();
            assert!(
                ratio <= slack,
                "trial {trial}, {omega:?}, {k} estimates: empirical/fused = {ratio:.4}"
            );
        }
    }
}

#[test]
fn trace_optimal_omega_never_loses_to_one_half() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    for _ in 0..200 {
        let n = rng.gen_range(1..=6);
        let a = Gaussian {
            x: DVector::zeros(n),
            P: random_spd(&mut rng, n),
        };
        let b = Gaussian {
            x: DVector::zeros(n),
            P: random_spd(&mut rng, n),
        };
        let w = trace_optimal_omega(&a, &b).unwrap();
        let t_opt = intersect(&a, &b, w, &vec![false; n]).unwrap().P.trace();
        let t_half = intersect(&a, &b, 0.5, &vec![false; n]).unwrap().P.trace();
        assert!(t_opt <= t_half * (1.0 + 1e-12), "ω* = {w}: {t_opt} > {t_half}");
    }
}
