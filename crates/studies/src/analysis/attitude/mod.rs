//! Attitude from a recording, scored against the recording's own reference orientation: the quaternion EKF of
//! Lesecq's slides and the multiplicative EKF beside Madgwick's, Mahony's and VQF on the same samples (the filters
//! in [`filters`]), with noise levels, gyro bias and the navigation-frame field estimated from the recording itself
//! rather than set by hand; and any filter run elsewhere, scored the same way ([`Comparison::score_outside`]).
//!
//! The navigation frame is z up with x along the horizontal part of the field (magnetic north); a reference given
//! z down (NED) is turned into it. Errors are split into heading (the rotation about the vertical between estimate
//! and reference) and tilt (the rest), and given as recorded and with the constant heading offset removed: a
//! reference whose north is not magnetic north differs by that offset alone.

use nalgebra::{Quaternion, UnitQuaternion, Vector3, Vector4};

use simnet_engine::estimate::ahrs::{Madgwick, Mahony, MADGWICK_BETA_IMU, MADGWICK_BETA_MARG, MAHONY_KI, MAHONY_KP};
use simnet_engine::estimate::attitude::{from_euler, rotate_to_body};
use simnet_engine::estimate::mekf::MekfModel;
use simnet_engine::estimate::EstimateError;
use simnet_engine::imu_csv::ImuRecording;

pub mod across;
pub mod calibrate;
pub mod check;
pub mod disturbance;
pub mod filters;
pub mod sensor;
pub mod study;

pub use filters::{Consistency, Ekf, Filter, Gated, GyroOnly, MultiplicativeEkf, Nis, Open, Sample, Vqf};
pub use sensor::{characterise, Characterised, Field, Gates, GATES};

#[derive(Debug, thiserror::Error)]
pub enum AttitudeError {
    #[error("the recording has no reference orientation (quaternion or roll, pitch, yaw columns) to score against")]
    NoReference,
    #[error("the recording has {0} samples: at least 3 are needed")]
    TooShort(usize),
    #[error("the recording's sample rate ({0} Hz) is not a positive finite number")]
    Rate(f64),
    #[error("{0}")]
    Estimate(#[from] EstimateError),
    #[error("{name}: {got} attitudes for the recording's {want} samples")]
    Length { name: String, got: usize, want: usize },
    #[error("--compare {name}=…: `{name}` is taken (simnet's own: {taken})")]
    NameTaken { name: String, taken: String },
    #[error(
        "the recording's {sensor} shows no noise (its white-noise variance, measured at rest or from second \
         differences, is {var:e}): simnet's EKFs take their noise covariances from the recording, and a noiseless \
         (simulated or constant) {sensor} leaves them singular; give a recording whose {sensor} has its sensor noise"
    )]
    Noiseless { sensor: &'static str, var: f64 },
}

/// One filter's error against the reference, degrees.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Errors {
    pub mean: f64,
    pub rms: f64,
    pub max: f64,
    pub heading_mean: f64,
    pub tilt_mean: f64,
}

#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Score {
    pub filter: String,
    /// Run outside simnet and scored here ([`Comparison::score_outside`]).
    pub outside: bool,
    pub as_recorded: Errors,
    /// With the constant heading offset (reported) removed.
    pub offset_removed: Errors,
    pub heading_offset_deg: f64,
    /// None for a filter without gates.
    pub gated: Option<Gated>,
    /// None for a filter that keeps no covariance.
    pub consistency: Option<Consistency>,
}

fn unit(q: &Vector4<f64>) -> UnitQuaternion<f64> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]))
}

/// The rotation about the vertical (z) of d and the angle of what is left (d = swing ⊗ twist), rad.
fn swing_twist(d: &UnitQuaternion<f64>) -> (f64, f64) {
    let twist = 2.0 * d.k.atan2(d.w);
    // cos(swing/2) = √(w² + z²).
    let swing = 2.0 * (d.w * d.w + d.k * d.k).sqrt().min(1.0).acos();
    (simnet_engine::geom::wrap_angle(twist), swing)
}

