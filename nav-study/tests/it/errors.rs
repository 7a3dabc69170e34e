//! A study that cannot run says why, with a typed error, before any filter runs.

use nav_sim::Scenario;
use nav_study::{run_study, NoProgress, StudyConfig, StudyError};

fn default_scenario() -> Scenario {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../scenarios/default.toml");
    Scenario::from_file(std::path::Path::new(path)).expect("default scenario")
}

#[test]
fn one_run_per_cell_is_refused() {
    let cfg = StudyConfig::new(default_scenario(), 1, 1);
    let e = run_study(&cfg, &NoProgress).unwrap_err();
    assert!(matches!(e, StudyError::TooFewRuns(1)), "{e:?}");
    assert_eq!(
        e.to_string(),
        "the study needs at least 2 runs per cell (got 1)"
    );
}

#[test]
fn an_outage_past_the_end_of_the_data_is_refused() {
    let mut cfg = StudyConfig::new(default_scenario(), 2, 1);
    cfg.outage_start_rel_s = 1.0e6;
    let e = run_study(&cfg, &NoProgress).unwrap_err();
    match e {
        StudyError::OutageBeyondData {
            start_s, data_s, ..
        } => {
            assert_eq!(start_s, 1.0e6);
            assert!(data_s > 0.0 && data_s < 1.0e6, "{data_s}");
        }
        e => panic!("{e:?}"),
    }
}

#[test]
fn variant_names_are_the_command_line_names() {
    use nav_study::setup::Variant;
    for (name, v) in [
        ("n", Variant::N),
        ("nbk", Variant::Nbk),
        ("nbk-single", Variant::NbkSingle),
        ("n-id-gyro", Variant::NIdGyro),
    ] {
        assert_eq!(name.parse::<Variant>().unwrap(), v);
        assert_eq!(v.to_string(), name);
    }
    assert!("kbn".parse::<Variant>().is_err());
}
