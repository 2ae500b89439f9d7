//! Studies over whole runs, as a library: the covariance bounds of a linear model set against runs measured at
//! each arrival rate (`bounds.rs`); attitude filters on a recording scored against its own reference orientation
//! (`attitude.rs`). The β protocol search is [`crate::protocol`].

pub mod attitude;
pub mod bounds;
