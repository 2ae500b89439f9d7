//! Datagram format: a postcard-encoded header and payload followed by a CRC-32 of everything before it.
//!
//! ```text
//! | header: magic u16 | version u8 | kind u8 | flags u8 | scheme u8 | src u32 | dst u32 | seq u32 |
//! |         pertains u64 ns | sent u64 ns |                                     (postcard varints)
//! | payload: rows u64 (bit i = row i present) | values: [f64] (one per present row)     |
//! |       or round u8 | body: a measurement, information pair(s), estimate, or bytes    |
//! |                           in a format the scheme owns                               |
//! | crc32 (4 bytes, little endian) of all bytes above                                   |
//! ```
//! The header says who sent a datagram to whom ([`BROADCAST`]: every node that hears it), its place in the
//! sender's sequence to that receiver (a gap is a datagram lost, not one never sent), the simulated time its
//! content pertains to (a measurement's sampling time; a round's step) and the time it was sent
//! ([`crate::time::Time`], nanoseconds since the run began), and, for a round's message, which scheme it belongs
//! to (its index in `simnet estimators`), so that the receiver hands the body to that scheme.
//! A [`Payload::Round`] carries one distributed estimator's message of one consensus round; matrices travel as
//! their upper triangle, row by row (they are symmetric), so that a 9-state hybrid message fits one datagram.
//! At most [`MAX_DATAGRAM`] bytes. `flags` bit 0 marks a sealed datagram ([`secure`]: AES-128-CCM, the header as
//! associated data, an epoch and counter after it, an 8-byte tag after the payload); other flags are rejected.
//! Decoding untrusted bytes never panics: every failure is a [`WireError`].
//!
//! ```
//! use simnet_core::time::Time;
//! use simnet_core::wire::{Datagram, Header, Payload};
//! let at = Time::from_secs(0.42);
//! let d = Datagram { header: Header::new(3, 5, 7, at), payload: Payload::measurement(0b11, vec![1.0, 2.0]) };
//! let bytes = d.encode().unwrap();
//! assert_eq!(Datagram::decode(&bytes).unwrap(), d);
//! assert_eq!((d.header.dst, d.header.pertains, d.header.sent), (5, at, at));
//! ```

use bytes::Bytes;
use serde::{Deserialize, Serialize};

use crate::time::Time;

mod frame;
pub mod secure;
pub mod sequence;
pub use frame::{Frame, FrameView, FrameWriter, Nack, MAX_FRAME};

/// The first two bytes of every datagram: "SN".
pub const MAGIC: u16 = 0x534E; // "SN"
/// The datagram format's version; a datagram of another version is refused.
pub const VERSION: u8 = 5;
/// Fits any MTU.
pub const MAX_DATAGRAM: usize = 1200;
/// Rows of one measurement (the `rows` bitmask is 64 bits wide).
pub const MAX_ROWS: usize = 64;
/// The CRC-32 that ends every datagram.
pub const CRC_LEN: usize = 4;

/// Why bytes are not a datagram (decoding untrusted bytes never panics).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WireError {
    /// Fewer bytes than the smallest datagram.
    #[error("datagram of {0} bytes is shorter than any valid datagram")]
    TooShort(usize),
    /// More than [`MAX_DATAGRAM`] bytes.
    #[error("datagram of {0} bytes exceeds the {MAX_DATAGRAM}-byte limit")]
    TooLong(usize),
    /// The CRC-32 does not match.
    #[error("checksum mismatch (corrupted datagram)")]
    Checksum,
    /// postcard could not read (or write) the header or the payload.
    #[error("malformed encoding: {0}")]
    Malformed(String),
    /// Bytes left over after the payload.
    #[error("{0} trailing bytes after the payload")]
    Trailing(usize),
    /// Not simnet's [`MAGIC`].
    #[error("bad magic {0:#06x}")]
    Magic(u16),
    /// A [`VERSION`] other than this one.
    #[error("unsupported version {0}")]
    Version(u8),
    /// Flags this decoder does not know (or a sealed datagram given to the unsealed decoder).
    #[error("reserved flags set: {0:#04x}")]
    Flags(u8),
    /// Well formed, but not a valid payload (row mask and values disagree, a non-finite value, …).
    #[error("invalid payload: {0}")]
    Invalid(&'static str),
}