/// Per sample: the angle between estimate and reference (turned by `offset` about the vertical), its heading part
/// and its tilt part, rad.
pub fn error_angles(est: &[Vector4<f64>], reference: &[Vector4<f64>], offset: f64) -> Vec<[f64; 3]> {
    let rz = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), offset);
    est.iter()
        .zip(reference)
        .map(|(e, r)| {
            // The navigation-frame rotation from the (turned) reference to the estimate.
            let d = unit(e) * (rz * unit(r)).inverse();
            let (twist, swing) = swing_twist(&d);
            [d.angle(), twist.abs(), swing]
        })
        .collect()
}

fn errors_of(est: &[Vector4<f64>], reference: &[Vector4<f64>], offset: f64) -> Errors {
    let e = error_angles(est, reference, offset);
    let n = e.len().max(1) as f64;
    let mean = |i: usize| (e.iter().map(|x| x[i]).sum::<f64>() / n).to_degrees();
    Errors {
        mean: mean(0),
        rms: (e.iter().map(|x| x[0] * x[0]).sum::<f64>() / n).sqrt().to_degrees(),
        max: e.iter().map(|x| x[0]).fold(0.0, f64::max).to_degrees(),
        heading_mean: mean(1),
        tilt_mean: mean(2),
    }
}

/// The constant rotation about the vertical that best takes the reference to the estimate: the circular mean of
/// the heading differences.
fn heading_offset(est: &[Vector4<f64>], reference: &[Vector4<f64>]) -> f64 {
    let (mut s, mut c) = (0.0, 0.0);
    for (e, r) in est.iter().zip(reference) {
        let (tw, _) = swing_twist(&(unit(e) * unit(r).inverse()));
        s += tw.sin();
        c += tw.cos();
    }
    s.atan2(c)
}

/// The reference as z-up quaternions: a reference whose "up" is −z (NED) is turned by π about x. Which one the
/// file uses is read off its first sample: the accelerometer points up.
pub fn reference_up(rec: &ImuRecording) -> Result<(Vec<Vector4<f64>>, bool), AttitudeError> {
    let q: Vec<Vector4<f64>> = match (&rec.quat, &rec.euler) {
        (Some(q), _) => q.clone(),
        (None, Some(e)) => e.iter().map(from_euler).collect(),
        _ => return Err(AttitudeError::NoReference),
    };
    Ok(z_up(q, &rec.accel[0]))
}

/// `q` turned by π about x when its first attitude puts the specific force `f0` (up, at rest) along −z; and whether
/// it was.
fn z_up(q: Vec<Vector4<f64>>, f0: &Vector3<f64>) -> (Vec<Vector4<f64>>, bool) {
    let Some(first) = q.first() else {
        return (q, false);
    };
    let (up, _) = rotate_to_body(first, &Vector3::z());
    if up.dot(&f0.normalize()) >= 0.0 {
        return (q, false);
    }
    let flip = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI);
    let turned = q
        .iter()
        .map(|x| {
            let u = flip * unit(x);
            Vector4::new(u.w, u.i, u.j, u.k)
        })
        .collect();
    (turned, true)
}

/// `q`'s errors against `reference`, as recorded and with the constant heading offset removed.
fn score(name: &str, q: &[Vector4<f64>], reference: &[Vector4<f64>]) -> Score {
    let off = heading_offset(q, reference);
    Score {
        filter: name.to_string(),
        outside: false,
        as_recorded: errors_of(q, reference, 0.0),
        offset_removed: errors_of(q, reference, off),
        heading_offset_deg: off.to_degrees(),
        gated: None,
        consistency: None,
    }
}

