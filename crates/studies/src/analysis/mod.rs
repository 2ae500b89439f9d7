//! Studies over whole runs, as a library: the covariance bounds of a linear model set against runs measured at
//! each arrival rate (`bounds.rs`); attitude filters on a recording scored against its own reference orientation
//! (`attitude/`: `sensor.rs` what the recording tells of its sensor and the gates, `calibrate.rs` the magnetometer's
//! ellipsoid fit). The β protocol search is [`crate::protocol`].

pub mod attitude;
pub mod bounds;
