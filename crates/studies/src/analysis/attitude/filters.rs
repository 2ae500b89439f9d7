//! The filters `compare` runs, each behind [`Filter`]: the quaternion EKF and the multiplicative EKF with the
//! recording's noise model and gates (and the NIS of their corrections), Madgwick's and Mahony's filters as
//! published, VQF as published, and the gyro alone.

use nalgebra::{DMatrix, DVector, Matrix3, Quaternion, UnitQuaternion, Vector3, Vector4};

use super::Characterised;
use simnet_engine::estimate::ahrs::{compensated_field, Ahrs};
use simnet_engine::estimate::attitude::{measurement, rotate_to_body, turn, AttitudeEkf, AttitudeModel, Form};
use simnet_engine::estimate::mekf::{Mekf, MekfModel};
use simnet_engine::estimate::EstimateError;

/// How many corrections a filter's gates left out.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Gated {
    pub accel: usize,
    pub field: usize,
}

/// The mean normalised innovation squared per degree of freedom of one sensor's corrections, and the 99 % band it
/// would lie in were the filter consistent and its innovations white (Bar-Shalom, Li & Kirubarajan 2001, §5.4):
/// below the band the model overstates the sensor's disturbance, above it understates.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Nis {
    pub per_dof: f64,
    pub dof: usize,
    pub band: [f64; 2],
}

/// The normalised innovations of a filter's accelerometer and magnetometer corrections.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Consistency {
    pub accel: Option<Nis>,
    pub field: Option<Nis>,
}

impl Consistency {
    /// From the running sums of the accelerometer's and the magnetometer's corrections.
    fn of(nis: &[NisSum; 2]) -> Consistency {
        Consistency {
            accel: nis[0].mean(),
            field: nis[1].mean(),
        }
    }
}

/// A running sum of NIS values and their degrees of freedom.
#[derive(Debug, Clone, Copy, Default)]
struct NisSum {
    sum: f64,
    dof: usize,
}

impl NisSum {
    fn add(&mut self, value: f64, dof: usize) {
        self.sum += value;
        self.dof += dof;
    }

    fn mean(&self) -> Option<Nis> {
        (self.dof > 0).then(|| {
            let n = self.dof as f64;
            Nis {
                per_dof: self.sum / n,
                dof: self.dof,
                band: [
                    simnet_engine::stats::chi2_quantile(0.005, n) / n,
                    simnet_engine::stats::chi2_quantile(0.995, n) / n,
                ],
            }
        })
    }
}

/// One sample as the filters take it.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    pub w: Vector3<f64>,
    pub f: Vector3<f64>,
    pub m: Option<Vector3<f64>>,
    /// Time since the previous sample; zero for the first.
    pub dt: f64,
    /// Whether the sample passed the accelerometer and field gates.
    pub accel_ok: bool,
    pub field_ok: bool,
}

/// An attitude filter run over a recording.
pub trait Filter {
    fn name(&self) -> &'static str;
    fn step(&mut self, s: &Sample) -> Result<(), EstimateError>;
    fn q(&self) -> Vector4<f64>;
    /// The corrections its gates left out, for a filter that has gates.
    fn gated(&self) -> Option<Gated> {
        None
    }
    /// Its innovations against their covariance, for a filter that keeps one.
    fn consistency(&self) -> Option<Consistency> {
        None
    }
}

/// The quaternion EKF with the recording's noise and gates: a correction the gates refuse counts as a missing
/// channel, inflated by λ (the per-channel loss model of the source document).
pub struct Ekf {
    ekf: AttitudeEkf,
    model: AttitudeModel,
    bias: Vector3<f64>,
    /// The navigation-frame field the recording gives.
    h: Vector3<f64>,
    marg: bool,
    gated: Gated,
    nis: [NisSum; 2],
}

impl Ekf {
    /// Gyro noise R_g and bias from `c`; accelerometer R the white noise plus the white-noise equivalent of the
    /// linear acceleration the gate lets through (its variance times its correlation time), magnetometer R likewise
    /// with the field's disturbance.
    pub fn new(
        q0: Vector4<f64>,
        c: &Characterised,
        g: Vector3<f64>,
        h: Option<Vector3<f64>>,
    ) -> Result<Ekf, EstimateError> {
        let (ra, rm) = (c.r_accel(), c.r_mag().unwrap_or(1.0));
        let hv = h.unwrap_or_else(Vector3::x);
        let model = AttitudeModel {
            g,
            h: hv,
            Rg: Matrix3::identity() * c.gyro_var,
            R: DMatrix::from_diagonal(&DVector::from_vec(vec![ra, ra, ra, rm, rm, rm])),
            lambda: 1e3,
        };
        Ok(Ekf {
            ekf: AttitudeEkf::new(q0, &(DMatrix::identity(4, 4) * 1e-2), Form::Standard)?,
            model,
            bias: c.gyro_bias,
            h: hv,
            marg: h.is_some(),
            gated: Gated::default(),
            nis: Default::default(),
        })
    }