/// The clear header every datagram starts with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    /// Always [`MAGIC`].
    pub magic: u16,
    /// Always [`VERSION`].
    pub version: u8,
    /// [`KIND_MEASUREMENT`], [`KIND_HELLO`] or [`KIND_ROUND`]: must match the payload.
    pub kind: u8,
    /// Bit 0: sealed ([`secure::SEALED`]); every other bit must be 0.
    pub flags: u8,
    /// A round's message: its scheme's index in `simnet estimators`; 0 for a measurement or a hello.
    pub scheme: u8,
    /// Sending node (its id in the topology).
    pub src: u32,
    /// Receiving node (its id in the topology), or [`BROADCAST`]. On the wire as `dst + 1`, wrapping: a broadcast
    /// takes one byte, as a small id does.
    #[serde(with = "dst_on_the_wire")]
    pub dst: u32,
    /// The sender's sequence number towards `dst` (a broadcast has a sequence of its own); duplicates share it.
    pub seq: u32,
    /// The simulated time the content pertains to: a measurement's sampling time, a round's step.
    pub pertains: Time,
    /// The simulated time the sender sent it.
    pub sent: Time,
}

/// `Header::dst` of a datagram for every node that hears it.
pub const BROADCAST: u32 = u32::MAX;

/// `dst + 1`, wrapping ([`BROADCAST`] is 0): the varint of a broadcast is one byte rather than five.
mod dst_on_the_wire {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(dst: &u32, s: S) -> Result<S::Ok, S::Error> {
        dst.wrapping_add(1).serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
        u32::deserialize(d).map(|v| v.wrapping_sub(1))
    }
}

impl Header {
    /// A measurement's header: from `src` to `dst`, number `seq` on that link, sampled and sent at `at`.
    pub fn new(src: u32, dst: u32, seq: u32, at: Time) -> Header {
        Header {
            magic: MAGIC,
            version: VERSION,
            kind: KIND_MEASUREMENT,
            flags: 0,
            scheme: 0,
            src,
            dst,
            seq,
            pertains: at,
            sent: at,
        }
    }

    /// The header of scheme `scheme`'s message of a round of the step at `step`, sent at `sent`.
    pub fn round(src: u32, dst: u32, seq: u32, scheme: u8, step: Time, sent: Time) -> Header {
        Header {
            kind: KIND_ROUND,
            scheme,
            sent,
            ..Header::new(src, dst, seq, step)
        }
    }

    /// A handshake hello's header (it pertains to no step: time 0), sent at `sent`.
    pub fn hello(src: u32, dst: u32, seq: u32, sent: Time) -> Header {
        Header {
            kind: KIND_HELLO,
            sent,
            ..Header::new(src, dst, seq, Time::ZERO)
        }
    }

    /// Whether node `id` is a receiver this datagram is meant for.
    pub fn is_for(&self, id: u32) -> bool {
        self.dst == id || self.dst == BROADCAST
    }
}

/// `Header::kind` of a [`Payload::Measurement`].
pub const KIND_MEASUREMENT: u8 = 1;
/// `Header::kind` of a [`Payload::Hello`].
pub const KIND_HELLO: u8 = 2;
/// `Header::kind` of a [`Payload::Round`].
pub const KIND_ROUND: u8 = 3;
/// Largest state a round's message may carry (a 16-state information pair is 1,216 bytes: too long anyway).
pub const MAX_STATES: usize = 15;

/// What a datagram carries after its header.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Payload {
    /// Some rows of one measurement vector: bit i of `rows` set means row i is present; `values` in row order.
    Measurement {
        /// Bit i set: row i is present.
        rows: u64,
        /// The present rows' values, in row order.
        values: Vec<f64>,
    },
    /// Start handshake of separate processes: "I am here", the step I am running, if any (the header pertains to
    /// time 0), the run I take part in (the smallest boot epoch heard: every node of one run ends on the same one),
    /// `boot`: this process's boot epoch, and `echo`: the boot epoch of the node the hello is sent to, as last heard
    /// from it (0: none yet). A hello that echoes a node's own boot was sealed after that boot began: nothing
    /// recorded in an earlier run carries it, so only such a hello may start or join a run. `probe`: a random
    /// challenge sent to an address the receiver's datagrams newly came from (0: none); `answer`: the last probe
    /// heard from the node the hello is sent to. A neighbour's address moves only to where a hello answering the
    /// probe sent there came from.
    Hello {
        /// The step the sender is running, if it has started.
        running: Option<u64>,
        /// The run the sender takes part in: the smallest boot epoch it has heard.
        run: u64,
        /// The sender's boot epoch.
        boot: u64,
        /// The receiver's boot epoch as last heard by the sender (0: none yet).
        echo: u64,
        /// A random challenge to a new address (0: none).
        probe: u64,
        /// The last probe heard from the receiver.
        answer: u64,
    },
    /// One estimator's message of consensus round `round` of the step `header.pertains`; `header.scheme` says
    /// which estimator's.
    Round {
        /// The consensus round, 0-based.
        round: u8,
        /// The scheme's message.
        body: Body,
    },
}

