//! The adversary model of `[[attack]]`: pure, seeded, per node — no socket, no clock.
//!
//! | kind | who | what |
//! |---|---|---|
//! | `forge` | an outsider in radio range of `target` | on each measurement `claim` sends, a datagram of its own claiming `claim`, with the values it could read (none when sealed) plus `bias`, ahead of the original |
//! | `tamper` | an outsider on the path `claim` → `target` | a copy of each datagram with its values moved by `bias` (ciphertext bytes flipped when sealed) and the checksum recomputed, ahead of the original |
//! | `replay` | an outsider on the same path | every datagram captured, sent again `delay_s` later |
//! | `flood` | anyone who can reach `target` | random bytes at `rate_hz` |
//! | `false-data` | `node` itself, compromised (it holds the key) | `bias + ramp·(t − start_s)` added to every measurement it sends |
//!
//! The outsiders act on the air in front of their target ([`Air`], a [`crate::medium::Ingress`] stage: the target
//! does not know what stands in front of it): what they inject goes through the target's
//! whole receive path (checksum, authentication, plausibility, the inbox) exactly as a datagram from a socket does,
//! with the claimed source as its address, as a spoofed source address would give it. They cannot silence the
//! original, so an attack that a key defeats leaves a run as it was. Each injection's fate is counted in a [`Tally`].

use std::collections::VecDeque;

use bytes::Bytes;
use nalgebra::DVector;
use rand::Rng as _;
use serde::{Deserialize, Serialize};

pub use crate::medium::{Injection, Refusals, Tally};
use crate::time::Time;
use crate::wire::{Datagram, Header, Payload, KIND_MEASUREMENT};

/// What an `[[attack]]` does.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AttackKind {
    /// Outsiders send datagrams in a neighbour's name.
    Forge,
    /// Outsiders change a neighbour's datagrams on the air.
    Tamper,
    /// Outsiders send a neighbour's datagrams again, `delay_s` later.
    Replay,
    /// Outsiders send garbage at `rate_hz`.
    Flood,
    /// A compromised node sends measurements moved by `bias` and `ramp`.
    FalseData,
}

impl AttackKind {
    /// Every kind, in the order of the tables.
    pub const ALL: [AttackKind; 5] = [
        AttackKind::Forge,
        AttackKind::Tamper,
        AttackKind::Replay,
        AttackKind::Flood,
        AttackKind::FalseData,
    ];

    /// The name in a topology file.
    pub fn as_str(self) -> &'static str {
        match self {
            AttackKind::Forge => "forge",
            AttackKind::Tamper => "tamper",
            AttackKind::Replay => "replay",
            AttackKind::Flood => "flood",
            AttackKind::FalseData => "false-data",
        }
    }

    /// The kind named `s` in a topology file.
    pub fn parse(s: &str) -> Option<AttackKind> {
        AttackKind::ALL.into_iter().find(|k| k.as_str() == s)
    }

    /// An outsider on the air in front of a target, rather than a compromised node.
    pub fn outsider(self) -> bool {
        self != AttackKind::FalseData
    }
}

/// One `[[attack]]`, validated; nodes by index.
#[derive(Debug, Clone, PartialEq)]
pub struct Attack {
    /// What the attack does.
    pub kind: AttackKind,
    /// The node attacked (outsiders).
    pub target: Option<usize>,
    /// The node whose datagrams are forged, tampered with or replayed: an in-neighbour of `target`.
    pub claim: Option<usize>,
    /// The compromised node (false-data).
    pub node: Option<usize>,
    /// Start of the attack, s.
    pub start_s: f64,
    /// End of the attack, s.
    pub end_s: f64,
    /// Added to each measurement row (forge, tamper, false-data).
    pub bias: Vec<f64>,
    /// Per second since `start_s`, on top of `bias` (false-data).
    pub ramp: Vec<f64>,
    /// How long a replayer holds a datagram before sending it again, s.
    pub delay_s: f64,
    /// Datagrams per second a flood sends.
    pub rate_hz: f64,
}

impl Attack {
    /// The attack is on at time `t`: start ≤ t < end, to the nanosecond (as a fault window is).
    pub fn active(&self, t: Time) -> bool {
        t >= Time::from_secs(self.start_s) && t < Time::from_secs(self.end_s)
    }

