#![doc = include_str!("../README.md")]
//!
//! `host-sim`: the host side of the navigation core, as a command line: `simulate` over the
//! `nav-sim` crate, `study` over `nav-study` (the source document's bias-model study), `run`
//! over the `nav-engine` crate's run engine and metrics, `allan` over `noise-id`, model
//! diagnosis, `mounting`, `init`, with their plots and reports. The data formats are read and
//! written by the `nav-io` crate.
//!
//! Every computation that also runs on the MCU lives in `nav-core`; this crate only drives it.
#![deny(missing_docs)]

pub mod allan;
pub mod cli_enum;
pub mod diagnose;
pub mod init;
pub mod mounting;
pub mod png;
pub mod run;
pub mod sim;
pub mod study;
