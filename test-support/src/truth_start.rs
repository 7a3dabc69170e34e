//! The initial uncertainty the run tests on simulated drives give the filter when it starts
//! from the simulation's exact truth (`nav_engine::run::InitSpec::exact_truth`): small, so
//! the start adds next to nothing to the errors the tests measure.

use nav_core::filter::InitialUncertainty;

/// 1-sigma of a start from a simulation's exact truth: attitude 0.1 mrad about the north and
/// east axes and 0.5 mrad about down, velocity 1 cm/s and position 2 cm on each NED axis.
pub const TRUTH_START_UNCERTAINTY: InitialUncertainty = InitialUncertainty {
    att_sigma_rad: [1e-4, 1e-4, 5e-4],
    vel_sigma_mps: [0.01; 3],
    pos_sigma_m: [0.02; 3],
};