/// Every filter's attitudes over the recording and its scores.
#[derive(Debug, Clone)]
pub struct Comparison {
    pub characterised: Characterised,
    pub reference_z_down: bool,
    /// Navigation-frame gravity and field the filters use.
    pub g: Vector3<f64>,
    pub h: Option<Vector3<f64>>,
    pub scores: Vec<Score>,
    pub attitudes: Vec<(String, Vec<Vector4<f64>>)>,
    /// The reference, z up.
    pub reference: Vec<Vector4<f64>>,
    /// The noise model held against the reference.
    pub noise_check: check::NoiseCheck,
    /// The multiplicative EKF's model, from the recording.
    pub mekf_model: MekfModel,
}

/// Run the filters of [`filters`] on `rec`, each initialised from the first accelerometer and magnetometer samples
/// (VQF from its own), the EKFs with the noise levels, field and gates of [`characterise`].
pub fn compare(rec: &ImuRecording, rate_hz: f64) -> Result<Comparison, AttitudeError> {
    compare_with(rec, rate_hz, &GATES)
}

/// [`compare`] with other gates (`f64::INFINITY` opens one).
pub fn compare_with(rec: &ImuRecording, rate_hz: f64, gates: &Gates) -> Result<Comparison, AttitudeError> {
    let n = rec.t.len();
    if n < 3 {
        return Err(AttitudeError::TooShort(n));
    }
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(AttitudeError::Rate(rate_hz));
    }
    let (reference, z_down) = reference_up(rec)?;
    let c = characterise(rec, rate_hz, gates);
    let vars = [
        ("gyro", Some(c.gyro_var)),
        ("accelerometer", Some(c.accel_var)),
        ("magnetometer", c.mag_var),
    ];
    for (sensor, var) in vars {
        if let Some(var) = var.filter(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(AttitudeError::Noiseless { sensor, var });
        }
    }
    let (g, h, q0) = (sensor::gravity(c.g), c.field.map(|f| f.nav()), c.start);
    let mekf_model = c.mekf_model(g, h, rate_hz);
    let beta = if h.is_some() {
        MADGWICK_BETA_MARG
    } else {
        MADGWICK_BETA_IMU
    };
    let mut filters: Vec<Box<dyn Filter>> = vec![
        Box::new(Ekf::new(q0, &c, g, h)?),
        Box::new(MultiplicativeEkf::new(q0, mekf_model.clone(), c.gyro_bias)?),
        Box::new(Open::new("madgwick", Madgwick::new(q0, beta), g, h)),
        Box::new(Open::new("mahony", Mahony::new(q0, MAHONY_KP, MAHONY_KI), g, h)),
        Box::new(GyroOnly::new(q0, c.gyro_bias)),
        Box::new(Vqf::new(q0, 1.0 / rate_hz, h.is_some())),
    ];
    let mut out: Vec<Vec<Vector4<f64>>> = filters.iter().map(|_| Vec::with_capacity(n)).collect();
    for k in 0..n {
        let (accel_ok, field_ok) = c.passed[k];
        let s = Sample {
            w: rec.gyro[k],
            f: rec.accel[k],
            m: rec.mag.as_ref().map(|m| m[k]),
            dt: if k == 0 { 0.0 } else { rec.t[k] - rec.t[k - 1] },
            accel_ok,
            field_ok,
        };
        for (f, o) in filters.iter_mut().zip(out.iter_mut()) {
            f.step(&s)?;
            o.push(f.q());
        }
    }
    let scores = filters
        .iter()
        .zip(&out)
        .map(|(f, q)| Score {
            gated: f.gated(),
            consistency: f.consistency(),
            ..score(f.name(), q, &reference)
        })
        .collect();
    let noise_check = check::check(rec, &reference, &c);
    Ok(Comparison {
        noise_check,
        mekf_model,
        characterised: c,
        reference_z_down: z_down,
        g,
        h,
        scores,
        attitudes: filters.iter().map(|f| f.name().to_string()).zip(out).collect(),
        reference,
    })
}

