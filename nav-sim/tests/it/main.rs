//! nav-sim's integration tests, one binary: one module per topic (the truth trajectory, the
//! sensor and GNSS errors).

mod sim_errors;
mod sim_trajectory;
