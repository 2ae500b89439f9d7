//! The virtual clock's envelope: everything one node's link to one neighbour delivers in the window of one step, in
//! delivery order, as one UDP datagram. A frame with no datagram is the marker that says "nothing more from me in this
//! window", so a receiver closes a step once it has one frame per in-neighbour, with no driver in between (as
//! conservative parallel discrete-event simulation does with null messages). A window whose datagrams exceed
//! [`MAX_FRAME`] goes out in several parts. Each inner datagram keeps its own checksum: the link layer's corruption is
//! still caught datagram by datagram.
//!
//! ```text
//! | magic "SF" u16 | version u8 | window u64 | part u16 | parts u16 | count u16 |   (little endian)
//! | count × (len u16, datagram bytes) | crc32 of all bytes above |
//! ```

use bytes::{BufMut, Bytes};

use super::{WireError, MAX_DATAGRAM};

pub const FRAME_MAGIC: u16 = 0x4653; // "SF"
pub const FRAME_VERSION: u8 = 1;
/// Largest frame: well inside a loopback datagram, and a window rarely needs more than one.
pub const MAX_FRAME: usize = 16 * 1024;
const HEAD: usize = 2 + 1 + 8 + 2 + 2 + 2;
const CRC: usize = 4;

/// A frame read in place: its datagrams are slices of the received bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameView<'a> {
    /// The step whose window this is.
    pub window: u64,
    /// 0-based; a window's parts are `0..parts`.
    pub part: u16,
    /// How many parts the window went out in.
    pub parts: u16,
    count: u16,
    /// The datagrams with their length prefixes.
    body: &'a [u8],
}

impl<'a> FrameView<'a> {
    /// Checked parse of untrusted bytes; the inner datagrams are not decoded (the node does that).
    pub fn parse(bytes: &'a [u8]) -> Result<FrameView<'a>, WireError> {
        if bytes.len() > MAX_FRAME {
            return Err(WireError::TooLong(bytes.len()));
        }
        if bytes.len() < HEAD + CRC {
            return Err(WireError::TooShort(bytes.len()));
        }
        let (body, crc) = bytes.split_at(bytes.len() - CRC);
        if crc32fast::hash(body) != u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]) {
            return Err(WireError::Checksum);
        }
        let u16_at = |i: usize| u16::from_le_bytes([body[i], body[i + 1]]);
        let magic = u16_at(0);
        if magic != FRAME_MAGIC {
            return Err(WireError::Magic(magic));
        }
        if body[2] != FRAME_VERSION {
            return Err(WireError::Version(body[2]));
        }
        let mut w = [0u8; 8];
        w.copy_from_slice(&body[3..11]);
        let (window, part, parts, count) = (u64::from_le_bytes(w), u16_at(11), u16_at(13), u16_at(15));
        if part >= parts {
            return Err(WireError::Invalid("frame part out of range"));
        }
        let v = FrameView {
            window,
            part,
            parts,
            count,
            body: &body[HEAD..],
        };
        // Walk the datagrams once so that a view in hand is known to be whole.
        let mut at = 0;
        for _ in 0..count {
            if at + 2 > v.body.len() {
                return Err(WireError::Invalid("frame shorter than its count"));
            }
            let len = u16::from_le_bytes([v.body[at], v.body[at + 1]]) as usize;
            at += 2;
            if len > MAX_DATAGRAM || at + len > v.body.len() {
                return Err(WireError::Invalid("inner datagram overruns the frame"));
            }
            at += len;
        }
        if at != v.body.len() {
            return Err(WireError::Trailing(v.body.len() - at));
        }
        Ok(v)
    }

    /// The datagrams, in delivery order.
    pub fn datagrams(&self) -> impl Iterator<Item = &'a [u8]> + 'a {
        let body = self.body;
        let mut at = 0;
        (0..self.count).map(move |_| {
            let len = u16::from_le_bytes([body[at], body[at + 1]]) as usize;
            let d = &body[at + 2..at + 2 + len];
            at += 2 + len;
            d
        })
    }

    /// The frame with its datagrams copied out of the received bytes.
    pub fn to_owned(&self) -> Frame {
        Frame {
            window: self.window,
            part: self.part,
            parts: self.parts,
            datagrams: self.datagrams().map(Bytes::copy_from_slice).collect(),
        }
    }
}

/// Writes the frames of one window into a buffer it keeps, so that a sender allocates nothing per frame.
#[derive(Debug, Default)]
pub struct FrameWriter {
    buf: Vec<u8>,
    /// Each part's span in `buf`, checksum included.
    spans: Vec<(usize, usize)>,
}

