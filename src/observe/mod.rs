//! What is measured about a run as it goes: per-filter error, NEES, trace P and LMI figures
//! ([`metrics::FilterMetrics`]) and per-source receive counters ([`metrics::RxCounters`]). Nodes record into them;
//! `report` turns them into the summary.

pub mod metrics;
