//! Simulated time: [`Time`], whole nanoseconds since the run began. Every datagram carries two of them (the time
//! its content pertains to, the time it was sent), so a receiver can place what it hears on its own time line
//! whatever the step, the rate or the delay; durations between times are [`core::time::Duration`].
//!
//! A step's time is its index over the rate, rounded to the nanosecond, and reads back as the same step for every
//! rate up to 1 GHz and every run shorter than 584 years:
//!
//! ```
//! use simnet_core::time::Time;
//! let dt = 1.0 / 300.0; // 300 Hz: 3,333,333.3… ns a step
//! for k in [0, 1, 2, 299, 300, 1_000_000] {
//!     let t = Time::at_step(k, dt);
//!     assert_eq!(t.step(dt), k);
//! }
//! assert_eq!(Time::at_step(300, dt).as_nanos(), 1_000_000_000);
//! assert_eq!(Time::from_secs(0.25) + core::time::Duration::from_millis(750), Time::from_secs(1.0));
//! ```

use core::time::Duration;

use serde::{Deserialize, Serialize};

/// A point in simulated time: nanoseconds since the run began (t = 0 at step 0).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Time(u64);

impl Time {
    /// The run's start.
    pub const ZERO: Time = Time(0);

    /// The latest time there is: what a driver waits until to flush everything still queued.
    pub const MAX: Time = Time(u64::MAX);

    /// `ns` nanoseconds after the start.
    pub const fn from_nanos(ns: u64) -> Time {
        Time(ns)
    }

    /// Nanoseconds after the start.
    pub const fn as_nanos(self) -> u64 {
        self.0
    }

    /// `s` seconds after the start, to the nearest nanosecond (negative or NaN: the start; past 584 years: the
    /// largest time).
    pub fn from_secs(s: f64) -> Time {
        Time::since_start(nanos(s * 1e9))
    }

    /// Seconds after the start, the double nearest to them (a time read from decimal seconds with at most nine
    /// places reads back as the same double).
    pub fn as_secs(self) -> f64 {
        // A quotient is correctly rounded; a product by 1e-9 (itself inexact) is not: 10⁹ · 1e-9 ≠ 1.
        self.0 as f64 / 1e9
    }

    /// The time of step `k` of a run stepping every `dt` seconds.
    pub fn at_step(k: u64, dt: f64) -> Time {
        Time::from_secs(k as f64 * dt)
    }

    /// The step of a run stepping every `dt` seconds that this time is nearest to.
    pub fn step(self, dt: f64) -> u64 {
        (self.as_secs() / dt).round() as u64
    }

    /// The time `d` after the run began (the largest time if that is past it): a wall clock's reading as
    /// simulated time.
    pub fn since_start(d: Duration) -> Time {
        Time::ZERO + d
    }

    /// How long after the run began this is: what a driver adds to the wall clock's reading at the start.
    pub fn as_duration(self) -> Duration {
        Duration::from_nanos(self.0)
    }

    /// The time `d` after this one (the largest time if that is past it).
    pub fn saturating_add(self, d: Duration) -> Time {
        Time(self.0.saturating_add(u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)))
    }

    /// How long after `earlier` this is (zero when it is not after it).
    pub fn since(self, earlier: Time) -> Duration {
        Duration::from_nanos(self.0.saturating_sub(earlier.0))
    }
}

/// The whole nanoseconds nearest `ns` as a duration (negative or NaN: zero; past 584 years: the longest): how a
/// delay, a deadline or a replay's lag given as a decimal becomes simulated time, in one place.
pub fn nanos(ns: f64) -> Duration {
    // `as` saturates: NaN and negatives give 0, too large gives u64::MAX.
    Duration::from_nanos(ns.round() as u64)
}

impl core::ops::Add<Duration> for Time {
    type Output = Time;
    fn add(self, d: Duration) -> Time {
        self.saturating_add(d)
    }
}

impl core::fmt::Display for Time {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(f, "{}.{:09} s", self.0 / 1_000_000_000, self.0 % 1_000_000_000)
    }
}

#[cfg(test)]
mod tests {
    use super::Time;

    /// Every step of a long run at awkward rates reads back as itself (checked against exact rational arithmetic:
    /// the nanosecond nearest k·10⁹/rate).
    #[test]
    fn step_times_are_the_nearest_nanosecond_and_read_back() {
        for rate in [1.0, 3.0, 7.0, 100.0, 300.0, 333.0, 1000.0, 4096.0] {
            let dt = 1.0 / rate;
            for k in (0..2_000u64).chain((0..50).map(|i| 10_000_000 + 7919 * i)) {
                let t = Time::at_step(k, dt);
                assert_eq!(t.step(dt), k, "rate {rate}, step {k}");
                let exact = (k as u128 * 1_000_000_000 * 2 + rate as u128) / (2 * rate as u128);
                assert!(t.as_nanos().abs_diff(exact as u64) <= 1, "rate {rate}, step {k}: {t}");
            }
        }
    }

    #[test]
    fn out_of_range_seconds_saturate() {
        assert_eq!(Time::from_secs(-1.0), Time::ZERO);
        assert_eq!(Time::from_secs(f64::NAN), Time::ZERO);
        assert_eq!(Time::from_secs(1e12).as_nanos(), u64::MAX);
        assert_eq!(
            Time::from_nanos(u64::MAX) + core::time::Duration::from_secs(1),
            Time::from_nanos(u64::MAX)
        );
        assert_eq!(
            Time::from_nanos(5).since(Time::from_nanos(9)),
            core::time::Duration::ZERO
        );
        assert_eq!(Time::from_nanos(1_500_000_000).to_string(), "1.500000000 s");
    }

    /// Seconds written with up to nine decimals come back as the same double, and times compare as the seconds they
    /// were read from.
    #[test]
    fn decimal_seconds_read_back() {
        for s in [0.0, 0.3, 1.0, 1.25, 2.5, 7.001, 10.0, 59.999999999, 123.456789, 3600.5] {
            assert_eq!(Time::from_secs(s).as_secs(), s, "{s}");
        }
        assert!(Time::at_step(3, 0.1) == Time::from_secs(0.3) && Time::at_step(70, 0.01) == Time::from_secs(0.7));
        assert_eq!(Time::MAX.as_nanos(), u64::MAX);
    }
}
