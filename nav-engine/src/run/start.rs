//! Ready-made starts of a run: a vehicle standing level at a known place
//! ([`RunOptions::standing_start`], [`InitSpec::at_rest`]) and a start from the truth
//! without injected errors ([`InitSpec::exact_truth`]).

use super::{InitSpec, Model, RunOptions};
use nalgebra::Vector3;
use nav_core::config::FilterConfig;
use nav_core::earth::Llh;
use nav_core::filter::InitialUncertainty;
use nav_core::strapdown::NavState;

/// The initial 1-sigma of a standing start ([`RunOptions::standing_start`]): attitude 1 mrad
/// about the north and east axes (level) and 10 mrad about down (heading), velocity 0.1 m/s
/// and position 1 m on each NED axis.
pub const STANDING_START_UNCERTAINTY: InitialUncertainty = InitialUncertainty {
    att_sigma_rad: [1e-3, 1e-3, 1e-2],
    vel_sigma_mps: [0.1; 3],
    pos_sigma_m: [1.0; 3],
};

impl InitSpec {
    /// The truth at the first truth epoch (at or after the start time) without injected
    /// errors, the filter told the 1-sigma `unc`.
    pub fn exact_truth(unc: InitialUncertainty) -> Self {
        Self::FromTruth {
            pos_err_m: [0.0; 3],
            vel_err_mps: [0.0; 3],
            att_err_rad: [0.0; 3],
            unc,
        }
    }

    /// A vehicle at rest at `pos`, level, its body x axis pointing north (body axes = NED),
    /// at `t0_s` (GPS seconds of week, the initial epoch), the filter told the 1-sigma `unc`
    /// ([`STANDING_START_UNCERTAINTY`] for a standing start).
    pub fn at_rest(t0_s: f64, pos: Llh, unc: InitialUncertainty) -> Self {
        Self::Given(
            NavState::from_rpy(t0_s, pos, Vector3::zeros(), [0.0; 3]),
            unc,
        )
    }
}

impl RunOptions {
    /// A run of a vehicle standing still at `pos` from `t0_s` (GPS seconds of week): the
    /// source's classical model [`Model::N`] with its noise
    /// ([`FilterConfig::source_n_model`]), started at rest there ([`InitSpec::at_rest`] with [`STANDING_START_UNCERTAINTY`]); the rest as
    /// [`RunOptions::new`] (f64, no outages, default recording).
    pub fn standing_start(t0_s: f64, pos: Llh) -> Self {
        Self::new(
            Model::N,
            FilterConfig::source_n_model(),
            InitSpec::at_rest(t0_s, pos, STANDING_START_UNCERTAINTY),
        )
    }
}
