//! What a recording says of its sensor, read off the samples with no setting by hand: the white-noise level of each
//! sensor (from second differences, which motion that is smooth at the sample rate hardly touches), a window where
//! the sensor was at rest if it had one (the gyro bias there), |g| and the earth field's magnitude and dip, and the
//! gates that keep disturbed samples out of the filter's corrections.

use nalgebra::{Vector3, Vector4};

use super::across::{self, Across};
use super::disturbance::mean_square;
pub use super::disturbance::{correlation_time, correlation_time_of, Part, MAX_LAG};
use simnet_engine::estimate::attitude::{from_euler, level};
use simnet_engine::estimate::mekf::{GaussMarkov, MekfModel};
use simnet_engine::imu_csv::ImuRecording;
use simnet_engine::stats;

/// The gates of the corrections, as fractions. An accelerometer sample whose |a| departs from |g| by more than
/// `accel` of |g| is taken as linear acceleration; a magnetometer sample whose |m| departs from the field's
/// magnitude by more than `field` of it, or whose dip departs by more than `dip` (rad), is taken as disturbed.
/// The accelerometer's 0.1 is the magnitude error where Valenti, Dryanovski & Xiao (2015, "Keeping a good
/// attitude", §5.1) start to lower their filter's gain; the field's are the same fraction and the dip it allows
/// (asin 0.1 ≈ 5.7°). The field must pass for `settle` seconds on end, from the start and after every refusal,
/// before its samples correct, since the first samples back within bounds are often the tail of a disturbance: 0.5 s
/// is the minimum undisturbed time of VQF's magnetic disturbance rejection (Laidig & Seel 2023; the default of
/// `magMinUndisturbedTime` in its reference implementation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gates {
    pub accel: f64,
    pub field: f64,
    pub dip: f64,
    pub settle: f64,
}

pub const GATES: Gates = Gates {
    accel: 0.1,
    field: 0.1,
    dip: 0.1,
    settle: 0.5,
};

impl Gates {
    /// Every gate open: every sample corrects.
    pub const OPEN: Gates = Gates {
        accel: f64::INFINITY,
        field: f64::INFINITY,
        dip: f64::INFINITY,
        settle: 0.0,
    };

    /// `off`, or `accel=F,field=F,dip=DEG,settle=S` (any of them; the others keep [`GATES`]; `settle=0` corrects
    /// from the first sample back within bounds).
    pub fn parse(spec: &str) -> Result<Gates, String> {
        if spec.trim() == "off" {
            return Ok(Gates::OPEN);
        }
        let mut g = GATES;
        for part in spec.split(',').filter(|p| !p.trim().is_empty()) {
            let (k, v) = part
                .split_once('=')
                .ok_or_else(|| format!("`{}`: write accel=F,field=F,dip=DEG,settle=S or off", part.trim()))?;
            let (k, v) = (k.trim(), v.trim());
            let x: Option<f64> = v.parse().ok();
            // An infinite bound opens that gate alone.
            let bound = || {
                x.filter(|x| *x > 0.0)
                    .ok_or_else(|| format!("{k}: `{v}` is not a positive number"))
            };
            match k {
                "accel" => g.accel = bound()?,
                "field" => g.field = bound()?,
                "dip" => g.dip = bound()?.to_radians(),
                "settle" => {
                    g.settle = x
                        .filter(|x| x.is_finite() && *x >= 0.0)
                        .ok_or_else(|| format!("settle: `{v}` is not a duration in seconds (0 or more)"))?
                }
                other => return Err(format!("`{other}` is not a gate (accel, field, dip, settle)")),
            }
        }
        Ok(g)
    }
}

impl Field {
    /// The navigation-frame field: x toward magnetic north, z up.
    pub fn nav(&self) -> Vector3<f64> {
        Vector3::new(self.magnitude * self.dip.cos(), 0.0, -self.magnitude * self.dip.sin())
    }
}

