//! The live run (samples and fixes pushed one by one) against the streaming run of the same
//! case: the same files byte for byte, no deadlock, refusal after the run has ended.

use nav_core::earth::Llh;
use nav_core::filter::InitialUncertainty;
use nav_engine::run::live::QUEUE;
use nav_engine::run::output::OUTPUT_NAMES;
use nav_engine::run::{CaseData, InitSpec, Outage, RunOptions, STANDING_START_UNCERTAINTY};
use nav_engine::{execute_streaming, LiveRun, Prepared};
use std::path::Path;

const T0: f64 = 1000.0;

/// Two minutes of a standing vehicle at 100 Hz with 1 Hz fixes and a 30 s outage.
fn prepared() -> Prepared {
    let pos = Llh {
        lat_rad: 0.8,
        lon_rad: 0.3,
        h_m: 200.0,
    };
    let mut opts = RunOptions::standing_start(T0, pos);
    opts.init = InitSpec::at_rest(
        T0,
        pos,
        InitialUncertainty {
            att_sigma_rad: [0.01; 3],
            ..STANDING_START_UNCERTAINTY
        },
    );
    opts.outages = vec![Outage {
        start_s: T0 + 40.0,
        duration_s: 30.0,
    }];
    Prepared {
        case: CaseData {
            imu: test_support::standing::imu(pos, T0, 100.0, 12_000).collect(),
            gnss: test_support::standing::fixes(pos, T0, 1.0, 119).collect(),
            ..CaseData::default()
        },
        opts,
        week: 2300,
        description: String::new(),
    }
}

fn without_data(p: &Prepared) -> Prepared {
    let mut q = p.clone();
    q.case.imu.clear();
    q.case.gnss.clear();
    q
}

fn same_files(a: &Path, b: &Path) {
    for name in OUTPUT_NAMES {
        let fa = std::fs::read(a.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        let fb = std::fs::read(b.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(fa == fb, "{name} differs between the two runs");
    }
}

#[test]
fn a_live_run_fed_sample_by_sample_writes_the_files_of_the_streaming_run_byte_for_byte() {
    let p = prepared();
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    let (want, _) = execute_streaming(&p, None, None, &a, &[], None, &mut |_, _| {}).unwrap();
    // samples and fixes interleaved in time order, as a capture holds them
    let mut s = LiveRun::to_dir(without_data(&p), None, b.clone(), Vec::new(), None, false);
    let mut fixes = p.case.gnss.iter().peekable();
    for x in &p.case.imu {
        while let Some(f) = fixes.next_if(|f| f.t_s <= x.t_s) {
            s.push_fix(*f).unwrap();
        }
        s.push_imu(*x).unwrap();
    }
    for f in fixes {
        s.push_fix(*f).unwrap();
    }
    assert_eq!(s.imu_pushed(), p.case.imu.len());
    let (got, _) = s.finish().unwrap();
    assert_eq!(got.counters, want.counters);
    assert!(want.counters.gnss_withheld > 0 && want.counters.gnss_accepted > 0);
    same_files(&a, &b);
}

#[test]
fn a_live_run_given_every_sample_before_any_fix_still_completes_the_same_run() {
    // more samples than the queue holds before the first fix: the engine waits for a fix,
    // so the pushing side may go on (no deadlock), and the result is the same
    let p = prepared();
    assert!(p.case.imu.len() > QUEUE);
    let tmp = tempfile::tempdir().unwrap();
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    execute_streaming(&p, None, None, &a, &[], None, &mut |_, _| {}).unwrap();
    let mut s = LiveRun::to_dir(without_data(&p), None, b.clone(), Vec::new(), None, false);
    for x in &p.case.imu {
        s.push_imu(*x).unwrap();
    }
    for f in &p.case.gnss {
        s.push_fix(*f).unwrap();
    }
    s.finish().unwrap();
    same_files(&a, &b);
}

#[test]
fn a_live_run_refuses_pushes_once_its_run_has_ended_and_finish_says_why() {
    // an IMU time going backwards ends the run; the pushes after it are refused (the
    // pushing side is at most a queue ahead of the filter)
    let p = prepared();
    let tmp = tempfile::tempdir().unwrap();
    let mut s = LiveRun::to_dir(
        without_data(&p),
        None,
        tmp.path().join("o"),
        Vec::new(),
        None,
        false,
    );
    let mut refused = false;
    let mut fixes = p.case.gnss.iter().peekable();
    for (k, x) in p.case.imu.iter().enumerate() {
        let mut x = *x;
        if k == 500 {
            x.t_s -= 10.0;
        }
        while let Some(f) = fixes.next_if(|f| f.t_s <= x.t_s) {
            let _ = s.push_fix(*f);
        }
        if s.push_imu(x).is_err() {
            refused = true;
            break;
        }
    }
    assert!(refused, "the pushes after the end of the run are refused");
    let e = s.finish().unwrap_err();
    assert!(
        format!("{e:#}").contains("is not after the previous sample"),
        "the error names the sample: {e:#}"
    );
}
