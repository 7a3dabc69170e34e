//! The run engine's errors carry the nav-core error as their typed source.

use nav_core::config::{ConfigError, FilterConfig};
use nav_core::earth::Llh;
use nav_core::filter::{FilterError, InitialUncertainty};
use nav_core::strapdown::NavState;
use nav_core::types::ImuSample;
use nav_engine::run::{InitSpec, Model};
use nav_engine::{run_filter, CaseData, RunError, RunOptions};
use std::error::Error;

fn case() -> CaseData {
    let imu = (1..=100)
        .map(|k| ImuSample {
            t_s: 100.0 + 0.01 * k as f64,
            dtheta_rad: [0.0; 3],
            dv_mps: [0.0, 0.0, -0.098],
            temperature_c: f64::NAN,
        })
        .collect();
    CaseData {
        imu,
        ..CaseData::default()
    }
}

fn opts(pos: Llh, cfg: FilterConfig) -> RunOptions {
    let init = NavState::from_rpy(100.0, pos, nalgebra::Vector3::zeros(), [0.0; 3]);
    let unc = InitialUncertainty {
        att_sigma_rad: [0.01; 3],
        vel_sigma_mps: [0.1; 3],
        pos_sigma_m: [1.0; 3],
    };
    RunOptions::new(Model::N, cfg, InitSpec::Given(init, unc))
}

#[test]
fn a_filter_error_is_the_typed_source_of_run_error_filter() {
    // a non-finite initial position: the filter refuses its construction
    let o = opts(
        Llh::from_deg(f64::NAN, 114.0, 20.0),
        FilterConfig::source_n_model(),
    );
    let e = run_filter(&case(), &o).expect_err("a NaN initial position must fail");
    assert!(
        matches!(e, RunError::Filter { .. }),
        "expected RunError::Filter, got {e:?}"
    );
    let src = e.source().expect("a source");
    assert_eq!(
        src.downcast_ref::<FilterError>(),
        Some(&FilterError::InitialState)
    );
    assert!(e.to_string().contains(&src.to_string()), "{e}");
}

#[test]
fn an_invalid_configuration_is_the_typed_source_of_run_error_filter_config() {
    let mut cfg = FilterConfig::source_n_model();
    cfg.accel.s_n = [-1.0; 3];
    let o = opts(Llh::from_deg(30.0, 114.0, 20.0), cfg);
    let e = run_filter(&case(), &o).expect_err("a negative PSD must fail");
    let src = e.source().expect("a source");
    assert!(
        src.downcast_ref::<ConfigError>().is_some(),
        "source of {e:?} is not a ConfigError"
    );
}