impl FrameWriter {
    /// Write the frames of `window` carrying `datagrams` in order: as few parts as fit, at least one (the marker).
    /// Returns how many; [`FrameWriter::part`] gives each until the next call.
    pub fn pack<'d>(&mut self, window: u64, datagrams: impl IntoIterator<Item = &'d [u8]>) -> usize {
        self.buf.clear();
        self.spans.clear();
        let mut start = self.open(window);
        let mut count = 0u16;
        for d in datagrams {
            if self.buf.len() - start + 2 + d.len() + CRC > MAX_FRAME && count > 0 {
                self.close(start, count);
                start = self.open(window);
                count = 0;
            }
            self.push(d);
            count += 1;
        }
        self.close(start, count);
        let parts = self.spans.len() as u16;
        self.seal(|i| (i as u16, parts));
        self.spans.len()
    }

    /// Part `i` of the last [`FrameWriter::pack`].
    pub fn part(&self, i: usize) -> &[u8] {
        let (s, e) = self.spans[i];
        &self.buf[s..e]
    }

    fn open(&mut self, window: u64) -> usize {
        let start = self.buf.len();
        self.buf.put_u16_le(FRAME_MAGIC);
        self.buf.put_u8(FRAME_VERSION);
        self.buf.put_u64_le(window);
        // Part, parts and count are filled in once known.
        self.buf.put_bytes(0, 6);
        start
    }

    fn push(&mut self, d: &[u8]) {
        self.buf.put_u16_le(d.len() as u16);
        self.buf.put_slice(d);
    }

    fn close(&mut self, start: usize, count: u16) {
        self.buf[start + 15..start + 17].copy_from_slice(&count.to_le_bytes());
        self.buf.put_bytes(0, CRC);
        self.spans.push((start, self.buf.len()));
    }

    /// Write each part's (part, parts) as `numbering` gives them, then its checksum.
    fn seal(&mut self, numbering: impl Fn(usize) -> (u16, u16)) {
        for (i, &(s, e)) in self.spans.iter().enumerate() {
            let (part, parts) = numbering(i);
            self.buf[s + 11..s + 13].copy_from_slice(&part.to_le_bytes());
            self.buf[s + 13..s + 15].copy_from_slice(&parts.to_le_bytes());
            let crc = crc32fast::hash(&self.buf[s..e - CRC]);
            self.buf[e - CRC..e].copy_from_slice(&crc.to_le_bytes());
        }
    }
}

/// A receiver's request for the frames of one window it has not had from one sender (the kernel dropped them on a
/// full receive buffer), sent to the control socket of the sender's worker: the sender resends what it kept of that
/// window on that link. Nodes by index.
///
/// ```text
/// | magic "SK" u16 | version u8 | window u64 | from u32 (the receiver) | to u32 (the sender) | crc32 |   (little endian)
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Nack {
    /// The window whose frames are missing.
    pub window: u64,
    /// The receiver, which asks.
    pub from: u32,
    /// The sender, which resends.
    pub to: u32,
}

pub const NACK_MAGIC: u16 = 0x4B53; // "SK"
const NACK_LEN: usize = 2 + 1 + 8 + 4 + 4 + CRC;

impl Nack {
    /// The bytes on the wire.
    pub fn encode(&self) -> [u8; NACK_LEN] {
        let mut b = [0u8; NACK_LEN];
        b[..2].copy_from_slice(&NACK_MAGIC.to_le_bytes());
        b[2] = FRAME_VERSION;
        b[3..11].copy_from_slice(&self.window.to_le_bytes());
        b[11..15].copy_from_slice(&self.from.to_le_bytes());
        b[15..19].copy_from_slice(&self.to.to_le_bytes());
        let crc = crc32fast::hash(&b[..19]);
        b[19..].copy_from_slice(&crc.to_le_bytes());
        b
    }

    /// Checked parse of untrusted bytes: `None` unless they are exactly a NACK.
    pub fn parse(bytes: &[u8]) -> Option<Nack> {
        if bytes.len() != NACK_LEN || bytes[..2] != NACK_MAGIC.to_le_bytes() || bytes[2] != FRAME_VERSION {
            return None;
        }
        let word = |i: usize| u32::from_le_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
        if crc32fast::hash(&bytes[..19]) != word(19) {
            return None;
        }
        let mut w = [0u8; 8];
        w.copy_from_slice(&bytes[3..11]);
        Some(Nack {
            window: u64::from_le_bytes(w),
            from: word(11),
            to: word(15),
        })
    }
}

