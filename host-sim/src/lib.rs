//! `host-sim`: the host side of the navigation core. Simulation of trajectories and sensors,
//! readers and writers for the data formats users have, Allan-variance noise identification,
//! the source document's bias-model study, model diagnosis, metrics, plots and reports.
//!
//! Every computation that also runs on the MCU lives in `nav-core`; this crate only drives it.
#![deny(missing_docs)]

pub mod allan;
pub mod diagnose;
pub mod io;
pub mod metrics;
pub mod noise;
pub mod run;
pub mod sim;
pub mod smooth;
pub mod study;
