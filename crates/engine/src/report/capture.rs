//! `capture.csv`: every datagram the nodes sent and every copy the medium delivered, in order of time — the run's
//! capture ([`crate::medium::Capture`]), from which each datagram's fate reads off: a `sent` line and the
//! `delivered` lines with its number (none: lost; two to one receiver: duplicated), and `delivered` lines with no
//! number (a bit flipped on the way).

use std::fmt::Write as _;

use crate::link::Stream;
use crate::medium::{Captured, Event};
use crate::scenario::Scenario;

/// The file's columns.
pub const HEADER: &str = "t,event,from,to,datagram,bytes,stream";

/// The capture's lines as CSV text, nodes by their ids.
pub fn csv(lines: &[Captured], scenario: &Scenario) -> String {
    let id = |i: usize| scenario.nodes().get(i).map_or(i as u32, |n| n.id);
    let mut out = String::with_capacity(40 * (lines.len() + 1));
    out.push_str(HEADER);
    out.push('\n');
    for c in lines {
        let ns = c.at.as_nanos();
        // Whole nanoseconds, exactly.
        let _ = write!(out, "{}.{:09},", ns / 1_000_000_000, ns % 1_000_000_000);
        out.push_str(match c.event {
            Event::Sent => "sent,",
            Event::Delivered => "delivered,",
        });
        let _ = write!(out, "{},", id(c.from));
        if let Some(to) = c.to {
            let _ = write!(out, "{}", id(to));
        }
        out.push(',');
        if let Some(n) = c.datagram {
            let _ = write!(out, "{n}");
        }
        let _ = write!(out, ",{},", c.len);
        match c.stream {
            Some(Stream::Measurement) => out.push_str("measurement"),
            Some(Stream::Round(r)) => {
                let _ = write!(out, "round-{r}");
            }
            None => {}
        }
        out.push('\n');
    }
    out
}
