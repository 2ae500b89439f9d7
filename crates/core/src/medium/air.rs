//! What one receiver makes of the frames on the air around it: which frame it locks onto, and the chance that the
//! frame survives the noise and every frame that overlaps it. This is the reception of an IEEE 802.15.4 PHY as
//! ns-3's `LrWpanPhy` models it, in closed form over one receiver's timeline:
//!
//! - a receiver that is listening locks onto a frame as it starts if the frame's SINR then — over the noise and
//!   every frame already on the air — exceeds −5 dB (below it the bit error rate is over 10 %: IEEE 802.15.4
//!   Annex E, Fig. E.2; ns-3's `StartRx`); otherwise it stays listening;
//! - while it receives one frame it takes no other: a frame that starts meanwhile is lost to it, and interferes;
//! - the frame survives each stretch between changes of the interference with probability (1 − BER(SINR))^bits
//!   ([`super::phy::frame_success_rate`]), bits = the stretch's length at 250 kbit/s; the stretches multiply.
//!   Unlike ns-3 (3.44), which takes a new stretch only when a frame starts or its own frame ends, the stretch also
//!   closes when an interferer ends, so that an interferer counts for exactly the time it overlaps;
//! - it is half-duplex: while it transmits it hears nothing, and a frame it is receiving when it begins to
//!   transmit is lost.
//!
//! The caller draws the fate with its own seeded stream: the frame arrives if a uniform draw falls below
//! `success`.
//!
//! ```
//! use simnet_core::medium::air::{receive, OnAir, Reception};
//! use simnet_core::medium::phy::{self, Receiver};
//! use simnet_core::time::Time;
//!
//! let us = |n: u64| Time::from_nanos(n * 1000);
//! let noise = Receiver::MAX_SENSITIVITY.noise_w();
//! let strong = phy::dbm_to_w(-90.0);
//! // A 26-octet frame (832 µs), and a second one 400 µs later, 10 dB weaker.
//! let frames = [
//!     OnAir { start: us(0), end: us(832), power_w: strong },
//!     OnAir { start: us(400), end: us(1232), power_w: strong / 10.0 },
//! ];
//! let got = receive(&frames, &[], noise);
//! let Reception::Locked { success, .. } = got[0] else { panic!("{got:?}") };
//! assert!(success > 0.99, "10 dB above its interferer it survives: {success}");
//! assert_eq!(got[1], Reception::Busy);
//! ```

use super::phy;
use crate::time::Time;

/// The SINR below which a receiver does not lock onto a frame, dB.
pub const LOCK_SINR_DB: f64 = -5.0;

/// Bits per second on the air (2.4 GHz O-QPSK).
pub const BIT_RATE: f64 = 250_000.0;

/// One frame as one receiver hears it: on the air from `start` to `end`, at `power_w` watts at the receiver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnAir {
    /// The first bit of its synchronisation header reaches the receiver.
    pub start: Time,
    /// Its last bit has passed.
    pub end: Time,
    /// Its power at the receiver, W.
    pub power_w: f64,
}

/// What became of one frame at one receiver.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Reception {
    /// The receiver locked onto it; it arrives with probability `success`. `sinr_min` is the lowest SINR over it
    /// (linear), `rssi_w` its power.
    Locked {
        /// The probability it arrives intact.
        success: f64,
        /// The lowest SINR over the frame (linear).
        sinr_min: f64,
    },
    /// The receiver was receiving another frame when it began.
    Busy,
    /// The receiver was transmitting when it began.
    Transmitting,
    /// Its SINR as it began was below [`LOCK_SINR_DB`] (linear value given).
    Weak {
        /// The SINR as it began (linear).
        sinr: f64,
    },
}

/// What one receiver makes of `frames` (in any order; a frame of zero length is ignored as [`Reception::Weak`]
/// would be), over a noise floor of `noise_w` watts, while it transmits during each of `transmitting` ([start, end)
/// intervals). One entry per frame, in the order given. Frames that start at the same instant are taken in the
/// order given.
pub fn receive(frames: &[OnAir], transmitting: &[(Time, Time)], noise_w: f64) -> Vec<Reception> {
    timeline(frames, transmitting, noise_w, |_| true)
}