/// What a round's message carries: `n` is the state dimension, `sym` a symmetric n×n matrix's upper triangle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Body {
    /// Some rows of a measurement (the schemes that exchange measurements).
    Measurement {
        /// Bit i set: row i is present.
        rows: u64,
        /// The present rows' values, in row order.
        values: Vec<f64>,
    },
    /// (Y, y): an information matrix and vector.
    Information {
        /// State dimension.
        n: u8,
        /// Y's upper triangle, row by row.
        sym: Vec<f64>,
        /// y.
        vec: Vec<f64>,
    },
    /// The prior's and the measurement's information pairs.
    Hybrid {
        /// State dimension.
        n: u8,
        /// The prior's (Y, y), Y as its upper triangle.
        prior: (Vec<f64>, Vec<f64>),
        /// The measurement's (Y, y), likewise.
        measurement: (Vec<f64>, Vec<f64>),
    },
    /// (x, P).
    Estimate {
        /// State dimension.
        n: u8,
        /// The state estimate.
        x: Vec<f64>,
        /// P's upper triangle, row by row.
        sym: Vec<f64>,
    },
    /// Bytes in a format the scheme owns ([`crate::estimators::Message::Own`]): the wire checks only that there are
    /// some; the scheme decodes them, and a body it cannot read is its failed update.
    Own(Vec<u8>),
}

impl Body {
    fn validate(&self) -> Result<(), WireError> {
        let pair = |n: u8, sym: &[f64], vec: &[f64]| {
            let n = n as usize;
            if n == 0 || n > MAX_STATES {
                return Err(WireError::Invalid("state dimension out of range"));
            }
            if sym.len() != n * (n + 1) / 2 || vec.len() != n {
                return Err(WireError::Invalid(
                    "matrix or vector length does not match the state dimension",
                ));
            }
            if sym.iter().chain(vec).any(|v| !v.is_finite()) {
                return Err(WireError::Invalid("non-finite value"));
            }
            Ok(())
        };
        match self {
            Body::Measurement { rows, values } => check_measurement(*rows, values),
            Body::Information { n, sym, vec } => pair(*n, sym, vec),
            Body::Hybrid { n, prior, measurement } => {
                pair(*n, &prior.0, &prior.1)?;
                pair(*n, &measurement.0, &measurement.1)
            }
            Body::Estimate { n, x, sym } => pair(*n, sym, x),
            Body::Own(bytes) if bytes.is_empty() => Err(WireError::Invalid("a scheme's own body of no bytes")),
            Body::Own(_) => Ok(()),
        }
    }
}

fn check_measurement(rows: u64, values: &[f64]) -> Result<(), WireError> {
    if rows == 0 {
        return Err(WireError::Invalid("measurement with no rows"));
    }
    if rows.count_ones() as usize != values.len() {
        return Err(WireError::Invalid("row mask and value count disagree"));
    }
    if values.iter().any(|v| !v.is_finite()) {
        return Err(WireError::Invalid("non-finite value"));
    }
    Ok(())
}

impl Payload {
    /// Rows `rows` (bit i: row i) with their values in row order.
    pub fn measurement(rows: u64, values: Vec<f64>) -> Payload {
        Payload::Measurement { rows, values }
    }

    /// The `Header::kind` this payload travels under.
    pub fn kind(&self) -> u8 {
        match self {
            Payload::Measurement { .. } => KIND_MEASUREMENT,
            Payload::Hello { .. } => KIND_HELLO,
            Payload::Round { .. } => KIND_ROUND,
        }
    }
}

/// One datagram: a header and its payload.
#[derive(Debug, Clone, PartialEq)]
pub struct Datagram {
    /// The clear header.
    pub header: Header,
    /// What it carries.
    pub payload: Payload,
}

impl Datagram {
    /// The bytes on the wire, checksum included; an invalid payload or one over [`MAX_DATAGRAM`] is an error.
    pub fn encode(&self) -> Result<Bytes, WireError> {
        Datagram::encode_parts(&self.header, &self.payload)
    }

