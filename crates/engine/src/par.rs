//! Spread independent jobs over every core (scoped threads pulling the next index), results in input order.

use std::sync::atomic::{AtomicUsize, Ordering};

/// `f` applied to every item on `available_parallelism` threads; `tick` after each item (a progress bar).
pub fn map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync, tick: &(dyn Fn() + Sync)) -> Vec<R> {
    let workers = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items.len().max(1));
    let next = AtomicUsize::new(0);
    let parts: Vec<Vec<(usize, R)>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..workers)
            .map(|_| {
                s.spawn(|| {
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(item) = items.get(i) else { break };
                        mine.push((i, f(item)));
                        tick();
                    }
                    mine
                })
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)))
            .collect()
    });
    let mut out: Vec<(usize, R)> = parts.into_iter().flatten().collect();
    out.sort_by_key(|(i, _)| *i);
    out.into_iter().map(|(_, r)| r).collect()
}

#[cfg(test)]
mod tests {
    #[test]
    fn keeps_input_order_and_ticks_once_per_item() {
        let n = std::sync::atomic::AtomicUsize::new(0);
        let out = super::map(&(0..1000).collect::<Vec<u64>>(), |x| x * x, &|| {
            n.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        });
        assert_eq!(out, (0..1000).map(|x| x * x).collect::<Vec<u64>>());
        assert_eq!(n.into_inner(), 1000);
    }
}
