//! The run engine's errors carry the nav-core error as their typed source.

use nav_core::config::{ConfigError, FilterConfig};
use nav_core::earth::Llh;
use nav_core::filter::{FilterError, InitialUncertainty};
use nav_core::imu_guard::GuardError;
use nav_core::types::ImuSample;
use nav_engine::run::{FaultCause, InitSpec, Model, STANDING_START_UNCERTAINTY};
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
    let unc = InitialUncertainty {
        att_sigma_rad: [0.01; 3],
        ..STANDING_START_UNCERTAINTY
    };
    RunOptions::new(Model::N, cfg, InitSpec::at_rest(100.0, pos, unc))
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

#[test]
fn a_fault_mid_run_carries_the_nav_core_error_as_its_typed_source() {
    // a 100 s hole in the IMU record: the guard refuses to bridge it and the run stops there
    let mut c = case();
    for s in c.imu.iter_mut().skip(50) {
        s.t_s += 100.0;
    }
    let o = opts(
        Llh::from_deg(30.0, 114.0, 20.0),
        FilterConfig::source_n_model(),
    );
    let e = run_filter(&c, &o).expect_err("a 100 s IMU gap must stop the run");
    let RunError::Fault { t_s, partial, .. } = &e else {
        panic!("expected RunError::Fault, got {e:?}");
    };
    assert_eq!(*t_s, c.imu[50].t_s);
    assert!(
        !partial.nav.is_empty(),
        "the samples before the gap are kept"
    );
    let src = e.source().expect("a source");
    let cause = src
        .downcast_ref::<FaultCause>()
        .expect("the source is the typed FaultCause");
    assert!(
        matches!(cause, FaultCause::Guard(GuardError::GapTooLong { .. })),
        "{cause:?}"
    );
    // the message says the guard's own words once, with where it happened
    assert!(e.to_string().contains(&cause.to_string()), "{e}");
}
