//! One recording studied end to end, as a library call: read (with a reference from a file of its own when there is
//! one), the magnetometer calibrated if asked, the filters compared; the result as JSON and as a per-sample table.
//! `simnet attitude` and the Python package print and write what this returns.

use super::calibrate::{self, Calibration, Refused};
use super::{compare_with, error_angles, AttitudeError, Comparison, Gates};
use crate::imu_csv::layout::{self, ReadOptions, Reading};
use crate::imu_csv::CsvError;

/// A file's text and the name errors show for it.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    pub text: &'a str,
    pub name: &'a str,
}

#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    #[error("{0}")]
    Read(#[from] CsvError),
    #[error("{name}: its times ({from:.3}–{to:.3} s) hardly overlap the recording's")]
    NoOverlap { name: String, from: f64, to: f64 },
    #[error("{0}: --calibrate-mag: the recording has no magnetometer")]
    NoMagnetometer(String),
    #[error("{name}: {source}")]
    Attitude { name: String, source: AttitudeError },
}

#[derive(Debug, Clone)]
pub struct Study {
    pub name: String,
    pub reading: Reading,
    /// Asked for: the fit, or why it was refused.
    pub calibration: Option<Result<Calibration, Refused>>,
    pub gates: Gates,
    pub comparison: Comparison,
}

/// Read `file` (and `reference`), calibrate if asked, compare the filters behind `gates`.
pub fn study(
    file: Source,
    reference: Option<Source>,
    o: &ReadOptions,
    calibrate_mag: bool,
    gates: Gates,
) -> Result<Study, StudyError> {
    let mut reading = layout::read_any(file.text, file.name, o)?;
    if let Some(r) = reference {
        let ro = ReadOptions {
            columns: Vec::new(),
            ..o.clone()
        };
        let refr = layout::read_reference(r.text, r.name, &ro)?;
        let q: Vec<_> = match (&refr.recording.quat, &refr.recording.euler) {
            (Some(q), _) => q.clone(),
            (_, Some(e)) => e.iter().map(crate::estimate::attitude::from_euler).collect(),
            _ => unreachable!("read_reference returns a reference or an error"),
        };
        let dropped = crate::imu_csv::join_reference(&mut reading.recording, &refr.recording.t, &q);
        if reading.recording.t.len() < 3 {
            return Err(StudyError::NoOverlap {
                name: r.name.to_string(),
                from: refr.recording.t[0],
                to: refr.recording.t.last().copied().unwrap_or(0.0),
            });
        }
        reading.notes.push(format!(
            "reference: {} ({} samples at {:.4} Hz), interpolated at the recording's times{}",
            r.name,
            refr.recording.t.len(),
            refr.rate_hz,
            if dropped > 0 {
                format!("; {dropped} samples outside its time span left out")
            } else {
                String::new()
            }
        ));
        reading
            .columns
            .extend(refr.columns.into_iter().filter(|(t, _)| t != "t"));
    }
    let mut calibration = None;
    if calibrate_mag {
        let Some(mag) = reading.recording.mag.as_mut() else {
            return Err(StudyError::NoMagnetometer(file.name.to_string()));
        };
        calibration = Some(calibrate::fit(mag).inspect(|c| {
            for m in mag.iter_mut() {
                *m = c.apply(m);
            }
        }));
    }
    let comparison =
        compare_with(&reading.recording, reading.rate_hz, &gates).map_err(|source| StudyError::Attitude {
            name: file.name.to_string(),
            source,
        })?;
    Ok(Study {
        name: file.name.to_string(),
        reading,
        calibration,
        gates,
        comparison,
    })
}

/// An open gate (∞) as JSON null.
fn finite(x: f64) -> Option<f64> {
    x.is_finite().then_some(x)
}

impl Study {
    /// The window at rest, in seconds from the first sample.
    pub fn still_s(&self) -> Option<[f64; 2]> {
        let t = &self.reading.recording.t;
        self.comparison
            .characterised
            .still
            .map(|(a, b)| [t[a] - t[0], t[b] - t[0]])
    }

