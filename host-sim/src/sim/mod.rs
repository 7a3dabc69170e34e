//! `host-sim simulate`: the command line over the `nav-sim` crate (scenarios, truth, sensor
//! and GNSS errors, case files) and the trajectory's overview plot.
pub mod cli;
pub mod plot;
