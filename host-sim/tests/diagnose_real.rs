//! `diagnose` on the real drive (`../shared/data/rtklibexplorer-drive0708`, consumer MEMS IMU +
//! RTK, `configs/drive0708.toml`) with 10 s outages every 60 s from 120 s: the withheld RTK
//! fixes are the reference. Checks: an IMU-GNSS time offset is found first, of the size of
//! the logging delay the data's source corrects (0.125 s, applied there to the IMU time; not
//! applied by our configuration), every added effect is finite, the outage error after is
//! below the error before, and the augmented configuration loads and runs with the IMU
//! effects via `--effects`.
use host_sim::diagnose::{diagnose, write_outputs, DiagnoseOptions};
use host_sim::run::cli::{execute, prepare, RunArgs};
use host_sim::run::parse_periodic;
use std::path::Path;

fn data_dir() -> Option<&'static Path> {
    let d = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../shared/data"));
    if d.exists() {
        return Some(d);
    }
    assert!(
        std::env::var("CI").as_deref() != Ok("true"),
        "../shared/data not found (CI=true: required)"
    );
    None
}

#[test]
fn real_drive_diagnosis_finds_the_logging_delay_and_lowers_the_outage_error() {
    if data_dir().is_none() {
        println!("SKIPPED real_drive_diagnosis: ../shared/data not found");
        return;
    }
    let config = concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/drive0708.toml");
    let mut a = RunArgs::new(config);
    a.periodic_outages = vec![parse_periodic("120:10:60").unwrap()];
    let p = prepare(&a).expect("loading the drive");
    let out = diagnose(&p, &DiagnoseOptions::default()).expect("diagnose");
    let d = &out.diagnosis;
    println!("{}", d.verdict);
    for e in &d.added_effects {
        println!("{} {:?} +- {:?} [{}]", e.name, e.estimate, e.sigma, e.unit);
    }
    let (b, af) = (
        d.error_before.outage_max_3d_rms_m,
        d.error_after.outage_max_3d_rms_m,
    );
    println!("outage error before {b:.3} m after {af:.3} m");
    assert_eq!(d.error_before.reference, "withheld_gnss");
    assert_eq!(d.error_before.outages, 7);
    let first = d.added_effects.first().expect("effects on the real drive");
    assert_eq!(first.name, "time_offset");
    // the source's logging delay is 0.125 s; ours is estimated with the datasheet noise
    assert!(
        (first.estimate[0] - 0.125).abs() < 0.1,
        "{:?}",
        first.estimate
    );
    for e in &d.added_effects {
        assert!(e.estimate.iter().chain(&e.sigma).all(|v| v.is_finite()));
    }
    assert!(af.is_finite() && af < b, "before {b} after {af}");

    // the augmented configuration alone: lever arm and time offset folded into [gnss], the
    // IMU effects in its `effects` key
    let dir = tempfile::tempdir().unwrap();
    write_outputs(dir.path(), &p, &out, Some(Path::new(config))).unwrap();
    let aug = host_sim::io::read_run_config(dir.path().join("augmented.toml"))
        .expect("augmented.toml is a valid run configuration");
    let imu_effects: Vec<String> = d
        .added_effects
        .iter()
        .map(|e| e.name.clone())
        .filter(|n| n != "lever_arm" && n != "time_offset")
        .collect();
    assert_eq!(aug.effects, imu_effects);
    let mut a2 = RunArgs::new(dir.path().join("augmented.toml"));
    a2.periodic_outages = a.periodic_outages.clone();
    let p2 = prepare(&a2).expect("the augmented configuration loads");
    assert_eq!(p2.opts.extra_blocks.len(), imu_effects.len());
    let (_, m2) = execute(&p2, &mut |_, _| {}).expect("and runs");
    let e2 = host_sim::diagnose::outage_error_m(&m2);
    println!("run with the augmented configuration: outage error {e2:.3} m");
    assert!(e2.is_finite() && e2 < b, "augmented {e2} vs before {b}");
}
