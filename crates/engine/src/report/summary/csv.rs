//! `links.csv`.

use super::*;
use std::io::{self, Write};

/// `links.csv`: the per-link counters.
pub fn write_links(w: &mut impl Write, links: &[LinkSummary]) -> io::Result<()> {
    use crate::report::trace::num;
    let opt = |v: Option<f64>| v.map_or(String::new(), num);
    writeln!(w, "from,to,sent,delivered,late,corrupted,lost,lost_random,lost_down,duplicated,loss_rate,arrival_rate,mean_loss_run,longest_loss_run")?;
    for l in links {
        writeln!(
            w,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            l.from,
            l.to,
            l.sent,
            l.delivered,
            l.late,
            l.corrupted,
            l.lost,
            l.lost_random,
            l.lost_down,
            l.duplicated,
            opt(l.loss_rate),
            opt(l.arrival_rate),
            num(l.mean_loss_run),
            l.longest_loss_run
        )?;
    }
    Ok(())
}
