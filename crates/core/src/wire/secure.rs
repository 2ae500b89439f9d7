//! Authenticated datagrams, on the model of IEEE 802.15.4 security and OSCORE: AES-128-CCM with an 8-byte tag over
//! the payload, the header authenticated as associated data.
//!
//! ```text
//! | header (postcard, flags = SEALED) | epoch u64 LE | counter u64 LE | CCM(payload) | tag (8) | crc32 |
//!   └──────────── associated data ───────────────────┘ + the receiver's boot (not sent)
//! ```
//!
//! AES-CCM with 8-byte tags (CCM*'s security level of 802.15.4, OSCORE's default algorithm) rather than
//! ChaCha20-Poly1305: it is what a sensor node's radio computes in hardware, so real firmware could join a simnet
//! network, and its tag is half the size of Poly1305's in a 1200-byte budget.
//!
//! **One key per link and sender boot**: HKDF-SHA-256 of the network key with the sender's id, the receiver's id and
//! the sender's boot epoch. Each link numbers its datagrams from 0, so the nonce (the sender's id and the counter)
//! never repeats under a key, across crashes and process restarts alike, as long as a boot's epoch is new — larger
//! than every earlier boot's (the restart count in a simulation; the boot time with random low bits for a process).
//! A datagram opens only at the node it was sealed for: one sent to node 2 and re-sent to node 1 fails its tag there.
//!
//! **Bound to the receiver's boot**: a measurement's or a round's associated data ends with the boot epoch of the
//! receiver as the sender knows it (each process's boot, random in its low bits; one random epoch for every node of a
//! run in one process). Nothing sealed for an earlier run opens in this one, whatever its epoch. Hellos are bound to
//! no boot (0): a node greets a neighbour before it knows its boot, and a hello carries the boot it echoes inside.
//!
//! The CRC stays outside, so that a link's bit flip still counts as corruption and only a datagram whose checksum
//! holds and whose tag does not counts as forged.
//!
//! A receiver keeps, per source, the epoch it accepts and a 64-entry window of counters ([`Replay`]), checked once
//! the tag holds: a counter seen before is a replay, one below the window or an earlier epoch is too old, a later epoch (the source
//! restarted) replaces the window once a datagram of it authenticates.

use std::collections::HashMap;

use aes::Aes128;
use bytes::Bytes;
use ccm::aead::{AeadInPlace, KeyInit};
use ccm::consts::{U13, U8};
use ccm::Ccm;
use hkdf::Hkdf;
use sha2::Sha256;

use super::{Datagram, Header, Payload, WireError, MAX_DATAGRAM};

type Cipher = Ccm<Aes128, U8, U13>;

/// `header.flags` of a sealed datagram.
pub const SEALED: u8 = 1;
/// Bytes of the authentication tag after a sealed payload.
pub const TAG_LEN: usize = 8;
/// Epoch and counter, in the clear after the header.
const SEQ_LEN: usize = 16;
/// Replay window, in datagrams.
pub const WINDOW: u64 = 64;

/// The network's key (`simnet keygen`); never printed.
#[derive(Clone, PartialEq, Eq)]
pub struct Key([u8; 16]);

impl std::fmt::Debug for Key {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Key(…)")
    }
}

/// Why a key file was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum KeyError {
    /// Not one line `simnet-key-v1 <32 hex digits>`.
    #[error("not a simnet key file: expected one line `simnet-key-v1 <32 hex digits>`")]
    Format,
}

/// First word of a key file.
const KEY_TAG: &str = "simnet-key-v1";

impl Key {
    /// A key of these 16 bytes.
    pub fn from_bytes(b: [u8; 16]) -> Key {
        Key(b)
    }