    /// [`Datagram::encode`] of `payload` under `header`, with no datagram made to hold them: one payload goes out
    /// under each receiver's header.
    pub fn encode_parts(header: &Header, payload: &Payload) -> Result<Bytes, WireError> {
        header.validate(0)?;
        validate_payload(header, payload)?;
        // Room for a typical datagram from the start: growing from empty costs a node-step several reallocations.
        let mut buf = postcard::to_extend(&(header, payload), Vec::with_capacity(128))
            .map_err(|e| WireError::Malformed(e.to_string()))?;
        let crc = crc32fast::hash(&buf);
        buf.extend_from_slice(&crc.to_le_bytes());
        if buf.len() > MAX_DATAGRAM {
            return Err(WireError::TooLong(buf.len()));
        }
        Ok(Bytes::from(buf))
    }

    /// The length [`Datagram::encode_parts`] gives `payload` under `header` (checksum included), counted without
    /// writing a byte: what a sender checks a message against before it chooses the receivers' headers.
    pub fn encoded_len(header: &Header, payload: &Payload) -> Result<usize, WireError> {
        let len = postcard::serialize_with_flavor(&(header, payload), postcard::ser_flavors::Size::default())
            .map_err(|e| WireError::Malformed(e.to_string()))?;
        Ok(len + CRC_LEN)
    }

    /// Checked decode of untrusted bytes (an unsealed datagram: a sealed one goes through [`secure::Opener`]).
    pub fn decode(bytes: &[u8]) -> Result<Datagram, WireError> {
        let body = checked_body(bytes)?;
        let ((header, payload), rest): ((Header, Payload), &[u8]) =
            postcard::take_from_bytes(body).map_err(|e| WireError::Malformed(e.to_string()))?;
        if !rest.is_empty() {
            return Err(WireError::Trailing(rest.len()));
        }
        let d = Datagram { header, payload };
        d.validate()?;
        Ok(d)
    }

    fn validate(&self) -> Result<(), WireError> {
        self.header.validate(0)?;
        validate_payload(&self.header, &self.payload)
    }
}

/// The payload is of the header's kind and within its limits, and the header's scheme and times fit it.
fn validate_payload(header: &Header, payload: &Payload) -> Result<(), WireError> {
    if header.kind != payload.kind() {
        return Err(WireError::Invalid("kind does not match the payload"));
    }
    if header.kind != KIND_ROUND && header.scheme != 0 {
        return Err(WireError::Invalid("a scheme named outside a round's message"));
    }
    if header.sent < header.pertains && header.kind != KIND_HELLO {
        return Err(WireError::Invalid("sent before the time it pertains to"));
    }
    match payload {
        Payload::Hello { .. } => {}
        Payload::Measurement { rows, values } => check_measurement(*rows, values)?,
        Payload::Round { body, .. } => body.validate()?,
    }
    Ok(())
}

impl Header {
    /// Magic, version, and `flags` as expected (0, or [`secure::SEALED`]).
    fn validate(&self, flags: u8) -> Result<(), WireError> {
        if self.magic != MAGIC {
            return Err(WireError::Magic(self.magic));
        }
        if self.version != VERSION {
            return Err(WireError::Version(self.version));
        }
        if self.flags != flags {
            return Err(WireError::Flags(self.flags));
        }
        Ok(())
    }
}

/// The bytes before the checksum, if the length is possible and the checksum holds.
/// The clear header of a datagram whose checksum holds, sealed or not, unauthenticated: what anyone who hears it
/// can read.
pub fn peek_header(bytes: &[u8]) -> Result<Header, WireError> {
    let body = checked_body(bytes)?;
    let (header, _): (Header, &[u8]) =
        postcard::take_from_bytes(body).map_err(|e| WireError::Malformed(e.to_string()))?;
    Ok(header)
}

fn checked_body(bytes: &[u8]) -> Result<&[u8], WireError> {
    if bytes.len() > MAX_DATAGRAM {
        return Err(WireError::TooLong(bytes.len()));
    }
    if bytes.len() < CRC_LEN + 8 {
        return Err(WireError::TooShort(bytes.len()));
    }
    let (body, crc) = bytes.split_at(bytes.len() - CRC_LEN);
    if crc32fast::hash(body) != u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]) {
        return Err(WireError::Checksum);
    }
    Ok(body)
}

#[cfg(test)]
pub(crate) mod tests;