    /// The NIS of the corrections `update` is about to make, each channel on its own (its block of S): the
    /// accelerometer's three rows, and the magnetometer's one informative direction, across the compensated field
    /// (the reading's misfit lies along it alone).
    #[allow(non_snake_case)]
    fn record_nis(&mut self, y: &DVector<f64>, accel: bool, field: bool) -> Result<(), EstimateError> {
        let (pred, C) = measurement(&self.ekf.q, &self.model.g, &self.model.h);
        let S = &C * self.ekf.P() * C.transpose() + &self.model.R;
        let nu = y - pred;
        if accel {
            let s = S.view((0, 0), (3, 3)).into_owned();
            let v = nu.rows(0, 3).into_owned();
            let chol = simnet_engine::estimate::cholesky(&s, "accelerometer innovation covariance")?;
            self.nis[0].add(v.dot(&chol.solve(&v)), 3);
        }
        if field {
            let up = -self.model.g.normalize();
            if let Some(u) = up.cross(&self.model.h).try_normalize(1e-12) {
                let (a, _) = rotate_to_body(&self.ekf.q, &u);
                let s = (a.transpose() * S.view((3, 3), (3, 3)) * a)[(0, 0)];
                let v = a.dot(&nu.rows(3, 3));
                self.nis[1].add(v * v / s, 1);
            }
        }
        Ok(())
    }
}

impl Filter for Ekf {
    fn name(&self) -> &'static str {
        "ekf"
    }

    fn step(&mut self, s: &Sample) -> Result<(), EstimateError> {
        if s.dt > 0.0 {
            self.ekf.predict(&(s.w - self.bias), s.dt, &self.model)?;
        }
        let mut y = DVector::zeros(6);
        y.rows_mut(0, 3).copy_from(&s.f);
        if let Some(m) = s.m {
            y.rows_mut(3, 3).copy_from(&m);
            // The field reference of Madgwick's eqs. 45–46: the measured dip and strength, the estimated north, so
            // that the magnetometer corrects heading and leaves tilt to the accelerometer.
            if let Some(b) = compensated_field(&self.ekf.q, &m, &self.model.g, &self.h) {
                self.model.h = b;
            }
        }
        let field = self.marg && s.field_ok;
        self.gated.accel += usize::from(!s.accel_ok);
        self.gated.field += usize::from(self.marg && !s.field_ok);
        self.record_nis(&y, s.accel_ok, field)?;
        self.ekf.update(&y, [s.accel_ok, field], &self.model)
    }

    fn q(&self) -> Vector4<f64> {
        self.ekf.q
    }

    fn gated(&self) -> Option<Gated> {
        Some(self.gated)
    }

    fn consistency(&self) -> Option<Consistency> {
        Some(Consistency::of(&self.nis))
    }
}

/// The multiplicative EKF of [`simnet_engine::estimate::mekf`] with the recording's noise, disturbances
/// ([`Characterised::mekf_model`]) and gates: a correction the gates refuse is skipped, and the shaping states
/// carry the disturbance between corrections.
pub struct MultiplicativeEkf {
    mekf: Mekf,
    bias: Vector3<f64>,
    gated: Gated,
    nis: [NisSum; 2],
}

impl MultiplicativeEkf {
    pub fn new(q0: Vector4<f64>, model: MekfModel, bias: Vector3<f64>) -> Result<MultiplicativeEkf, EstimateError> {
        Ok(MultiplicativeEkf {
            mekf: Mekf::new(q0, model)?,
            bias,
            gated: Gated::default(),
            nis: Default::default(),
        })
    }
}

impl Filter for MultiplicativeEkf {
    fn name(&self) -> &'static str {
        "mekf"
    }

    fn step(&mut self, s: &Sample) -> Result<(), EstimateError> {
        if s.dt > 0.0 {
            self.mekf.predict(&(s.w - self.bias), s.dt)?;
        }
        if s.accel_ok {
            let n = self.mekf.update_accel(&s.f)?;
            self.nis[0].add(n.value, n.dof);
        } else {
            self.gated.accel += 1;
        }
        if let Some(m) = s.m {
            if !s.field_ok {
                self.gated.field += 1;
            } else if let Some(n) = self.mekf.update_field(&m)? {
                self.nis[1].add(n.value, n.dof);
            }
        }
        Ok(())
    }

    fn q(&self) -> Vector4<f64> {
        self.mekf.q()
    }

    fn gated(&self) -> Option<Gated> {
        Some(self.gated)
    }

    fn consistency(&self) -> Option<Consistency> {
        Some(Consistency::of(&self.nis))
    }
}

