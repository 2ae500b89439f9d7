//! Studies over whole runs, as a library: the covariance bounds of a linear model set against runs measured at
//! each arrival rate (`bounds.rs`). The β protocol search is [`crate::protocol`].

pub mod bounds;
