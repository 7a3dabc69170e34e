//! Careless and hostile use of `host-sim run`: option values and configuration numbers out of
//! their physical range are refused with a message naming the option and the range, quickly
//! and without growing memory; a run whose GNSS fixes were all unusable (each cause written
//! as a careless user or a broken logger would) is not reported as a navigation solution:
//! exit code 2 and a message naming the cause, and the summary says where every fix went.

use nav_core::earth::Llh;
use nav_core::types::GnssFix;
use proptest::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use test_support::cli::{run, Bin, Ran};
use test_support::runcase::TACTICAL_NOISE;
use test_support::{alloc, standing};

#[global_allocator]
static A: alloc::Counting = alloc::Counting;

const RATE_HZ: f64 = 200.0;
const SECONDS: f64 = 60.0;
const T0: f64 = 100_000.0;
const WEEK: u32 = 2300;

fn pos() -> Llh {
    Llh::from_deg(30.5, 114.3, 20.0)
}

fn host_sim() -> Bin {
    Bin::new(env!("CARGO_BIN_EXE_host-sim"))
}

/// A standing vehicle's IMU file (60 s at 200 Hz) in `dir`.
fn write_imu(dir: &Path) {
    let imu: Vec<_> = standing::imu(pos(), T0, RATE_HZ, (SECONDS * RATE_HZ) as usize).collect();
    nav_io::write_imu_text(dir.join("imu.txt"), &imu).unwrap();
}

/// 1 Hz fixes over the IMU data, changed by `f`.
fn fixes(f: impl Fn(&mut GnssFix)) -> Vec<GnssFix> {
    standing::fixes(pos(), T0, 1.0, SECONDS as usize - 1)
        .map(|mut g| {
            f(&mut g);
            g
        })
        .collect()
}

/// The run configuration: the IMU file, the GNSS file `gnss` of `format`, `gnss_extra` in
/// `[gnss]`, a given initial state.
fn config(dir: &Path, name: &str, gnss: &str, format: &str, gnss_extra: &str) -> PathBuf {
    let text = format!(
        r#"name = "{name}"

[imu]
path = "imu.txt"
format = "text"

[gnss]
path = "{gnss}"
format = "{format}"
{gnss_extra}

[init]
pos_std_m = [1.0, 1.0, 1.0]
vel_std_mps = [0.1, 0.1, 0.1]
att_std_deg = [0.1, 0.1, 1.0]

[init.given]
pos_deg_deg_m = [30.5, 114.3, 20.0]
vel_ned_mps = [0.0, 0.0, 0.0]
rpy_deg = [0.0, 0.0, 0.0]

{TACTICAL_NOISE}"#
    );
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, text).unwrap();
    p
}

fn run_config(cfg: &Path, out: &Path, extra: &[&str], bound: Duration) -> Ran {
    let t = Instant::now();
    let mut args = vec![
        "run".to_string(),
        "--config".into(),
        cfg.to_str().unwrap().into(),
        "--out".into(),
        out.to_str().unwrap().into(),
        "--quiet".into(),
    ];
    args.extend(extra.iter().map(|s| s.to_string()));
    let r = run(host_sim().command().args(&args));
    let el = t.elapsed();
    assert!(el < bound, "{extra:?} took {el:?} (bound {bound:?})");
    r
}