    /// A key file's text: `simnet-key-v1 <32 hex digits>` (comments after `#`).
    pub fn parse(text: &str) -> Result<Key, KeyError> {
        let line = text
            .lines()
            .map(|l| l.split('#').next().unwrap_or("").trim())
            .find(|l| !l.is_empty())
            .ok_or(KeyError::Format)?;
        let hex = line.strip_prefix(KEY_TAG).ok_or(KeyError::Format)?.trim();
        if hex.len() != 32 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
            return Err(KeyError::Format);
        }
        let mut k = [0u8; 16];
        for (i, b) in k.iter_mut().enumerate() {
            *b = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).map_err(|_| KeyError::Format)?;
        }
        Ok(Key(k))
    }

    /// The key file's text.
    pub fn to_file(&self) -> String {
        let hex: String = self.0.iter().map(|b| format!("{b:02x}")).collect();
        format!("# simnet network key: every node of a run holds the same one. Keep it secret.\n{KEY_TAG} {hex}\n")
    }

    /// The key of one link in one sender boot: HKDF-SHA-256 (RFC 5869) of the network key, `info` = the sender's
    /// id, the receiver's id and the sender's epoch.
    fn link(&self, src: u32, dst: u32, epoch: u64) -> Cipher {
        let mut info = [0u8; 16];
        info[..4].copy_from_slice(&src.to_be_bytes());
        info[4..8].copy_from_slice(&dst.to_be_bytes());
        info[8..].copy_from_slice(&epoch.to_be_bytes());
        let mut k = [0u8; 16];
        // 16 bytes is far inside HKDF-SHA-256's limit: expand cannot fail.
        let _ = Hkdf::<Sha256>::new(Some(b"simnet link key"), &self.0).expand(&info, &mut k);
        Cipher::new(&k.into())
    }
}

/// The 13-byte CCM nonce: the sender's id and the counter (unique under a link's key).
fn nonce(src: u32, counter: u64) -> [u8; 13] {
    let mut n = [0u8; 13];
    n[..4].copy_from_slice(&src.to_be_bytes());
    n[4..12].copy_from_slice(&counter.to_be_bytes());
    n
}

/// The receiver's boot a datagram of header kind `kind` is bound to: none for a hello.
fn bound(kind: u8, receiver_boot: u64) -> u64 {
    if kind == super::KIND_HELLO {
        0
    } else {
        receiver_boot
    }
}

/// The associated data: the clear part (header, epoch, counter) and the receiver's boot it is bound to.
fn associated(clear: &[u8], kind: u8, receiver_boot: u64) -> Vec<u8> {
    let mut aad = Vec::with_capacity(clear.len() + 8);
    aad.extend_from_slice(clear);
    aad.extend_from_slice(&bound(kind, receiver_boot).to_le_bytes());
    aad
}

/// One boot of a sender: each link's key and next counter.
pub struct Sealer {
    key: Key,
    src: u32,
    epoch: u64,
    /// By receiver id: the link's key and next counter.
    links: HashMap<u32, (Cipher, u64)>,
}

impl Sealer {
    /// The sealer of node `src` for the boot of epoch `epoch` (its counter starts at 0).
    pub fn new(key: &Key, src: u32, epoch: u64) -> Sealer {
        Sealer {
            key: key.clone(),
            src,
            epoch,
            links: HashMap::new(),
        }
    }

    /// This boot's epoch.
    pub fn epoch(&self) -> u64 {
        self.epoch
    }

    /// The counter the next datagram to `dst` takes.
    pub fn next_counter(&self, dst: u32) -> u64 {
        self.links.get(&dst).map_or(0, |(_, c)| *c)
    }

    /// `d` sealed for node `dst`, bound to `dst`'s boot `dst_boot` as this node knows it: its header must name
    /// this sender.
    pub fn seal(&mut self, d: &Datagram, dst: u32, dst_boot: u64) -> Result<Bytes, WireError> {
        self.seal_parts(&d.header, &d.payload, dst, dst_boot)
    }

