//! The real drive (`../shared/data/rtklibexplorer-drive0708`, consumer MEMS IMU + RTK) through
//! the run engine (`nav-engine`, what `host-sim run` runs) with `configs/drive0708.toml` and imposed GNSS outages: the withheld RTK
//! fixes are the reference. Checks: the solution stays on the road without outages, outage
//! errors are finite, and the filter beats free-inertial coasting from the same points.
use nav_engine::metrics::{Metrics, OutageSummary};
use nav_engine::run::{parse_periodic, FixUse, PeriodicOutages, RunOutput};
use nav_engine::RunSpec;

fn config() -> String {
    concat!(env!("CARGO_MANIFEST_DIR"), "/../configs/drive0708.toml").to_string()
}

fn run(periodic: Option<PeriodicOutages>) -> (RunOutput, Metrics) {
    let mut spec = RunSpec::new(config());
    spec.periodic_outages = periodic.into_iter().collect();
    let loaded =
        nav_engine::load(&spec, false).expect("loading the drive through configs/drive0708.toml");
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    nav_engine::execute(&loaded.prepared, &mut |_, _| {}).expect("running the filter on the drive")
}

fn print(name: &str, m: &Metrics) {
    println!("== {name}\n{}", nav_engine::metrics::summary_table(m));
}

fn raw_coasting(m: &Metrics) -> &nav_engine::metrics::CoastingMetrics {
    m.coasting
        .iter()
        .find(|c| c.mode.starts_with("raw"))
        .expect("raw coasting baseline")
}

fn check_outages(name: &str, out: &RunOutput, m: &Metrics, expected: usize) {
    print(name, m);
    assert_eq!(m.reference, "withheld_gnss");
    assert_eq!(out.outages.len(), expected, "{name}: outages");
    assert_eq!(m.per_outage.len(), expected, "{name}: outages evaluated");
    // every fix in an outage withheld, none used
    for r in &out.innovations {
        if out.outages.iter().any(|o| o.contains(r.t_s)) {
            assert_eq!(r.used, FixUse::Withheld, "{name}: {r:?}");
        }
    }
    for o in &m.per_outage {
        for v in [
            o.end.horizontal_m,
            o.end.height_m,
            o.max.horizontal_m,
            o.max.d3_m,
        ] {
            assert!(
                v.is_finite(),
                "{name}: outage {} not finite: {o:?}",
                o.index
            );
        }
    }
    // the filter against free-inertial coasting (no sensor-error correction) from the same
    // state at the same outage start: lower in every outage (3D maximum), and in the RMS of
    // the horizontal end error and of the height
    let raw = raw_coasting(m);
    assert_eq!(raw.outages.len(), expected);
    for (f, c) in m.per_outage.iter().zip(&raw.outages) {
        assert_eq!(f.index, c.index);
        assert!(
            f.max.d3_m < c.max.d3_m,
            "{name}: outage {}: filter max 3D {:.2} m vs coasting {:.2} m",
            f.index,
            f.max.d3_m,
            c.max.d3_m
        );
    }
    let (fs, cs): (&OutageSummary, &OutageSummary) = (&m.outage_summary, &raw.summary);
    assert!(fs.end_horizontal_m.rms < cs.end_horizontal_m.rms, "{name}");
    assert!(fs.end_height_m.rms < 0.5 * cs.end_height_m.rms, "{name}");
}

#[test]
fn real_drive_stays_on_the_road_and_beats_free_inertial_coasting_in_outages() {
    if test_support::real_data(
        "real_drive_stays_on_the_road_and_beats_free_inertial_coasting_in_outages",
    )
    .is_none()
    {
        return;
    }
    // no outage: the solution against the next RTK fix (0.25 s of prediction)
    let (out, m) = run(None);
    print("no outage", &m);
    assert!(out.counters.imu_epochs > 50_000);
    assert_eq!(out.counters.gnss_accepted as usize, out.innovations.len());
    let h = m.gnss_residuals.horizontal_m.rms;
    assert!(h < 0.5, "no-outage horizontal error vs RTK {h} m RMS");
    // 10 s and 30 s every 60 s after the first 2 minutes (548 s of data: 7 outages each)
    let (o10, m10) = run(Some(parse_periodic("120:10:60").unwrap()));
    check_outages("10 s every 60 s", &o10, &m10, 7);
    let (o30, m30) = run(Some(parse_periodic("120:30:60").unwrap()));
    check_outages("30 s every 60 s", &o30, &m30, 7);
    // errors grow with the outage length
    assert!(m30.outage_summary.end_horizontal_m.rms > m10.outage_summary.end_horizontal_m.rms);
    // the KF-GINS protocol: 60 s every 180 s (2 outages in 9 minutes)
    let (ok, mk) = run(Some(PeriodicOutages::KF_GINS));
    check_outages("KF-GINS protocol", &ok, &mk, 2);
}
