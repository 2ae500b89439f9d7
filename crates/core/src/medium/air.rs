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
    let mut events: Vec<(Time, Event)> = Vec::with_capacity(2 * (frames.len() + transmitting.len()));
    for (i, f) in frames.iter().enumerate() {
        if f.end > f.start {
            events.push((f.start, Event::FrameStart(i as u64)));
            events.push((f.end, Event::FrameEnd(i as u64)));
        }
    }
    for &(a, b) in transmitting.iter().filter(|(a, b)| b > a) {
        events.push((a, Event::TxStart));
        events.push((b, Event::TxEnd));
    }
    events.sort();
    let mut out: Vec<Reception> = frames.iter().map(|_| Reception::Weak { sinr: 0.0 }).collect();
    let mut ear = Listener::new(noise_w);
    for (t, event) in events {
        let power_w = match event {
            Event::FrameStart(i) | Event::FrameEnd(i) => frames[i as usize].power_w,
            _ => 0.0,
        };
        if let Some((i, r)) = ear.hear(t, event, power_w, true) {
            out[i as usize] = r;
        }
    }
    out
}

/// What happens at a receiver. At one instant they are taken in this order: frames end (a frame that ends as
/// another starts does not overlap it), its own transmission ends, one begins, frames start; frames in the order
/// they were sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Event {
    /// Frame `id` leaves the air.
    FrameEnd(u64),
    /// The receiver's own transmission ends.
    TxEnd,
    /// The receiver begins to transmit.
    TxStart,
    /// Frame `id` reaches the receiver.
    FrameStart(u64),
}

/// One receiver, fed what happens around it in time order ([`Event`]'s order at an instant): what it locks onto
/// and the chance it survives, as [`receive`] works out over a whole timeline, one event at a time.
#[derive(Debug, Clone)]
pub struct Listener {
    noise_w: f64,
    /// Frames on the air it hears, and their power summed since the air was last silent (so that no rounding
    /// residue outlives a silence).
    active: usize,
    active_w: f64,
    locked: Option<Lock>,
    /// Its own transmissions under way.
    sending: usize,
}

/// The frame a receiver is locked onto: its power, its chance so far, its lowest SINR, and the start of the
/// stretch not yet counted; its chance is only worked out when `wanted`.
#[derive(Debug, Clone, Copy)]
struct Lock {
    id: u64,
    power_w: f64,
    success: f64,
    sinr_min: f64,
    since: Time,
    wanted: bool,
}

impl Listener {
    /// A receiver listening over a noise floor of `noise_w` watts, the air silent.
    pub fn new(noise_w: f64) -> Listener {
        Listener {
            noise_w,
            active: 0,
            active_w: 0.0,
            locked: None,
            sending: 0,
        }
    }

    /// The frame it is locked onto.
    pub fn locked(&self) -> Option<u64> {
        self.locked.map(|l| l.id)
    }

    /// `event` at `t` (of a frame at `power_w` watts here; its chance worked out if `wanted`): the fate of a frame
    /// it settles — at a frame's start if the receiver does not lock onto it, at its end if it does, as it begins to
    /// transmit for one it was receiving.
    pub fn hear(&mut self, t: Time, event: Event, power_w: f64, wanted: bool) -> Option<(u64, Reception)> {
        match event {
            Event::FrameStart(id) => {
                self.close(t);
                let r = if self.sending > 0 {
                    Some(Reception::Transmitting)
                } else if self.locked.is_some() {
                    Some(Reception::Busy)
                } else {
                    let sinr = power_w / (self.noise_w + self.active_w);
                    if 10.0 * sinr.log10() > LOCK_SINR_DB {
                        self.locked = Some(Lock {
                            id,
                            power_w,
                            success: 1.0,
                            sinr_min: f64::INFINITY,
                            since: t,
                            wanted,
                        });
                        None
                    } else {
                        Some(Reception::Weak { sinr })
                    }
                };
                self.active += 1;
                self.active_w += power_w;
                r.map(|r| (id, r))
            }
            Event::FrameEnd(id) => {
                self.close(t);
                let done = self.locked.filter(|l| l.id == id).map(|l| {
                    self.locked = None;
                    (
                        id,
                        Reception::Locked {
                            success: l.success,
                            sinr_min: l.sinr_min,
                        },
                    )
                });
                self.active = self.active.saturating_sub(1);
                self.active_w -= power_w;
                if self.active == 0 || self.active_w < 0.0 || !self.active_w.is_finite() {
                    self.active_w = 0.0;
                }
                done
            }
            Event::TxStart => {
                // Half-duplex: what it was receiving is lost (its SINR as far as it came).
                self.close(t);
                self.sending += 1;
                self.locked.take().map(|l| {
                    (
                        l.id,
                        Reception::Locked {
                            success: 0.0,
                            sinr_min: l.sinr_min,
                        },
                    )
                })
            }
            Event::TxEnd => {
                self.sending = self.sending.saturating_sub(1);
                None
            }
        }
    }

    /// Close the locked frame's stretch at `t` under the interference on the air until then: it survives the
    /// stretch's bits with probability (1 − BER(SINR))^bits.
    fn close(&mut self, t: Time) {
        let (noise_w, active_w) = (self.noise_w, self.active_w);
        if let Some(l) = self.locked.as_mut().filter(|l| l.wanted) {
            let sinr = l.power_w / (noise_w + (active_w - l.power_w).max(0.0));
            let bits = (t.as_nanos() - l.since.as_nanos()) as f64 * 1e-9 * BIT_RATE;
            l.success *= (bits * (-phy::bit_error_rate(sinr)).ln_1p()).exp();
            l.sinr_min = l.sinr_min.min(sinr);
            l.since = t;
        }
    }
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
}
