//! The checks every part of validation shares (a topology file, a `[model]` table, overrides): each records a
//! [`Problem`] naming its key and returns a usable default, so that one pass reports every problem of a file.

use std::fmt;

use nalgebra::DMatrix;

/// One problem found in a topology file.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// Dotted key path, e.g. `edge[2].nodes`.
    pub key: String,
    /// What is wrong with it.
    pub message: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}`: {}", self.key, self.message)
    }
}

/// Checks a probability, a positive number, a matrix, … and records a problem naming the key.
#[derive(Debug, Default)]
pub struct Checks {
    /// Every problem found so far, in the order found.
    pub problems: Vec<Problem>,
    /// Recordings already read, by resolved path: validating a changed scenario again does not re-read them.
    pub loaded: std::collections::HashMap<String, std::sync::Arc<crate::imu_csv::ImuRecording>>,
}

/// A number as a message shows it: exponent form when very large or very small (1e308, not 309 digits).
pub fn num(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e7).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

impl Checks {
    /// Record a problem at `key`.
    pub fn bad(&mut self, key: impl Into<String>, message: impl Into<String>) {
        self.problems.push(Problem {
            key: key.into(),
            message: message.into(),
        });
    }

    /// `v` if it is a probability in [0, 1], else a problem and `default`; `default` when absent.
    pub fn prob(&mut self, key: &str, v: Option<f64>, default: f64) -> f64 {
        match v {
            Some(x) if !(0.0..=1.0).contains(&x) || !x.is_finite() => {
                self.bad(key, format!("must be a probability in [0, 1], got {x}"));
                default
            }
            Some(x) => x,
            None => default,
        }
    }

    /// `v` if it is positive and finite, else a problem and `default`; `default` when absent.
    pub fn positive(&mut self, key: &str, v: Option<f64>, default: f64) -> f64 {
        match v {
            Some(x) if !(x > 0.0 && x.is_finite()) => {
                self.bad(key, format!("must be a positive finite number, got {x}"));
                default
            }
            Some(x) => x,
            None => default,
        }
    }

    /// `v` (already checked finite) no larger than `max`: a value past what any run needs would overflow the clocks
    /// and distributions it feeds (a 1e308 ms jitter, a delay of 1e20 s).
    pub fn at_most(&mut self, key: &str, v: f64, max: f64, unit: &str) -> f64 {
        if v > max {
            self.bad(key, format!("must be at most {}{unit}, got {}", num(max), num(v)));
            return max;
        }
        v
    }

    /// `v` if it is zero or more and finite, else a problem and `default`; `default` when absent.
    pub fn non_negative(&mut self, key: &str, v: Option<f64>, default: f64) -> f64 {
        match v {
            Some(x) if !(x >= 0.0 && x.is_finite()) => {
                self.bad(key, format!("must be a non-negative finite number, got {x}"));
                default
            }
            Some(x) => x,
            None => default,
        }
    }

    /// The matrix of `rows` (rows of equal length, finite values), else a problem; none when absent.
    pub fn matrix(&mut self, key: &str, rows: &Option<Vec<Vec<f64>>>) -> Option<DMatrix<f64>> {
        let rows = rows.as_ref()?;
        let r = rows.len();
        let c = rows.first().map_or(0, |x| x.len());
        if r == 0 || c == 0 {
            self.bad(key, "must be a non-empty array of rows");
            return None;
        }
        if rows.iter().any(|x| x.len() != c) {
            self.bad(key, format!("rows must all have {c} entries"));
            return None;
        }
        if rows.iter().flatten().any(|x| !x.is_finite()) {
            self.bad(key, "entries must be finite");
            return None;
        }
        Some(DMatrix::from_fn(r, c, |i, j| rows[i][j]))
    }

    /// A problem unless `m` is n × n, symmetric and positive definite (positive semidefinite when `semi`).
    pub fn spd(&mut self, key: &str, m: &DMatrix<f64>, n: usize, semi: bool) {
        if m.nrows() != n || m.ncols() != n {
            self.bad(key, format!("must be {n}×{n}, got {}×{}", m.nrows(), m.ncols()));
            return;
        }
        if (m - m.transpose()).amax() > 1e-9 * (1.0 + m.amax()) {
            self.bad(key, "must be symmetric");
            return;
        }
        let min = m.clone().symmetric_eigenvalues().min();
        if (semi && min < -1e-12) || (!semi && min <= 0.0) {
            let what = if semi {
                "positive semidefinite"
            } else {
                "positive definite"
            };
            self.bad(key, format!("must be {what} (smallest eigenvalue {min:.3e})"));
        }
    }
}
