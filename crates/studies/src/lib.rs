//! simnet's studies (the crate `simnet-studies`): what is built on whole runs and on recordings rather than on one
//! step. Each takes its runs from the engine (`simnet-engine`) in memory, or from a runner the caller hands in (the
//! CLI's runs over UDP), so that this crate names no socket.
//!
//! | module | owns |
//! |---|---|
//! | [`analysis`] | Sinopoli's covariance bounds against runs measured at each arrival rate; attitude filters on a real recording against its own reference (noise, gates and magnetometer calibration read off the recording; the noise model checked against the reference) |
//! | [`protocol`] | β protocol search over whole in-memory runs: the paper's family by bisection on (17)/(19); all β by SDP (feature `sdp`) |
//! | [`reconstruct`] | position from a recorded IMU file as a boundary value problem (FEM), trapezoid for comparison, sensor-error model |
//! | [`reproduce`] | the source documents' experiments rerun: claims tables with simnet's figures, and plots |

pub mod analysis;
pub mod protocol;
pub mod reconstruct;
pub mod reproduce;
