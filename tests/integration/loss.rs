//! (h) Loss statistics of the pure link model against theory, within 3σ over ≥ 100,000 packets.

use simnet::link::{FaultSchedule, Link, LinkConfig, LossModel, Verdict};
use simnet::time::Time;

const PACKETS: usize = 200_000;

/// The loss indicator sequence of one link.
fn losses(model: LossModel, seed: u64) -> Vec<bool> {
    let cfg = LinkConfig {
        loss: model,
        ..Default::default()
    };
    let mut link = Link::new(0, 1, cfg, simnet::rng::stream(seed, "link", 0, 1));
    let schedule = FaultSchedule::default();
    (0..PACKETS)
        .map(|i| {
            matches!(
                link.verdict(Time::at_step(i as u64, 0.01), 40, &schedule),
                Verdict::Drop(_)
            )
        })
        .collect()
}

fn runs(l: &[bool]) -> Vec<usize> {
    let mut out = Vec::new();
    let mut cur = 0;
    for &x in l {
        if x {
            cur += 1;
        } else if cur > 0 {
            out.push(cur);
            cur = 0;
        }
    }
    out
}

#[test]
fn bernoulli_loss_rate_within_3_sigma() {
    for (p, seed) in [(0.2, 1), (0.05, 2), (0.5, 3)] {
        let l = losses(LossModel::Bernoulli { p }, seed);
        let rate = l.iter().filter(|x| **x).count() as f64 / PACKETS as f64;
        let sigma = (p * (1.0 - p) / PACKETS as f64).sqrt();
        assert!(
            (rate - p).abs() < 3.0 * sigma,
            "p = {p}: measured {rate}, 3σ = {}",
            3.0 * sigma
        );
        // Independent losses: runs are geometric with mean 1/(1−p).
        let r = runs(&l);
        let mean = r.iter().sum::<usize>() as f64 / r.len() as f64;
        let sd = (p / (1.0 - p).powi(2) / r.len() as f64).sqrt();
        assert!((mean - 1.0 / (1.0 - p)).abs() < 3.0 * sd, "p = {p}: mean run {mean}");
    }
}

#[test]
fn gilbert_elliott_loss_rate_and_mean_run_within_3_sigma() {
    for (target, burst, seed) in [(0.2, 4.0, 11), (0.1, 2.0, 12), (0.3, 8.0, 13)] {
        let model = LossModel::gilbert_elliott_from(target, burst).unwrap();
        let LossModel::GilbertElliott { p, r, .. } = model else {
            unreachable!()
        };
        assert!((model.stationary_loss() - target).abs() < 1e-12);
        let l = losses(model, seed);
        let n = PACKETS as f64;
        let rate = l.iter().filter(|x| **x).count() as f64 / n;
        // With 1−h = 1, 1−k = 0 the loss indicator is the Bad-state indicator of a two-state chain whose second
        // eigenvalue is ρ = 1 − p − r: Var(mean) ≈ π(1−π)/n · (1+ρ)/(1−ρ).
        let rho = 1.0 - p - r;
        let sigma = (target * (1.0 - target) / n * (1.0 + rho) / (1.0 - rho)).sqrt();
        assert!(
            (rate - target).abs() < 3.0 * sigma,
            "L = {target}, B = {burst}: measured {rate}, 3σ = {}",
            3.0 * sigma
        );
        // Bad sojourns are geometric with mean 1/r = B: the mean loss run.
        let rs = runs(&l);
        let mean = rs.iter().sum::<usize>() as f64 / rs.len() as f64;
        let sd = ((1.0 - r) / (r * r) / rs.len() as f64).sqrt();
        assert!(
            (mean - burst).abs() < 3.0 * sd,
            "L = {target}, B = {burst}: mean run {mean} ± {sd}"
        );
    }
}

/// netem's full four-parameter form (losses in both states): the stationary rate, with σ from batch means.
#[test]
fn gilbert_elliott_four_parameters() {
    let model = LossModel::GilbertElliott {
        p: 0.05,
        r: 0.3,
        one_minus_h: 0.7,
        one_minus_k: 0.02,
    };
    let expect = (0.3 * 0.02 + 0.05 * 0.7) / 0.35;
    assert!((model.stationary_loss() - expect).abs() < 1e-15);
    let l = losses(model, 21);
    let batches = 200;
    let size = PACKETS / batches;
    let means: Vec<f64> = l
        .chunks(size)
        .map(|c| c.iter().filter(|x| **x).count() as f64 / c.len() as f64)
        .collect();
    let mean = means.iter().sum::<f64>() / batches as f64;
    let var = means.iter().map(|m| (m - mean).powi(2)).sum::<f64>() / (batches - 1) as f64;
    let sigma = (var / batches as f64).sqrt();
    assert!(
        (mean - expect).abs() < 3.0 * sigma,
        "measured {mean}, expected {expect} ± {sigma}"
    );
}

/// The link's own counters agree with the verdicts.
#[test]
fn link_counters_track_loss_runs() {
    let cfg = LinkConfig {
        loss: LossModel::gilbert_elliott_from(0.2, 4.0).unwrap(),
        ..Default::default()
    };
    let mut link = Link::new(0, 1, cfg, simnet::rng::stream(5, "link", 0, 1));
    let s = FaultSchedule::default();
    let l: Vec<bool> = (0..50_000)
        .map(|i| matches!(link.verdict(Time::from_secs(i as f64), 10, &s), Verdict::Drop(_)))
        .collect();
    let c = link.counters();
    assert_eq!(c.sent, 50_000);
    assert_eq!(c.lost_random, l.iter().filter(|x| **x).count() as u64);
    let rs = runs(&l);
    let mean = rs.iter().sum::<usize>() as f64 / rs.len() as f64;
    let open = l.last() == Some(&true);
    if !open {
        assert!((c.mean_loss_run() - mean).abs() < 1e-12);
    }
}
