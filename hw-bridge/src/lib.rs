#![doc = include_str!("../README.md")]
//!
//! `hw-bridge`: moves IMU/GNSS frames between a serial port and `nav-core`; records captures
//! and replays them bit-exactly. The wire codec itself lives in `nav-core::wire`; the text
//! formats in `nav_io`.
#![deny(missing_docs)]

pub mod capture;
#[cfg(feature = "cli")]
pub mod cmd;
pub mod frames;
pub mod fuzz_checks;
/// The firmware's board-independent application (`firmware/src/app.rs`: wire frames in, the
/// f32 filter, solutions out), compiled for the host: `stream --host-filter` runs it on the
/// frames of the link, so the host shows what the board's own code computes from them.
#[cfg(feature = "cli")]
#[path = "../../firmware/src/app.rs"]
#[allow(dead_code, missing_docs)]
pub mod fwapp;
#[cfg(feature = "cli")]
pub mod outputs;
pub mod serial;
pub mod status;
/// The firmware's time-base trait (used by [`fwapp`]).
#[cfg(feature = "cli")]
#[path = "../../firmware/src/time.rs"]
#[allow(dead_code, missing_docs)]
pub mod time;