    /// What row `r` is moved by at `t`.
    pub fn offset(&self, r: usize, t: Time) -> f64 {
        let at = |v: &[f64]| v.get(r).copied().unwrap_or(0.0);
        at(&self.bias) + at(&self.ramp) * (t.as_secs() - self.start_s).max(0.0)
    }

    /// A compromised node's measurement as it sends it (false-data).
    pub fn taint(&self, z: &mut DVector<f64>, t: Time) {
        for (r, v) in z.iter_mut().enumerate() {
            *v += self.offset(r, t);
        }
    }
}

/// Captures a replayer holds at most (a bounded recorder).
const MAX_CAPTURES: usize = 4096;

/// The outsiders attacking one node: what they inject, from what they hear of its traffic.
pub struct Air {
    /// (attack index, attack, claimed node's id) of the attacks on this node.
    attacks: Vec<(usize, Attack, u32)>,
    /// (due time, attack index, bytes) captured by replayers.
    captured: VecDeque<(Time, usize, Bytes)>,
    /// Flood credit per attack (fractional datagrams carried between steps).
    credit: Vec<f64>,
    rng: crate::rng::Rng,
    /// The forger's own sequence numbers.
    seq: u32,
    /// What became of each attack's datagrams, by attack index.
    tallies: std::collections::BTreeMap<usize, Tally>,
}

impl Air {
    /// The attacks of `all` (with their indices) aimed at node `index`; `id_of` gives a node's id.
    pub fn new(all: &[Attack], index: usize, id_of: impl Fn(usize) -> u32, seed: u64) -> Air {
        let attacks: Vec<(usize, Attack, u32)> = all
            .iter()
            .enumerate()
            .filter(|(_, a)| a.kind.outsider() && a.target == Some(index))
            .map(|(i, a)| (i, a.clone(), a.claim.map(&id_of).unwrap_or(u32::MAX)))
            .collect();
        Air {
            credit: vec![0.0; attacks.len()],
            attacks,
            captured: VecDeque::new(),
            rng: crate::rng::stream(seed, "attack", index as u64, 0),
            seq: 0,
            tallies: Default::default(),
        }
    }

    /// No attack is aimed at this node.
    pub fn is_empty(&self) -> bool {
        self.attacks.is_empty()
    }

    /// The target begins a step at `t` (length `dt`): the flood of the step, and the replays now due.
    fn floods_and_replays(&mut self, t: Time, dt: f64) -> Vec<Injection> {
        let mut out = Vec::new();
        while self.captured.front().is_some_and(|(due, _, _)| *due <= t) {
            let (_, attack, bytes) = self.captured.pop_front().expect("front exists");
            let from = self
                .attacks
                .iter()
                .find(|(i, _, _)| *i == attack)
                .and_then(|(_, a, _)| a.claim);
            out.push(Injection { attack, from, bytes });
        }
        for (slot, (i, a, _)) in self.attacks.iter().enumerate() {
            if a.kind != AttackKind::Flood || !a.active(t) {
                continue;
            }
            self.credit[slot] += a.rate_hz * dt;
            let n = self.credit[slot].floor();
            self.credit[slot] -= n;
            for _ in 0..n as u64 {
                let len = self.rng.gen_range(1..=crate::wire::MAX_DATAGRAM);
                let mut b = vec![0u8; len];
                self.rng.fill(&mut b[..]);
                out.push(Injection {
                    attack: *i,
                    from: None,
                    bytes: Bytes::from(b),
                });
            }
        }
        out
    }