impl Comparison {
    /// The score with the smallest mean error, as recorded or with the constant heading offset removed (a filter
    /// run elsewhere included).
    pub fn closest(&self, offset_removed: bool) -> Option<&Score> {
        let mean = |s: &Score| {
            if offset_removed {
                s.offset_removed.mean
            } else {
                s.as_recorded.mean
            }
        };
        self.scores.iter().min_by(|a, b| mean(a).total_cmp(&mean(b)))
    }

    /// Score a filter run elsewhere the way simnet's own are: `q`, one unit quaternion (scalar first, body to
    /// navigation) per sample of the recording, against the same reference. Its navigation frame may be z down
    /// (turned as the reference is, read off the first sample) and its north anywhere: the offset-removed errors
    /// do not see a constant heading.
    pub fn score_outside(&mut self, rec: &ImuRecording, name: &str, q: Vec<Vector4<f64>>) -> Result<(), AttitudeError> {
        if name == "ref" || self.attitudes.iter().any(|(n, _)| n == name) {
            return Err(AttitudeError::NameTaken {
                name: name.to_string(),
                taken: self
                    .attitudes
                    .iter()
                    .map(|(n, _)| n.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            });
        }
        let want = self.reference.len();
        if q.len() != want {
            return Err(AttitudeError::Length {
                name: name.to_string(),
                got: q.len(),
                want,
            });
        }
        let (q, _) = z_up(q, &rec.accel[0]);
        self.scores.push(Score {
            outside: true,
            ..score(name, &q, &self.reference)
        });
        self.attitudes.push((name.to_string(), q));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Matrix3;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use simnet_engine::estimate::attitude::turn;

    const DT: f64 = 0.01;

    /// A noiseless recording (a simulation without noise) is an error that names the sensor, not a failed
    /// decomposition deep in a filter.
    #[test]
    fn a_noiseless_recording_is_named_as_such() {
        let n = 500;
        let rec = ImuRecording {
            t: (0..n).map(|k| k as f64 * DT).collect(),
            gyro: vec![Vector3::zeros(); n],
            accel: vec![Vector3::new(0.0, 0.0, 9.81); n],
            mag: Some(vec![Vector3::new(0.25, 0.0, 0.43); n]),
            quat: Some(vec![Vector4::new(1.0, 0.0, 0.0, 0.0); n]),
            ..Default::default()
        };
        let e = compare_with(&rec, 1.0 / DT, &GATES).unwrap_err().to_string();
        assert!(
            e.contains("gyro shows no noise") && e.contains("give a recording"),
            "{e}"
        );
    }

    /// A simulated recording at 100 Hz: 3 s at rest, then turning about a slowly changing axis with bursts of linear
    /// acceleration; white noise on every sensor, a gyro bias, and from 20 s to 30 s the field disturbed by a
    /// constant body-frame offset of half its strength (a magnet carried with the sensor).
    fn recording(seed: u64, bias: Vector3<f64>, disturb: bool) -> (ImuRecording, std::ops::Range<usize>) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let (sg, sa, sm) = (0.005, 0.05, 0.005);
        let (ng, na, nm) = (
            Normal::new(0.0, sg).unwrap(),
            Normal::new(0.0, sa).unwrap(),
            Normal::new(0.0, sm).unwrap(),
        );
        let g = Vector3::new(0.0, 0.0, -9.81);
        let dip = 60f64.to_radians();
        let h = Vector3::new(dip.cos(), 0.0, -dip.sin()) * 0.5;
        let n = 4000;
        let disturbed = 2000..3000;
        let mut rec = ImuRecording {
            mag: Some(Vec::new()),
            quat: Some(Vec::new()),
            ..Default::default()
        };
        let mut q = from_euler(&Vector3::new(0.1, -0.2, 0.7));
        for k in 0..n {
            let t = k as f64 * DT;
            let w = if t < 3.0 {
                Vector3::zeros()
            } else {
                Vector3::new(0.6 * (0.7 * t).sin(), 0.4 * (0.45 * t).cos(), 0.5 * (0.3 * t).sin())
            };
            // Linear acceleration in bursts of 0.5 s every 4 s (navigation frame), up to 3 m/s².
            let lin = if t > 3.0 && (t % 4.0) < 0.5 {
                Vector3::new(3.0 * (12.0 * t).sin(), 2.0 * (9.0 * t).cos(), 1.5)
            } else {
                Vector3::zeros()
            };
            let noise =
                |d: &Normal<f64>, r: &mut rand_chacha::ChaCha8Rng| Vector3::new(d.sample(r), d.sample(r), d.sample(r));
            let f = rotate_to_body(&q, &(lin - g)).0 + noise(&na, &mut rng);
            let mut m = rotate_to_body(&q, &h).0 + noise(&nm, &mut rng);
            if disturb && disturbed.contains(&k) {
                m += Vector3::new(0.25, -0.1, 0.05);
            }
            rec.t.push(t);
            rec.gyro.push(w + bias + noise(&ng, &mut rng));
            rec.accel.push(f);
            rec.mag.as_mut().unwrap().push(m);
            rec.quat.as_mut().unwrap().push(q);
            q = turn(&q, &w, DT);
        }
        (rec, disturbed)
    }

    fn mean_error(c: &Comparison, filter: &str, range: std::ops::Range<usize>) -> f64 {
        let (_, q) = c.attitudes.iter().find(|(n, _)| *n == filter).unwrap();
        let e = error_angles(&q[range.clone()], &c.reference[range.clone()], 0.0);
        e.iter().map(|x| x[0]).sum::<f64>().to_degrees() / range.len() as f64
    }

    /// The rest at the start is found, the gyro bias read there within four standard errors, the white noise within
    /// 15 %, |g| and the field's dip within their noise.
    #[test]
    fn the_recording_tells_its_noise_bias_and_field() {
        let bias = Vector3::new(0.01, -0.02, 0.015);
        let (rec, _) = recording(7, bias, true);
        let c = characterise(&rec, 100.0, &GATES);
        let (s, e) = c.still.expect("a still second");
        assert!(rec.t[e] <= 3.0, "still window {s}–{e}");
        let se = 0.005 / ((e - s + 1) as f64).sqrt();
        assert!((c.gyro_bias - bias).amax() < 4.0 * se, "{:?}", c.gyro_bias);
        for (got, sd) in [(c.gyro_var, 0.005), (c.accel_var, 0.05), (c.mag_var.unwrap(), 0.005)] {
            assert!((got.sqrt() / sd - 1.0).abs() < 0.15, "sd {} against {sd}", got.sqrt());
        }
        assert!((c.g - 9.81).abs() < 0.02, "|g| {}", c.g);
        let f = c.field.unwrap();
        assert!(
            (f.magnitude - 0.5).abs() < 0.01 && (f.dip.to_degrees() - 60.0).abs() < 1.0,
            "{f:?}"
        );
    }

    /// Against the truth the simulation knows, the check measures each component: the field's white noise (σ 0.005
    /// on every axis, no disturbance) as σ² in all three directions with a correlation time near one sample, and the
    /// linear acceleration across g as an independent sum over the samples the gate passes, within 10 %. The
    /// gyro-aided fit, which has no reference, comes within a factor 2 of both.
    #[test]
    fn the_noise_check_measures_what_the_simulation_put_in() {
        let (rec, _) = recording(5, Vector3::zeros(), false);
        let c = compare(&rec, 100.0).unwrap();
        let f = c.noise_check.field.expect("a magnetometer");
        for (name, p) in [
            ("horizontal", f.across_horizontal),
            ("vertical", f.across_vertical),
            ("along", f.along),
        ] {
            assert!((p.var / 0.005f64.powi(2) - 1.0).abs() < 0.1, "{name}: {p:?}");
            assert!(p.tau < 1.5, "{name}: {p:?}");
        }
        let passed: Vec<usize> = (0..rec.t.len()).filter(|&k| c.characterised.passed[k].0).collect();
        let horizontal: f64 = passed
            .iter()
            .map(|&k| {
                let t = rec.t[k];
                if t > 3.0 && (t % 4.0) < 0.5 {
                    0.5 * ((3.0 * (12.0 * t).sin()).powi(2) + (2.0 * (9.0 * t).cos()).powi(2))
                } else {
                    0.0
                }
            })
            .sum::<f64>()
            / passed.len() as f64;
        let expected = horizontal + 0.05f64.powi(2);
        let got = c.noise_check.accel_across.var;
        assert!((got / expected - 1.0).abs() < 0.1, "{got} against {expected}");
        // The gyro-aided fit, with no reference, sees the same plus what the integration leaves: the gyro's random
        // walk over the 40 s, σ_g·dt·√n ≈ 3 mrad, which adds about (3 mrad · 9.81)² ≈ 1e-3 (m/s²)² across g.
        // Both components within a factor 2 of the truth, and never below it.
        let x = c.characterised.across.expect("the fit converges");
        let fx = x.field.unwrap();
        for (name, got, truth) in [
            ("accel", x.accel.var, expected),
            ("field", fx.var, f.across_horizontal.var),
        ] {
            assert!((1.0..2.0).contains(&(got / truth)), "{name}: {got} against {truth}");
        }
    }

    /// Second differences find white noise under smooth motion: over 20 000 samples of a sinusoid with σ = 0.1,
    /// within 5 %.
    #[test]
    fn second_differences_see_the_noise_and_not_the_motion() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let d = Normal::new(0.0, 0.1).unwrap();
        let v: Vec<Vector3<f64>> = (0..20_000)
            .map(|k| {
                let t = k as f64 * 0.01;
                Vector3::new(3.0 * t.sin(), (2.0 * t).cos(), 0.5 * t) + Vector3::from_fn(|_, _| d.sample(&mut rng))
            })
            .collect();
        let sd = sensor::white_noise_var(&v).sqrt();
        assert!((sd / 0.1 - 1.0).abs() < 0.05, "{sd}");
    }

