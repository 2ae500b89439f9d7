//! simnet's integration tests, one binary (keeps builds lean). Fixed seeds throughout.

mod attacks;
mod attitude;
mod campaign;
mod cli;
mod common;
mod estimation;
mod estimators;
mod fusion;
mod golden;
mod loss;
mod network;
mod outputs;
mod protocol;
mod reproduce;
mod riccati;
mod untrusted;
mod wire_attacks;
