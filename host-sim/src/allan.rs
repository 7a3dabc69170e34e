//! `host-sim allan`: the command-line front end and plots of the noise identification in the
//! `noise-id` crate (Allan-family deviations, confidence intervals, noise-model fit).
pub mod cli;
pub mod params;
pub mod plot;
