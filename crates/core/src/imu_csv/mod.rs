//! Recorded IMU files: `t,ax,ay,az,gx,gy,gz[,mx,my,mz]` in SI units (s, m/s² specific force in the body frame,
//! rad/s), optionally with reference columns `x,y,z` (position, m) and `roll,pitch,yaw` (Euler ZYX, rad). A header
//! line names the columns, in any order; `#` starts a comment line. `simnet run --out` writes one per sensing node
//! (`imu-ID.csv`, with the true pose as reference). `layout/` reads the files IMU makers and loggers write
//! (`names.rs`: their column names and units).

use nalgebra::Vector3;

use crate::sensor::ImuSample;
use crate::text::clip;

pub mod layout;

/// One IMU sample as sensed, with the true pose at its time (`imu-ID.csv`).
#[derive(Debug, Clone, Copy)]
pub struct ImuRow {
    /// Time, s.
    pub t: f64,
    /// Specific force and angular rate.
    pub sample: ImuSample,
    /// Magnetometer (attitude model).
    pub mag: Option<Vector3<f64>>,
    /// Reference position, m.
    pub position: Vector3<f64>,
    /// Euler ZYX [roll, pitch, yaw], rad.
    pub euler: Vector3<f64>,
}

/// A line of a recorded IMU file that cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{file}:{line}: {message}")]
pub struct CsvError {
    /// The file, as named to the user.
    pub file: String,
    /// 1-based line number.
    pub line: usize,
    /// What is wrong with the line.
    pub message: String,
}

/// A recorded IMU file, column by column.
#[derive(Debug, Clone, Default)]
pub struct ImuRecording {
    /// Sample times, s, increasing.
    pub t: Vec<f64>,
    /// Specific force, body frame, m/s².
    pub accel: Vec<Vector3<f64>>,
    /// Angular rate, body frame, rad/s.
    pub gyro: Vec<Vector3<f64>>,
    /// Magnetometer, if recorded.
    pub mag: Option<Vec<Vector3<f64>>>,
    /// Reference position, m, if recorded.
    pub position: Option<Vec<Vector3<f64>>>,
    /// Reference attitude, Euler ZYX [roll, pitch, yaw], rad, if recorded.
    pub euler: Option<Vec<Vector3<f64>>>,
    /// Reference attitude as a unit quaternion (scalar first, body to navigation), as makers' files give it.
    pub quat: Option<Vec<nalgebra::Vector4<f64>>>,
}

const GROUPS: [(&str, [&str; 3]); 5] = [
    ("accelerometer", ["ax", "ay", "az"]),
    ("gyro", ["gx", "gy", "gz"]),
    ("magnetometer", ["mx", "my", "mz"]),
    ("reference position", ["x", "y", "z"]),
    ("reference attitude", ["roll", "pitch", "yaw"]),
];