    /// What `simnet attitude --json` prints.
    pub fn json(&self) -> serde_json::Value {
        let (e, c, gates) = (&self.comparison.characterised, &self.comparison, &self.gates);
        serde_json::json!({
            "file": self.name,
            "columns": self.reading.columns,
            "read": self.reading.notes,
            "rate_hz": self.reading.rate_hz,
            "estimated": {
                "still_s": self.still_s(),
                "gyro_bias": e.gyro_bias.as_slice(),
                "gyro_sd": e.gyro_var.sqrt(),
                "accel_sd": e.accel_var.sqrt(),
                "mag_sd": e.mag_var.map(f64::sqrt),
                "g": e.g,
                "accel_motion_sd": e.accel_motion_var.sqrt(),
                "accel_motion_tau": e.accel_motion_tau,
                "accel_passed": e.accel_passed,
                "across": e.across.map(|x| serde_json::json!({
                    "accel": x.accel,
                    "field": x.field,
                    "bias_correction": x.bias_correction.as_slice(),
                })),
                "field": e.field.map(|f| serde_json::json!({
                    "magnitude": f.magnitude,
                    "dip_deg": f.dip.to_degrees(),
                    "passed": f.passed,
                    "disturbance_sd": e.mag_disturbance_var.map(f64::sqrt),
                    "disturbance_tau": e.mag_disturbance_tau,
                })),
            },
            "noise_check": c.noise_check,
            "mekf_model": {
                "gyro_sd": c.mekf_model.gyro_var.sqrt(),
                "accel_sd": c.mekf_model.accel_var.sqrt(),
                "mag_sd": c.mekf_model.mag_var.sqrt(),
                "accel_horizontal": gauss_markov(&c.mekf_model.accel_horizontal),
                "accel_vertical": gauss_markov(&c.mekf_model.accel_vertical),
                "field": c.h.map(|_| gauss_markov(&c.mekf_model.field)),
            },
            "reference_z_down": c.reference_z_down,
            "gates": {
                "accel": finite(gates.accel),
                "field": finite(gates.field),
                "dip_deg": finite(gates.dip.to_degrees()),
            },
            "mag_calibration": self.calibration.as_ref().map(|r| match r {
                Ok(c) => serde_json::json!({
                    "offset": c.offset.as_slice(),
                    "matrix": c.matrix.transpose().as_slice(),
                    "spread_before": c.spread_before,
                    "spread_after": c.spread_after,
                }),
                Err(e) => serde_json::json!({ "refused": e.to_string() }),
            }),
            "scores": c.scores,
        })
    }

    /// Per-sample errors against the reference (rad): heading-offset not removed.
    pub fn error_angles(&self) -> Vec<Vec<[f64; 3]>> {
        let c = &self.comparison;
        c.attitudes
            .iter()
            .map(|(_, q)| error_angles(q, &c.reference, 0.0))
            .collect()
    }

    /// `attitude.csv`: time from the first sample, the reference, the gates' verdicts, and each filter's quaternion
    /// and error (total, heading, tilt; degrees).
    pub fn csv(&self) -> String {
        let c = &self.comparison;
        let t = &self.reading.recording.t;
        let errors = self.error_angles();
        let mut csv = String::from("t,ref_qw,ref_qx,ref_qy,ref_qz,accel_passed,field_passed");
        for (name, _) in &c.attitudes {
            csv.push_str(&format!(
                ",{name}_qw,{name}_qx,{name}_qy,{name}_qz,{name}_error_deg,{name}_heading_deg,{name}_tilt_deg"
            ));
        }
        csv.push('\n');
        for k in 0..t.len() {
            let r = &c.reference[k];
            let (a, f) = c.characterised.passed[k];
            csv.push_str(&format!(
                "{},{},{},{},{},{},{}",
                t[k] - t[0],
                r[0],
                r[1],
                r[2],
                r[3],
                u8::from(a),
                u8::from(f)
            ));
            for ((_, q), e) in c.attitudes.iter().zip(&errors) {
                let (q, e) = (q[k], e[k]);
                csv.push_str(&format!(
                    ",{},{},{},{},{},{},{}",
                    q[0],
                    q[1],
                    q[2],
                    q[3],
                    e[0].to_degrees(),
                    e[1].to_degrees(),
                    e[2].to_degrees()
                ));
            }
            csv.push('\n');
        }
        csv
    }
}

/// A Gauss–Markov process as `--json` gives it: standard deviation and correlation time in seconds.
fn gauss_markov(p: &crate::estimate::mekf::GaussMarkov) -> serde_json::Value {
    serde_json::json!({ "sd": p.var.sqrt(), "tau_s": p.tau })
}
