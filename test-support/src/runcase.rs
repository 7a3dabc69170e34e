//! Simulated cases run through `host-sim` from a test, the set-up several end-to-end tests
//! share: simulate a scenario with the CLI into a case directory, write a run configuration
//! of the case (IMU text, a GNSS file, truth, static alignment, a `[noise]` section), run it
//! with a 30 s outage.
//!
//! ```no_run
//! use test_support::cli::Bin;
//! use test_support::runcase::{case_config, run_case, simulate_case, TACTICAL_NOISE};
//! use test_support::scenario::four_minute_drive;
//! let host_sim = Bin::new("target/release/host-sim"); // env!("CARGO_BIN_EXE_host-sim")
//! let dir = std::path::Path::new("/tmp/t");
//! let case = simulate_case(host_sim, dir, "drive", &four_minute_drive("d").build(), "tactical", 4);
//! let cfg = case_config("drive", &case, "gnss.txt", "text", "", TACTICAL_NOISE);
//! let (stdout, out_dir) = run_case(host_sim, dir, "drive", &cfg);
//! assert!(out_dir.join("metrics.json").exists() && stdout.contains("horizontal"));
//! ```
use crate::cli::Bin;
use std::path::{Path, PathBuf};

/// The `tactical` error preset's true IMU noise as a run configuration's `[noise]` section
/// (NBK: accelerometer 50 ug/sqrt(Hz), Gauss-Markov 50 ug / 300 s, turn-on 200 ug; gyro
/// 0.1 deg/sqrt(h), Gauss-Markov 1 deg/h / 300 s, turn-on 1 deg/h).
pub const TACTICAL_NOISE: &str = "[noise]
model = \"nbk\"
[noise.accel]
n_ug_per_sqrt_hz = 50.0
gm_sigma_ug = 50.0
t_b_s = 300.0
bias_init_ug = 200.0
[noise.gyro]
arw_deg_per_sqrt_h = 0.1
gm_sigma_deg_per_h = 1.0
t_b_s = 300.0
bias_init_deg_per_h = 1.0
";

/// Simulates `scenario_toml` (the scenario's TOML text, written to `dir/<name>-scenario.toml`) with
/// the error model `errors` (a preset name or a file) and `seed` into `dir/<name>`, with
/// `host-sim simulate`; returns the case directory (`imu.txt`, `gnss.txt`, `truth.nav`).
pub fn simulate_case(
    host_sim: Bin,
    dir: &Path,
    name: &str,
    scenario_toml: &str,
    errors: &str,
    seed: u64,
) -> PathBuf {
    let sc = dir.join(format!("{name}-scenario.toml"));
    std::fs::write(&sc, scenario_toml).unwrap_or_else(|e| panic!("{}: {e}", sc.display()));
    let case = dir.join(name);
    host_sim.run_ok([
        "simulate",
        "--scenario",
        path_str(&sc),
        "--errors",
        errors,
        "--seed",
        &seed.to_string(),
        "--out",
        path_str(&case),
    ]);
    case
}

/// The run configuration `name` of a simulated `case`: its `imu.txt` (text), the GNSS file
/// `gnss` of format `gnss_format` (velocities used when it has them; RTKLIB quality 1 only),
/// `gnss_extra` appended to the `[gnss]` table (e.g. a `[gnss.log]` table), its
/// `truth.nav`, static alignment over 20 s (heading from the GNSS course), initial sigmas
/// 5/5/10 cm, 5 cm/s, 1/1/5 deg, and `noise` (a `[noise]` section).
pub fn case_config(
    name: &str,
    case: &Path,
    gnss: &str,
    gnss_format: &str,
    gnss_extra: &str,
    noise: &str,
) -> String {
    format!(
        r#"name = "{name}"
[imu]
path = "{imu}"
format = "text"
[gnss]
path = "{gnss}"
format = "{gnss_format}"
use_velocity = true
max_q = 1
{gnss_extra}
[truth]
path = "{truth}"
format = "nav_text"
[init]
pos_std_m = [0.05, 0.05, 0.1]
vel_std_mps = [0.05, 0.05, 0.05]
att_std_deg = [1.0, 1.0, 5.0]
[init.align]
static_s = 20.0

{noise}"#,
        imu = case.join("imu.txt").display(),
        gnss = case.join(gnss).display(),
        truth = case.join("truth.nav").display(),
    )
}

/// Writes `cfg` to `dir/<name>.toml` and runs it with `host-sim run` and a 30 s outage from
/// 120 s into `dir/out-<name>`; returns the run's standard output and error and the output
/// directory (`metrics.json`, `nav.txt`, ...). Panics, with both outputs, when it fails.
pub fn run_case(host_sim: Bin, dir: &Path, name: &str, cfg: &str) -> (String, PathBuf) {
    let p = dir.join(format!("{name}.toml"));
    std::fs::write(&p, cfg).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let out = dir.join(format!("out-{name}"));
    let so = host_sim.run_ok_both([
        "run",
        "--config",
        path_str(&p),
        "--out",
        path_str(&out),
        "--outage",
        "120:30",
        "--quiet",
    ]);
    (so, out)
}

fn path_str(p: &Path) -> &str {
    p.to_str()
        .unwrap_or_else(|| panic!("{} is not UTF-8", p.display()))
}