/// A recording from simnet's CSV text (`t,ax,ay,az,gx,gy,gz[,…]`); `file` names it in errors.
pub fn parse(text: &str, file: &str) -> Result<ImuRecording, CsvError> {
    let err = |line: usize, message: String| CsvError {
        file: file.to_string(),
        line,
        message,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (hl, header) = lines
        .next()
        .ok_or_else(|| err(1, "empty file: expected a header `t,ax,ay,az,gx,gy,gz`".into()))?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let known = |n: &str| n == "t" || GROUPS.iter().any(|(_, g)| g.contains(&n));
    const EXPECTED: &str = "t, ax…az, gx…gz, mx…mz, x, y, z, roll, pitch, yaw";
    if !names.iter().any(|n| known(n)) {
        // Not an IMU file at all: say so without quoting what it holds.
        return Err(err(
            hl,
            format!("not an IMU file: its header names none of the columns {EXPECTED}"),
        ));
    }
    if let Some(bad) = names.iter().find(|n| !known(n)) {
        return Err(err(hl, format!("unknown column `{}` (expected {EXPECTED})", clip(bad))));
    }
    for (i, n) in names.iter().enumerate() {
        if names[..i].contains(n) {
            return Err(err(hl, format!("column `{n}` appears twice")));
        }
    }
    let col = |n: &str| names.iter().position(|c| *c == n);
    let t_col = col("t").ok_or_else(|| err(hl, "no `t` column".into()))?;
    let mut groups: Vec<Option<[usize; 3]>> = Vec::new();
    for (what, g) in GROUPS {
        let idx: Vec<Option<usize>> = g.iter().map(|n| col(n)).collect();
        match (idx.iter().all(Option::is_some), idx.iter().any(Option::is_some)) {
            (true, _) => groups.push(Some([idx[0].unwrap_or(0), idx[1].unwrap_or(0), idx[2].unwrap_or(0)])),
            (false, true) => {
                return Err(err(hl, format!("the {what} needs all three columns {}", g.join(", "))));
            }
            (false, false) => groups.push(None),
        }
    }
    for (i, what) in [(0, "accelerometer"), (1, "gyro")] {
        if groups[i].is_none() {
            return Err(err(hl, format!("no {what} columns ({})", GROUPS[i].1.join(", "))));
        }
    }
    let mut rec = ImuRecording {
        mag: groups[2].map(|_| Vec::new()),
        position: groups[3].map(|_| Vec::new()),
        euler: groups[4].map(|_| Vec::new()),
        ..Default::default()
    };
    for (ln, line) in lines {
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(err(
                ln,
                format!("{} fields, the header has {}", fields.len(), names.len()),
            ));
        }
        let mut values = Vec::with_capacity(fields.len());
        for (f, n) in fields.iter().zip(&names) {
            match f.parse::<f64>() {
                Ok(v) if v.is_finite() => values.push(v),
                _ => return Err(err(ln, format!("`{}` in column `{n}` is not a finite number", clip(f)))),
            }
        }
        let t = values[t_col];
        if let Some(prev) = rec.t.last() {
            if t <= *prev {
                return Err(err(ln, format!("time {t} does not increase (previous {prev})")));
            }
        }
        rec.t.push(t);
        let v3 = |g: [usize; 3]| Vector3::new(values[g[0]], values[g[1]], values[g[2]]);
        rec.accel.push(v3(groups[0].expect("checked")));
        rec.gyro.push(v3(groups[1].expect("checked")));
        for (slot, g) in [
            (&mut rec.mag, groups[2]),
            (&mut rec.position, groups[3]),
            (&mut rec.euler, groups[4]),
        ] {
            if let (Some(v), Some(g)) = (slot.as_mut(), g) {
                v.push(v3(g));
            }
        }
    }
    if rec.t.len() < 3 {
        return Err(err(hl, format!("{} samples: need at least 3", rec.t.len())));
    }
    Ok(rec)
}

/// A recording read at a run's steps t_k = k Δt, time counted from its first row: the row itself where one falls
/// on t_k (a file written by `simnet run --out` replays exactly), else linear interpolation between neighbours
/// (angles along the shorter arc).
#[derive(Debug, Clone, PartialEq)]
pub struct StepRecording {
    /// One IMU interval's samples per step.
    pub imu: Vec<ImuSample>,
    /// Magnetometer per step, if recorded.
    pub mag: Option<Vec<Vector3<f64>>>,
    /// Reference position per step, if recorded.
    pub position: Option<Vec<Vector3<f64>>>,
    /// Reference attitude per step, if recorded.
    pub euler: Option<Vec<Vector3<f64>>>,
}

impl StepRecording {
    /// Steps covered.
    pub fn len(&self) -> usize {
        self.imu.len()
    }
    /// No step.
    pub fn is_empty(&self) -> bool {
        self.imu.is_empty()
    }
}

