//! Recordings as IMU makers and loggers write them: the delimiter (tab, comma, semicolon or spaces) and comment lines
//! (`#`, `//`, `%`) detected; columns found by their usual names (`Acc_X`, `Gyroscope X (deg/s)`, `Quat_w`, …) or
//! mapped by hand (`t=Counter/rate,ax=Acc_X,…`); units read from the header (`(g)`, `(deg/s)`, `(us)`) or declared;
//! the rate taken from a `Sample rate: 50Hz` comment, a declared rate or the time column. Everything comes out in
//! simnet's units (s, m/s², rad/s; the magnetometer as given, only its direction is used), with the reference
//! orientation as a quaternion (scalar first, body to navigation) or Euler ZYX angles.

use nalgebra::{Vector3, Vector4};

use super::{CsvError, ImuRecording};
use crate::text::clip;

mod names;

pub use names::{parse_columns, parse_units, unit_factor, ColumnMap, Target, Units, G0};
use names::{split_unit, squash, usual, ALL_TARGETS};

/// How to read a file beyond what it says of itself.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReadOptions {
    /// `TARGET=COLUMN` pairs (`t=Counter/rate,ax=Acc_X`); unnamed targets are found by their usual names.
    pub columns: Vec<(String, String)>,
    /// The units of the columns (when the header does not say).
    pub units: Units,
    /// Samples per second, when the file has only a counter.
    pub rate_hz: Option<f64>,
}

/// What a file is read as: each target's column and the factor into simnet's units, and what was assumed.
#[derive(Debug, Clone, Default)]
pub struct Reading {
    /// What was read.
    pub recording: ImuRecording,
    /// `(target, column as the file names it)`.
    pub columns: Vec<(String, String)>,
    /// What was detected or assumed, for the user to see ("delimiter: tab", "gyro: rad/s (assumed)").
    pub notes: Vec<String>,
    /// The rate the time column gives (median interval), Hz.
    pub rate_hz: f64,
}

/// A comment's `Sample rate: 50.0Hz` (or `rate = 100 Hz`, `frequency: 200`), Hz.
fn rate_in_comment(c: &str) -> Option<f64> {
    let l = c.to_ascii_lowercase();
    let i = ["sample rate", "sampling rate", "samplerate", "frequency", "rate"]
        .iter()
        .find_map(|k| l.find(k).map(|i| i + k.len()))?;
    let rest = l[i..].trim_start_matches([':', '=', ' ', '\t']);
    let num: String = rest.chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
    num.parse::<f64>().ok().filter(|r| *r > 0.0 && r.is_finite())
}

fn is_comment(l: &str) -> bool {
    l.starts_with('#') || l.starts_with("//") || l.starts_with('%')
}

/// Split a line on `delim` (None: runs of white space); a trailing delimiter makes no field.
fn fields(line: &str, delim: Option<char>) -> Vec<&str> {
    match delim {
        Some(d) => {
            let l = line.strip_suffix(d).unwrap_or(line);
            l.split(d).map(str::trim).collect()
        }
        None => line.split_whitespace().collect(),
    }
}

/// The rate the time column gives: one over the median interval, Hz (NaN for fewer than two samples).
fn median_rate(t: &[f64]) -> f64 {
    let dts: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    1.0 / crate::stats::median(&dts)
}

/// Read simnet's own CSV (a comma-separated header of simnet's column names alone, t, ax…az and gx…gz among them,
/// and no option given) with its strict reader, which keeps the reference position, and any other layout with
/// [`read`].
pub fn read_any(text: &str, file: &str, o: &ReadOptions) -> Result<Reading, CsvError> {
    let header = text.lines().map(str::trim).find(|l| !l.is_empty() && !is_comment(l));
    let simnet = header.is_some_and(|h| {
        let names: Vec<&str> = h.split(',').map(str::trim).collect();
        let known = |n: &&str| *n == "t" || super::GROUPS.iter().any(|(_, g)| g.contains(n));
        names.iter().all(known)
            && ["t", "ax", "ay", "az", "gx", "gy", "gz"]
                .iter()
                .all(|n| names.contains(n))
    });
    if !simnet || *o != ReadOptions::default() {
        return read(text, file, o);
    }
    let recording = super::parse(text, file)?;
    let rate_hz = median_rate(&recording.t);
    let columns = header
        .unwrap_or_default()
        .split(',')
        .map(|n| (n.trim().to_string(), n.trim().to_string()))
        .collect();
    let notes = vec![format!(
        "simnet's CSV: {} samples over {:.2} s at {rate_hz:.4} Hz",
        recording.t.len(),
        recording.span()
    )];
    Ok(Reading {
        recording,
        columns,
        notes,
        rate_hz,
    })
}

