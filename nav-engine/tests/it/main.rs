//! nav-engine's integration tests, one binary: one module per topic. They use the public API
//! only, so the filter's instantiations are compiled once, in the library. Simulated drives
//! come from `nav-sim`; the real drives are read in place from `../shared/data` (CI only).

mod aiding;
mod errors;
mod kfgins_parity;
mod live;
mod mounting_check;
mod mounting_estimate;
mod run_motion_align;
mod run_sim;
mod smooth_rts;
mod stops;
mod undeclared_effects;

use nav_engine::run::CaseData;

/// The measurements and truth of a simulated case, as the run engine takes them.
pub(crate) fn case_data(case: &nav_sim::Case) -> CaseData {
    CaseData {
        imu: case.meas.imu.clone(),
        gnss: case.meas.gnss.clone(),
        truth: Some(case.trajectory.truth.clone()),
        imu_origin: None,
    }
}
