#![doc = include_str!("../README.md")]
//!
//! `host-sim`: the host side of the navigation core. Simulation of trajectories and sensors,
//! the source document's bias-model study, model diagnosis, plots, reports and the command
//! line (`run` over the `nav-engine` crate's run engine and metrics, `allan` over the
//! `noise-id` crate). The data formats are read and written by the `nav-io` crate.
//!
//! Every computation that also runs on the MCU lives in `nav-core`; this crate only drives it.
#![deny(missing_docs)]

pub mod allan;
pub mod diagnose;
pub mod mounting;
pub mod noise;
pub mod run;
// The run engine's metrics and smoother live in `nav-engine`. These re-exports (and `run`'s
// `pub use nav_engine::run::*`) serve host-sim's own modules (`diagnose` and `study` name
// `crate::metrics`, `crate::smooth`, `crate::run::...`); tests and other crates name
// `nav_engine::...`, the crate that owns them.
pub use nav_engine::{metrics, smooth};
pub mod sim;
pub mod study;