/// What one receiver makes of `frames[k]`: [`receive`]'s entry for it, the other frames' chances not worked out.
pub fn receive_one(frames: &[OnAir], transmitting: &[(Time, Time)], noise_w: f64, k: usize) -> Reception {
    timeline(frames, transmitting, noise_w, |i| i == k)
        .get(k)
        .copied()
        .unwrap_or(Reception::Weak { sinr: 0.0 })
}

/// Which of `frames` one receiver locks onto and keeps to their end or to its own transmission (a
/// [`Reception::Locked`] of [`receive`]), their chances not worked out.
pub fn locks(frames: &[OnAir], transmitting: &[(Time, Time)], noise_w: f64) -> Vec<bool> {
    timeline(frames, transmitting, noise_w, |_| false)
        .into_iter()
        .map(|r| matches!(r, Reception::Locked { .. }))
        .collect()
}

/// [`receive`], working out the chance of success only of the frames `wanted` (the others locked onto come out
/// as `Locked` with success 1 and no SINR): which frame is locked onto never depends on a chance.
fn timeline(
    frames: &[OnAir],
    transmitting: &[(Time, Time)],
    noise_w: f64,
    wanted: impl Fn(usize) -> bool,
) -> Vec<Reception> {
    // Events at one instant: ends before starts (a frame that ends as another starts does not overlap it), the
    // receiver's own transmissions ending before frames start, and starting after frames end.
    #[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
    enum Ev {
        FrameEnd(usize),
        TxEnd,
        TxStart,
        FrameStart(usize),
    }
    let mut events: Vec<(Time, Ev)> = Vec::with_capacity(2 * (frames.len() + transmitting.len()));
    for (i, f) in frames.iter().enumerate() {
        if f.end > f.start {
            events.push((f.start, Ev::FrameStart(i)));
            events.push((f.end, Ev::FrameEnd(i)));
        }
    }
    for &(a, b) in transmitting.iter().filter(|(a, b)| b > a) {
        events.push((a, Ev::TxStart));
        events.push((b, Ev::TxEnd));
    }
    events.sort();
    let mut out: Vec<Reception> = frames.iter().map(|_| Reception::Weak { sinr: 0.0 }).collect();
    // The interference on the air (every frame started and not ended), the frame locked onto (its success so far,
    // the lowest SINR, the start of the stretch not yet counted), and how many own transmissions are under way.
    let mut active_w = 0.0;
    let mut locked: Option<(usize, f64, f64, Time)> = None;
    let mut sending = 0usize;
    // Close the locked frame's stretch at `t` under the interference on the air until then.
    let close = |locked: &mut Option<(usize, f64, f64, Time)>, active_w: f64, t: Time| {
        if let Some((i, success, sinr_min, since)) = locked.as_mut().filter(|l| wanted(l.0)) {
            let p = frames[*i].power_w;
            let sinr = p / (noise_w + (active_w - p).max(0.0));
            let bits = (t.as_nanos() - since.as_nanos()) as f64 * 1e-9 * BIT_RATE;
            *success *= (bits * (-phy::bit_error_rate(sinr)).ln_1p()).exp();
            *sinr_min = sinr_min.min(sinr);
            *since = t;
        }
    };
    for (t, ev) in events {
        match ev {
            Ev::FrameStart(i) => {
                close(&mut locked, active_w, t);
                let p = frames[i].power_w;
                out[i] = if sending > 0 {
                    Reception::Transmitting
                } else if locked.is_some() {
                    Reception::Busy
                } else {
                    let sinr = p / (noise_w + active_w);
                    if 10.0 * sinr.log10() > LOCK_SINR_DB {
                        locked = Some((i, 1.0, f64::INFINITY, t));
                    }
                    Reception::Weak { sinr }
                };
                active_w += p;
            }
            Ev::FrameEnd(i) => {
                close(&mut locked, active_w, t);
                if let Some((j, success, sinr_min, _)) = locked.filter(|(j, ..)| *j == i) {
                    out[j] = Reception::Locked { success, sinr_min };
                    locked = None;
                }
                active_w -= frames[i].power_w;
                if active_w < 0.0 || !active_w.is_finite() {
                    active_w = 0.0;
                }
            }
            Ev::TxStart => {
                // Half-duplex: what it was receiving is lost (its SINR as far as it came).
                close(&mut locked, active_w, t);
                if let Some((j, _, sinr_min, _)) = locked.take() {
                    out[j] = Reception::Locked { success: 0.0, sinr_min };
                }
                sending += 1;
            }
            Ev::TxEnd => sending -= 1,
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::medium::phy::{dbm_to_w, frame_success_rate, Receiver};

    fn us(n: u64) -> Time {
        Time::from_nanos(n * 1000)
    }

    fn noise() -> f64 {
        Receiver::MAX_SENSITIVITY.noise_w()
    }

    fn success(r: Reception) -> f64 {
        match r {
            Reception::Locked { success, .. } => success,
            other => panic!("not locked: {other:?}"),
        }
    }

    /// Alone on the air, a frame survives as the frame error rate says: (1 − BER(S/N))^bits over all its bits.
    #[test]
    fn a_frame_alone_survives_by_its_snr() {
        for dbm in [-108.0, -106.0, -104.0] {
            let p = dbm_to_w(dbm);
            // 26 octets on the air: 832 µs, 208 bits.
            let got = receive(
                &[OnAir {
                    start: us(100),
                    end: us(932),
                    power_w: p,
                }],
                &[],
                noise(),
            );
            let want = frame_success_rate(p / noise(), 208);
            assert!(
                (success(got[0]) - want).abs() <= 1e-12 * want,
                "{dbm} dBm: {got:?} against {want}"
            );
        }
    }

    /// Two frames overlapping at the receiver: the one locked onto survives with the product of the closed form
    /// over its three stretches — alone, under the other (S / (N + I)), alone again; the other is lost to it.
    #[test]
    fn an_overlapping_frame_interferes_for_exactly_its_overlap() {
        let (s, i) = (dbm_to_w(-98.0), dbm_to_w(-104.0));
        let frames = [
            OnAir {
                start: us(0),
                end: us(1000),
                power_w: s,
            },
            OnAir {
                start: us(300),
                end: us(700),
                power_w: i,
            },
        ];
        let got = receive(&frames, &[], noise());
        let n = noise();
        let want =
            frame_success_rate(s / n, 75) * frame_success_rate(s / (n + i), 100) * frame_success_rate(s / n, 175);
        assert!((success(got[0]) - want).abs() <= 1e-12, "{got:?} against {want}");
        assert!(want < frame_success_rate(s / n, 250) && want > 0.0);
        let Reception::Locked { sinr_min, .. } = got[0] else {
            unreachable!()
        };
        assert!((sinr_min - s / (n + i)).abs() <= 1e-12 * sinr_min);
        assert_eq!(got[1], Reception::Busy);
        // An interferer that ends as the frame starts, or starts as it ends, does not overlap it.
        let apart = [
            OnAir {
                start: us(0),
                end: us(300),
                power_w: i,
            },
            OnAir {
                start: us(300),
                end: us(1300),
                power_w: s,
            },
            OnAir {
                start: us(1300),
                end: us(1600),
                power_w: i,
            },
        ];
        let got = receive(&apart, &[], n);
        assert!((success(got[1]) - frame_success_rate(s / n, 250)).abs() <= 1e-12);
    }

    /// No capture: a strong frame that begins while a weak one is received is lost, and ruins the weak one.
    #[test]
    fn a_later_stronger_frame_is_lost_and_ruins_the_first() {
        let (weak, strong) = (dbm_to_w(-100.0), dbm_to_w(-80.0));
        let frames = [
            OnAir {
                start: us(0),
                end: us(1000),
                power_w: weak,
            },
            OnAir {
                start: us(200),
                end: us(1200),
                power_w: strong,
            },
        ];
        let got = receive(&frames, &[], noise());
        assert!(success(got[0]) < 1e-9, "{got:?}");
        assert_eq!(got[1], Reception::Busy);
    }

    /// A frame that begins under an interferer 5 dB or more above it is not locked onto; one that begins 4 dB below
    /// it is.
    #[test]
    fn a_receiver_locks_only_above_minus_5_db() {
        let loud = dbm_to_w(-70.0);
        for (below_db, locks) in [(6.0, false), (4.0, true)] {
            let frames = [
                OnAir {
                    start: us(0),
                    end: us(2000),
                    power_w: loud,
                },
                OnAir {
                    start: us(10),
                    end: us(500),
                    power_w: loud / 10f64.powf(below_db / 10.0),
                },
            ];
            // The receiver was transmitting as the loud one began: it is free when the second begins.
            let got = receive(&frames, &[(us(0), us(5))], noise());
            assert_eq!(got[0], Reception::Transmitting);
            assert_eq!(
                matches!(got[1], Reception::Locked { .. }),
                locks,
                "{below_db} dB below: {got:?}"
            );
        }
    }

    /// Half-duplex: a frame that begins while the receiver transmits is not heard; one it is receiving when it
    /// begins to transmit is lost; after its transmission it hears again.
    #[test]
    fn a_transmitting_receiver_hears_nothing() {
        let p = dbm_to_w(-80.0);
        let frames = [
            OnAir {
                start: us(0),
                end: us(800),
                power_w: p,
            },
            OnAir {
                start: us(1000),
                end: us(1800),
                power_w: p,
            },
            OnAir {
                start: us(2500),
                end: us(3300),
                power_w: p,
            },
        ];
        let got = receive(&frames, &[(us(400), us(1200))], noise());
        assert_eq!(success(got[0]), 0.0);
        assert_eq!(got[1], Reception::Transmitting);
        assert!(success(got[2]) > 0.999);
    }

    /// Frames that start together: the first given is locked onto, the second lost to it; their equal powers leave
    /// the first a SINR of 0 dB over the noise-free part, which 16-chip spreading mostly survives.
    #[test]
    fn frames_that_start_together_are_taken_in_order() {
        let p = dbm_to_w(-80.0);
        let frames = [
            OnAir {
                start: us(0),
                end: us(800),
                power_w: p,
            },
            OnAir {
                start: us(0),
                end: us(800),
                power_w: p,
            },
        ];
        let got = receive(&frames, &[], noise());
        let want = frame_success_rate(p / (noise() + p), 200);
        assert!((success(got[0]) - want).abs() <= 1e-12, "{got:?} against {want}");
        assert!(want > 0.5 && want < 0.99, "{want}");
        assert_eq!(got[1], Reception::Busy);
    }

    proptest::proptest! {
        /// One frame's reception, and which frames are locked onto, worked out alone equal [`receive`]'s, exactly.
        #[test]
        fn one_frame_alone_is_the_whole_timelines_entry(
            spec in proptest::collection::vec((0u64..3000, 1u64..1500, -105.0f64..-60.0), 1..12),
            tx in proptest::collection::vec((0u64..3000, 1u64..800), 0..3),
        ) {
            let frames: Vec<OnAir> = spec
                .iter()
                .map(|&(s, len, dbm)| OnAir { start: us(s), end: us(s + len), power_w: dbm_to_w(dbm) })
                .collect();
            let sending: Vec<(Time, Time)> = tx.iter().map(|&(s, len)| (us(s), us(s + len))).collect();
            let all = receive(&frames, &sending, noise());
            let locks = locks(&frames, &sending, noise());
            for k in 0..frames.len() {
                proptest::prop_assert_eq!(receive_one(&frames, &sending, noise(), k), all[k]);
                proptest::prop_assert_eq!(locks[k], matches!(all[k], Reception::Locked { .. }));
            }
        }
    }
}