/// Read a recording in any common layout (see the module's documentation).
pub fn read(text: &str, file: &str, o: &ReadOptions) -> Result<Reading, CsvError> {
    read_as(text, file, o, false)
}

/// Read a file that holds the reference orientation alone (a maker's `quaternion.csv` beside its `sensors.csv`):
/// a time column and a quaternion (`W,X,Y,Z` too) or Euler angles. The reading's accelerometer and gyro are zero.
pub fn read_reference(text: &str, file: &str, o: &ReadOptions) -> Result<Reading, CsvError> {
    read_as(text, file, o, true)
}

fn read_as(text: &str, file: &str, o: &ReadOptions, reference_only: bool) -> Result<Reading, CsvError> {
    let err = |line: usize, message: String| CsvError {
        file: file.to_string(),
        line,
        message,
    };
    let mut notes = Vec::new();
    let mut comment_rate = None;
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty());
    let (hl, header) = loop {
        match lines.next() {
            Some((_, l)) if is_comment(l) => comment_rate = comment_rate.or_else(|| rate_in_comment(l)),
            Some(h) => break h,
            None => return Err(err(1, "empty file: no header line".into())),
        }
    };
    let delim = ['\t', ',', ';']
        .into_iter()
        .map(|d| (header.matches(d).count(), d))
        .filter(|(n, _)| *n > 0)
        .max_by_key(|(n, _)| *n)
        .map(|(_, d)| d);
    notes.push(format!(
        "delimiter: {}",
        match delim {
            Some('\t') => "tab",
            Some(',') => "comma",
            Some(';') => "semicolon",
            _ => "spaces",
        }
    ));
    let names: Vec<&str> = fields(header, delim);
    let keys: Vec<(String, Option<String>)> = names.iter().map(|n| split_unit(n)).collect();
    // Each target's column: mapped by hand, else by its usual names.
    let mut chosen: Vec<(Target, usize, f64)> = Vec::new(); // (target, column, factor before units)
    let mut mapped: Vec<Target> = Vec::new();
    for (k, v) in &o.columns {
        let target = Target::parse(k).ok_or_else(|| err(hl, format!("--columns: `{}` is not a target", clip(k))))?;
        // COLUMN, COLUMN/rate, COLUMN/K or COLUMN*K.
        let (col, scale) = match v.rsplit_once(['/', '*']) {
            Some((c, by)) if by.trim() == "rate" && v.contains('/') => {
                let r = o
                    .rate_hz
                    .or(comment_rate)
                    .ok_or_else(|| err(hl, format!("--columns {k}={v}: no rate in the file: give --rate HZ")))?;
                (c.trim(), 1.0 / r)
            }
            Some((c, by)) => match by.trim().parse::<f64>() {
                Ok(x) if x != 0.0 && x.is_finite() => (c.trim(), if v.contains('/') { 1.0 / x } else { x }),
                _ => (v.as_str(), 1.0),
            },
            None => (v.as_str(), 1.0),
        };
        let idx = names
            .iter()
            .position(|n| n.trim() == col)
            .or_else(|| names.iter().position(|n| n.trim().eq_ignore_ascii_case(col)))
            .ok_or_else(|| err(hl, format!("--columns {k}=…: the header has no column `{}`", clip(col))))?;
        chosen.push((target, idx, scale));
        mapped.push(target);
    }
    for t in ALL_TARGETS {
        if mapped.contains(&t) || (reference_only && !matches!(t, Target::T | Target::Quat(_) | Target::Euler(_))) {
            continue;
        }
        let mut usual = usual(t);
        if let (true, Target::Quat(i)) = (reference_only, t) {
            // A file of quaternions alone may name the components by their letters.
            usual.push(["w", "x", "y", "z"][i].to_string());
        }
        if let Some(i) = keys.iter().position(|(k, _)| usual.contains(&squash(k))) {
            if !chosen.iter().any(|(_, c, _)| *c == i) {
                chosen.push((t, i, 1.0));
            }
        }
    }
    let col_of = |t: Target| chosen.iter().find(|(x, _, _)| *x == t).map(|&(_, i, s)| (i, s));
    // Groups are whole or absent.
    let groups: [(&str, Vec<Target>); 5] = [
        ("accelerometer", (0..3).map(Target::Accel).collect()),
        ("gyro", (0..3).map(Target::Gyro).collect()),
        ("magnetometer", (0..3).map(Target::Mag).collect()),
        ("reference quaternion", (0..4).map(Target::Quat).collect()),
        ("reference Euler angles", (0..3).map(Target::Euler).collect()),
    ];
    let mut present = [false; 5];
    for (g, (what, ts)) in groups.iter().enumerate() {
        let have: Vec<bool> = ts.iter().map(|t| col_of(*t).is_some()).collect();
        if have.iter().all(|h| *h) {
            present[g] = true;
        } else if have.iter().any(|h| *h) {
            let missing: Vec<String> = ts
                .iter()
                .zip(&have)
                .filter(|(_, h)| !**h)
                .map(|(t, _)| t.name())
                .collect();
            return Err(err(
                hl,
                format!("the {what} lacks {} (map it with --columns)", missing.join(", ")),
            ));
        }
    }
    if reference_only && !present[3] && !present[4] {
        return Err(err(
            hl,
            "no reference orientation columns found (a quaternion or roll, pitch, yaw; map them with --columns)".into(),
        ));
    }
    for (g, what) in [(0, "accelerometer"), (1, "gyro")] {
        if !present[g] && !reference_only {
            return Err(err(
                hl,
                format!("no {what} columns found (name them with --columns, e.g. ax=Acc_X,ay=Acc_Y,az=Acc_Z)"),
            ));
        }
    }
    // Units: declared, else the header's, else assumed.
    let header_unit = |t: Target, what: &str| -> Result<Option<f64>, CsvError> {
        match col_of(t).and_then(|(i, _)| keys[i].1.clone()) {
            Some(u) => match unit_factor(what, &u) {
                Some(f) => Ok(Some(f)),
                // A unit simnet does not know is fine for the magnetometer (only its direction counts).
                None if what == "mag" => Ok(None),
                None => Err(err(
                    hl,
                    format!(
                        "column `{}`: unknown {what} unit `{}`",
                        clip(names[col_of(t).map_or(0, |c| c.0)]),
                        clip(&u)
                    ),
                )),
            },
            None => Ok(None),
        }
    };
    // 0: decided from the data below.
    let accel = o.units.accel.or(header_unit(Target::Accel(0), "accel")?).unwrap_or(0.0);
    let gyro = match o.units.gyro.or(header_unit(Target::Gyro(0), "gyro")?) {
        _ if reference_only => 1.0,
        Some(f) => {
            notes.push(format!("gyro: {}", if f == 1.0 { "rad/s" } else { "deg/s" }));
            f
        }
        None => {
            notes.push("gyro: rad/s (assumed; declare deg/s with --units gyro=deg/s)".into());
            1.0
        }
    };
    let angle = if present[4] {
        // 0: decided from the data below.
        o.units.angle.or(header_unit(Target::Euler(0), "angle")?).unwrap_or(0.0)
    } else {
        1.0
    };
    let t_col = col_of(Target::T);
    let counter = t_col.is_some_and(|(i, s)| {
        s == 1.0
            && matches!(
                squash(&keys[i].0).as_str(),
                "counter" | "packetcounter" | "packetnumber"
            )
    });
    let time = match (t_col, o.units.time) {
        (None, _) => None,
        (Some(_), Some(f)) => Some(f),
        (Some((i, s)), None) if counter => {
            let r = o.rate_hz.or(comment_rate).ok_or_else(|| {
                err(
                    hl,
                    format!(
                        "column `{}` counts samples: give the rate with --rate HZ",
                        clip(names[i])
                    ),
                )
            })?;
            notes.push(format!("time: sample counter at {r} Hz"));
            Some(s / r)
        }
        (Some((i, s)), None) => Some(match keys[i].1.as_deref() {
            Some(u) => {
                let f = unit_factor("time", u).ok_or_else(|| {
                    err(
                        hl,
                        format!(
                            "column `{}`: unknown time unit `{}` (s, ms, us, ns)",
                            clip(names[i]),
                            clip(u)
                        ),
                    )
                })?;
                f * s
            }
            None => s,
        }),
    };
    // Rows.
    let mut raw: Vec<Vec<f64>> = Vec::new();
    let mut row_lines = Vec::new();
    for (ln, line) in lines {
        if is_comment(line) {
            continue;
        }
        let f = fields(line, delim);
        if f.len() != names.len() {
            return Err(err(ln, format!("{} fields, the header has {}", f.len(), names.len())));
        }
        let mut vals = vec![f64::NAN; names.len()];
        for &(t, i, _) in &chosen {
            match f[i].parse::<f64>() {
                Ok(v) if v.is_finite() => vals[i] = v,
                _ => {
                    return Err(err(
                        ln,
                        format!(
                            "`{}` in column `{}` ({}) is not a finite number",
                            clip(f[i]),
                            clip(names[i]),
                            t.name()
                        ),
                    ))
                }
            }
        }
        raw.push(vals);
        row_lines.push(ln);
    }
    if raw.len() < 3 {
        return Err(err(hl, format!("{} samples: need at least 3", raw.len())));
    }
    let v3 = |row: &[f64], t: fn(usize) -> Target, k: f64| {
        Vector3::from_fn(|a, _| col_of(t(a)).map_or(0.0, |(i, s)| row[i] * s * k))
    };
    // Accelerometer unit from the data: a recording's median |a| is about 1 in g and about 9.8 in m/s².
    let accel = if reference_only {
        1.0
    } else if accel > 0.0 {
        // Values in g that are near 9.8 are m/s² mislabelled: a recording's median |a| is not 3 g or more.
        let mut n: Vec<f64> = raw.iter().map(|r| v3(r, Target::Accel, 1.0).norm()).collect();
        n.sort_by(f64::total_cmp);
        let med = n[n.len() / 2];
        if accel != 1.0 && med >= 3.0 {
            return Err(err(
                hl,
                format!(
                    "the accelerometer is declared in g, but its median |a| is then {:.2} m/s² ({med:.2} g): the \
                     values look like m/s² (--units accel=m/s2)",
                    med * accel
                ),
            ));
        }
        notes.push(format!("accelerometer: {}", if accel == 1.0 { "m/s²" } else { "g" }));
        accel
    } else {
        let mut n: Vec<f64> = raw.iter().map(|r| v3(r, Target::Accel, 1.0).norm()).collect();
        n.sort_by(f64::total_cmp);
        let med = n[n.len() / 2];
        let g = if (med - 1.0).abs() < (med - G0).abs() { G0 } else { 1.0 };
        notes.push(format!(
            "accelerometer: {} (from the median |a| = {med:.3}; declare with --units accel=g|m/s2)",
            if g == 1.0 { "m/s²" } else { "g" }
        ));
        g
    };
    let angle = if angle > 0.0 {
        angle
    } else {
        // Angles beyond ±2π are degrees.
        let big = raw
            .iter()
            .any(|r| v3(r, Target::Euler, 1.0).amax() > 2.0 * std::f64::consts::PI);
        notes.push(format!("reference angles: {}", if big { "degrees" } else { "radians" }));
        if big {
            std::f64::consts::PI / 180.0
        } else {
            1.0
        }
    };
    let mut rec = ImuRecording {
        mag: present[2].then(Vec::new),
        euler: present[4].then(Vec::new),
        quat: present[3].then(Vec::new),
        ..Default::default()
    };
    // A 16-bit sample counter wraps: unwrap it.
    let mut offset = 0.0;
    let mut prev_raw: Option<f64> = None;
    for (row, &ln) in raw.iter().zip(&row_lines) {
        let t = match (t_col, time) {
            (Some((i, _)), Some(f)) => {
                let mut c = row[i];
                if counter {
                    if let Some(p) = prev_raw {
                        if c + offset < p && p - (c + offset) > 30_000.0 {
                            offset += 65_536.0;
                        }
                    }
                    c += offset;
                    prev_raw = Some(c);
                }
                c * f
            }
            _ => {
                let r = o.rate_hz.or(comment_rate).ok_or_else(|| {
                    err(
                        hl,
                        "no time column and no rate: give --rate HZ or map one with --columns t=…".into(),
                    )
                })?;
                rec.t.len() as f64 / r
            }
        };
        if let Some(p) = rec.t.last() {
            if t <= *p {
                return Err(err(ln, format!("time {t} s does not increase (previous {p} s)")));
            }
        }
        rec.t.push(t);
        rec.accel.push(v3(row, Target::Accel, accel));
        rec.gyro.push(v3(row, Target::Gyro, gyro));
        if let Some(m) = rec.mag.as_mut() {
            m.push(v3(row, Target::Mag, 1.0));
        }
        if let Some(e) = rec.euler.as_mut() {
            e.push(v3(row, Target::Euler, angle));
        }
        if let Some(q) = rec.quat.as_mut() {
            let v = Vector4::from_fn(|a, _| col_of(Target::Quat(a)).map_or(0.0, |(i, s)| row[i] * s));
            match v.try_normalize(1e-9) {
                Some(u) => q.push(u),
                None => return Err(err(ln, "the reference quaternion is zero".into())),
            }
        }
    }
    let rate_hz = median_rate(&rec.t);
    notes.push(format!(
        "{} samples over {:.2} s at {rate_hz:.4} Hz{}",
        rec.t.len(),
        rec.span(),
        if present[2] { ", with magnetometer" } else { "" }
    ));
    let mut columns: Vec<(String, String)> = chosen
        .iter()
        .map(|&(t, i, _)| (t.name(), names[i].trim().to_string()))
        .collect();
    columns.sort_by_key(|(t, _)| ALL_TARGETS.iter().position(|x| x.name() == *t));
    Ok(Reading {
        recording: rec,
        columns,
        notes,
        rate_hz,
    })
}

#[cfg(test)]
mod tests;
