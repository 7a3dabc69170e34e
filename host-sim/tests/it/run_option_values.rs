//! `host-sim run` (the binary) with option values and configuration numbers drawn by
//! proptest from wide ranges and careless spellings: outages, periodic outages, nav and std
//! rates, IMU time offsets, noise scales, GNSS lever arms and time offsets; values 0, tiny,
//! huge, negative, NaN, infinite, empty or not a number at all. Every run, on a 20 s standing
//! case, ends within a bounded time and peak memory (its own resident set, `wait4`), exits
//! 0, 1 (an error naming the option or the configuration key) or 2 (not a navigation
//! solution, named; or a value the command-line parser refused, naming the option), and
//! never panics.
//!
//! A few cases in the normal suite (each run is a fraction of a second);
//! `HOST_SIM_OPTION_CASES=N` draws N.
use nav_core::earth::Llh;
use proptest::prelude::*;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;
use test_support::cli::run_bounded;
use test_support::runcase::TACTICAL_NOISE;
use test_support::standing;

const HOST_SIM: &str = env!("CARGO_BIN_EXE_host-sim");
/// A run longer than this is a hang.
const WALL_LIMIT: Duration = Duration::from_secs(60);
/// CPU time bound of one run, s (a run of this case takes well under a second).
const CPU_BOUND_S: f64 = 10.0;
/// Peak resident set bound of one run, KiB.
const RSS_BOUND_KIB: u64 = 256 * 1024;

/// The 20 s standing case (200 Hz IMU, 1 Hz fixes): its folder.
fn case() -> &'static Path {
    static CASE: OnceLock<tempfile::TempDir> = OnceLock::new();
    CASE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let pos = Llh::from_deg(30.5, 114.3, 20.0);
        let imu: Vec<_> = standing::imu(pos, 100_000.0, 200.0, 4000).collect();
        nav_io::write_imu_text(dir.path().join("imu.txt"), &imu).unwrap();
        let fixes: Vec<_> = standing::fixes(pos, 100_000.0, 1.0, 19).collect();
        nav_io::write_gnss_text(dir.path().join("gnss.txt"), &fixes).unwrap();
        dir
    })
    .path()
}