    /// The magnet carried from 20 s to 30 s: the field gate refuses nine in ten of those samples or more and passes
    /// nearly all others; with it both EKFs hold the attitude within 2° through the disturbance, and opening the gates
    /// costs them accuracy there. The accelerometer gate refuses the bursts of linear acceleration.
    #[test]
    fn gates_keep_a_magnetic_disturbance_and_linear_acceleration_out() {
        let (rec, disturbed) = recording(11, Vector3::new(0.01, -0.02, 0.015), true);
        let c = compare(&rec, 100.0).unwrap();
        let refused_in = disturbed.clone().filter(|&k| !c.characterised.passed[k].1).count();
        let refused_out = (0..rec.t.len())
            .filter(|k| !disturbed.contains(k) && !c.characterised.passed[*k].1 && c.characterised.passed[*k].0)
            .count();
        assert!(
            refused_in as f64 >= 0.9 * disturbed.len() as f64,
            "{refused_in} of {}",
            disturbed.len()
        );
        assert!(
            refused_out < rec.t.len() / 20,
            "{refused_out} undisturbed samples refused"
        );
        // Bursts: 0.5 s of every 4 s after 3 s, 100 samples a second.
        let bursts = (0..rec.t.len())
            .filter(|&k| rec.t[k] > 3.0 && rec.t[k] % 4.0 < 0.5)
            .count();
        let open = Gates {
            accel: f64::INFINITY,
            field: f64::INFINITY,
            dip: f64::INFINITY,
            settle: 0.0,
        };
        let o = compare_with(&rec, 100.0, &open).unwrap();
        for filter in ["ekf", "mekf"] {
            let score = c.scores.iter().find(|s| s.filter == filter).unwrap();
            let gated = score.gated.unwrap();
            assert_eq!(gated.field, c.characterised.passed.iter().filter(|p| !p.1).count());
            assert!(
                gated.accel as f64 >= 0.5 * bursts as f64 && gated.accel <= bursts + 50,
                "{filter}: {} of {bursts}",
                gated.accel
            );
            let during = mean_error(&c, filter, disturbed.clone());
            let ungated = mean_error(&o, filter, disturbed.clone());
            let overall = score.as_recorded.mean;
            assert!(during < 2.0, "{filter} through the disturbance: {during}°");
            assert!(ungated > during, "{filter}: ungated {ungated}° against gated {during}°");
            assert!(overall < 2.0, "{filter} over the recording: {overall}°");
        }
    }

