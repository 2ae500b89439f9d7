//! The vocabulary of makers' files: the targets simnet reads (t, ax…az, gx…gz, mx…mz, qw…qz, roll, pitch, yaw), the
//! usual names makers give them, their units and the factors into simnet's units, and the `--columns`/`--units`
//! flags that name what the usual names miss.

use crate::text::clip;

/// Standard gravity, m/s² per g.
pub const G0: f64 = 9.80665;

/// What each value of the file becomes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Target {
    /// Time.
    T,
    /// Accelerometer axis (0 = x).
    Accel(usize),
    /// Gyro axis.
    Gyro(usize),
    /// Magnetometer axis.
    Mag(usize),
    /// Reference quaternion component (0 = scalar).
    Quat(usize),
    /// Reference Euler ZYX angle: roll, pitch, yaw.
    Euler(usize),
}

impl Target {
    /// The target named `s` (`t`, `ax`, `gz`, `qw`, …).
    pub fn parse(s: &str) -> Option<Target> {
        let axis = |c: char| "xyz".find(c);
        let mut ch = s.chars();
        match (ch.next(), ch.next(), ch.next()) {
            (Some('t'), None, _) => Some(Target::T),
            (Some('a'), Some(c), None) => axis(c).map(Target::Accel),
            (Some('g'), Some(c), None) => axis(c).map(Target::Gyro),
            (Some('m'), Some(c), None) => axis(c).map(Target::Mag),
            (Some('q'), Some(c), None) => "wxyz".find(c).map(Target::Quat),
            _ => ["roll", "pitch", "yaw"].iter().position(|n| *n == s).map(Target::Euler),
        }
    }

    /// Its name (`ax`, `qw`, …).
    pub fn name(self) -> String {
        let xyz = |i: usize| ["x", "y", "z"][i];
        match self {
            Target::T => "t".into(),
            Target::Accel(i) => format!("a{}", xyz(i)),
            Target::Gyro(i) => format!("g{}", xyz(i)),
            Target::Mag(i) => format!("m{}", xyz(i)),
            Target::Quat(i) => format!("q{}", ["w", "x", "y", "z"][i]),
            Target::Euler(i) => ["roll", "pitch", "yaw"][i].into(),
        }
    }
}

/// Units of the file's values; None: read from the header, else assumed (and said).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Units {
    /// Multiplies the accelerometer into m/s² (1 for m/s², [`G0`] for g).
    pub accel: Option<f64>,
    /// Multiplies the gyro into rad/s.
    pub gyro: Option<f64>,
    /// Multiplies the time column into s; for a sample counter, 1/rate.
    pub time: Option<f64>,
    /// Multiplies reference angles into rad.
    pub angle: Option<f64>,
}

/// `(target, column)` pairs of `--columns` (a named type: clap would take a bare `Vec` for repeated values).
pub type ColumnMap = Vec<(String, String)>;

/// `TARGET=COLUMN,...` of `--columns`.
pub fn parse_columns(spec: &str) -> Result<ColumnMap, String> {
    spec.split(',')
        .filter(|p| !p.trim().is_empty())
        .map(|p| {
            let (k, v) = p
                .split_once('=')
                .ok_or_else(|| format!("`{}`: write TARGET=COLUMN, e.g. ax=Acc_X", clip(p.trim())))?;
            let k = k.trim();
            if Target::parse(k).is_none() {
                return Err(format!(
                    "`{}` is not a column simnet reads (t, ax…az, gx…gz, mx…mz, qw…qz, roll, pitch, yaw)",
                    clip(k)
                ));
            }
            Ok((k.to_string(), v.trim().to_string()))
        })
        .collect()
}

/// `WHAT=UNIT,...` of `--units` (accel=g, gyro=deg/s, time=us, angle=deg).
pub fn parse_units(spec: &str) -> Result<Units, String> {
    let mut u = Units::default();
    for part in spec.split(',').filter(|p| !p.trim().is_empty()) {
        let (k, v) = part
            .split_once('=')
            .ok_or_else(|| format!("`{}`: write WHAT=UNIT, e.g. gyro=deg/s", clip(part.trim())))?;
        let k = k.trim();
        let slot = match k {
            "accel" => &mut u.accel,
            "gyro" => &mut u.gyro,
            "time" => &mut u.time,
            "angle" => &mut u.angle,
            _ => {
                return Err(format!(
                    "`{}` is not a quantity with a unit (accel, gyro, time, angle)",
                    clip(k)
                ))
            }
        };
        *slot = Some(unit_factor(k, v).ok_or_else(|| format!("`{}` is not a unit of {k}", clip(v.trim())))?);
    }
    Ok(u)
}

