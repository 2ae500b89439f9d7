//! The disturbances across g and across the field, read off the recording with the gyro as the link between
//! samples. |a| − |g| and |m| − |h| see only the component along; a correction sees the ones across: the horizontal
//! linear acceleration tilts an estimate, and the field's horizontal component across it turns heading. The gyro,
//! integrated over the recording, turns every sample into one frame, where gravity and the earth field are constant
//! and what is left is the disturbance, component by component. The integration's slow errors are fitted out against
//! the accelerometer alone (least squares over the samples its gate passes): a gyro bias, constant over the
//! recording, and the tilt of the start. The field is then measured in that frame and fits nothing, so that its
//! disturbance cannot be fitted away. What the fit cannot take out (the gyro's random walk, a bias that wanders)
//! counts as disturbance: the estimate errs on the heavy side.

use nalgebra::{Matrix3, SMatrix, SVector, UnitQuaternion, Vector3, Vector4};

use super::disturbance::Part;
use simnet_engine::estimate::attitude::{rotation, turn};
use simnet_engine::imu_csv::ImuRecording;

/// What the fit takes: the recording, its start, the gyro bias already estimated, |g| and the gates' verdicts.
pub struct Input<'a> {
    pub rec: &'a ImuRecording,
    pub q0: Vector4<f64>,
    pub bias: Vector3<f64>,
    pub g: f64,
    pub passed: &'a [(bool, bool)],
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Across {
    /// Horizontal linear acceleration (mean of the two axes) over the samples the accelerometer gate passes.
    pub accel: Part,
    /// The field's horizontal component across it, over the samples the field gate passes.
    pub field: Option<Part>,
    /// The gyro bias the fit adds to the one given, rad/s.
    pub bias_correction: Vector3<f64>,
}

/// Parameters: gyro bias correction (3), tilt of the start about x and y (2).
type P = SVector<f64, 5>;

fn integrate(inp: &Input, db: &Vector3<f64>) -> Vec<Matrix3<f64>> {
    let rec = inp.rec;
    let mut q = inp.q0;
    let mut out = Vec::with_capacity(rec.t.len());
    for k in 0..rec.t.len() {
        if k > 0 {
            let dt = rec.t[k] - rec.t[k - 1];
            q = turn(&q, &(rec.gyro[k] - inp.bias - db), dt);
        }
        out.push(rotation(&q));
    }
    out
}

/// The specific force, turned into the integration's frame, less gravity, for every sample the gate passes.
fn residuals(inp: &Input, p: &P, rot: &[Matrix3<f64>]) -> Vec<f64> {
    let tilt = UnitQuaternion::from_scaled_axis(Vector3::new(p[3], p[4], 0.0));
    let up = Vector3::new(0.0, 0.0, inp.g);
    let mut r = Vec::new();
    for (k, c) in rot.iter().enumerate() {
        if inp.passed[k].0 {
            r.extend((tilt * (c * inp.rec.accel[k]) - up).iter());
        }
    }
    r
}

/// Gauss–Newton over the five parameters, the Jacobian by central differences; None when no sample passes the
/// accelerometer gate or the normal equations are singular.
pub fn fit(inp: &Input) -> Option<Across> {
    let n = inp.rec.t.len();
    let mut p = P::zeros();
    let mut rot = integrate(inp, &Vector3::zeros());
    for _ in 0..20 {
        let r0 = residuals(inp, &p, &rot);
        if r0.is_empty() {
            return None;
        }
        let mut jt = vec![vec![0.0; r0.len()]; 5];
        for (i, col) in jt.iter_mut().enumerate() {
            let step = if i < 3 { 1e-6 } else { 1e-6 * (1.0 + p[i].abs()) };
            let eval = |s: f64| {
                let mut q = p;
                q[i] += s;
                // Only the bias moves the integration; the tilt turns its frame after it.
                if i < 3 {
                    residuals(inp, &q, &integrate(inp, &Vector3::new(q[0], q[1], q[2])))
                } else {
                    residuals(inp, &q, &rot)
                }
            };
            let (plus, minus) = (eval(step), eval(-step));
            for (j, c) in col.iter_mut().enumerate() {
                *c = (plus[j] - minus[j]) / (2.0 * step);
            }
        }
        let mut jtj = SMatrix::<f64, 5, 5>::zeros();
        let mut jtr = P::zeros();
        for a in 0..5 {
            jtr[a] = jt[a].iter().zip(&r0).map(|(x, y)| x * y).sum();
            for b in 0..5 {
                jtj[(a, b)] = jt[a].iter().zip(&jt[b]).map(|(x, y)| x * y).sum();
            }
        }
        let delta = jtj.lu().solve(&(-jtr))?;
        p += delta;
        rot = integrate(inp, &Vector3::new(p[0], p[1], p[2]));
        if delta.amax() < 1e-10 {
            break;
        }
    }
    if !p.iter().all(|x| x.is_finite()) {
        return None;
    }
    let tilt = UnitQuaternion::from_scaled_axis(Vector3::new(p[3], p[4], 0.0));
    let up = Vector3::new(0.0, 0.0, inp.g);
    let lin: Vec<Vector3<f64>> = (0..n).map(|k| tilt * (rot[k] * inp.rec.accel[k]) - up).collect();
    let accel_ok = |k: usize| inp.passed[k].0;
    let accel = Part::mean(
        Part::of(&lin.iter().map(|v| v[0]).collect::<Vec<_>>(), accel_ok),
        Part::of(&lin.iter().map(|v| v[1]).collect::<Vec<_>>(), accel_ok),
    );
    // The earth field in that frame: the mean over the samples the field gate passes.
    let field = inp.rec.mag.as_ref().and_then(|m| {
        let ok: Vec<usize> = (0..n).filter(|&k| inp.passed[k].1).collect();
        if ok.is_empty() {
            return None;
        }
        let m_nav: Vec<Vector3<f64>> = (0..n).map(|k| tilt * (rot[k] * m[k])).collect();
        let h = ok.iter().map(|&k| m_nav[k]).sum::<Vector3<f64>>() / ok.len() as f64;
        let across = Vector3::z().cross(&h).try_normalize(1e-12)?;
        let d: Vec<f64> = m_nav.iter().map(|x| (x - h).dot(&across)).collect();
        Some(Part::of(&d, |k| inp.passed[k].1))
    });
    Some(Across {
        accel,
        field,
        bias_correction: Vector3::new(p[0], p[1], p[2]),
    })
}
