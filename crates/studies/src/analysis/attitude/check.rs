//! The EKF's noise model held against the reference. The reference gives what the recording alone cannot: each
//! sample in the navigation frame, so the linear acceleration across gravity and the field's disturbance across the
//! field can be measured component by component. The noise model reaches the components across with the gyro alone
//! ([`super::across`]); this says how close it comes. Nothing here feeds a filter: the reference only scores.

use nalgebra::{Vector3, Vector4};

use super::disturbance::Part;
use super::sensor::Characterised;
use super::unit;
use simnet_engine::imu_csv::ImuRecording;
use simnet_engine::stats;

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct FieldCheck {
    /// Across the field and horizontal: the component that turns heading.
    pub across_horizontal: Part,
    /// Across the field in its vertical plane: it changes the dip.
    pub across_vertical: Part,
    /// Along the field: it changes |m|.
    pub along: Part,
    /// What the EKF's noise model takes for each component ([`Characterised::r_mag`]).
    pub model: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct NoiseCheck {
    /// Linear acceleration across gravity (mean of the two horizontal axes) over the samples the accelerometer gate
    /// passes, the sensor's white noise included.
    pub accel_across: Part,
    /// What the EKF's noise model takes for each axis ([`Characterised::r_accel`]).
    pub accel_model: f64,
    /// None without a magnetometer.
    pub field: Option<FieldCheck>,
}

/// Measure each component against `reference` (z up, one quaternion per sample of `rec`).
pub fn check(rec: &ImuRecording, reference: &[Vector4<f64>], c: &Characterised) -> NoiseCheck {
    let nav = |v: &[Vector3<f64>]| -> Vec<Vector3<f64>> { v.iter().zip(reference).map(|(x, q)| unit(q) * x).collect() };
    let f = nav(&rec.accel);
    let axis = |v: &[Vector3<f64>], u: &Vector3<f64>| -> Vec<f64> { v.iter().map(|x| x.dot(u)).collect() };
    // Specific force is +|g| up at rest: what is left is linear acceleration.
    let lin: Vec<Vector3<f64>> = f.iter().map(|x| x - Vector3::new(0.0, 0.0, c.g)).collect();
    let accel_ok = |k: usize| c.passed[k].0;
    let accel_across = Part::mean(
        Part::of(&axis(&lin, &Vector3::x()), accel_ok),
        Part::of(&axis(&lin, &Vector3::y()), accel_ok),
    );
    let field = rec.mag.as_ref().and_then(|m| {
        let m = nav(m);
        let field_ok = |k: usize| c.passed[k].1;
        let ok: Vec<usize> = (0..m.len()).filter(|&k| field_ok(k)).collect();
        let median = |i: usize| stats::median(&ok.iter().map(|&k| m[k][i]).collect::<Vec<_>>());
        // The field where the gate passes it, in the reference's frame.
        let h = Vector3::new(median(0), median(1), median(2));
        let along = h.try_normalize(1e-12)?;
        let horizontal = Vector3::z().cross(&along).try_normalize(1e-12)?;
        let vertical = along.cross(&horizontal);
        let d: Vec<Vector3<f64>> = m.iter().map(|x| x - h).collect();
        Some(FieldCheck {
            across_horizontal: Part::of(&axis(&d, &horizontal), field_ok),
            across_vertical: Part::of(&axis(&d, &vertical), field_ok),
            along: Part::of(&axis(&d, &along), field_ok),
            model: c.r_mag()?,
        })
    });
    NoiseCheck {
        accel_across,
        accel_model: c.r_accel(),
        field,
    }
}
