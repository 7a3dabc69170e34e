//! `hw-bridge`: moves IMU/GNSS frames between a serial port and `nav-core`; records captures
//! and replays them bit-exactly. The wire codec itself lives in `nav-core::wire`.
#![deny(missing_docs)]

pub mod gnss;
