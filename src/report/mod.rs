//! Results: `summary.json`, the stdout table, `trace.csv`, `links.csv` and plots. Writers take `impl Write`.

pub mod parts;
pub mod plot;
pub mod summary;
pub mod trace;