/// The earth field as the recording measures it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Field {
    /// |h| in the file's unit: the median |m| over samples the accelerometer gate passes.
    pub magnitude: f64,
    /// Angle below the horizontal, rad (median over the same samples).
    pub dip: f64,
    /// Share of the magnetometer samples the field gate passed.
    pub passed: f64,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Characterised {
    /// A second at rest: first and last sample; None when no second of the recording was still.
    pub still: Option<(usize, usize)>,
    /// Gyro bias: the mean rate over the still window, zero without one, rad/s.
    pub gyro_bias: Vector3<f64>,
    /// White-noise variance per axis (mean of the three): gyro (rad/s)², accelerometer (m/s²)², magnetometer
    /// (file unit)²; over the still window when there is one, else from second differences.
    pub gyro_var: f64,
    pub accel_var: f64,
    pub mag_var: Option<f64>,
    /// |g| as the sensor reads it: over the still window, else the median |a|, m/s².
    pub g: f64,
    /// Mean (|a| − |g|)² over every sample, (m/s²)²: the linear acceleration along g, before the gate, which
    /// bounds that component alone. The noise model falls back on it, as the per-axis variance, when the gyro-aided
    /// fit ([`Characterised::across`]) fails.
    pub accel_motion_var: f64,
    /// Its correlation time, samples ([`correlation_time`] of |a| − |g|).
    pub accel_motion_tau: f64,
    /// Mean (|m| − |h|)² over every sample, (file unit)², and its correlation time: the field's disturbance along
    /// it, the fallback likewise.
    pub mag_disturbance_var: Option<f64>,
    pub mag_disturbance_tau: Option<f64>,
    pub field: Option<Field>,
    /// Share of the accelerometer samples the gate passed.
    pub accel_passed: f64,
    /// The disturbances across g and across the field, the gyro linking the samples ([`across::fit`]); None
    /// when the fit fails.
    pub across: Option<Across>,
    /// Per sample: whether the accelerometer and the field passed their gates (the field's false without a
    /// magnetometer).
    pub passed: Vec<(bool, bool)>,
    /// The attitude every filter starts from: levelled on the first accelerometer and magnetometer samples.
    pub start: Vector4<f64>,
}

/// Navigation-frame gravity (z up) for |g| = `g`.
pub fn gravity(g: f64) -> Vector3<f64> {
    Vector3::new(0.0, 0.0, -g)
}

impl Characterised {
    /// The EKF's accelerometer R per axis: the white-noise equivalent (variance times correlation time) of the
    /// specific force across g over the samples the gate passes, white noise and linear acceleration together, as
    /// the gyro-aided fit measures it; without the fit, the white noise plus |a| − |g|'s equivalent.
    pub fn r_accel(&self) -> f64 {
        match &self.across {
            Some(x) => x.accel.white_equivalent,
            None => self.accel_var + self.accel_motion_var * self.accel_motion_tau,
        }
    }

    /// Its magnetometer R per axis, the same of the field's horizontal component across it (the one that turns
    /// heading; the compensated field reference leaves the EKF no other); None without a magnetometer.
    pub fn r_mag(&self) -> Option<f64> {
        match self.across.and_then(|x| x.field) {
            Some(f) => Some(f.white_equivalent),
            None => Some(self.mag_var? + self.mag_disturbance_var? * self.mag_disturbance_tau?),
        }
    }

    /// The multiplicative EKF's model ([`simnet_engine::estimate::mekf`]): white noise as measured; the horizontal linear
    /// acceleration and the field's disturbance across it as the gyro-aided fit measures them, less the white noise
    /// the fit's residuals also hold; the vertical linear acceleration from |a| − |g|. Correlation times go from
    /// samples to seconds at `rate_hz`. Without the fit, |a| − |g| and |m| − |h| stand for the components across.
    pub fn mekf_model(&self, g: Vector3<f64>, h: Option<Vector3<f64>>, rate_hz: f64) -> MekfModel {
        let s = |samples: f64| samples / rate_hz;
        let vertical = GaussMarkov {
            var: self.accel_motion_var,
            tau: s(self.accel_motion_tau),
        };
        let horizontal = match &self.across {
            Some(x) => GaussMarkov {
                var: (x.accel.var - self.accel_var).max(0.0),
                tau: s(x.accel.tau),
            },
            None => vertical,
        };
        let mag_var = self.mag_var.unwrap_or(1.0);
        let field = match (
            self.across.and_then(|x| x.field),
            self.mag_disturbance_var,
            self.mag_disturbance_tau,
        ) {
            (Some(f), _, _) => GaussMarkov {
                var: (f.var - mag_var).max(0.0),
                tau: s(f.tau),
            },
            (None, Some(var), Some(tau)) => GaussMarkov { var, tau: s(tau) },
            _ => GaussMarkov { var: 0.0, tau: 1.0 },
        };
        MekfModel {
            g,
            h,
            gyro_var: self.gyro_var,
            accel_var: self.accel_var,
            mag_var,
            accel_horizontal: horizontal,
            accel_vertical: vertical,
            field,
        }
    }
}

