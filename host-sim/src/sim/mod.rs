//! Motion scenarios, truth and ideal IMU increments by inverse mechanization, sensor and GNSS
//! error generation, and `host-sim simulate`.
pub mod cli;
