//! The Kalman and consensus updates, the fixed-ω fusion cascade and NEES on stack matrices: no allocation inside
//! but the posterior's, and loops the compiler unrolls. The sizes come from the models: simnet's own (pose 9 states
//! × 6 rows, attitude 4 × 6, scalar 1 × 1) are built in, and a program's model gets the same path for its sizes by
//! one [`register`]`(`[`Size::of`]`::<N, M>())`. The dynamic entry points ([`super::kalman_update`],
//! [`super::consensus_update`], [`super::fusion::cascade`], [`super::nees`]) call these when the sizes are covered
//! and every row is kept (R diagonal, or every row present); the formulas are the same, and the tests check both
//! paths agree to rounding.

use std::sync::RwLock;

use nalgebra::{Cholesky, DMatrix, DVector, SMatrix, SVector};

use super::types::{ConsensusOutcome, Gaussian, Observation, Source};
use super::EstimateError;

type Joseph = fn(&Gaussian, &Observation, &DVector<f64>, &[bool], f64) -> Result<Gaussian, EstimateError>;
type Consensus =
    fn(&Gaussian, &Observation, f64, &[Source<'_>], &[bool], f64, f64) -> Result<ConsensusOutcome, EstimateError>;
type Cascade = fn(&[Gaussian], f64, &[bool]) -> Result<Gaussian, EstimateError>;
type Nees = fn(&Gaussian, &DVector<f64>, &[bool]) -> Option<f64>;

/// The stack kernels of one model size: `states` states, `rows` measurement rows.
#[derive(Clone, Copy)]
pub struct Size {
    /// n, the state's size.
    pub states: usize,
    /// m, the measurement's rows.
    pub rows: usize,
    joseph: Joseph,
    consensus: Consensus,
    cascade: Cascade,
    nees: Nees,
}

impl std::fmt::Debug for Size {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Size({} × {})", self.states, self.rows)
    }
}

impl Size {
    /// The kernels of a model with `N` states and `M` measurement rows, compiled for those sizes.
    pub const fn of<const N: usize, const M: usize>() -> Size {
        Size {
            states: N,
            rows: M,
            joseph: joseph::<N, M>,
            consensus: consensus::<N, M>,
            cascade: cascade_fixed::<N>,
            nees: nees_fixed::<N>,
        }
    }
}

/// simnet's own models' sizes: pose, attitude, scalar.
const BUILT_IN: [Size; 3] = [Size::of::<9, 6>(), Size::of::<4, 6>(), Size::of::<1, 1>()];

/// The sizes programs registered (looked up after the built-in ones, which need no lock).
static REGISTERED: RwLock<Vec<Size>> = RwLock::new(Vec::new());

/// Give a model of `size.states` states and `size.rows` rows the stack path (once is enough; again changes
/// nothing). Meant for small models: every matrix of the kernels lives on the stack (an n × n one is 8n² bytes), so
/// a state of a few dozen rows is better left to the dynamic path.
pub fn register(size: Size) {
    if covers(size.states, size.rows) {
        return;
    }
    if let Ok(mut r) = REGISTERED.write() {
        r.push(size);
    }
}

/// Whether `states` × `rows` has the stack path.
pub fn covers(states: usize, rows: usize) -> bool {
    find(|s| s.states == states && s.rows == rows).is_some()
}

fn find(like: impl Fn(&Size) -> bool) -> Option<Size> {
    BUILT_IN
        .iter()
        .find(|s| like(s))
        .copied()
        .or_else(|| REGISTERED.read().ok()?.iter().find(|s| like(s)).copied())
}

/// A column-major slice copied to the stack (one memcpy; nalgebra's `from_column_slice` goes element by element).
#[inline]
pub fn fixed<const R: usize, const C: usize>(m: &[f64]) -> SMatrix<f64, R, C> {
    let mut s = SMatrix::<f64, R, C>::zeros();
    s.as_mut_slice().copy_from_slice(m);
    s
}

/// A stack matrix copied to the heap, likewise.
#[inline]
pub fn dynamic<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> DMatrix<f64> {
    DMatrix::from_vec(R, C, m.as_slice().to_vec())
}

/// `m ← (m + mᵀ)/2` in place: a covariance kept symmetric against rounding.
#[inline]
pub fn symmetrize<const N: usize>(m: &mut SMatrix<f64, N, N>) {
    for i in 0..N {
        for j in (i + 1)..N {
            let a = 0.5 * (m[(i, j)] + m[(j, i)]);
            m[(i, j)] = a;
            m[(j, i)] = a;
        }
    }
}

#[inline]
fn gaussian<const N: usize>(x: &SVector<f64, N>, P: &SMatrix<f64, N, N>) -> Gaussian {
    Gaussian {
        x: DVector::from_vec(x.as_slice().to_vec()),
        P: dynamic(P),
    }
}

/// The observation with every row kept: H, R̄ (rows missing from every source inflated by λ², eq. (11)'s
/// per-channel rule) and, per source, the innovation z − H x (angle rows wrapped, zero where the source lacks the
/// row).
struct Terms<const N: usize, const M: usize> {
    x: SVector<f64, N>,
    P: SMatrix<f64, N, N>,
    H: SMatrix<f64, M, N>,
    R: SMatrix<f64, M, M>,
}

impl<const N: usize, const M: usize> Terms<N, M> {
    #[inline]
    fn new(prior: &Gaussian, obs: &Observation, present_any: &[bool], lambda: f64) -> Terms<N, M> {
        let mut R = fixed::<M, M>(obs.R.as_slice());
        for i in 0..M {
            if !present_any[i] {
                R[(i, i)] *= lambda * lambda;
            }
        }
        Terms {
            x: fixed(prior.x.as_slice()),
            P: fixed(prior.P.as_slice()),
            H: fixed(obs.H.as_slice()),
            R,
        }
    }

    #[inline]
    fn innovation(&self, obs: &Observation, z: &DVector<f64>, present: &[bool]) -> SVector<f64, M> {
        let mut nu = fixed::<M, 1>(z.as_slice()) - self.H * self.x;
        for i in 0..M {
            nu[i] = if !present[i] {
                0.0
            } else if obs.angle_rows[i] {
                crate::geom::wrap_angle(nu[i])
            } else {
                nu[i]
            };
        }
        nu
    }

    /// S = H P Hᵀ + R̄ (5) and K = P Hᵀ S⁻¹ (6), as (S⁻¹ H P)ᵀ.
    #[inline]
    fn gain(&self) -> Result<(SMatrix<f64, M, M>, SMatrix<f64, N, M>), EstimateError> {
        let what = "innovation covariance S";
        // H P once: S and K both start from it (the same products, so the same bits, as computing it twice).
        let HP = self.H * self.P;
        let S = HP * self.H.transpose() + self.R;
        if S.iter().any(|v| !v.is_finite()) {
            return Err(EstimateError::NonFinite { what });
        }
        let chol = Cholesky::new(S).ok_or(EstimateError::NotPositiveDefinite { what })?;
        Ok((S, chol.solve(&HP).transpose()))
    }
}

fn joseph<const N: usize, const M: usize>(
    prior: &Gaussian,
    obs: &Observation,
    z: &DVector<f64>,
    present: &[bool],
    lambda: f64,
) -> Result<Gaussian, EstimateError> {
    let t = Terms::<N, M>::new(prior, obs, present, lambda);
    let nu = t.innovation(obs, z, present);
    let (_, K) = t.gain()?;
    let x = t.x + K * nu;
    let IKH = SMatrix::<f64, N, N>::identity() - K * t.H;
    let mut P = IKH * t.P * IKH.transpose() + K * t.R * K.transpose();
    symmetrize(&mut P);
    if x.iter().chain(P.iter()).any(|v| !v.is_finite()) {
        return Err(EstimateError::NonFinite { what: "posterior" });
    }
    Ok(gaussian(&x, &P))
}

/// The Joseph-form update of [`super::kalman_update`] with every row kept (`lambda` inflates the rows not present).
pub(super) fn kalman_update(
    prior: &Gaussian,
    obs: &Observation,
    z: &DVector<f64>,
    present: &[bool],
    lambda: f64,
) -> Option<Result<Gaussian, EstimateError>> {
    if z.len() != obs.dim() || present.len() != obs.dim() || prior.x.len() != obs.H.ncols() {
        return None;
    }
    let (n, m) = (obs.H.ncols(), obs.dim());
    find(|s| s.states == n && s.rows == m).map(|s| (s.joseph)(prior, obs, z, present, lambda))
}

#[allow(clippy::too_many_arguments)]
fn consensus<const N: usize, const M: usize>(
    prior: &Gaussian,
    obs: &Observation,
    beta0: f64,
    sources: &[Source<'_>],
    present_any: &[bool],
    lambda: f64,
    scale: f64,
) -> Result<ConsensusOutcome, EstimateError> {
    let t = Terms::<N, M>::new(prior, obs, present_any, lambda);
    let (S, K) = t.gain()?;
    // (7)–(9): K z̃ = Σ βⱼ K z̃ⱼ; P_{k|k} = P − (1 − β₀) K S Kᵀ + Σ βⱼ Fⱼ − K z̃ z̃ᵀ Kᵀ, Fⱼ = K z̃ⱼ z̃ⱼᵀ Kᵀ.
    let mut c = SVector::<f64, N>::zeros();
    let mut P = t.P - K * S * K.transpose() * (1.0 - beta0);
    for s in sources {
        let kz = K * t.innovation(obs, s.z, s.present);
        c += kz * s.beta;
        P += kz * kz.transpose() * s.beta;
    }
    P -= c * c.transpose();
    symmetrize(&mut P);
    let x = t.x + c;
    if x.iter().chain(P.iter()).any(|v| !v.is_finite()) {
        return Err(EstimateError::NonFinite {
            what: "consensus posterior",
        });
    }
    // (17) and (19) as in [`super::consensus::feasible`]: P_{k|k} ≻ 0, I − Z ≻ 0, I + Z ≻ 0.
    let mut Z = (P - t.P) * scale;
    symmetrize(&mut Z);
    let I = SMatrix::<f64, N, N>::identity();
    // P is finite (checked above), so Z is unless it overflowed: one check covers I ± Z.
    let spd = |m: SMatrix<f64, N, N>| Cholesky::new(m).is_some();
    let feasible = Z.iter().all(|v| v.is_finite()) && spd(P) && spd(I - Z) && spd(I + Z);
    Ok(ConsensusOutcome {
        posterior: gaussian(&x, &P),
        feasible,
    })
}

/// [`super::consensus_update`] with every row kept, for sources that carry at least one row (`present_any`, their
/// union); `scale` is e^{γk}/α of (15).
#[allow(clippy::too_many_arguments)]
pub(super) fn consensus_update(
    prior: &Gaussian,
    obs: &Observation,
    beta0: f64,
    sources: &[Source<'_>],
    present_any: &[bool],
    lambda: f64,
    scale: f64,
) -> Option<Result<ConsensusOutcome, EstimateError>> {
    let m = obs.dim();
    if prior.x.len() != obs.H.ncols() || sources.iter().any(|s| s.z.len() != m || s.present.len() != m) {
        return None;
    }
    let n = obs.H.ncols();
    find(|s| s.states == n && s.rows == m)
        .map(|s| (s.consensus)(prior, obs, beta0, sources, present_any, lambda, scale))
}

fn information<const N: usize>(P: &DMatrix<f64>, what: &'static str) -> Result<SMatrix<f64, N, N>, EstimateError> {
    let P = fixed::<N, N>(P.as_slice());
    if P.iter().any(|v| !v.is_finite()) {
        return Err(EstimateError::NonFinite { what });
    }
    Ok(Cholesky::new(P)
        .ok_or(EstimateError::NotPositiveDefinite { what })?
        .inverse())
}

/// The fixed-ω cascade of [`super::fusion::cascade`] carried in information form: the fused information
/// Y = ω Y_acc + (1 − ω) P_b⁻¹ of each stage is the next stage's Y_acc, so a stage inverts one covariance and
/// solves for its mean; P = Y⁻¹ once, at the end.
fn cascade_fixed<const N: usize>(
    estimates: &[Gaussian],
    omega: f64,
    angle_states: &[bool],
) -> Result<Gaussian, EstimateError> {
    let Some((first, rest)) = estimates.split_first() else {
        return Err(EstimateError::Dimension {
            what: "no estimate to fuse".into(),
        });
    };
    if rest.is_empty() {
        return Ok(first.clone());
    }
    let mut x = fixed::<N, 1>(first.x.as_slice());
    let mut Y = information::<N>(&first.P, "P₁")?;
    for e in rest {
        let Yb = information::<N>(&e.P, "P₂")?;
        let mut xb = fixed::<N, 1>(e.x.as_slice());
        for (i, ang) in angle_states.iter().enumerate().take(N) {
            if *ang {
                xb[i] = x[i] + crate::geom::wrap_angle(xb[i] - x[i]);
            }
        }
        let info = Y * omega + Yb * (1.0 - omega);
        let what = "fused information";
        if info.iter().any(|v| !v.is_finite()) {
            return Err(EstimateError::NonFinite { what });
        }
        let chol = Cholesky::new(info).ok_or(EstimateError::NotPositiveDefinite { what })?;
        x = chol.solve(&(Y * x * omega + Yb * xb * (1.0 - omega)));
        for (i, ang) in angle_states.iter().enumerate().take(N) {
            if *ang {
                x[i] = crate::geom::wrap_angle(x[i]);
            }
        }
        Y = info;
    }
    let mut P = Cholesky::new(Y)
        .ok_or(EstimateError::NotPositiveDefinite {
            what: "fused information",
        })?
        .inverse();
    symmetrize(&mut P);
    Ok(gaussian(&x, &P))
}

/// [`cascade_fixed`] where every estimate has a state size with the stack path.
pub(super) fn cascade(
    estimates: &[Gaussian],
    omega: f64,
    angle_states: &[bool],
) -> Option<Result<Gaussian, EstimateError>> {
    let n = estimates.first()?.x.len();
    if estimates.iter().any(|e| e.x.len() != n || e.P.shape() != (n, n)) || angle_states.len() != n {
        return None;
    }
    find(|s| s.states == n).map(|s| (s.cascade)(estimates, omega, angle_states))
}

fn nees_fixed<const N: usize>(g: &Gaussian, truth: &DVector<f64>, angle_states: &[bool]) -> Option<f64> {
    let mut e = fixed::<N, 1>(truth.as_slice()) - fixed::<N, 1>(g.x.as_slice());
    for (i, ang) in angle_states.iter().enumerate().take(N) {
        if *ang {
            e[i] = crate::geom::wrap_angle(e[i]);
        }
    }
    let P = fixed::<N, N>(g.P.as_slice());
    if P.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let v = e.dot(&Cholesky::new(P)?.solve(&e));
    v.is_finite().then_some(v)
}

/// [`super::nees`] on the stack, where the state size has the stack path.
pub(super) fn nees(g: &Gaussian, truth: &DVector<f64>, angle_states: &[bool]) -> Option<Option<f64>> {
    let n = g.x.len();
    if truth.len() != n || g.P.shape() != (n, n) || angle_states.len() != n {
        return None;
    }
    find(|s| s.states == n).map(|s| (s.nees)(g, truth, angle_states))
}

#[cfg(test)]
mod tests {
    use nalgebra::{DMatrix, DVector};
    use rand::{Rng, SeedableRng};

    use super::super::consensus::{dynamic_update, Source};
    use super::super::kalman::{joseph, Gaussian, MissingChannels, Observation};

    fn random_spd(rng: &mut impl Rng, n: usize, floor: f64) -> DMatrix<f64> {
        let a = DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0));
        &a * a.transpose() + DMatrix::identity(n, n) * floor
    }

    fn close(a: &Gaussian, b: &Gaussian) -> bool {
        let scale = 1.0 + b.P.amax() + b.x.amax();
        (&a.x - &b.x).amax() < 1e-11 * scale && (&a.P - &b.P).amax() < 1e-11 * scale
    }

    /// Both paths of the Kalman and consensus updates agree to rounding on every built-in size and on one a program
    /// registers, with rows missing from some sources, angle rows, and several sources.
    #[test]
    fn the_stack_kernels_are_the_dynamic_ones() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut checked = 0;
        // A size no built-in model has, as a program's model registers it.
        assert!(!super::covers(5, 3));
        super::register(super::Size::of::<5, 3>());
        assert!(super::covers(5, 3) && !super::covers(5, 2));
        for &(n, m) in &[(9usize, 6usize), (4, 6), (1, 1), (5, 3)] {
            for _ in 0..200 {
                let prior = Gaussian {
                    x: DVector::from_fn(n, |_, _| rng.gen_range(-2.0..2.0)),
                    P: random_spd(&mut rng, n, 0.05),
                };
                let obs = Observation {
                    H: DMatrix::from_fn(m, n, |_, _| rng.gen_range(-1.0..1.0)),
                    R: DMatrix::from_diagonal(&DVector::from_fn(m, |_, _| rng.gen_range(0.01..1.0))),
                    angle_rows: (0..m).map(|i| i >= m / 2 && m > 1).collect(),
                    channel_of_row: (0..m).map(|i| i * 2 / m.max(1)).collect(),
                };
                let lambda = rng.gen_range(1.0..50.0);
                let zs: Vec<DVector<f64>> = (0..4)
                    .map(|_| DVector::from_fn(m, |_, _| rng.gen_range(-3.0..3.0)))
                    .collect();
                let presents: Vec<Vec<bool>> = (0..4).map(|_| (0..m).map(|_| rng.gen_bool(0.8)).collect()).collect();
                let policy = MissingChannels::Inflate(lambda);
                if presents[0].iter().any(|p| *p) {
                    let fast = super::kalman_update(&prior, &obs, &zs[0], &presents[0], lambda)
                        .unwrap()
                        .unwrap();
                    let slow = joseph(&prior, &obs, &zs[0], &presents[0], policy).unwrap();
                    assert!(close(&fast, &slow), "{n}×{m}: {fast:?} against {slow:?}");
                }
                let k = rng.gen_range(1..4);
                let sources: Vec<Source<'_>> = (0..k)
                    .map(|j| Source {
                        beta: rng.gen_range(0.05..0.6),
                        z: &zs[j],
                        present: &presents[j],
                    })
                    .collect();
                let mut any = vec![false; m];
                for s in &sources {
                    any.iter_mut().zip(s.present).for_each(|(a, p)| *a |= *p);
                }
                if !any.iter().any(|p| *p) {
                    continue;
                }
                let (beta0, scale) = (rng.gen_range(0.0..0.5), rng.gen_range(0.5..3.0));
                let fast = super::consensus_update(&prior, &obs, beta0, &sources, &any, lambda, scale)
                    .unwrap()
                    .unwrap();
                let slow = dynamic_update(&prior, &obs, beta0, &sources, policy, 0, 1.0 / scale, 0.0).unwrap();
                assert!(close(&fast.posterior, &slow.posterior), "{n}×{m} consensus");
                assert_eq!(fast.feasible, slow.feasible, "{n}×{m} consensus feasibility");
                checked += 1;
            }
        }
        assert!(checked > 730, "{checked} consensus cases");
    }

    /// The information-form cascade is the chain of pairwise intersections, and the stack NEES is eᵀ P⁻¹ e by an
    /// explicit inverse, to rounding, on every built-in state size and on one a program registers.
    #[test]
    fn the_stack_cascade_and_nees_are_the_dynamic_ones() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        super::register(super::Size::of::<7, 2>());
        for &n in &[9usize, 4, 1, 7] {
            let angles: Vec<bool> = (0..n).map(|i| n == 9 && i >= 6).collect();
            for _ in 0..100 {
                let count = rng.gen_range(1..12);
                let gs: Vec<Gaussian> = (0..count)
                    .map(|_| Gaussian {
                        x: DVector::from_fn(n, |_, _| rng.gen_range(-3.0..3.0)),
                        P: random_spd(&mut rng, n, 0.02),
                    })
                    .collect();
                let omega = rng.gen_range(0.1..0.9);
                let fast = super::cascade(&gs, omega, &angles).unwrap().unwrap();
                let mut slow = gs[0].clone();
                for g in &gs[1..] {
                    slow = super::super::fusion::intersect(&slow, g, omega, &angles).unwrap();
                }
                assert!(close(&fast, &slow), "{n} states, {count} estimates");
                let truth = DVector::from_fn(n, |_, _| rng.gen_range(-3.0..3.0));
                let mut e = &truth - &gs[0].x;
                super::super::wrap_rows(&mut e, &angles);
                let want = (e.transpose() * gs[0].P.clone().try_inverse().unwrap() * &e)[(0, 0)];
                let got = super::nees(&gs[0], &truth, &angles).unwrap().unwrap();
                assert!((got - want).abs() < 1e-9 * (1.0 + want), "NEES {got} against {want}");
            }
        }
    }
}
