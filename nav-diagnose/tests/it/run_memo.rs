//! The diagnosis's runs asked for again are answered from its memo of the last runs: the
//! answer is the run's own records bit for bit whatever the navigation recording rate asked
//! (the filter does not depend on it), and a run on other data (the IMU samples adjusted: a
//! bias step removed) is not answered by the run on the recorded samples.

use std::sync::Arc;

use nav_core::earth::Llh;
use nav_diagnose::changepoint::BiasStepSensor;
use nav_diagnose::imu_cache::{Adjust, Case, ImuCache};
use nav_diagnose::spill::{run_innovations, temp_folder};
use nav_engine::run::{CaseData, ImuSourceInfo, InnovationRecord, Outage, RunOptions};
use test_support::standing;

const T0: f64 = 100_000.0;

fn bits(r: &[InnovationRecord]) -> Vec<u64> {
    r.iter()
        .flat_map(|x| {
            [x.t_s, x.nis]
                .into_iter()
                .chain(x.innovation)
                .chain(x.innovation_var)
                .map(f64::to_bits)
        })
        .collect()
}

/// Two minutes of a standing vehicle at 100 Hz with 1 Hz fixes (a 10 s outage withheld), its
/// IMU record in a file, and the case's data and options.
fn setup() -> (Arc<ImuCache>, CaseData, RunOptions) {
    let pos = Llh::from_deg(30.5, 114.3, 20.0);
    let folder = temp_folder().unwrap();
    let samples = standing::imu(pos, T0, 100.0, 12_000).map(|s| Ok((s, 0)));
    let cache = ImuCache::write(&folder, samples, ImuSourceInfo::default()).unwrap();
    let data = CaseData {
        imu: Vec::new(),
        gnss: standing::fixes(pos, T0, 1.0, 119).collect(),
        truth: None,
        imu_origin: None,
    };
    let mut opts = RunOptions::standing_start(T0, pos);
    opts.outages.push(Outage {
        start_s: T0 + 60.0,
        duration_s: 10.0,
    });
    (Arc::new(cache), data, opts)
}

#[test]
fn a_run_asked_again_is_its_own_records_at_any_navigation_rate_and_only_on_the_same_data() {
    let (cache, data, opts) = setup();
    let at = |rate: Option<f64>| {
        let mut o = opts.clone();
        o.record.nav_rate_hz = rate;
        o
    };
    let case = Case::new(data.clone(), cache.clone());
    let first = run_innovations(&case, &at(Some(25.0))).unwrap();
    assert!(first.innovations.len() > 100, "{}", first.innovations.len());
    // asked again at another rate: the memo's answer; a new case (no memo): a new run
    let again = run_innovations(&case, &at(None)).unwrap();
    let fresh = run_innovations(&Case::new(data.clone(), cache.clone()), &at(None)).unwrap();
    assert_eq!(bits(&again.innovations), bits(&first.innovations));
    assert_eq!(bits(&fresh.innovations), bits(&first.innovations));
    assert_eq!(again.final_blocks.len(), fresh.final_blocks.len());
    assert!(again.nav.is_empty() && fresh.nav.is_empty());
    // the same model on the samples with an accelerometer bias step removed: its own run
    let stepped = Adjust {
        bias_step: Some((BiasStepSensor::Accel, T0 + 30.0, [0.02, -0.01, 0.0])),
        time_shift_s: 0.0,
    };
    let on_step = run_innovations(&case.adjusted(stepped), &at(None)).unwrap();
    let on_step_fresh =
        run_innovations(&Case::new(data, cache).adjusted(stepped), &at(Some(25.0))).unwrap();
    assert_ne!(bits(&on_step.innovations), bits(&first.innovations));
    assert_eq!(bits(&on_step.innovations), bits(&on_step_fresh.innovations));
}
