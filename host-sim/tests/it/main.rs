//! The integration tests of `host-sim` in one test binary: one build and one link instead of one
//! per file. Tests with a counting global allocator (memory bounds) stay separate binaries
//! in `tests/`.

mod aiding_inputs;
mod allan_adis16405;
mod allan_params_run;
mod cli_helpers;
mod diagnose_clock_gnss_step;
mod diagnose_gnss_gm;
mod diagnose_gnss_noise;
mod diagnose_gyro_misalignment;
mod diagnose_gyro_step;
mod diagnose_heldout;
mod diagnose_sim;
mod init;
mod run_careless_inputs;
mod run_cli;
mod run_config_stream;
mod run_faults;
mod run_gnss_logs;
mod run_option_values;
mod run_outputs_safety;
mod run_slow_rover;
mod run_stream_equiv;
mod run_truth_stream;
mod sim_cli;
mod smooth_real;
mod smooth_sim;
