//! `host-sim run`: the command line ([`cli`]) over the run engine, which lives in the
//! `nav-engine` crate and is re-exported here (`nav_engine::run::X` is `nav_engine::run::X`).

pub use nav_engine::run::*;

pub mod cli;
pub mod smoothed;

/// The measurements and truth of a simulated case, as the run engine takes them.
pub fn case_data(case: &nav_sim::Case) -> CaseData {
    CaseData {
        imu: case.meas.imu.clone(),
        gnss: case.meas.gnss.clone(),
        truth: Some(case.trajectory.truth.clone()),
        imu_origin: None,
    }
}