/// White-noise variance of a three-axis signal, mean over the axes: for x = s + e with s smooth and e white of
/// variance σ², the second difference `x[k+1] − 2x[k] + x[k−1]` has variance 6σ² (Gasser, Sroka & Jennen-Steinmetz
/// 1986); its spread is taken robustly, 1.4826 × the median absolute deviation, so that a few jerks do not count.
pub fn white_noise_var(v: &[Vector3<f64>]) -> f64 {
    if v.len() < 3 {
        return 0.0;
    }
    let mut total = 0.0;
    for axis in 0..3 {
        let d: Vec<f64> = v
            .windows(3)
            .map(|w| w[2][axis] - 2.0 * w[1][axis] + w[0][axis])
            .collect();
        let m = stats::median(&d);
        let mad = stats::median(&d.iter().map(|x| (x - m).abs()).collect::<Vec<_>>());
        total += (1.4826 * mad).powi(2) / 6.0;
    }
    total / 3.0
}

fn mean_var(v: &[Vector3<f64>]) -> (Vector3<f64>, f64) {
    let n = v.len() as f64;
    let m = v.iter().sum::<Vector3<f64>>() / n;
    let var = v.iter().map(|x| (x - m).norm_squared()).sum::<f64>() / (3.0 * (n - 1.0).max(1.0));
    (m, var)
}

/// A window at rest: the gyro and the accelerometer vary there by no more than twice their white-noise variance
/// (a body that moves adds the motion's variance to it). Of the one-second windows, the stillest by the gyro.
fn still_window(rec: &ImuRecording, w: usize, gyro_var: f64, accel_var: f64) -> Option<(usize, usize)> {
    let n = rec.t.len();
    let mut best: Option<(f64, usize)> = None;
    let mut i = 0;
    while i + w <= n {
        let (_, gv) = mean_var(&rec.gyro[i..i + w]);
        let (_, av) = mean_var(&rec.accel[i..i + w]);
        if gv <= 2.0 * gyro_var && av <= 2.0 * accel_var && best.is_none_or(|(b, _)| gv < b) {
            best = Some((gv, i));
        }
        i += (w / 4).max(1);
    }
    best.map(|(_, s)| (s, s + w - 1))
}

/// Whether the accelerometer sample passes the gate: |a| within `gates.accel` of |g|.
pub fn accel_passes(a: &Vector3<f64>, g: f64, gates: &Gates) -> bool {
    (a.norm() - g).abs() <= gates.accel * g
}

/// The dip of field sample `m` against the vertical the accelerometer sample `a` gives, rad.
pub fn dip_of(m: &Vector3<f64>, a: &Vector3<f64>) -> Option<f64> {
    let down = -a.try_normalize(1e-12)?;
    Some(m.try_normalize(1e-12)?.dot(&down).clamp(-1.0, 1.0).asin())
}

/// Whether the magnetometer sample passes the gate: |m| within `gates.field` of |h|, and, when the accelerometer
/// gives the vertical (`a` passed its gate), the dip within `gates.dip`.
pub fn field_passes(m: &Vector3<f64>, a: Option<&Vector3<f64>>, field: &Field, gates: &Gates) -> bool {
    if (m.norm() - field.magnitude).abs() > gates.field * field.magnitude {
        return false;
    }
    match a.and_then(|a| dip_of(m, a)) {
        Some(d) => (d - field.dip).abs() <= gates.dip,
        None => true,
    }
}