    /// [`Sealer::seal`] of `payload` under `header`, with no datagram made to hold them.
    pub fn seal_parts(
        &mut self,
        header: &Header,
        payload: &Payload,
        dst: u32,
        dst_boot: u64,
    ) -> Result<Bytes, WireError> {
        if header.src != self.src {
            return Err(WireError::Invalid("a sealer seals its own node's datagrams"));
        }
        if !header.is_for(dst) {
            return Err(WireError::Invalid("sealed for a node the header does not address"));
        }
        super::validate_payload(header, payload)?;
        let header = Header {
            flags: SEALED,
            ..*header
        };
        let (src, epoch) = (self.src, self.epoch);
        let key = &self.key;
        let (cipher, counter) = self.links.entry(dst).or_insert_with(|| (key.link(src, dst, epoch), 0));
        let mut buf = postcard::to_allocvec(&header).map_err(|e| WireError::Malformed(e.to_string()))?;
        buf.extend_from_slice(&epoch.to_le_bytes());
        buf.extend_from_slice(&counter.to_le_bytes());
        let aad = associated(&buf, header.kind, dst_boot);
        let mut body = postcard::to_allocvec(payload).map_err(|e| WireError::Malformed(e.to_string()))?;
        let tag = cipher
            .encrypt_in_place_detached(&nonce(src, *counter).into(), &aad, &mut body)
            .map_err(|_| WireError::Invalid("payload too long to seal"))?;
        buf.extend_from_slice(&body);
        buf.extend_from_slice(&tag);
        let crc = crc32fast::hash(&buf);
        buf.extend_from_slice(&crc.to_le_bytes());
        if buf.len() > MAX_DATAGRAM {
            return Err(WireError::TooLong(buf.len()));
        }
        // Never again under this key, whatever happened to the datagram.
        *counter += 1;
        Ok(Bytes::from(buf))
    }
}

/// Why a datagram was not accepted by [`Opener::open`].
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Rejected {
    /// Checksum failed: damaged on the way.
    #[error("corrupted: {0}")]
    Corrupted(WireError),
    /// Not a datagram at all, or not sealed where a key is required.
    #[error("malformed: {0}")]
    Malformed(WireError),
    /// The checksum holds but the tag does not: forged or tampered with.
    #[error("the authentication tag does not verify")]
    BadTag,
    /// A counter already accepted.
    #[error("replayed: counter {counter} of epoch {epoch} was accepted before")]
    Replay {
        /// The source's boot epoch.
        epoch: u64,
        /// The datagram's counter.
        counter: u64,
    },
    /// An earlier epoch of the source, or a counter below its window.
    #[error("too old: counter {counter} of epoch {epoch}")]
    TooOld {
        /// The source's boot epoch.
        epoch: u64,
        /// The datagram's counter.
        counter: u64,
    },
    /// A source the receiver does not hear from.
    #[error("from unknown source {0}")]
    UnknownSource(u32),
}

/// The counters of one source's current epoch that were accepted: the highest, and a bitmap of the 64 below it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Replay {
    /// The source's boot epoch the window belongs to.
    pub epoch: u64,
    highest: u64,
    /// Bit i: counter `highest − i` was accepted.
    seen: u64,
}

impl Replay {
    /// Whether (epoch, counter) may be accepted, without changing anything.
    fn check(this: Option<&Replay>, epoch: u64, counter: u64) -> Result<(), Rejected> {
        let Some(w) = this else { return Ok(()) };
        if epoch < w.epoch {
            return Err(Rejected::TooOld { epoch, counter });
        }
        if epoch > w.epoch || counter > w.highest {
            return Ok(());
        }
        let back = w.highest - counter;
        if back >= WINDOW {
            Err(Rejected::TooOld { epoch, counter })
        } else if w.seen & (1 << back) != 0 {
            Err(Rejected::Replay { epoch, counter })
        } else {
            Ok(())
        }
    }

    /// Record an accepted (epoch, counter) that passed [`Replay::check`].
    fn accept(this: &mut Option<Replay>, epoch: u64, counter: u64) {
        match this {
            Some(w) if w.epoch == epoch => {
                if counter > w.highest {
                    let shift = counter - w.highest;
                    w.seen = if shift >= WINDOW { 0 } else { w.seen << shift };
                    w.highest = counter;
                    w.seen |= 1;
                } else {
                    w.seen |= 1 << (w.highest - counter);
                }
            }
            // A first datagram, or the source restarted: a new window.
            _ => {
                *this = Some(Replay {
                    epoch,
                    highest: counter,
                    seen: 1,
                })
            }
        }
    }
}

/// A receiver: the key, its own id and boot, each source's link key and replay window.
pub struct Opener {
    key: Key,
    /// This node's id: only datagrams sealed for it open.
    me: u32,
    /// This node's boot, as its neighbours know it: measurements and rounds bound to another do not open.
    boot: u64,
    /// By source: the accepted epoch's link key, so that it is derived once per boot.
    boots: HashMap<u32, (u64, Cipher)>,
    windows: HashMap<u32, Option<Replay>>,
}

