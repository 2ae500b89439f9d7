//! Running statistics of one filter, and the per-link figures, as written to `summary.json`.

use serde::{Deserialize, Serialize};

/// Accumulates a filter's figures step by step; means exclude the burn-in.
#[derive(Debug, Clone, Default)]
pub struct FilterMetrics {
    n: u64,
    /// Counted steps with a known truth (a recording without reference columns has none).
    n_error: u64,
    sum_error: f64,
    sum_sq_error: f64,
    sum_trace_prior: f64,
    sum_trace_post: f64,
    max_trace_post: f64,
    sum_nees: f64,
    n_nees: u64,
    feasible: u64,
    /// Steps, burn-in included, at which the LMI guard rejected the consensus update.
    infeasible: u64,
    pub final_error: Option<f64>,
    pub diverged: bool,
}

impl FilterMetrics {
    /// No step recorded.
    pub const EMPTY: FilterMetrics = FilterMetrics {
        n: 0,
        n_error: 0,
        sum_error: 0.0,
        sum_sq_error: 0.0,
        sum_trace_prior: 0.0,
        sum_trace_post: 0.0,
        max_trace_post: 0.0,
        sum_nees: 0.0,
        n_nees: 0,
        feasible: 0,
        infeasible: 0,
        final_error: None,
        diverged: false,
    };

    /// Record one step. `counted` is false during the burn-in (only divergence and the final error are tracked);
    /// `error` is `None` where the truth is unknown.
    pub fn record(
        &mut self,
        counted: bool,
        error: Option<f64>,
        trace_prior: f64,
        trace_post: f64,
        nees: Option<f64>,
        feasible: bool,
    ) {
        self.final_error = error;
        self.infeasible += !feasible as u64;
        if !(error.is_none_or(f64::is_finite) && trace_prior.is_finite() && trace_post.is_finite()) {
            self.diverged = true;
        }
        if !counted {
            return;
        }
        self.n += 1;
        if let Some(e) = error {
            self.n_error += 1;
            self.sum_error += e;
            self.sum_sq_error += e * e;
        }
        self.sum_trace_prior += trace_prior;
        self.sum_trace_post += trace_post;
        self.max_trace_post = self.max_trace_post.max(trace_post);
        if let Some(v) = nees {
            self.sum_nees += v;
            self.n_nees += 1;
        }
        self.feasible += feasible as u64;
    }

    pub fn mark_diverged(&mut self) {
        self.diverged = true;
    }

    pub fn summary(&self, with_lmi: bool) -> FilterSummary {
        let n = self.n as f64;
        let mean = |s: f64| if self.n > 0 { finite(s / n) } else { None };
        let mean_error = |s: f64| {
            if self.n_error > 0 {
                finite(s / self.n_error as f64)
            } else {
                None
            }
        };
        FilterSummary {
            mean_error: mean_error(self.sum_error),
            rms_error: mean_error(self.sum_sq_error).map(f64::sqrt),
            final_error: self.final_error.and_then(finite),
            mean_trace_p_prior: mean(self.sum_trace_prior),
            mean_trace_p_post: mean(self.sum_trace_post),
            max_trace_p_post: if self.n > 0 { finite(self.max_trace_post) } else { None },
            nees_mean: if self.n_nees > 0 {
                finite(self.sum_nees / self.n_nees as f64)
            } else {
                None
            },
            diverged: self.diverged,
            lmi_feasible_fraction: with_lmi.then(|| mean(self.feasible as f64)).flatten(),
            lmi_infeasible_steps: with_lmi.then_some(self.infeasible),
        }
    }
}

fn finite(v: f64) -> Option<f64> {
    v.is_finite().then_some(v)
}

/// Non-finite numbers become `null`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct FilterSummary {
    pub mean_error: Option<f64>,
    pub rms_error: Option<f64>,
    pub final_error: Option<f64>,
    pub mean_trace_p_prior: Option<f64>,
    pub mean_trace_p_post: Option<f64>,
    pub max_trace_p_post: Option<f64>,
    pub nees_mean: Option<f64>,
    pub diverged: bool,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub lmi_feasible_fraction: Option<f64>,
    /// Steps, burn-in included, at which (17) or (19) failed and the node fell back to its independent update.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub lmi_infeasible_steps: Option<u64>,
}

impl FilterSummary {
    /// The mean error as a comparison of runs counts it: infinite where divergence left no finite mean, `None`
    /// where no error was measured (a recorded IMU without reference columns).
    pub fn scored_error(&self) -> Option<f64> {
        self.mean_error.or(self.diverged.then_some(f64::INFINITY))
    }
}

/// What the receiving end of a link saw, per source.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct RxCounters {
    /// Datagrams accepted in time (duplicates excluded).
    pub delivered: u64,
    pub late: u64,
    pub duplicates: u64,
    /// Datagrams that failed the checksum.
    pub corrupted: u64,
    /// Datagrams that arrived while this node was down.
    pub while_down: u64,
    /// Steps this node closed without any measurement from this source (loss as the receiver sees it).
    pub missing_steps: u64,
    /// Steps this node closed with this source as a neighbour (the denominator of the arrival rate).
    #[serde(default)]
    pub steps: u64,
    /// Measurements left out of the networked update by the innovation gate.
    #[serde(default)]
    pub gated: u64,
    /// Datagrams the source numbered for this node (or broadcast) that never came intact, from the gaps in their
    /// sequence numbers: loss as the receiver alone can count it (a corrupted one is a gap too; one that comes
    /// over 64 datagrams late is counted in the gap and as late). A later boot of a sender's process is counted
    /// from its first datagram accepted.
    #[serde(default)]
    pub seq_gaps: u64,
}

/// Receive counters by source node index, held only for the sources heard from or expected (a node's memory grows
/// with its neighbours, not with the network).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RxBySource {
    /// Sorted by source.
    by: Vec<(usize, RxCounters)>,
}

impl RxBySource {
    /// Counters kept for these sources from the start (zero until something arrives).
    pub fn for_sources(sources: impl IntoIterator<Item = usize>) -> RxBySource {
        let mut by: Vec<(usize, RxCounters)> = sources.into_iter().map(|s| (s, RxCounters::default())).collect();
        by.sort_unstable_by_key(|(s, _)| *s);
        by.dedup_by_key(|(s, _)| *s);
        RxBySource { by }
    }

    /// The counters of `src` (zero if nothing came from it).
    pub fn get(&self, src: usize) -> RxCounters {
        self.by
            .binary_search_by_key(&src, |(s, _)| *s)
            .map_or_else(|_| RxCounters::default(), |i| self.by[i].1)
    }

    pub fn get_mut(&mut self, src: usize) -> &mut RxCounters {
        let i = match self.by.binary_search_by_key(&src, |(s, _)| *s) {
            Ok(i) => i,
            Err(i) => {
                self.by.insert(i, (src, RxCounters::default()));
                i
            }
        };
        &mut self.by[i].1
    }

    /// (source, counters), by source.
    pub fn iter(&self) -> impl Iterator<Item = (usize, &RxCounters)> {
        self.by.iter().map(|(s, c)| (*s, c))
    }
}
