//! One recording studied end to end, as a library call: read (with a reference from a file of its own when there is
//! one), the magnetometer calibrated if asked, the filters compared; the result as JSON and as a per-sample table.
//! `simnet attitude` and the Python package print and write what this returns.

use super::calibrate::{self, Calibration, Refused};
use super::{compare_with, error_angles, AttitudeError, Comparison, Gates};
use simnet_engine::imu_csv::layout::{self, ReadOptions, Reading};
use simnet_engine::imu_csv::CsvError;

/// A file's text and the name errors show for it.
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    pub text: &'a str,
    pub name: &'a str,
}

/// A filter run elsewhere, to be scored beside simnet's: its name in the table and the file of its attitudes
/// (a quaternion or roll, pitch, yaw per row; with a time column it is matched to the recording by time, without
/// one it has a row per sample of the recording).
#[derive(Debug, Clone, Copy)]
pub struct Outside<'a> {
    pub name: &'a str,
    pub source: Source<'a>,
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
    #[error("--compare {name}=…: {why}")]
    OutsideName { name: String, why: String },
    #[error(
        "{file}: its times ({from:.3}–{to:.3} s) do not cover the recording's ({need_from:.3}–{need_to:.3} s): \
             a filter compared needs an attitude at every sample"
    )]
    OutsideSpan {
        file: String,
        from: f64,
        to: f64,
        need_from: f64,
        need_to: f64,
    },
    #[error("{file}: {rows} rows and no time column: without one it needs a row per sample of the recording ({want})")]
    OutsideRows { file: String, rows: usize, want: usize },
}

/// The attitudes a reference-only reading holds, as quaternions.
fn attitudes_of(r: &Reading) -> Vec<nalgebra::Vector4<f64>> {
    match (&r.recording.quat, &r.recording.euler) {
        (Some(q), _) => q.clone(),
        (_, Some(e)) => e.iter().map(simnet_engine::estimate::attitude::from_euler).collect(),
        _ => Vec::new(),
    }
}

fn check_name(name: &str, before: &[Outside]) -> Result<(), StudyError> {
    let why = if name.is_empty() || name.len() > 16 {
        Some("a name is 1 to 16 characters".to_string())
    } else if !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
        Some("a name is letters, digits, `_` and `-` (it heads columns of attitude.csv)".to_string())
    } else if before.iter().any(|o| o.name == name) {
        Some(format!("`{name}` is given twice"))
    } else {
        None
    };
    why.map_or(Ok(()), |why| {
        Err(StudyError::OutsideName {
            name: name.to_string(),
            why,
        })
    })
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

/// Read `file` (and `reference`), calibrate if asked, compare the filters behind `gates`, and score the filters
/// run elsewhere (`outside`) beside them.
pub fn study(
    file: Source,
    reference: Option<Source>,
    outside: &[Outside],
    o: &ReadOptions,
    calibrate_mag: bool,
    gates: Gates,
) -> Result<Study, StudyError> {
    for (i, x) in outside.iter().enumerate() {
        check_name(x.name, &outside[..i])?;
    }
    let mut reading = layout::read_any(file.text, file.name, o)?;
    // The recording's times and, after a reference apart has dropped some, which of its rows are left.
    let all_t = reading.recording.t.clone();
    let mut kept: Vec<usize> = (0..all_t.len()).collect();
    if let Some(r) = reference {
        let ro = ReadOptions {
            columns: Vec::new(),
            ..o.clone()
        };
        let refr = layout::read_reference(r.text, r.name, &ro)?;
        kept = simnet_engine::imu_csv::join_reference(&mut reading.recording, &refr.recording.t, &attitudes_of(&refr));
        let dropped = all_t.len() - kept.len();
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
    let mut comparison =
        compare_with(&reading.recording, reading.rate_hz, &gates).map_err(|source| StudyError::Attitude {
            name: file.name.to_string(),
            source,
        })?;
    for x in outside {
        let q = outside_attitudes(x.source, o, reading.rate_hz, &all_t, &kept, &reading.recording.t)?;
        comparison
            .score_outside(&reading.recording, x.name, q)
            .map_err(|source| StudyError::Attitude {
                name: x.source.name.to_string(),
                source,
            })?;
    }
    Ok(Study {
        name: file.name.to_string(),
        reading,
        calibration,
        gates,
        comparison,
    })
}

/// A filter's attitudes from its file, one per sample the comparison keeps: by time when the file has a time column
/// (within half a sample of the recording's ends), else row for row with the recording (`all_t`), of which `kept`
/// are left at the times `t`.
fn outside_attitudes(
    src: Source,
    o: &ReadOptions,
    rate_hz: f64,
    all_t: &[f64],
    kept: &[usize],
    t: &[f64],
) -> Result<Vec<nalgebra::Vector4<f64>>, StudyError> {
    let ro = ReadOptions {
        columns: Vec::new(),
        rate_hz: Some(rate_hz),
        ..o.clone()
    };
    let r = layout::read_reference(src.text, src.name, &ro)?;
    let q = attitudes_of(&r);
    if !r.columns.iter().any(|(target, _)| target == "t") {
        if q.len() != all_t.len() {
            return Err(StudyError::OutsideRows {
                file: src.name.to_string(),
                rows: q.len(),
                want: all_t.len(),
            });
        }
        return Ok(kept.iter().map(|&k| q[k]).collect());
    }
    let (from, to) = (r.recording.t[0], r.recording.t[r.recording.t.len() - 1]);
    let (need_from, need_to) = (t[0], t[t.len() - 1]);
    let slack = 0.5 / rate_hz;
    if from > need_from + slack || to < need_to - slack {
        return Err(StudyError::OutsideSpan {
            file: src.name.to_string(),
            from,
            to,
            need_from,
            need_to,
        });
    }
    Ok(simnet_engine::imu_csv::attitudes_at(&r.recording.t, &q, t))
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
                "settle_s": gates.settle,
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
fn gauss_markov(p: &simnet_engine::estimate::mekf::GaussMarkov) -> serde_json::Value {
    serde_json::json!({ "sd": p.var.sqrt(), "tau_s": p.tau })
}