    /// A sample passes the settled gate only as the `need`-th passing sample on end or later, counted anew after
    /// every refusal; `settle=0` leaves the gate as it was, and `--gates` reads the duration in seconds.
    #[test]
    fn the_field_must_pass_for_a_while_before_it_corrects() {
        let ok = [true, true, true, false, true, true, true, true, false, true];
        let t = |v: &[bool]| v.iter().map(|&b| if b { '1' } else { '0' }).collect::<String>();
        assert_eq!(t(&sensor::settled(&ok, 0)), t(&ok));
        assert_eq!(t(&sensor::settled(&ok, 1)), t(&ok));
        assert_eq!(t(&sensor::settled(&ok, 2)), "0110011100");
        assert_eq!(t(&sensor::settled(&ok, 9)), "0000000000");
        assert_eq!(Gates::parse("settle=0.25").unwrap().settle, 0.25);
        assert_eq!(Gates::parse("settle=0").unwrap().settle, 0.0);
        assert_eq!(Gates::parse("accel=0.2").unwrap().settle, GATES.settle);
        assert_eq!(Gates::parse("off").unwrap(), Gates::OPEN);
        assert_eq!(Gates::parse("accel=inf").unwrap().accel, f64::INFINITY);
        for bad in ["settle=-1", "settle=inf", "settle=x"] {
            assert!(Gates::parse(bad).unwrap_err().contains("not a duration"), "{bad}");
        }
    }

