//! `hw-bridge`: moves IMU/GNSS frames between a serial port and `nav-core`; records captures
//! and replays them bit-exactly. The wire codec itself lives in `nav-core::wire`; the text
//! formats in `nav_io`.
#![deny(missing_docs)]

pub mod capture;
#[cfg(feature = "cli")]
pub mod cmd;
pub mod frames;
pub mod fuzz_checks;
pub mod gnss;
#[cfg(feature = "cli")]
pub mod outputs;
pub mod serial;
pub mod status;