impl Opener {
    /// The receiving end of node `me` in its boot `boot`.
    pub fn new(key: &Key, me: u32, boot: u64) -> Opener {
        Opener {
            key: key.clone(),
            me,
            boot,
            boots: HashMap::new(),
            windows: HashMap::new(),
        }
    }

    /// Checked open of untrusted bytes from a source `known(src)` accepts: (datagram, epoch, counter). Nothing in
    /// the receiver changes unless the datagram authenticates and is new.
    pub fn open(&mut self, bytes: &[u8], known: impl Fn(u32) -> bool) -> Result<(Datagram, u64, u64), Rejected> {
        let body = super::checked_body(bytes).map_err(|e| match e {
            WireError::Checksum => Rejected::Corrupted(e),
            e => Rejected::Malformed(e),
        })?;
        let (header, rest): (Header, &[u8]) =
            postcard::take_from_bytes(body).map_err(|e| Rejected::Malformed(WireError::Malformed(e.to_string())))?;
        header.validate(SEALED).map_err(Rejected::Malformed)?;
        if !known(header.src) {
            return Err(Rejected::UnknownSource(header.src));
        }
        if rest.len() < SEQ_LEN + TAG_LEN {
            return Err(Rejected::Malformed(WireError::TooShort(bytes.len())));
        }
        let mut e = [0u8; 8];
        e.copy_from_slice(&rest[..8]);
        let epoch = u64::from_le_bytes(e);
        e.copy_from_slice(&rest[8..16]);
        let counter = u64::from_le_bytes(e);
        let aad = associated(&body[..body.len() - rest.len() + SEQ_LEN], header.kind, self.boot);
        let (sealed, tag) = rest[SEQ_LEN..].split_at(rest.len() - SEQ_LEN - TAG_LEN);
        let mut plain = sealed.to_vec();
        let fresh;
        let cipher = match self.boots.get(&header.src) {
            Some((ep, c)) if *ep == epoch => c,
            _ => {
                fresh = self.key.link(header.src, self.me, epoch);
                &fresh
            }
        };
        cipher
            .decrypt_in_place_detached(&nonce(header.src, counter).into(), &aad, &mut plain, tag.into())
            .map_err(|_| Rejected::BadTag)?;
        // The window after the tag: a datagram sealed for another link or boot, whatever its counter, is forged
        // here (`BadTag`), and only a genuine one seen before is a replay.
        let window = self.windows.get(&header.src).copied().flatten();
        Replay::check(window.as_ref(), epoch, counter)?;
        let (payload, left): (Payload, &[u8]) =
            postcard::take_from_bytes(&plain).map_err(|e| Rejected::Malformed(WireError::Malformed(e.to_string())))?;
        if !left.is_empty() {
            return Err(Rejected::Malformed(WireError::Trailing(left.len())));
        }
        let d = Datagram {
            header: Header { flags: 0, ..header },
            payload,
        };
        super::validate_payload(&d.header, &d.payload).map_err(Rejected::Malformed)?;
        // Authentic and new: remember it.
        if self.boots.get(&header.src).is_none_or(|(ep, _)| *ep != epoch) {
            self.boots
                .insert(header.src, (epoch, self.key.link(header.src, self.me, epoch)));
        }
        Replay::accept(self.windows.entry(header.src).or_default(), epoch, counter);
        Ok((d, epoch, counter))
    }
}

/// The (source, epoch, counter) a sealed datagram's clear part claims, unauthenticated: what a capture of the
/// wire shows of its nonce.
pub fn claimed_nonce(bytes: &[u8]) -> Result<(u32, u64, u64), WireError> {
    claimed(bytes).map(|(h, epoch, counter)| (h.src, epoch, counter))
}