    /// The same motion read through hard and soft iron: uncalibrated, the field gate refuses much of it and the
    /// attitude suffers; the ellipsoid fit of the recording takes the iron out and the EKF is back within 1°.
    #[test]
    fn an_ellipsoid_fit_takes_hard_and_soft_iron_out() {
        let (mut rec, _) = recording(13, Vector3::zeros(), false);
        let s = Matrix3::new(1.3, 0.1, 0.0, 0.1, 0.8, 0.05, 0.0, 0.05, 1.1);
        let b = Vector3::new(0.2, -0.15, 0.1);
        for m in rec.mag.as_mut().unwrap() {
            *m = s * *m + b;
        }
        let raw = compare(&rec, 100.0).unwrap();
        let fit = calibrate::fit(rec.mag.as_ref().unwrap()).unwrap();
        for m in rec.mag.as_mut().unwrap() {
            *m = fit.apply(m);
        }
        let cal = compare(&rec, 100.0).unwrap();
        let ekf = |c: &Comparison| c.scores[0].clone();
        assert!(ekf(&cal).as_recorded.mean < 1.0, "{:?}", ekf(&cal));
        assert!(
            ekf(&raw).as_recorded.mean > ekf(&cal).as_recorded.mean,
            "{:?}",
            ekf(&raw)
        );
        assert!(
            ekf(&cal).gated.unwrap().field < ekf(&raw).gated.unwrap().field,
            "{:?} against {:?}",
            ekf(&cal).gated,
            ekf(&raw).gated
        );
    }
}
