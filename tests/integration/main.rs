//! simnet's integration tests, one binary (keeps builds lean). Fixed seeds throughout.

mod attacks;
mod attitude;
mod book_commands;
mod campaign;
mod cli;
mod common;
mod docs;
mod estimation;
mod estimators;
mod fusion;
mod golden;
mod layering;
mod loss;
mod network;
mod ns3;
mod outputs;
mod protocol;
mod radio;
mod reproduce;
mod riccati;
mod untrusted;
mod wire_attacks;