    /// A datagram reaches the target at `t` from `from`: what the outsiders send ahead of it, and what they
    /// capture of it.
    fn ahead_of(&mut self, t: Time, from: Option<usize>, bytes: &[u8]) -> Vec<Injection> {
        let mut out = Vec::new();
        let Some(from) = from else { return out };
        let Ok(header) = crate::wire::peek_header(bytes) else {
            return out;
        };
        // What an outsider can read: the clear header always, the values only when the datagram is not sealed.
        let clear = Datagram::decode(bytes).ok();
        for (i, a, claim_id) in &self.attacks {
            if a.claim != Some(from) || header.src != *claim_id || !a.active(t) {
                continue;
            }
            match a.kind {
                AttackKind::Replay if self.captured.len() < MAX_CAPTURES => {
                    let delay = crate::time::nanos(a.delay_s * 1e9);
                    self.captured.push_back((t + delay, *i, Bytes::copy_from_slice(bytes)));
                }
                AttackKind::Forge if header.kind == KIND_MEASUREMENT => {
                    let (rows, values) = match &clear {
                        Some(Datagram {
                            payload: Payload::Measurement { rows, values },
                            ..
                        }) => (*rows, moved(a, *rows, values, t)),
                        // Sealed: the forger cannot read the values and sends its bias over every row it moves.
                        _ => {
                            let m = a.bias.len().min(64);
                            let rows = if m == 64 { u64::MAX } else { (1u64 << m) - 1 };
                            (rows, moved(a, rows, &vec![0.0; m], t))
                        }
                    };
                    // Addressed and timed as the datagram it overheard, numbered by the forger.
                    let d = Datagram {
                        header: Header {
                            sent: header.sent,
                            ..Header::new(*claim_id, header.dst, self.seq, header.pertains)
                        },
                        payload: Payload::measurement(rows, values),
                    };
                    self.seq = self.seq.wrapping_add(1);
                    if let Ok(bytes) = d.encode() {
                        out.push(Injection {
                            attack: *i,
                            from: Some(from),
                            bytes,
                        });
                    }
                }
                AttackKind::Tamper if header.kind == KIND_MEASUREMENT => {
                    let bytes = match &clear {
                        Some(Datagram {
                            header,
                            payload: Payload::Measurement { rows, values },
                        }) => Datagram {
                            header: *header,
                            payload: Payload::measurement(*rows, moved(a, *rows, values, t)),
                        }
                        .encode()
                        .ok(),
                        _ => Some(flip_sealed(bytes)),
                    };
                    if let Some(bytes) = bytes {
                        out.push(Injection {
                            attack: *i,
                            from: Some(from),
                            bytes,
                        });
                    }
                }
                _ => {}
            }
        }
        out
    }
}

/// The outsiders stand in front of their target: it takes what they inject ahead of what arrives and as each step
/// begins, and tells them what became of it.
impl crate::medium::Ingress for Air {
    fn on_arrival(&mut self, t: Time, from: Option<usize>, bytes: &[u8]) -> Vec<Injection> {
        self.ahead_of(t, from, bytes)
    }
    fn on_step(&mut self, t: Time, dt: f64) -> Vec<Injection> {
        self.floods_and_replays(t, dt)
    }
    fn on_fate(&mut self, source: usize, fate: &Tally) {
        self.tallies.entry(source).or_default().add(fate);
    }
    fn tallies(&self) -> Vec<(usize, Tally)> {
        self.tallies.iter().map(|(i, t)| (*i, *t)).collect()
    }
}

/// `values` of the rows in `rows` (in row order), each moved by the attack's offset at `t`.
fn moved(a: &Attack, rows: u64, values: &[f64], t: Time) -> Vec<f64> {
    (0..64)
        .filter(|r| rows & (1 << r) != 0)
        .zip(values)
        .map(|(r, v)| v + a.offset(r, t))
        .collect()
}

/// A sealed datagram with one ciphertext byte flipped (CCM's counter mode is malleable: without the tag, this
/// would move the value under it) and its checksum recomputed.
fn flip_sealed(bytes: &[u8]) -> Bytes {
    let crc = crate::wire::CRC_LEN;
    let mut b = bytes.to_vec();
    if b.len() < crc {
        return Bytes::from(b);
    }
    if b.len() > crc + crate::wire::secure::TAG_LEN + 1 {
        let at = b.len() - crc - crate::wire::secure::TAG_LEN - 1;
        b[at] ^= 0x40;
    }
    let n = b.len().saturating_sub(crc);
    let sum = crc32fast::hash(&b[..n]);
    b[n..].copy_from_slice(&sum.to_le_bytes());
    Bytes::from(b)
}

#[cfg(test)]
mod tests;