/// `ok` with each run of passing samples refused until it is `need` samples long: the `need`-th passes, as in VQF,
/// which adds each sample's period to the undisturbed time, itself included, and accepts once that time reaches
/// the minimum.
pub fn settled(ok: &[bool], need: usize) -> Vec<bool> {
    let mut run = 0;
    ok.iter()
        .map(|&o| {
            run = if o { run + 1 } else { 0 };
            o && run >= need
        })
        .collect()
}

/// Everything above, from the recording at `rate_hz`.
pub fn characterise(rec: &ImuRecording, rate_hz: f64, gates: &Gates) -> Characterised {
    let n = rec.t.len();
    let gyro_var = white_noise_var(&rec.gyro);
    let accel_var = white_noise_var(&rec.accel);
    let mag_var = rec.mag.as_ref().map(|m| white_noise_var(m));
    let w = ((rate_hz.round() as usize).max(10)).min(n);
    let still = still_window(rec, w, gyro_var, accel_var);
    // At rest the sensor's own noise shows alone: take it there when the recording has such a second.
    let (gyro_bias, g, gyro_var, accel_var, mag_var) = match still {
        Some((s, e)) => {
            let (bias, gv) = mean_var(&rec.gyro[s..=e]);
            let (a, av) = mean_var(&rec.accel[s..=e]);
            let mv = rec.mag.as_ref().map(|m| mean_var(&m[s..=e]).1);
            (bias, a.norm(), gv, av, mv)
        }
        None => (
            Vector3::zeros(),
            stats::median(&rec.accel.iter().map(|a| a.norm()).collect::<Vec<_>>()),
            gyro_var,
            accel_var,
            mag_var,
        ),
    };
    let passes: Vec<bool> = rec.accel.iter().map(|a| accel_passes(a, g, gates)).collect();
    let kept = passes.iter().filter(|p| **p).count();
    let motion: Vec<f64> = rec.accel.iter().map(|a| a.norm() - g).collect();
    let (field, mag_disturbance, field_ok) = match &rec.mag {
        Some(mag) => {
            let level: Vec<usize> = (0..n).filter(|&k| passes[k]).collect();
            let magnitude = stats::median(&level.iter().map(|&k| mag[k].norm()).collect::<Vec<_>>());
            let dip = stats::median(
                &level
                    .iter()
                    .filter_map(|&k| dip_of(&mag[k], &rec.accel[k]))
                    .collect::<Vec<_>>(),
            );
            let mut f = Field {
                magnitude,
                dip,
                passed: 0.0,
            };
            let ok: Vec<bool> = (0..n)
                .map(|k| field_passes(&mag[k], Some(&rec.accel[k]).filter(|_| passes[k]), &f, gates))
                .collect();
            let ok = settled(&ok, (gates.settle * rate_hz).round() as usize);
            f.passed = ok.iter().filter(|p| **p).count() as f64 / n.max(1) as f64;
            let d: Vec<f64> = mag.iter().map(|m| m.norm() - magnitude).collect();
            (Some(f), Some((mean_square(&d), correlation_time(&d))), ok)
        }
        None => (None, None, vec![false; n]),
    };
    let passed: Vec<(bool, bool)> = passes.iter().copied().zip(field_ok).collect();
    let h = field.map(|f| f.nav());
    let m0 = rec.mag.as_ref().map(|m| m[0]);
    let q0 = from_euler(&level(
        &rec.accel[0],
        m0.as_ref(),
        &gravity(g),
        &h.unwrap_or_else(Vector3::x),
    ));
    let motion_var = mean_square(&motion);
    let across = across::fit(&across::Input {
        rec,
        q0,
        bias: gyro_bias,
        g,
        passed: &passed,
    });
    Characterised {
        across,
        start: q0,
        still,
        gyro_bias,
        gyro_var,
        accel_var,
        mag_var,
        g,
        accel_motion_var: motion_var,
        accel_motion_tau: correlation_time(&motion),
        mag_disturbance_var: mag_disturbance.map(|d| d.0),
        mag_disturbance_tau: mag_disturbance.map(|d| d.1),
        field,
        accel_passed: kept as f64 / n.max(1) as f64,
        passed,
    }
}