#[test]
fn option_values_out_of_range_are_refused_naming_the_option_and_the_range() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_imu(d);
    nav_io::write_gnss_text(d.join("gnss.txt"), &fixes(|_| {})).unwrap();
    let cfg = config(d, "ok", "gnss.txt", "text", "");
    let out = d.join("out");
    let ok = run_config(&cfg, &out, &[], Duration::from_secs(60));
    assert!(ok.ok, "{}\n{}", ok.stdout, ok.stderr);
    assert!(
        ok.stdout
            .contains("GNSS fixes: 59 in the data: 0 before the IMU data, 0 after it, 59 used"),
        "{}",
        ok.stdout
    );
    let nav_all = std::fs::read(out.join("nav.txt")).unwrap();
    // (option values, what the message names)
    let cases: &[(&[&str], &[&str])] = &[
        (
            &["--periodic-outage", "0:1e-5:1e-5"],
            &["--periodic-outage", "at least one IMU interval"],
        ),
        (
            &["--periodic-outage", "0:0.0051:0.0051"],
            &["--periodic-outage", "at most 10000 outages"],
        ),
        (&["--outage", "1e9:10"], &["--outage 1000000000:10", "[0, "]),
        (
            &["--outage", "10:1e-4"],
            &["--outage 10:0.0001", "IMU interval"],
        ),
        (&["--kf-gins-outages"], &["--kf-gins-outages", "[0, "]),
        (&["--nav-rate", "0"], &["--nav-rate 0", "(0, 200"]),
        (&["--nav-rate", "NaN"], &["--nav-rate NaN", "(0, 200"]),
        (&["--std-rate", "-1"], &["--std-rate -1", "(0, 200"]),
        (
            &["--imu-time-offset", "1e300"],
            &["--imu-time-offset", "[-60, 60] s"],
        ),
        (
            &["--noise-scale", "1e300"],
            &["--noise-scale", "[0.000001, 1000000]"],
        ),
        (
            &["--imu-max-gap", "1e300"],
            &["--imu-max-gap", "(0, 3600] s"],
        ),
    ];
    for (args, names) in cases {
        let r = run_config(&cfg, &d.join("bad"), args, Duration::from_secs(20));
        assert_eq!(
            r.status.code(),
            Some(1),
            "{args:?}: {}\n{}",
            r.stdout,
            r.stderr
        );
        for n in *names {
            assert!(r.stderr.contains(n), "{args:?}: no {n:?} in {}", r.stderr);
        }
    }
    // a rate above the IMU's is clamped to it, with a note: the output of every epoch, fast
    for rate in ["1e300", "1e8", "400"] {
        let o = d.join(format!("rate{rate}"));
        let r = run_config(&cfg, &o, &["--nav-rate", rate], Duration::from_secs(60));
        assert!(r.ok, "--nav-rate {rate}: {}", r.stderr);
        assert!(
            r.stderr.contains(&format!("--nav-rate {rate}")) && r.stderr.contains("clamped to it"),
            "{}",
            r.stderr
        );
        assert!(
            std::fs::read(o.join("nav.txt")).unwrap() == nav_all,
            "--nav-rate {rate}"
        );
    }
    // configuration numbers: the file, the line, the key and the range
    let bad_cfgs = [
        (
            "lever",
            "lever_arm_m = [1e300, 0.0, 0.0]",
            "line 10: gnss.lever_arm_m",
            "at most 100 m",
        ),
        (
            "toff",
            "time_offset_s = 1e300",
            "line 10: gnss.time_offset_s",
            "[-60, 60] s",
        ),
        (
            "leap",
            "[gnss.log]\nleap_seconds = -100000",
            "line 11: gnss.log.leap_seconds",
            "range [0, 18] s",
        ),
    ];
    for (name, extra, key, range) in bad_cfgs {
        let c = config(d, name, "gnss.txt", "text", extra);
        let r = run_config(&c, &d.join("badcfg"), &[], Duration::from_secs(20));
        assert_eq!(r.status.code(), Some(1), "{name}: {}", r.stderr);
        let file = format!("{name}.toml");
        for want in [file.as_str(), key, range] {
            assert!(
                r.stderr.contains(want),
                "{name}: no {want:?} in {}",
                r.stderr
            );
        }
    }
}

