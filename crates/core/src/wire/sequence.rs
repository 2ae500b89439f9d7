//! What a receiver learns from one link's sequence numbers (a sender numbers the datagrams it sends to each receiver,
//! and its broadcasts, 0, 1, 2, …): how many it numbered that never came. A node that sends nothing numbers
//! nothing, so a gap is a datagram lost, never one not sent.
//!
//! ```
//! use simnet_core::wire::sequence::{Seen, Sequence};
//! let mut q = Sequence::default();
//! for seq in [0, 1, 3, 2] {
//!     assert_eq!(q.see(seq), Seen::First); // 2 came late: not a gap
//! }
//! assert_eq!((q.see(3), q.see(6)), (Seen::Again, Seen::First));
//! assert_eq!(q.missing(), 2); // 4 and 5
//! ```

/// How far behind the highest number a datagram may come and still be told from a duplicate.
pub const WINDOW: u64 = 64;

/// The numbers one receiver has seen on one link.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sequence {
    /// One past the highest number seen (0 before any), counted past the 32-bit wrap.
    next: u64,
    /// Bit i: number `next − 1 − i` has come.
    seen: u64,
    /// Distinct numbers that came in time to be told from duplicates.
    distinct: u64,
}

/// What one number turned out to be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seen {
    /// Its first arrival (late ones included, within [`WINDOW`] of the highest).
    First,
    /// It came before.
    Again,
    /// Over [`WINDOW`] behind the highest: counted missing, as it cannot be told from a duplicate.
    TooOld,
}

impl Sequence {
    /// The numbers from `first` on, `first` seen: those before it are not this receiver's to count (a sender's
    /// earlier boot numbered them, or this one's before the receiver could accept it), and one that comes later is
    /// taken for a duplicate.
    pub fn from_first(first: u32) -> Sequence {
        Sequence {
            next: u64::from(first) + 1,
            seen: u64::MAX,
            distinct: u64::from(first) + 1,
        }
    }

    /// Number `seq` arrived.
    pub fn see(&mut self, seq: u32) -> Seen {
        // The 32-bit number nearest the highest seen, read as a position in the whole sequence.
        let ahead = i64::from(seq.wrapping_sub(self.next as u32) as i32);
        let Some(s) = self.next.checked_add_signed(ahead) else {
            return Seen::TooOld;
        };
        if s >= self.next {
            let shift = s - self.next + 1;
            self.seen = if shift >= WINDOW { 0 } else { self.seen << shift };
            self.seen |= 1;
            self.next = s + 1;
        } else {
            let i = self.next - 1 - s;
            if i >= WINDOW {
                return Seen::TooOld;
            }
            if self.seen & (1 << i) != 0 {
                return Seen::Again;
            }
            self.seen |= 1 << i;
        }
        self.distinct += 1;
        Seen::First
    }

    /// Numbers up to the highest seen that have not come (or came too late to count).
    pub fn missing(&self) -> u64 {
        self.next - self.distinct
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Against a set of every number sent: a lossy, reordering, duplicating link (reordered by at most 20 places),
    /// across the 32-bit wrap.
    #[test]
    fn missing_is_what_was_numbered_and_never_came() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for start in [0u32, u32::MAX - 500] {
            let mut arrivals: Vec<(f64, u32)> = Vec::new();
            let mut delivered = std::collections::BTreeSet::new();
            for i in 0..5_000u32 {
                let seq = start.wrapping_add(i);
                if rng.gen::<f64>() < 0.2 {
                    continue;
                }
                delivered.insert(i);
                let at = f64::from(i) + rng.gen_range(0.0..20.0);
                arrivals.push((at, seq));
                if rng.gen::<f64>() < 0.1 {
                    arrivals.push((at + rng.gen_range(0.0..10.0), seq));
                }
            }
            arrivals.sort_by(|a, b| a.0.total_cmp(&b.0));
            // Numbered from `start` as if the link began there: the numbers before it are not this test's.
            let mut q = Sequence {
                next: u64::from(start),
                distinct: u64::from(start),
                ..Sequence::default()
            };
            let (mut first, mut again) = (0, 0);
            for (_, seq) in &arrivals {
                match q.see(*seq) {
                    Seen::First => first += 1,
                    Seen::Again => again += 1,
                    Seen::TooOld => panic!("reordered by under {WINDOW}"),
                }
            }
            let highest = delivered.iter().max().unwrap();
            assert_eq!(first, delivered.len());
            assert_eq!(again + first, arrivals.len());
            assert_eq!(
                q.missing(),
                u64::from(*highest) + 1 - delivered.len() as u64,
                "from {start}"
            );
        }
    }

    #[test]
    fn a_first_number_past_zero_counts_those_before_it_and_stragglers_past_the_window_stay_missing() {
        let mut q = Sequence::default();
        assert_eq!(q.missing(), 0);
        assert_eq!(q.see(3), Seen::First);
        assert_eq!(q.missing(), 3);
        assert_eq!((q.see(1), q.see(1)), (Seen::First, Seen::Again));
        assert_eq!(q.missing(), 2);
        assert_eq!(q.see(200), Seen::First);
        assert_eq!(q.see(0), Seen::TooOld);
        assert_eq!(q.missing(), 200 - 2);
        let mut q = Sequence::from_first(500);
        assert_eq!((q.missing(), q.see(500), q.see(499)), (0, Seen::Again, Seen::Again));
        assert_eq!((q.see(503), q.missing()), (Seen::First, 2));
    }
}