/// The attitudes `(t, q)` interpolated (slerp, along the shorter arc) at each of the times `at` (ascending); a time
/// outside `t`'s span takes the nearer end.
pub fn attitudes_at(t: &[f64], q: &[nalgebra::Vector4<f64>], at: &[f64]) -> Vec<nalgebra::Vector4<f64>> {
    use nalgebra::{Quaternion, UnitQuaternion};
    let unit = |v: &nalgebra::Vector4<f64>| UnitQuaternion::from_quaternion(Quaternion::new(v[0], v[1], v[2], v[3]));
    let mut out = Vec::with_capacity(at.len());
    if t.is_empty() {
        return out;
    }
    let mut j = 0;
    for &tk in at {
        while j + 2 < t.len() && t[j + 1] < tk {
            j += 1;
        }
        let j1 = (j + 1).min(t.len() - 1);
        let span = t[j1] - t[j];
        let s = if span > 0.0 {
            ((tk - t[j]) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (a, mut b) = (unit(&q[j]), q[j1]);
        // q and −q are one attitude: take the nearer.
        if q[j].dot(&b) < 0.0 {
            b = -b;
        }
        let u = a.try_slerp(&unit(&b), s, 1e-12).unwrap_or(a);
        out.push(nalgebra::Vector4::new(u.w, u.i, u.j, u.k));
    }
    out
}

/// Samples of `rec` at the times of a reference recorded apart, `(t, q)`: the reference is interpolated
/// ([`attitudes_at`]) at each sample's time; samples outside the reference's time span are dropped. Returns the
/// indices of the samples kept.
pub fn join_reference(rec: &mut ImuRecording, t: &[f64], q: &[nalgebra::Vector4<f64>]) -> Vec<usize> {
    let keep: Vec<usize> = (0..rec.t.len())
        .filter(|&k| t.first().is_some_and(|a| rec.t[k] >= *a) && t.last().is_some_and(|b| rec.t[k] <= *b))
        .collect();
    let pick = |v: &Vec<Vector3<f64>>| keep.iter().map(|&k| v[k]).collect::<Vec<_>>();
    rec.t = keep.iter().map(|&k| rec.t[k]).collect();
    rec.quat = Some(attitudes_at(t, q, &rec.t));
    rec.accel = pick(&rec.accel);
    rec.gyro = pick(&rec.gyro);
    rec.mag = rec.mag.as_ref().map(pick);
    rec.position = rec.position.as_ref().map(pick);
    rec.euler = None;
    keep
}

impl ImuRecording {
    /// Seconds from the first row to the last.
    pub fn span(&self) -> f64 {
        self.t.last().copied().unwrap_or(0.0) - self.t.first().copied().unwrap_or(0.0)
    }

    /// The samples at steps 0, 1, … `steps − 1` of period `dt`, as far as the recording reaches.
    pub fn at_steps(&self, dt: f64, steps: u64) -> StepRecording {
        let t0 = self.t.first().copied().unwrap_or(0.0);
        let tol = 1e-6 * dt;
        // (row, weight of the next row) per covered step.
        let mut at: Vec<(usize, f64)> = Vec::new();
        let mut i = 0;
        for k in 0..steps {
            let tk = k as f64 * dt;
            while i + 1 < self.t.len() && self.t[i + 1] - t0 <= tk + tol {
                i += 1;
            }
            let ti = self.t[i] - t0;
            if (ti - tk).abs() <= tol {
                at.push((i, 0.0));
            } else if i + 1 < self.t.len() && ti < tk {
                at.push((i, (tk - ti) / (self.t[i + 1] - self.t[i])));
            } else {
                break;
            }
        }
        let lerp = |v: &[Vector3<f64>], angles: bool| -> Vec<Vector3<f64>> {
            at.iter()
                .map(|&(i, w)| {
                    if w == 0.0 {
                        return v[i];
                    }
                    let mut d = v[i + 1] - v[i];
                    if angles {
                        d = d.map(crate::geom::wrap_angle);
                    }
                    let mut x = v[i] + d * w;
                    if angles {
                        x = x.map(crate::geom::wrap_angle);
                    }
                    x
                })
                .collect()
        };
        let accel = lerp(&self.accel, false);
        let gyro = lerp(&self.gyro, false);
        StepRecording {
            imu: accel
                .into_iter()
                .zip(gyro)
                .map(|(accel, gyro)| ImuSample { accel, gyro })
                .collect(),
            mag: self.mag.as_deref().map(|v| lerp(v, false)),
            position: self.position.as_deref().map(|v| lerp(v, false)),
            euler: self.euler.as_deref().map(|v| lerp(v, true)),
        }
    }
}

/// The `imu-ID.csv` a run writes: samples (magnetometer too when every row has one) with the true pose as
/// reference. Numbers are written in their shortest exact form, so a file reads back to the same values.
pub fn write(rows: &[ImuRow]) -> String {
    let mag = !rows.is_empty() && rows.iter().all(|r| r.mag.is_some());
    let mut s = header(mag);
    for r in rows {
        push_row(&mut s, r, mag);
    }
    s
}

/// The header line, with the magnetometer columns when `mag`.
pub fn header(mag: bool) -> String {
    String::from(if mag {
        "t,ax,ay,az,gx,gy,gz,mx,my,mz,x,y,z,roll,pitch,yaw\n"
    } else {
        "t,ax,ay,az,gx,gy,gz,x,y,z,roll,pitch,yaw\n"
    })
}

/// One row, as [`header`] names the columns.
pub fn push_row(s: &mut String, r: &ImuRow, mag: bool) {
    let (a, g, p, e) = (r.sample.accel, r.sample.gyro, r.position, r.euler);
    s.push_str(&format!(
        "{},{},{},{},{},{},{}",
        r.t, a[0], a[1], a[2], g[0], g[1], g[2]
    ));
    if let (true, Some(m)) = (mag, r.mag) {
        s.push_str(&format!(",{},{},{}", m[0], m[1], m[2]));
    }
    s.push_str(&format!(",{},{},{},{},{},{}\n", p[0], p[1], p[2], e[0], e[1], e[2]));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A reference turning about z by 90° a second, sampled at 0, 1, 2 s (one sample with the other sign): the
    /// recording's samples between get the slerped attitude; those outside its span are dropped.
    #[test]
    fn a_reference_apart_is_slerped_onto_the_samples() {
        let yaw = |deg: f64| {
            let h = deg.to_radians() / 2.0;
            nalgebra::Vector4::new(h.cos(), 0.0, 0.0, h.sin())
        };
        let t_ref = [0.0, 1.0, 2.0];
        let q_ref = [yaw(0.0), -yaw(90.0), yaw(180.0)];
        let mut rec = ImuRecording {
            t: vec![-0.5, 0.5, 1.25, 2.0, 2.5],
            accel: vec![Vector3::z(); 5],
            gyro: vec![Vector3::zeros(); 5],
            ..Default::default()
        };
        assert_eq!(join_reference(&mut rec, &t_ref, &q_ref), vec![1, 2, 3]);
        assert_eq!(rec.t, vec![0.5, 1.25, 2.0]);
        let q = rec.quat.unwrap();
        for (got, deg) in q.iter().zip([45.0, 112.5, 180.0]) {
            let want = yaw(deg);
            assert!(
                (got - want).norm() < 1e-12 || (got + want).norm() < 1e-12,
                "{got} against {deg}°"
            );
        }
    }

    #[test]
    fn reads_columns_in_any_order_with_optional_groups() {
        let text = "# recorded\ngx,gy,gz,t,ax,ay,az,x,y,z\n0,0,0.1,0.0,0,0,9.81,1,2,3\n0,0,0.1,0.01,0,0,9.81,1,2,3\n\
                    0,0,0.1,0.02,0.1,0,9.81,1,2,3\n";
        let r = parse(text, "f.csv").unwrap();
        assert_eq!(r.t, vec![0.0, 0.01, 0.02]);
        assert_eq!(r.gyro[0], Vector3::new(0.0, 0.0, 0.1));
        assert_eq!(r.accel[2], Vector3::new(0.1, 0.0, 9.81));
        assert_eq!(r.position.unwrap()[1], Vector3::new(1.0, 2.0, 3.0));
        assert!(r.mag.is_none() && r.euler.is_none());
    }

    #[test]
    fn steps_take_rows_on_the_grid_and_interpolate_between() {
        let text = "t,ax,ay,az,gx,gy,gz,roll,pitch,yaw\n10,0,0,9,1,0,0,0,0,3.1\n10.02,2,0,9,3,0,0,0,0,-3.1\n\
                    10.04,4,0,9,5,0,0,0,0,-3.0\n";
        let r = parse(text, "f.csv").unwrap();
        let s = r.at_steps(0.01, 10);
        // 0.04 s of recording covers steps 0–4 at 100 Hz.
        assert_eq!(s.len(), 5);
        assert_eq!(s.imu[2].accel.x, 2.0);
        assert!((s.imu[1].accel.x - 1.0).abs() < 1e-9 && (s.imu[3].gyro.x - 4.0).abs() < 1e-9);
        // Yaw 3.1 → −3.1 crosses ±π: the midpoint is π, not 0.
        let yaw = s.euler.as_ref().unwrap()[1].z;
        assert!((yaw.abs() - std::f64::consts::PI).abs() < 1e-9, "{yaw}");
    }

    #[test]
    fn rejects_malformed_files_naming_the_line() {
        let head = "t,ax,ay,az,gx,gy,gz\n";
        let ok = "0,0,0,9.8,0,0,0\n0.01,0,0,9.8,0,0,0\n";
        let cases: Vec<(String, usize, &str)> = vec![
            (String::new(), 1, "empty file"),
            ("t,ax,ay,az,gx,gy\n".into(), 1, "gyro needs all three"),
            ("t,ax,ay,az,gx,gy,gz,q\n".into(), 1, "unknown column `q`"),
            ("t,ax,ay,az,gx,gy,gz,t\n".into(), 1, "appears twice"),
            (format!("{head}{ok}0.02,0,0,9.8,0,0\n"), 4, "6 fields"),
            (format!("{head}{ok}0.02,0,0,nine,0,0,0\n"), 4, "`nine` in column `az`"),
            (format!("{head}{ok}0.01,0,0,9.8,0,0,0\n"), 4, "does not increase"),
            (format!("{head}0,0,0,9.8,0,0,NaN\n"), 2, "not a finite number"),
            (format!("{head}{ok}"), 1, "need at least 3"),
        ];
        for (text, line, needle) in cases {
            let e = parse(&text, "f.csv").unwrap_err();
            assert_eq!(e.line, line, "{text:?}: {e}");
            assert!(
                e.to_string().contains(needle) && e.to_string().starts_with(&format!("f.csv:{line}:")),
                "{e}"
            );
        }
    }
}
