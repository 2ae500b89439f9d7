//! What a message costs on an IEEE 802.15.4 channel: the frames it takes, each with its headers, and their time on
//! the air. A data frame with 16-bit short addresses and a compressed PAN id carries a 9-octet MAC header and a
//! 2-octet FCS (IEEE 802.15.4-2020 §7.2); a secured one adds the auxiliary security header (security control 1,
//! frame counter 4, key index 1 octet) and an 8-octet MIC (§9.4, MIC-64). A message larger than one frame's payload
//! is fragmented as 6LoWPAN does (RFC 4944 §5.3): a 4-octet header on the first fragment, 5 on each later one, every
//! fragment but the last carrying a multiple of 8 octets; the message is lost if any fragment is.
//!
//! ```
//! use simnet_core::medium::frame::{self, Security};
//!
//! // A 65-octet message fits one frame: 65 + 11 octets of MAC overhead, on the air (6 + 76) × 32 µs.
//! assert_eq!(frame::psdus(65, Security::None), vec![76]);
//! assert_eq!(frame::airtime(65, Security::None).as_micros(), 82 * 32);
//! // A 453-octet one takes five.
//! assert_eq!(frame::psdus(453, Security::None).len(), 5);
//! ```

use std::time::Duration;

use super::phy;

/// MAC header (frame control 2, sequence number 1, destination PAN 2, destination and source short addresses 2
/// each) and FCS (2), octets.
pub const MAC_OVERHEAD: u32 = 9 + 2;

/// The auxiliary security header (6) and a MIC-64 (8), octets.
pub const SECURITY_OVERHEAD: u32 = 6 + 8;

/// The first fragment's header, octets (RFC 4944 FRAG1).
pub const FIRST_FRAGMENT_HEADER: u32 = 4;

/// A later fragment's header, octets (RFC 4944 FRAGN).
pub const NEXT_FRAGMENT_HEADER: u32 = 5;

/// Whether frames carry 802.15.4 security.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Security {
    /// No auxiliary header, no MIC.
    None,
    /// The auxiliary security header and a MIC-64 on every frame.
    Mic64,
}

impl Security {
    /// The MAC's overhead per frame, octets.
    pub fn overhead(self) -> u32 {
        match self {
            Security::None => MAC_OVERHEAD,
            Security::Mic64 => MAC_OVERHEAD + SECURITY_OVERHEAD,
        }
    }

    /// The largest payload one frame carries, octets.
    pub fn max_payload(self) -> u32 {
        phy::MAX_PSDU_OCTETS - self.overhead()
    }
}

/// The PSDU length of each frame a message of `octets` octets takes, in order.
pub fn psdus(octets: u32, security: Security) -> Vec<u32> {
    let (overhead, max) = (security.overhead(), security.max_payload());
    if octets <= max {
        return vec![overhead + octets];
    }
    // Fragments but the last carry a multiple of 8 octets (the offset field counts 8-octet units).
    let first = (max - FIRST_FRAGMENT_HEADER) / 8 * 8;
    let next = (max - NEXT_FRAGMENT_HEADER) / 8 * 8;
    let mut out = vec![overhead + FIRST_FRAGMENT_HEADER + first];
    let mut left = octets - first;
    while left > 0 {
        let take = left.min(next);
        out.push(overhead + NEXT_FRAGMENT_HEADER + take);
        left -= take;
    }
    out
}

/// The message's time on the air: its frames' airtimes ([`phy::airtime`]), back to back.
pub fn airtime(octets: u32, security: Security) -> Duration {
    psdus(octets, security).into_iter().map(phy::airtime).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every frame within 127 octets; the payloads add up to the message; a message that fits takes one frame and
    /// one that does not takes ⌈(size − first) / next⌉ + 1, the fragments' capacities computed here by hand.
    #[test]
    fn a_message_takes_the_frames_its_size_needs() {
        for security in [Security::None, Security::Mic64] {
            let max = security.max_payload();
            assert_eq!(max, if security == Security::None { 116 } else { 102 });
            let first = (max - 4) / 8 * 8;
            let next = (max - 5) / 8 * 8;
            for octets in [0, 1, 33, 65, max, max + 1, 453, 887, 5000] {
                let frames = psdus(octets, security);
                assert!(
                    frames.iter().all(|&p| p <= phy::MAX_PSDU_OCTETS),
                    "{octets}: {frames:?}"
                );
                let want = if octets <= max {
                    1
                } else {
                    1 + (octets - first).div_ceil(next) as usize
                };
                assert_eq!(frames.len(), want, "{octets} octets, {security:?}: {frames:?}");
                let headers = match frames.len() {
                    1 => 0,
                    n => 4 + 5 * (n as u32 - 1),
                };
                let carried: u32 = frames.iter().map(|p| p - security.overhead()).sum::<u32>() - headers;
                assert_eq!(carried, octets);
            }
        }
        // Without security, a full frame's fragment offset stays a multiple of 8: 112 then 104 octets.
        assert_eq!(
            psdus(300, Security::None),
            vec![11 + 4 + 112, 11 + 5 + 104, 11 + 5 + 84]
        );
    }

    /// A message's airtime is the sum of (6 + PSDU) × 32 µs over its frames.
    #[test]
    fn airtime_is_the_frames_octets_at_32_us() {
        let frames = psdus(887, Security::Mic64);
        let octets: u32 = frames.iter().map(|p| p + 6).sum();
        assert_eq!(
            airtime(887, Security::Mic64),
            Duration::from_micros(32 * u64::from(octets))
        );
    }
}