/// The gyro alone, its still-window bias removed, from the levelled start: the baseline every correction should
/// improve on.
pub struct GyroOnly {
    q: Vector4<f64>,
    bias: Vector3<f64>,
}

impl GyroOnly {
    pub fn new(q0: Vector4<f64>, bias: Vector3<f64>) -> GyroOnly {
        GyroOnly { q: q0, bias }
    }
}

impl Filter for GyroOnly {
    fn name(&self) -> &'static str {
        "gyro"
    }

    fn step(&mut self, s: &Sample) -> Result<(), EstimateError> {
        if s.dt > 0.0 {
            self.q = turn(&self.q, &(s.w - self.bias), s.dt);
        }
        Ok(())
    }

    fn q(&self) -> Vector4<f64> {
        self.q
    }
}

/// Madgwick's and Mahony's filters as published: the raw gyro, every sample, no gates.
pub struct Open<F> {
    name: &'static str,
    filter: F,
    g: Vector3<f64>,
    h: Option<Vector3<f64>>,
}

impl<F: Ahrs> Open<F> {
    /// `filter` under `name`, with the navigation-frame gravity `g` and field `h` (None: no magnetometer).
    pub fn new(name: &'static str, filter: F, g: Vector3<f64>, h: Option<Vector3<f64>>) -> Open<F> {
        Open { name, filter, g, h }
    }
}

impl<F: Ahrs> Filter for Open<F> {
    fn name(&self) -> &'static str {
        self.name
    }

    fn step(&mut self, s: &Sample) -> Result<(), EstimateError> {
        if s.dt > 0.0 {
            let m = s.m.filter(|_| self.h.is_some());
            let h = self.h.unwrap_or_else(Vector3::x);
            self.filter.update(&s.w, Some(&s.f), m.as_ref(), &self.g, &h, s.dt);
        }
        Ok(())
    }

    fn q(&self) -> Vector4<f64> {
        self.filter.attitude()
    }
}

/// VQF (Laidig & Seel 2023, "VQF: Highly accurate IMU orientation estimation with bias estimation and magnetic
/// disturbance rejection", Information Fusion 91) through `vqf-rs`, a port of its reference C++, with the published
/// defaults: its own rest detection, gyro bias estimation and magnetic disturbance rejection, at the recording's
/// nominal sample time, and none of simnet's estimates or gates.
pub struct Vqf {
    vqf: vqf_rs::VQF,
    mag: bool,
    /// From VQF's earth frame into the navigation frame: with a magnetometer VQF's frame is east-north-up, so −90°
    /// about z takes its north (y) to the navigation frame's (x); without one its heading is its own, and the first
    /// sample turns it onto the other filters' start.
    turn: Option<UnitQuaternion<f64>>,
    start: Vector4<f64>,
}

impl Vqf {
    /// At the sample time `ts` (s); `mag`: whether the magnetometer's samples are used.
    pub fn new(q0: Vector4<f64>, ts: f64, mag: bool) -> Vqf {
        Vqf {
            vqf: vqf_rs::VQF::new(ts, None, None, None),
            mag,
            turn: mag.then(|| UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -std::f64::consts::FRAC_PI_2)),
            start: q0,
        }
    }

    fn own(&self) -> UnitQuaternion<f64> {
        let q = if self.mag {
            self.vqf.quat_9d()
        } else {
            self.vqf.quat_6d()
        };
        UnitQuaternion::from_quaternion(Quaternion::new(q.0, q.1, q.2, q.3))
    }
}

impl Filter for Vqf {
    fn name(&self) -> &'static str {
        "vqf"
    }

    fn step(&mut self, s: &Sample) -> Result<(), EstimateError> {
        let m = s.m.filter(|_| self.mag).map(|m| [m[0], m[1], m[2]]);
        self.vqf.update([s.w[0], s.w[1], s.w[2]], [s.f[0], s.f[1], s.f[2]], m);
        if self.turn.is_none() {
            let d = super::unit(&self.start) * self.own().inverse();
            self.turn = Some(UnitQuaternion::from_axis_angle(
                &Vector3::z_axis(),
                super::swing_twist(&d).0,
            ));
        }
        Ok(())
    }

    fn q(&self) -> Vector4<f64> {
        let u = self.turn.unwrap_or_default() * self.own();
        Vector4::new(u.w, u.i, u.j, u.k)
    }
}