/// The header, epoch and counter a sealed datagram's clear part claims, unauthenticated.
pub fn claimed(bytes: &[u8]) -> Result<(Header, u64, u64), WireError> {
    let body = super::checked_body(bytes)?;
    let (header, rest): (Header, &[u8]) =
        postcard::take_from_bytes(body).map_err(|e| WireError::Malformed(e.to_string()))?;
    header.validate(SEALED)?;
    if rest.len() < SEQ_LEN + TAG_LEN {
        return Err(WireError::TooShort(bytes.len()));
    }
    let word = |i: usize| {
        let mut w = [0u8; 8];
        w.copy_from_slice(&rest[i..i + 8]);
        u64::from_le_bytes(w)
    };
    Ok((header, word(0), word(8)))
}

/// What sealing adds to a datagram's length.
pub const OVERHEAD: usize = SEQ_LEN + TAG_LEN;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wire::CRC_LEN;

    fn key() -> Key {
        Key::from_bytes([7; 16])
    }

    fn sample(src: u32, step: u64) -> Datagram {
        Datagram {
            header: Header::new(src, 9, step as u32, crate::time::Time::at_step(step, 0.01)),
            payload: Payload::measurement(0b101, vec![1.5, -2.0]),
        }
    }

    /// Node 9's receiving end, in boot 500.
    fn opener() -> Opener {
        Opener::new(&key(), 9, 500)
    }

    #[test]
    fn sealed_datagrams_open_once_and_only_with_the_key() {
        let mut s = Sealer::new(&key(), 3, 11);
        let mut o = opener();
        let d = sample(3, 40);
        let b = s.seal(&d, 9, 500).unwrap();
        assert_eq!(b.len(), d.encode().unwrap().len() + OVERHEAD);
        assert_eq!(o.open(&b, |_| true).unwrap(), (d.clone(), 11, 0));
        // The same bytes again: a replay.
        assert_eq!(o.open(&b, |_| true), Err(Rejected::Replay { epoch: 11, counter: 0 }));
        // Another key: the tag fails.
        let mut other = Opener::new(&Key::from_bytes([8; 16]), 9, 500);
        assert_eq!(
            other.open(&s.seal(&d, 9, 500).unwrap(), |_| true),
            Err(Rejected::BadTag)
        );
        // An unsealed datagram where a key is required, and an unknown source.
        assert!(matches!(
            o.open(&d.encode().unwrap(), |_| true),
            Err(Rejected::Malformed(_))
        ));
        assert_eq!(
            o.open(&s.seal(&d, 9, 500).unwrap(), |src| src != 3),
            Err(Rejected::UnknownSource(3))
        );
        // A sealer seals only its own node's datagrams.
        assert!(s.seal(&sample(4, 1), 9, 500).is_err());
    }

    /// A datagram opens only at the node it was sealed for, and only in the receiver's boot it was bound to; each
    /// link counts from 0 under its own key.
    #[test]
    fn a_datagram_opens_only_at_its_receiver_in_its_boot() {
        let mut s = Sealer::new(&key(), 3, 11);
        let d = sample(3, 40);
        let to9 = s.seal(&d, 9, 500).unwrap();
        let mut d4 = d.clone();
        d4.header.dst = 4;
        assert!(
            s.seal(&d4, 9, 500).is_err(),
            "sealed for a node its header does not address"
        );
        let to4 = s.seal(&d4, 4, 500).unwrap();
        assert_eq!(claimed_nonce(&to9).unwrap(), (3, 11, 0));
        assert_eq!(claimed_nonce(&to4).unwrap(), (3, 11, 0), "each link counts from 0");
        assert_ne!(to9, to4, "under different keys");
        assert_eq!(s.next_counter(9), 1);
        // Re-sent to node 4's neighbour 9 (a redirect), or 9's datagram at 4: the tag fails.
        assert_eq!(opener().open(&to4, |_| true), Err(Rejected::BadTag));
        assert_eq!(Opener::new(&key(), 4, 500).open(&to9, |_| true), Err(Rejected::BadTag));
        assert!(Opener::new(&key(), 4, 500).open(&to4, |_| true).is_ok());
        // Bound to another boot of node 9 (an earlier run's): refused, whatever its epoch.
        let old = s.seal(&d, 9, 499).unwrap();
        assert_eq!(opener().open(&old, |_| true), Err(Rejected::BadTag));
        // A hello is bound to no boot: it opens whatever boot its sender believed.
        let hello = Datagram {
            header: Header::hello(3, 9, 1, crate::time::Time::ZERO),
            payload: Payload::Hello {
                running: None,
                run: 11,
                boot: 11,
                echo: 0,
                probe: 0,
                answer: 0,
            },
        };
        assert!(opener().open(&s.seal(&hello, 9, 123).unwrap(), |_| true).is_ok());
        assert!(opener().open(&to9, |_| true).is_ok());
    }

    /// Every bit flip is caught: by the checksum, or by the tag once the checksum is made to match (tampering).
    #[test]
    fn every_flip_is_corruption_and_every_tampering_a_bad_tag() {
        let round = crate::wire::tests::information_round();
        let mut s = Sealer::new(&key(), 2, 1);
        let bytes = s.seal(&round, 9, 500).unwrap();
        let n = bytes.len();
        for bit in 0..n * 8 {
            let mut b = bytes.to_vec();
            b[bit / 8] ^= 1 << (bit % 8);
            let mut o = opener();
            assert!(o.open(&b, |_| true).is_err(), "bit {bit} went undetected");
            // With the checksum recomputed: anything but the CRC itself is caught by the header's checks or the tag.
            if bit / 8 < n - CRC_LEN {
                let crc = crc32fast::hash(&b[..n - CRC_LEN]);
                b[n - CRC_LEN..].copy_from_slice(&crc.to_le_bytes());
                let r = opener().open(&b, |_| true);
                assert!(
                    matches!(r, Err(Rejected::BadTag) | Err(Rejected::Malformed(_))),
                    "bit {bit}: {r:?}"
                );
            }
        }
    }

    /// The window takes reordered datagrams once each, refuses what fell out of it, and a restart's later epoch.
    #[test]
    fn the_window_tolerates_reordering_and_refuses_replays() {
        let mut s = Sealer::new(&key(), 1, 5);
        let sealed: Vec<Bytes> = (0..200).map(|k| s.seal(&sample(1, k), 9, 500).unwrap()).collect();
        let mut o = opener();
        // 0, then 100, then 60 (inside the window), then 20 (below it).
        assert!(o.open(&sealed[0], |_| true).is_ok());
        assert!(o.open(&sealed[100], |_| true).is_ok());
        assert!(o.open(&sealed[60], |_| true).is_ok());
        assert_eq!(
            o.open(&sealed[60], |_| true),
            Err(Rejected::Replay { epoch: 5, counter: 60 })
        );
        assert_eq!(
            o.open(&sealed[20], |_| true),
            Err(Rejected::TooOld { epoch: 5, counter: 20 })
        );
        assert!(o.open(&sealed[99], |_| true).is_ok());
        // The source restarts: epoch 6 from counter 0; epoch 5 is then too old.
        let mut again = Sealer::new(&key(), 1, 6);
        assert!(o.open(&again.seal(&sample(1, 300), 9, 500).unwrap(), |_| true).is_ok());
        assert_eq!(
            o.open(&sealed[150], |_| true),
            Err(Rejected::TooOld { epoch: 5, counter: 150 })
        );
        // A forged datagram of a later epoch changes nothing: its tag fails first.
        let mut forger = Sealer::new(&Key::from_bytes([9; 16]), 1, 99);
        assert_eq!(
            o.open(&forger.seal(&sample(1, 301), 9, 500).unwrap(), |_| true),
            Err(Rejected::BadTag)
        );
        assert!(o.open(&again.seal(&sample(1, 302), 9, 500).unwrap(), |_| true).is_ok());
    }

    #[test]
    fn key_files_read_back_and_bad_ones_say_what_is_expected() {
        let k = Key::from_bytes([0xab; 16]);
        assert_eq!(Key::parse(&k.to_file()).unwrap(), k);
        assert_eq!(format!("{k:?}"), "Key(…)");
        for bad in [
            "",
            "simnet-key-v1 abc",
            "root:x:0:0",
            "simnet-key-v1 zz000000000000000000000000000000",
        ] {
            let e = Key::parse(bad).unwrap_err().to_string();
            assert!(!e.contains("root") && e.contains("simnet-key-v1"), "{bad}: {e}");
        }
    }
}