/// `g`, `m/s2`, `deg/s`, … as the factor into simnet's units, for `what` (accel, gyro, time, angle).
pub fn unit_factor(what: &str, unit: &str) -> Option<f64> {
    let u = unit
        .trim()
        .to_ascii_lowercase()
        .replace(['²', ' '], "2")
        .replace("^2", "2");
    match (what, u.as_str()) {
        ("accel", "g") => Some(G0),
        ("accel", "m/s2" | "ms2" | "m/s/s" | "mps2") => Some(1.0),
        ("accel", "mg") => Some(G0 / 1000.0),
        ("gyro", "rad/s" | "rads" | "rps") => Some(1.0),
        ("gyro", "deg/s" | "dps" | "°/s") => Some(std::f64::consts::PI / 180.0),
        ("time", "s") => Some(1.0),
        ("time", "ms") => Some(1e-3),
        ("time", "us" | "µs" | "μs") => Some(1e-6),
        ("time", "ns") => Some(1e-9),
        ("angle", "rad") => Some(1.0),
        ("angle", "deg" | "°") => Some(std::f64::consts::PI / 180.0),
        _ => None,
    }
}

/// A column name in lower case without its unit, and the unit in parentheses or brackets, if any.
pub(super) fn split_unit(name: &str) -> (String, Option<String>) {
    let n = name.trim();
    for (open, close) in [('(', ')'), ('[', ']')] {
        if let (Some(a), true) = (n.rfind(open), n.ends_with(close)) {
            return (
                n[..a].trim().to_ascii_lowercase(),
                Some(n[a + 1..n.len() - 1].trim().to_string()),
            );
        }
    }
    (n.to_ascii_lowercase(), None)
}

/// The usual names of each target's column (lower case, units stripped, `_`, `-`, `.` and spaces removed).
pub(super) fn usual(target: Target) -> Vec<String> {
    let xyz = |i: usize| ["x", "y", "z"][i];
    match target {
        Target::T => [
            "t",
            "time",
            "timestamp",
            "times",
            "counter",
            "packetcounter",
            "packetnumber",
            "sampletimefine",
        ]
        .map(String::from)
        .to_vec(),
        Target::Accel(i) => ["acc", "accel", "accelerometer", "acceleration", "rawaccel", "a"]
            .iter()
            .map(|p| format!("{p}{}", xyz(i)))
            .collect(),
        Target::Gyro(i) => ["gyr", "gyro", "gyroscope", "rawgyro", "angularvelocity", "g"]
            .iter()
            .map(|p| format!("{p}{}", xyz(i)))
            .collect(),
        Target::Mag(i) => ["mag", "magnetometer", "magneticfield", "compass", "rawcompass", "m"]
            .iter()
            .map(|p| format!("{p}{}", xyz(i)))
            .collect(),
        Target::Quat(i) => {
            let c = ["w", "x", "y", "z"][i];
            let mut v: Vec<String> = ["quat", "q", "quaternion", "orientation"]
                .iter()
                .map(|p| format!("{p}{c}"))
                .collect();
            v.push(format!("{c}element"));
            v.push(format!("q{i}"));
            v
        }
        Target::Euler(i) => {
            let n = ["roll", "pitch", "yaw"][i];
            vec![n.to_string(), format!("euler{}", xyz(i)), format!("{n}angle")]
        }
    }
}

pub(super) fn squash(s: &str) -> String {
    s.chars().filter(|c| !matches!(c, '_' | '-' | '.' | ' ')).collect()
}

pub(super) const ALL_TARGETS: [Target; 17] = [
    Target::T,
    Target::Accel(0),
    Target::Accel(1),
    Target::Accel(2),
    Target::Gyro(0),
    Target::Gyro(1),
    Target::Gyro(2),
    Target::Mag(0),
    Target::Mag(1),
    Target::Mag(2),
    Target::Quat(0),
    Target::Quat(1),
    Target::Quat(2),
    Target::Quat(3),
    Target::Euler(0),
    Target::Euler(1),
    Target::Euler(2),
];
