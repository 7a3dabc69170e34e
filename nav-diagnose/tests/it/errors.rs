//! The diagnosis's typed errors: the cause is the variant, its own error the source.
use nav_core::earth::Llh;
use nav_diagnose::{diagnose, DiagnoseError, DiagnoseOptions};
use nav_engine::run::{CaseData, RunError, RunOptions};

/// A standing vehicle's fixes and options, with the IMU samples `imu`.
fn prepared(imu: Vec<nav_core::types::ImuSample>) -> nav_engine::Prepared {
    let pos = Llh::from_deg(30.5, 114.3, 20.0);
    let t0 = 100_000.0;
    nav_engine::Prepared {
        case: CaseData {
            imu,
            gnss: test_support::standing::fixes(pos, t0, 1.0, 9).collect(),
            truth: None,
            imu_origin: None,
        },
        opts: RunOptions::standing_start(t0, pos),
        week: 2227,
        description: "standing vehicle".into(),
    }
}

#[test]
fn a_case_without_imu_samples_ends_the_diagnosis_with_the_run_engines_error() {
    let Err(e) = diagnose(&prepared(Vec::new()), &DiagnoseOptions::default()) else {
        panic!("a case without IMU samples must end the diagnosis with an error");
    };
    assert!(matches!(e, DiagnoseError::Run(RunError::NoImu)), "{e:?}");
    assert_eq!(e.to_string(), RunError::NoImu.to_string());
    let boxed: Box<dyn std::error::Error> = Box::new(e);
    assert!(
        boxed.source().is_none(),
        "the run engine's error has no cause of its own"
    );
}

#[test]
fn a_write_error_names_the_file_and_keeps_the_systems_error_as_its_source() {
    let source = std::io::Error::new(std::io::ErrorKind::PermissionDenied, "denied");
    let e = DiagnoseError::Write {
        path: "out/diagnosis.json".into(),
        source,
    };
    assert_eq!(e.to_string(), "writing out/diagnosis.json");
    let s = std::error::Error::source(&e).expect("the system's error as the source");
    assert_eq!(s.to_string(), "denied");
}