#[test]
fn unusable_gnss_is_not_a_navigation_solution_and_each_cause_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_imu(d);
    let text = |name: &str, fx: Vec<GnssFix>| {
        nav_io::write_gnss_text(d.join(format!("{name}.txt")), &fx).unwrap();
        config(d, name, &format!("{name}.txt"), "text", "")
    };
    let mut cases = vec![
        (
            text("sigma0", fixes(|g| g.pos_std_ned_m = [0.0; 3])),
            vec!["0 of 59", "59 fix(es) invalid", "standard deviation zero"],
        ),
        (
            text("before", fixes(|g| g.t_s -= 1000.0)),
            vec!["59 of 59 fix(es) are before the IMU data"],
        ),
        (
            text("after", fixes(|g| g.t_s += 1000.0)),
            vec!["59 of 59 fix(es) are after the IMU data"],
        ),
        (
            text("week", fixes(|g| g.t_s += 604_800.0)),
            vec!["one GPS week (+604800 s) after the IMU data"],
        ),
        (text("empty", Vec::new()), vec!["hold no fix"]),
    ];
    // an RTKLIB .pos whose records are all of quality 5 (single), with max_q = 1
    let mut p = String::from(
        "%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   \
         sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n",
    );
    for k in 1..SECONDS as usize {
        let _ = writeln!(
            p,
            "{WEEK} {:.3}   30.500000000  114.300000000    20.0000   5  12   0.5000   0.5000   \
             1.0000   0.0000   0.0000   0.0000   0.00    0.0",
            T0 + k as f64
        );
    }
    std::fs::write(d.join("q5.pos"), p).unwrap();
    cases.push((
        config(d, "q5", "q5.pos", "rtklib_pos", "max_q = 1"),
        vec!["every one of the 59 GNSS record(s) was filtered out by the quality filter"],
    ));
    for (cfg, wants) in &cases {
        let out = d.join("out");
        let r = run_config(cfg, &out, &[], Duration::from_secs(60));
        let name = cfg.file_name().unwrap().to_string_lossy();
        assert_eq!(
            r.status.code(),
            Some(2),
            "{name}: {}\n{}",
            r.stdout,
            r.stderr
        );
        assert!(
            r.stderr.contains("not a navigation solution"),
            "{name}: {}",
            r.stderr
        );
        for w in wants {
            assert!(r.stderr.contains(w), "{name}: no {w:?} in {}", r.stderr);
        }
        assert!(r.stdout.contains("GNSS fixes: "), "{name}: {}", r.stdout);
        // the outputs are written all the same
        assert!(out.join("nav.txt").exists(), "{name}");
    }
}

/// The library API on the short standing case with drawn option values: an error or a run,
/// both quickly and within a memory bound.
fn run_library(
    cfg: &Path,
    out: &Path,
    spec: &nav_engine::run::prepare::RunSpec,
) -> anyhow::Result<()> {
    let l = nav_engine::load(spec, true)?;
    let (o, _) = nav_engine::run::execute::execute_streaming(
        &l.prepared,
        l.imu_stream.as_ref(),
        l.truth_stream.as_ref(),
        out,
        &l.inputs,
        l.nav_rate_hz,
        &mut |_, _| {},
    )?;
    let _ = cfg;
    l.check_gnss_use(&o.counters)?;
    Ok(())
}

fn value() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(-1.0),
        Just(1e-300),
        Just(1e300),
        Just(1e-5),
        Just(1e8),
        0.0..100.0f64,
    ]
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: None, ..ProptestConfig::default() })]
    #[test]
        fn drawn_option_values_end_quickly_in_bounded_memory(
        first in value(), dur in value(), period in value(), start in value(),
        nav_rate in value(), std_rate in value(), offset in value(),
    ) {
        static CASE: std::sync::OnceLock<(tempfile::TempDir, PathBuf)> = std::sync::OnceLock::new();
        let (dir, cfg) = CASE.get_or_init(|| {
            let dir = tempfile::tempdir().unwrap();
            let d = dir.path();
            write_imu(d);
            nav_io::write_gnss_text(d.join("gnss.txt"), &fixes(|_| {})).unwrap();
            let cfg = config(d, "prop", "gnss.txt", "text", "");
            (dir, cfg)
        });
        let mut spec = nav_engine::run::prepare::RunSpec::new(cfg);
        spec.periodic_outages.push(nav_engine::run::PeriodicOutages {
            first_start_s: first,
            duration_s: dur,
            period_s: period,
        });
        spec.outages.push(nav_engine::run::Outage { start_s: start, duration_s: dur });
        spec.record.nav_rate_hz = Some(nav_rate);
        spec.record.epoch_rate_hz = Some(std_rate);
        spec.imu_time_offset_s = Some(offset);
        let base = alloc::reset_peak();
        let t = Instant::now();
        let res = run_library(cfg, &dir.path().join("out"), &spec);
        let el = t.elapsed();
        let grew = alloc::peak_bytes().saturating_sub(base);
        prop_assert!(el < Duration::from_secs(20), "{spec:?}: {el:?}");
        prop_assert!(grew < 64 << 20, "{spec:?}: {grew} bytes");
        if let Err(e) = res {
            let m = e.to_string();
            prop_assert!(
                ["--periodic-outage", "--outage", "--nav-rate", "--std-rate", "--imu-time-offset", "navigation solution"]
                    .iter()
                    .any(|o| m.contains(o)),
                "{m}"
            );
        }
    }
}