/// One part of one window's delivery on one link.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Frame {
    /// The step whose window this is.
    pub window: u64,
    /// 0-based; a window's parts are `0..parts`.
    pub part: u16,
    /// How many parts the window goes out in.
    pub parts: u16,
    /// The inner datagrams, in delivery order, each with its own checksum.
    pub datagrams: Vec<Bytes>,
}

impl Frame {
    /// The frames of one window: `datagrams` packed in order into as few parts as fit, at least one (the marker).
    pub fn pack(window: u64, datagrams: impl IntoIterator<Item = Bytes>) -> Vec<Bytes> {
        let datagrams: Vec<Bytes> = datagrams.into_iter().collect();
        let mut w = FrameWriter::default();
        let n = w.pack(window, datagrams.iter().map(|d| &d[..]));
        (0..n).map(|i| Bytes::copy_from_slice(w.part(i))).collect()
    }

    /// This part as it is, in one buffer (whatever its size or numbering: tests build bad frames with it).
    pub fn encode(&self) -> Bytes {
        let mut w = FrameWriter::default();
        let start = w.open(self.window);
        for d in &self.datagrams {
            w.push(d);
        }
        w.close(start, self.datagrams.len() as u16);
        w.seal(|_| (self.part, self.parts));
        Bytes::copy_from_slice(w.part(0))
    }

    /// Checked decode of untrusted bytes ([`FrameView::parse`]).
    pub fn decode(bytes: &[u8]) -> Result<Frame, WireError> {
        FrameView::parse(bytes).map(|v| v.to_owned())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A NACK round-trips, and any change to its bytes is refused.
    #[test]
    fn a_nack_round_trips_and_refuses_damage() {
        let n = Nack {
            window: 123_456_789,
            from: 7,
            to: u32::MAX,
        };
        let b = n.encode();
        assert_eq!(Nack::parse(&b), Some(n));
        for i in 0..b.len() {
            let mut d = b;
            d[i] ^= 1;
            assert_eq!(Nack::parse(&d), None, "byte {i}");
        }
        assert_eq!(Nack::parse(&b[..b.len() - 1]), None);
        assert!(FrameView::parse(&b).is_err(), "a NACK is not a frame");
    }

    #[test]
    fn frames_round_trip_split_and_reject_damage() {
        let d = |n: u8, len: usize| Bytes::from(vec![n; len]);
        // The marker: one empty part.
        let m = Frame::pack(7, []);
        assert_eq!(m.len(), 1);
        assert_eq!(
            Frame::decode(&m[0]).unwrap(),
            Frame {
                window: 7,
                part: 0,
                parts: 1,
                datagrams: vec![]
            }
        );
        // Forty 1000-byte datagrams do not fit one frame: parts in order, every datagram once.
        let many: Vec<Bytes> = (0..40).map(|i| d(i, 1000)).collect();
        let parts = Frame::pack(9, many.clone());
        assert!(parts.len() >= 3 && parts.iter().all(|p| p.len() <= MAX_FRAME));
        let back: Vec<Frame> = parts.iter().map(|p| Frame::decode(p).unwrap()).collect();
        assert!(back
            .iter()
            .enumerate()
            .all(|(i, f)| f.part as usize == i && f.parts as usize == parts.len()));
        assert_eq!(back.into_iter().flat_map(|f| f.datagrams).collect::<Vec<_>>(), many);
        // Every single bit flip of a small frame is caught; so are short, long and inconsistent frames.
        let one = Frame::pack(3, [d(1, 20), d(2, 30)]).remove(0);
        // Packed and encoded frames are the same bytes, and decode back to what went in.
        let f = Frame::decode(&one).unwrap();
        assert_eq!(
            (f.encode(), f.datagrams.clone()),
            (one.clone(), vec![d(1, 20), d(2, 30)])
        );
        let v = FrameView::parse(&one).unwrap();
        assert_eq!(v.datagrams().collect::<Vec<_>>(), vec![&[1u8; 20][..], &[2u8; 30][..]]);
        for bit in 0..one.len() * 8 {
            let mut b = one.to_vec();
            b[bit / 8] ^= 1 << (bit % 8);
            assert!(Frame::decode(&Bytes::from(b)).is_err(), "bit {bit} went undetected");
        }
        assert!(matches!(
            Frame::decode(&Bytes::from_static(b"SF")),
            Err(WireError::TooShort(2))
        ));
        assert!(matches!(
            Frame::decode(&Bytes::from(vec![0; MAX_FRAME + 1])),
            Err(WireError::TooLong(_))
        ));
        let lying = Frame {
            window: 1,
            part: 2,
            parts: 1,
            datagrams: vec![],
        }
        .encode();
        assert!(matches!(Frame::decode(&lying), Err(WireError::Invalid(_))));
    }
}
