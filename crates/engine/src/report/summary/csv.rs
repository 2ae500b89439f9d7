//! `links.csv`.

use super::*;
use std::io::{self, Write};

/// `links.csv`: the per-link counters; on a radio channel also each pair's frames, distance, RSSI, SINR, LQI and
/// PRR.
pub fn write_links(w: &mut impl Write, links: &[LinkSummary]) -> io::Result<()> {
    use crate::report::trace::num;
    let opt = |v: Option<f64>| v.map_or(String::new(), num);
    let radio = links.iter().any(|l| l.radio.is_some());
    write!(w, "from,to,sent,delivered,late,corrupted,lost,lost_random,lost_down,duplicated,loss_rate,arrival_rate,mean_loss_run,longest_loss_run")?;
    writeln!(
        w,
        "{}",
        if radio {
            ",frames,distance_m,rssi_dbm,sinr_db,lqi,prr"
        } else {
            ""
        }
    )?;
    for l in links {
        write!(
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
        match (&l.radio, radio) {
            (Some(r), _) => writeln!(
                w,
                ",{},{},{},{},{},{}",
                r.frames,
                opt(r.distance_m),
                opt(r.rssi_dbm),
                opt(r.sinr_db),
                opt(r.lqi),
                opt(r.prr)
            )?,
            (None, true) => writeln!(w, ",0,,,,,")?,
            (None, false) => writeln!(w)?,
        }
    }
    Ok(())
}
