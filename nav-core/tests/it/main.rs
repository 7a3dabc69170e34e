//! The integration tests of `nav-core` in one test binary: one build and one link instead of one
//! per file. Tests with a counting global allocator (memory bounds) stay separate binaries
//! in `tests/`.

mod align;
mod allan_stream;
mod cov_predict_sparse;
mod effects_clock_gnss;
mod effects_combined;
mod effects_error_model;
mod effects_f32;
mod effects_gnss;
mod effects_sensor;
mod effects_temperature;
mod filter_consistency;
mod filter_error_model;
mod filter_f32_vs_f64;
mod filter_observe;
mod filter_updates;
mod gnss_velocity_gate;
mod imu_gaps;
mod mechanization;
mod navigator;
mod odometer;
mod robust_gating;
mod understated_sigmas;
mod wire_common;
mod wire_faults;
mod wire_roundtrip;
mod wire_stream;
