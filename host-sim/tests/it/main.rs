//! The integration tests of `host-sim` in one test binary: one build and one link instead of one
//! per file. Tests with a counting global allocator (memory bounds) stay separate binaries
//! in `tests/`.

mod aiding;
mod aiding_inputs;
mod allan_adis16405;
mod allan_fit_recovery;
mod allan_params_run;
mod allan_stream_agrees;
mod diagnose_clock_gnss_step;
mod diagnose_gnss_noise;
mod diagnose_heldout;
mod diagnose_sim;
mod init;
mod kfgins_parity;
mod mounting_check;
mod mounting_estimate;
mod noise_allan_mc;
mod run_careless_inputs;
mod run_cli;
mod run_config_stream;
mod run_faults;
mod run_gnss_logs;
mod run_motion_align;
mod run_option_values;
mod run_outputs_safety;
mod run_sim;
mod run_slow_rover;
mod run_stream_equiv;
mod run_truth_stream;
mod sim_cli;
mod sim_errors;
mod sim_trajectory;
mod smooth_real;
mod smooth_rts;
mod smooth_sim;
mod stops;
mod undeclared_effects;