/// A run configuration over the case with `[gnss]` lever arm and time offset as written.
fn config(dir: &Path, lever: &[String; 3], toff: &str) -> PathBuf {
    let c = case();
    let text = format!(
        "name = \"drawn\"\n[imu]\npath = \"{}\"\nformat = \"text\"\n[gnss]\npath = \"{}\"\n\
         format = \"text\"\nlever_arm_m = [{}, {}, {}]\ntime_offset_s = {toff}\n[init]\n\
         pos_std_m = [1.0, 1.0, 1.0]\nvel_std_mps = [0.1, 0.1, 0.1]\n\
         att_std_deg = [0.1, 0.1, 1.0]\n[init.given]\npos_deg_deg_m = [30.5, 114.3, 20.0]\n\
         vel_ned_mps = [0.0, 0.0, 0.0]\nrpy_deg = [0.0, 0.0, 0.0]\n{TACTICAL_NOISE}",
        c.join("imu.txt").display(),
        c.join("gnss.txt").display(),
        lever[0],
        lever[1],
        lever[2]
    );
    let p = dir.join("run.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// `--imu-time-offset` with a given initial state (timed at the first IMU sample): the state
/// moves with the IMU times, and the run goes to the end, its first solution at the first
/// shifted sample.
#[test]
fn an_imu_time_offset_moves_a_given_initial_state_with_the_samples() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = config(
        dir.path(),
        &["0.0".into(), "0.0".into(), "0.0".into()],
        "0.0",
    );
    for offset in ["12.5", "-0.5"] {
        let out = dir.path().join(format!("out{offset}"));
        let mut cmd = std::process::Command::new(HOST_SIM);
        cmd.args(["run", "--quiet", "--config"])
            .arg(&cfg)
            .arg("--out")
            .arg(&out);
        cmd.arg(format!("--imu-time-offset={offset}"));
        let r = run_bounded(&mut cmd, WALL_LIMIT);
        assert_eq!(r.code(), Some(0), "{offset}: {}", r.stderr);
        let nav = std::fs::read_to_string(out.join("nav.txt")).unwrap();
        let t: f64 = nav
            .lines()
            .next()
            .unwrap()
            .split_whitespace()
            .nth(1)
            .unwrap()
            .parse()
            .unwrap();
        let want = 100_000.005 + offset.parse::<f64>().unwrap();
        assert!(
            (t - want).abs() < 1e-6,
            "{offset}: first solution at {t}, not {want}"
        );
    }
}

/// `host-sim run` on the standing case with `extra` options (into `dir/out`).
fn run_standing(dir: &Path, extra: &[&str]) -> test_support::cli::Bounded {
    let zero = || "0.0".to_string();
    let cfg = config(dir, &[zero(), zero(), zero()], "0.0");
    let mut cmd = std::process::Command::new(HOST_SIM);
    cmd.args(["run", "--quiet", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(dir.join("out"))
        .args(extra);
    run_bounded(&mut cmd, WALL_LIMIT)
}

/// An outage beyond the data is refused with the times as a user reads them (no binary
/// rounding digits) and the span of the data.
#[test]
fn an_outage_beyond_the_data_is_told_with_the_data_span() {
    let dir = tempfile::tempdir().unwrap();
    for given in ["99999:10", "99999.1:0.3"] {
        let r = run_standing(dir.path(), &[&format!("--outage={given}")]);
        assert_eq!(r.code(), Some(1), "{given}: {}", r.stderr);
        // 4000 samples at 200 Hz from t = 100000.005 s: 19.995 s
        let want = format!(
            "--outage {given}: START is at or beyond the end of the data: the data span \
             19.995 s (IMU time 100000.005 to 100020.000 s), so START must be in [0, 19.995) s"
        );
        assert!(r.stderr.contains(&want), "{given}: {}", r.stderr);
    }
    let r = run_standing(dir.path(), &["--outage=5:0.001"]);
    assert_eq!(r.code(), Some(1), "{}", r.stderr);
    assert!(
        r.stderr.contains(
            "--outage 5:0.001: DURATION must be finite and at least one IMU interval, 5.000 ms"
        ),
        "{}",
        r.stderr
    );
    let r = run_standing(dir.path(), &["--periodic-outage=30:5:10"]);
    assert_eq!(r.code(), Some(1), "{}", r.stderr);
    assert!(
        r.stderr.contains(
            "--periodic-outage 30:5:10: FIRST must be in [0, 19.995) s (the data span 19.995 s"
        ),
        "{}",
        r.stderr
    );
}

/// `--gate off` is said once in the run's summary.
#[test]
fn gate_off_is_said_once_in_the_summary() {
    let dir = tempfile::tempdir().unwrap();
    let r = run_standing(dir.path(), &["--gate=off"]);
    assert_eq!(r.code(), Some(0), "{}", r.stderr);
    assert!(
        r.stdout.contains("gate (off): every valid fix used\n"),
        "{}",
        r.stdout
    );
    assert_eq!(r.stdout.matches("gate off").count(), 0, "{}", r.stdout);
}

/// A number as a user may type it on the command line: odd spellings and extremes, and
/// plausible values (drawn more often: runs that go to the end).
fn cli_number() -> impl Strategy<Value = String> {
    let odd = prop::sample::select(vec![
        "0", "-0", "NaN", "nan", "inf", "-inf", "1e-300", "1e300", "1e999", "-1", "", "abc",
        "0x10", "5 s",
    ])
    .prop_map(str::to_string);
    prop_oneof![
        2 => odd,
        1 => (-1e6..1e6f64).prop_map(|x| x.to_string()),
        5 => (0.0..30.0f64).prop_map(|x| format!("{x:.3}")),
    ]
}

/// A number as a user may write it in the TOML configuration (the same mix).
fn toml_number() -> impl Strategy<Value = String> {
    let odd = prop::sample::select(vec![
        "0.0", "-0.0", "nan", "inf", "-inf", "1e-300", "1e300", "-5.0", "\"0.3\"",
    ])
    .prop_map(str::to_string);
    prop_oneof![
        2 => odd,
        1 => (-200.0..200.0f64).prop_map(|x| format!("{x:?}")),
        5 => (-1.0..1.0f64).prop_map(|x| format!("{x:?}")),
    ]
}

/// Drawn command-line options: (option, value) pairs.
fn options() -> impl Strategy<Value = Vec<(&'static str, String)>> {
    let pair = |a: String, b: String| format!("{a}:{b}");
    (
        proptest::option::weighted(
            0.3,
            (cli_number(), cli_number()).prop_map(move |(a, b)| pair(a, b)),
        ),
        proptest::option::weighted(
            0.3,
            (cli_number(), cli_number(), cli_number()).prop_map(|(a, b, c)| format!("{a}:{b}:{c}")),
        ),
        proptest::option::weighted(0.3, cli_number()),
        proptest::option::weighted(0.3, cli_number()),
        proptest::option::weighted(0.3, cli_number()),
        proptest::option::weighted(0.3, cli_number()),
    )
        .prop_map(|(outage, periodic, nav, std, toff, noise)| {
            let mut v = Vec::new();
            let names = [
                "--outage",
                "--periodic-outage",
                "--nav-rate",
                "--std-rate",
                "--imu-time-offset",
                "--noise-scale",
            ];
            for (name, val) in names
                .into_iter()
                .zip([outage, periodic, nav, std, toff, noise])
            {
                if let Some(val) = val {
                    v.push((name, val));
                }
            }
            v
        })
}

fn cases() -> u32 {
    std::env::var("HOST_SIM_OPTION_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: cases(),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]
    #[test]
    fn drawn_option_values_end_in_bounded_time_and_memory_with_a_named_error(
        opts in options(),
        lever in [toml_number(), toml_number(), toml_number()],
        toff in toml_number(),
    ) {
        let dir = tempfile::tempdir().unwrap();
        let cfg = config(dir.path(), &lever, &toff);
        let mut cmd = std::process::Command::new(HOST_SIM);
        cmd.args(["run", "--quiet", "--config"]).arg(&cfg).arg("--out").arg(dir.path().join("out"));
        for (name, val) in &opts {
            // `--name=value`: a value starting with '-' stays the option's
            cmd.arg(format!("{name}={val}"));
        }
        let r = run_bounded(&mut cmd, WALL_LIMIT);
        let what = format!("{opts:?} lever {lever:?} time_offset {toff}: {r:?}");
        prop_assert!(!r.timed_out(), "hang: {what}");
        prop_assert!(!r.panicked(), "panic: {what}");
        prop_assert!(r.cpu_s < CPU_BOUND_S, "{} s CPU: {what}", r.cpu_s);
        prop_assert!(r.max_rss_kib < RSS_BOUND_KIB, "{} KiB: {what}", r.max_rss_kib);
        match r.code() {
            Some(0) => {}
            Some(1) => {
                // the message names what was wrong: one of the options given, or the
                // configuration file with the line and key
                let named = opts.iter().any(|(n, _)| r.stderr.contains(n))
                    || (r.stderr.contains("run.toml")
                        && r.stderr.contains("line ")
                        && (r.stderr.contains("lever_arm_m")
                            || r.stderr.contains("time_offset_s")));
                prop_assert!(named, "an error naming nothing given: {what}");
            }
            // 2: not a navigation solution only (a value the argument parser refused is an
            // error like any other: 1, naming the option)
            Some(2) => prop_assert!(r.stderr.contains("not a navigation solution"), "{what}"),
            _ => prop_assert!(false, "exit status: {what}"),
        }
    }
}
