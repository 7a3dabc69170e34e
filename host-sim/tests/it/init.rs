//! `host-sim init` on files written the way devices write them (the project's text from the
//! simulator, a phone CSV with a header in Unix ms / deg/s / g with a u-blox-style fix CSV, a
//! rover's text lines, RTKLIB `.pos`, NMEA): each written configuration is read by `run`, and
//! its solution equals that of a hand-written configuration with the same `[init]`, `[noise]`
//! and mounting (the readers' mapping is what `init` found). The real drive0708: `init` then
//! `run` (CI only, SKIPPED without the data).

use nav_core::types::{GnssFix, ImuSample};
use nav_io::gnss::encode::{nmea_epoch, utc_of_gps};
use nav_sim::{simulate, ErrorModel};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use test_support::scenario::ScenarioToml;

// 2025-07-08 is in GPS week 2374; GPS - UTC = 18 s
const WEEK: u16 = 2374;
const SOW0: f64 = 2.0 * 86400.0 + 19.0 * 3600.0;
const LEAP: i32 = 18;
/// Unix seconds of GPS week 0, second 0 (1980-01-06).
const GPS_EPOCH_UNIX: f64 = 315_964_800.0;

struct Sim {
    imu: Vec<ImuSample>,
    gnss: Vec<GnssFix>,
}

fn sim() -> Sim {
    let sc = ScenarioToml::new("init")
        .start(40.0966, -105.1474, 1600.0, 30.0)
        .gps_time(WEEK, SOW0)
        .imu_rate_hz(100.0)
        .stationary(15.0)
        .accelerate(10.0, 5.0)
        .turn(90.0, 30.0)
        .cruise(10.0)
        .turn(-90.0, 30.0)
        .cruise(10.0);
    let case = simulate(&sc.scenario(), &ErrorModel::preset("tactical").unwrap(), 3).unwrap();
    Sim {
        imu: case.meas.imu,
        gnss: case.meas.gnss,
    }
}

fn host_sim(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr);
    (out.status.success(), text)
}

fn init(dir: &Path, imu: &str, gnss: &str) -> (PathBuf, String) {
    let out = dir.join("init.toml");
    let (ok, text) = host_sim(&[
        "init",
        "--imu",
        dir.join(imu).to_str().unwrap(),
        "--gnss",
        dir.join(gnss).to_str().unwrap(),
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    (out, text)
}

/// Runs a configuration; returns the solution.
fn run(cfg: &Path, out: &Path) -> Vec<nav_core::types::NavSolution> {
    let (ok, text) = host_sim(&[
        "run",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    nav_io::read_nav_text(out.join("nav.txt")).unwrap()
}

/// The hand-written `[imu]` and `[gnss]` mapping with the init's mounting, `[init]` and
/// `[noise]`: run both, the same solution.
fn same_solution_as_hand(dir: &Path, written: &Path, hand_imu_gnss: &str) {
    let init_cfg = nav_io::read_run_config(written).unwrap();
    let hand: nav_io::RunConfig = nav_io::parse_run_config(
        Path::new("hand.toml"),
        &format!("{hand_imu_gnss}\n[noise.accel]\nn_ug_per_sqrt_hz = 1.0\n[noise.gyro]\nn_deg_per_s_per_sqrt_hz = 0.001\n"),
    )
    .unwrap();
    let mut cfg = init_cfg.clone();
    cfg.imu = nav_io::ImuSource {
        mounting: init_cfg.imu.mounting,
        ..hand.imu
    };
    cfg.gnss = hand.gnss;
    let hand_path = dir.join("hand.toml");
    nav_io::write_run_config(&hand_path, &cfg).unwrap();
    let a = run(written, &dir.join("out_init"));
    let b = run(&hand_path, &dir.join("out_hand"));
    assert!(a.len() > 1000, "{} epochs", a.len());
    assert_eq!(a.len(), b.len());
    let worst = a
        .iter()
        .zip(&b)
        .map(|(x, y)| {
            assert_eq!(x.t_s, y.t_s);
            ((x.lat_rad - y.lat_rad).abs() + (x.lon_rad - y.lon_rad).abs()) * 6.4e6
                + (x.h_m - y.h_m).abs()
        })
        .fold(0.0, f64::max);
    assert!(worst < 1e-3, "solutions differ by {worst} m");
}

fn text_of(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

#[test]
fn init_on_the_project_text_from_the_simulator_runs_as_the_hand_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = sim();
    nav_io::write_imu_text(d.join("imu.txt"), &s.imu).unwrap();
    nav_io::write_gnss_text(d.join("gnss.txt"), &s.gnss).unwrap();
    let (cfg, _) = init(d, "imu.txt", "gnss.txt");
    let t = text_of(&cfg);
    assert!(
        t.contains("format = \"text\"  # 7 white-space columns"),
        "{t}"
    );
    assert!(t.contains("static_s = "), "{t}");
    assert!(t.contains("the project's GNSS text"), "{t}");
    // the mounting: the simulator's IMU is in body axes, the estimate within 0.1 deg of it
    let c = nav_io::read_run_config(&cfg).unwrap();
    for a in c.imu.mounting.rpy_deg {
        let a = (a + 180.0).rem_euclid(360.0) - 180.0;
        assert!(a.abs() < 0.1, "{:?}\n{t}", c.imu.mounting);
    }
    same_solution_as_hand(
        d,
        &cfg,
        "[imu]\npath = \"imu.txt\"\nformat = \"text\"\n[gnss]\npath = \"gnss.txt\"\nformat = \"text\"\nuse_velocity = true\n",
    );
    // an existing file is kept without --force
    let (ok, text) = host_sim(&[
        "init",
        "--imu",
        d.join("imu.txt").to_str().unwrap(),
        "--gnss",
        d.join("gnss.txt").to_str().unwrap(),
        "-o",
        cfg.to_str().unwrap(),
    ]);
    assert!(!ok && text.contains("exists: give --force"), "{text}");
}

/// `init` reads the start of a long GNSS log, never the whole file: the log is the simulated
/// fixes followed by 110,000 more (past the 100,000 lines the format detection reads, which
/// hold about 50 MB) and a 512 MiB sparse tail of zero bytes (no disk used; a tail any reader
/// would refuse as "not a text file"). Its peak resident set (the process's `VmHWM`) stays
/// within 128 MiB of the same `init` on the short log, and the `[gnss]` section is the same.
/// Reading the whole file would hold its 550 MB.
#[test]
fn init_reads_only_the_start_of_a_long_gnss_log() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = sim();
    nav_io::write_imu_text(d.join("imu.txt"), &s.imu).unwrap();
    nav_io::write_gnss_text(d.join("gnss.txt"), &s.gnss).unwrap();
    let short = text_of(&d.join("gnss.txt"));
    let last = short.lines().last().unwrap();
    let (t, rest) = last.split_once(' ').unwrap();
    let t: f64 = t.parse().unwrap();
    let mut long = short.clone();
    for k in 1..=110_000 {
        writeln!(long, "{:.3} {rest}", t + f64::from(k)).unwrap();
    }
    let path = d.join("long.txt");
    std::fs::write(&path, &long).unwrap();
    let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
    f.set_len(long.len() as u64 + (512 << 20)).unwrap();
    drop(f);
    let measure = |gnss: &str, out: &str| {
        let o = d.join(out);
        let r = test_support::cli::run_bounded(
            Command::new(env!("CARGO_BIN_EXE_host-sim")).args([
                "init",
                "--imu",
                d.join("imu.txt").to_str().unwrap(),
                "--gnss",
                d.join(gnss).to_str().unwrap(),
                "-o",
                o.to_str().unwrap(),
            ]),
            std::time::Duration::from_secs(60),
        );
        assert_eq!(r.code(), Some(0), "{}", r.stderr);
        let gnss_section = text_of(&o)
            .split("[gnss]")
            .nth(1)
            .unwrap()
            .replace(gnss, "GNSS");
        (r.max_rss_kib, gnss_section)
    };
    let (short_kib, short_gnss) = measure("gnss.txt", "short.toml");
    let (long_kib, long_gnss) = measure("long.txt", "long.toml");
    assert_eq!(long_gnss, short_gnss);
    assert!(short_kib > 0, "VmHWM not read");
    assert!(
        long_kib < short_kib + 128 * 1024,
        "init on the long log peaked at {long_kib} KiB, on the short one at {short_kib} KiB"
    );
}

/// Rows separated by `;` (a European spreadsheet's CSV, with decimal points or decimal commas)
/// are named as such, with the line and how to convert the file, for the IMU and the GNSS
/// file, instead of "fewer than 10 data rows recognised"; the file converted as said, and the
/// same rows separated by tabs, are recognised.
#[test]
fn rows_separated_by_semicolons_are_named_with_the_conversion() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = sim();
    nav_io::write_imu_text(d.join("imu.txt"), &s.imu).unwrap();
    nav_io::write_gnss_text(d.join("gnss.txt"), &s.gnss).unwrap();
    let sep = |f: &str, sep: &str, decimal: &str| {
        text_of(&d.join(f))
            .lines()
            .map(|l| {
                l.replace('.', decimal)
                    .split_whitespace()
                    .collect::<Vec<_>>()
                    .join(sep)
                    + "\n"
            })
            .collect::<String>()
    };
    let header = "t;gx;gy;gz;ax;ay;az\n";
    std::fs::write(
        d.join("imu_sc.csv"),
        format!("{header}{}", sep("imu.txt", ";", ".")),
    )
    .unwrap();
    std::fs::write(
        d.join("imu_dc.csv"),
        format!("{header}{}", sep("imu.txt", ";", ",")),
    )
    .unwrap();
    std::fs::write(d.join("gnss_sc.csv"), sep("gnss.txt", ";", ".")).unwrap();
    std::fs::write(d.join("imu_tab.txt"), sep("imu.txt", "\t", ".")).unwrap();
    let out = d.join("init.toml");
    let refused = |imu: &str, gnss: &str| {
        let (ok, text) = host_sim(&[
            "init",
            "--imu",
            d.join(imu).to_str().unwrap(),
            "--gnss",
            d.join(gnss).to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(!ok && !out.exists(), "{text}");
        text
    };
    let first = |f: &str, line: usize| -> String {
        let l = text_of(&d.join(f))
            .lines()
            .nth(line - 1)
            .unwrap()
            .to_string();
        l.chars().take(60).collect::<String>() + "..."
    };
    let e = refused("imu_sc.csv", "gnss.txt");
    assert_eq!(
        e,
        format!(
            "error: recognising the IMU file {}: the rows are separated by ';' (line 2: `{}`): \
             init and the readers take commas or white space between the columns; replace each \
             ';' by ',' (e.g. `sed 's/;/,/g'`) and give init the converted file\n",
            d.join("imu_sc.csv").display(),
            first("imu_sc.csv", 2)
        )
    );
    let e = refused("imu_dc.csv", "gnss.txt");
    assert!(
        e.contains("the rows are separated by ';' and the numbers have decimal commas (line 2: ")
            && e.contains(
                "replace each ',' by '.' and then each ';' by ',' (e.g. `sed 's/,/./g; s/;/,/g'`)"
            ),
        "{e}"
    );
    let e = refused("imu.txt", "gnss_sc.csv");
    assert!(
        e.starts_with(&format!(
            "error: recognising the GNSS file {}: the rows are separated by ';' (line 1: `{}`)",
            d.join("gnss_sc.csv").display(),
            first("gnss_sc.csv", 1)
        )),
        "{e}"
    );
    // converted as said: recognised (the header's names mapped), and tabs are white space
    let converted = text_of(&d.join("imu_dc.csv"))
        .replace(',', ".")
        .replace(';', ",");
    std::fs::write(d.join("imu_conv.csv"), converted).unwrap();
    let (cfg, _) = init(d, "imu_conv.csv", "gnss.txt");
    assert!(
        text_of(&cfg).contains("format = \"csv\""),
        "{}",
        text_of(&cfg)
    );
    std::fs::remove_file(&cfg).unwrap();
    let (cfg, _) = init(d, "imu_tab.txt", "gnss.txt");
    assert!(
        text_of(&cfg).contains("format = \"text\""),
        "{}",
        text_of(&cfg)
    );
}

/// `-o` naming one of init's own inputs is refused even with `--force` (the data kept, byte
/// for byte), and so is a link to one; a link to any other file is replaced by the
/// configuration, its target untouched.
#[test]
fn init_never_writes_over_its_inputs_nor_through_a_link() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = sim();
    nav_io::write_imu_text(d.join("imu.txt"), &s.imu).unwrap();
    nav_io::write_gnss_text(d.join("gnss.txt"), &s.gnss).unwrap();
    let gnss_before = std::fs::read(d.join("gnss.txt")).unwrap();
    let imu_before = std::fs::read(d.join("imu.txt")).unwrap();
    std::os::unix::fs::symlink("gnss.txt", d.join("to-gnss.toml")).unwrap();
    std::fs::write(d.join("other.txt"), "other data\n").unwrap();
    std::os::unix::fs::symlink("other.txt", d.join("to-other.toml")).unwrap();
    let p = |n: &str| d.join(n).to_str().unwrap().to_string();
    let args = |out: &str| -> Vec<String> {
        [
            "init",
            "--imu",
            &p("imu.txt"),
            "--gnss",
            &p("gnss.txt"),
            "-o",
            out,
            "--force",
        ]
        .iter()
        .map(|x| x.to_string())
        .collect()
    };
    for out in ["gnss.txt", "imu.txt", "to-gnss.toml"] {
        let a = args(&p(out));
        let (ok, text) = host_sim(&a.iter().map(String::as_str).collect::<Vec<_>>());
        assert!(!ok, "{out}: {text}");
        assert!(
            text.contains("holds the input") && text.contains("nothing was written"),
            "{out}: {text}"
        );
        assert_eq!(
            std::fs::read(d.join("gnss.txt")).unwrap(),
            gnss_before,
            "{out}"
        );
        assert_eq!(
            std::fs::read(d.join("imu.txt")).unwrap(),
            imu_before,
            "{out}"
        );
        assert!(!d.join(format!("{out}.partial")).exists(), "{out}");
    }
    let a = args(&p("to-other.toml"));
    let (ok, text) = host_sim(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(ok, "{text}");
    assert_eq!(text_of(&d.join("other.txt")), "other data\n");
    let m = std::fs::symlink_metadata(d.join("to-other.toml")).unwrap();
    assert!(m.is_file(), "the link is replaced by the configuration");
    nav_io::read_run_config(d.join("to-other.toml")).unwrap();
}

/// An IMU that writes increments in a layout of its own: a comma-separated file with a header,
/// a GPS week column and seconds of week, velocity increments (m/s) before angle increments
/// (rad); the GNSS in the project's text.
#[test]
fn init_on_increments_with_a_week_column_in_a_layout_of_their_own() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = sim();
    let mut imu = String::from("gps_week,gps_sow,dv_x,dv_y,dv_z,dtheta_x,dtheta_y,dtheta_z\n");
    for x in &s.imu {
        let (v, a) = (x.dv_mps, x.dtheta_rad);
        let _ = writeln!(
            imu,
            "{WEEK},{},{},{},{},{},{},{}",
            x.t_s, v[0], v[1], v[2], a[0], a[1], a[2]
        );
    }
    std::fs::write(d.join("inc.csv"), imu).unwrap();
    nav_io::write_gnss_text(d.join("gnss.txt"), &s.gnss).unwrap();
    let (cfg, _) = init(d, "inc.csv", "gnss.txt");
    let t = text_of(&cfg);
    for want in [
        "convention = \"increments\"",
        "accel_unit = \"m/s^2\"",
        "gyro_unit = \"rad/s\"",
        "kind = \"week_sow\"",
        "week = \"gps_week\"",
        "time = \"gps_sow\"",
        "gyro = [\"dtheta_x\", \"dtheta_y\", \"dtheta_z\"]",
        "accel = [\"dv_x\", \"dv_y\", \"dv_z\"]",
    ] {
        assert!(t.contains(want), "{want} not in\n{t}");
    }
    // the rows read as the increments they are: the same samples as the simulator's, the
    // first row opening the first interval
    let c = nav_io::read_run_config(&cfg).unwrap();
    let read = nav_io::read_imu_csv(d.join("inc.csv"), c.imu.csv.as_ref().unwrap()).unwrap();
    assert_eq!(read.samples.len(), s.imu.len() - 1);
    for (r, x) in read.samples.iter().zip(&s.imu[1..]) {
        assert_eq!(
            (r.t_s, r.dtheta_rad, r.dv_mps),
            (x.t_s, x.dtheta_rad, x.dv_mps)
        );
    }
    same_solution_as_hand(
        d,
        &cfg,
        r#"[imu]
path = "inc.csv"
format = "csv"
[imu.csv]
skip_lines = 1
gyro_unit = "rad/s"
accel_unit = "m/s^2"
convention = "increments"
[imu.csv.columns]
week = "gps_week"
time = "gps_sow"
gyro = ["dtheta_x", "dtheta_y", "dtheta_z"]
accel = ["dv_x", "dv_y", "dv_z"]
[imu.csv.time]
kind = "week_sow"
[gnss]
path = "gnss.txt"
format = "text"
use_velocity = true
"#,
    );
}

/// A phone: IMU CSV with a header, Unix ms, deg/s and g; fixes in a u-blox-style CSV with
/// accuracy, speed and bearing columns.
#[test]
fn init_on_a_phone_csv_and_a_ublox_style_csv_finds_units_and_time_kind() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = sim();
    let unix_ms = |sow: f64| {
        ((f64::from(WEEK) * 604_800.0 + sow + GPS_EPOCH_UNIX - f64::from(LEAP)) * 1000.0).round()
    };
    let mut imu = String::from("time_ms,gx,gy,gz,ax,ay,az\n");
    let mut prev = s.imu[0].t_s - 0.01;
    for x in &s.imu {
        let dt = x.t_s - prev;
        prev = x.t_s;
        let w = x.dtheta_rad.map(|v| (v / dt).to_degrees());
        let f = x.dv_mps.map(|v| v / dt / 9.806_65);
        let _ = writeln!(
            imu,
            "{:.0},{:.6},{:.6},{:.6},{:.7},{:.7},{:.7}",
            unix_ms(x.t_s),
            w[0],
            w[1],
            w[2],
            f[0],
            f[1],
            f[2]
        );
    }
    std::fs::write(d.join("phone_imu.csv"), imu).unwrap();
    let mut g = String::from("time_ms,lat,lon,alt,acc,vacc,speed,bearing,speed_acc\n");
    for f in &s.gnss {
        let v = f.vel_ned_mps;
        let _ = writeln!(
            g,
            "{:.0},{:.9},{:.9},{:.4},{:.3},{:.3},{:.3},{:.3},0.100",
            unix_ms(f.t_s),
            f.lat_rad.to_degrees(),
            f.lon_rad.to_degrees(),
            f.h_m,
            f.pos_std_ned_m[0],
            f.pos_std_ned_m[2],
            v[0].hypot(v[1]),
            v[1].atan2(v[0]).to_degrees().rem_euclid(360.0)
        );
    }
    std::fs::write(d.join("fixes.csv"), g).unwrap();
    let (cfg, _) = init(d, "phone_imu.csv", "fixes.csv");
    let t = text_of(&cfg);
    for want in [
        "gyro_unit = \"deg/s\"",
        "accel_unit = \"g\"",
        "kind = \"unix_ms\"",
        "skip_lines = 1",
        "gyro = [\"gx\", \"gy\", \"gz\"]",
        "sigma_h = \"acc\"",
        "speed = \"speed\"",
    ] {
        assert!(t.contains(want), "{want} not in\n{t}");
    }
    same_solution_as_hand(
        d,
        &cfg,
        r#"[imu]
path = "phone_imu.csv"
format = "csv"
[imu.csv]
skip_lines = 1
gyro_unit = "deg/s"
accel_unit = "g"
[imu.csv.columns]
time = "time_ms"
gyro = ["gx", "gy", "gz"]
accel = ["ax", "ay", "az"]
[imu.csv.time]
kind = "unix_ms"
[gnss]
path = "fixes.csv"
format = "csv"
use_velocity = true
[gnss.csv]
skip_lines = 1
[gnss.csv.columns]
time = "time_ms"
lat = "lat"
lon = "lon"
h = "alt"
sigma_h = "acc"
sigma_v = "vacc"
speed = "speed"
course = "bearing"
speed_sigma = "speed_acc"
[gnss.csv.time]
kind = "unix_ms"
"#,
    );

    // the same IMU with date-time text (UTC, milliseconds) in its time column
    let imu_ms = std::fs::read_to_string(d.join("phone_imu.csv")).unwrap();
    let mut imu_text = String::from("utc,gx,gy,gz,ax,ay,az\n");
    for l in imu_ms.lines().skip(1) {
        let (ms, rest) = l.split_once(',').unwrap();
        let ms: i64 = ms.parse().unwrap();
        let gps_ms = ms - (GPS_EPOCH_UNIX as i64 - i64::from(LEAP)) * 1000;
        let (y, mo, dd, h, mi, sec) = utc_of_gps(
            gps_ms.div_euclid(604_800_000),
            gps_ms.rem_euclid(604_800_000) as f64 * 1e-3,
            LEAP,
        );
        let m = (sec * 1000.0).round() as u32;
        let _ = writeln!(
            imu_text,
            "{y}-{mo:02}-{dd:02}T{h:02}:{mi:02}:{:02}.{:03},{rest}",
            m / 1000,
            m % 1000
        );
    }
    std::fs::write(d.join("phone_imu_text.csv"), imu_text).unwrap();
    std::fs::remove_file(&cfg).unwrap();
    let (cfg, _) = init(d, "phone_imu_text.csv", "fixes.csv");
    let t = text_of(&cfg);
    for want in [
        "kind = \"text\"",
        "format = \"%Y-%m-%dT%H:%M:%S%.f\"",
        "scale = \"utc\"",
        "time = \"utc\"",
    ] {
        assert!(t.contains(want), "{want} not in\n{t}");
    }
    same_solution_as_hand(
        d,
        &cfg,
        r#"[imu]
path = "phone_imu_text.csv"
format = "csv"
[imu.csv]
skip_lines = 1
gyro_unit = "deg/s"
accel_unit = "g"
[imu.csv.columns]
time = "utc"
gyro = ["gx", "gy", "gz"]
accel = ["ax", "ay", "az"]
[imu.csv.time]
kind = "text"
format = "%Y-%m-%dT%H:%M:%S%.f"
scale = "utc"
[gnss]
path = "fixes.csv"
format = "csv"
use_velocity = true
[gnss.csv]
skip_lines = 1
[gnss.csv.columns]
time = "time_ms"
lat = "lat"
lon = "lon"
h = "alt"
sigma_h = "acc"
sigma_v = "vacc"
speed = "speed"
course = "bearing"
speed_sigma = "speed_acc"
[gnss.csv.time]
kind = "unix_ms"
"#,
    );
}

/// A rover's text lines `2015_11_26_15_00_02_617 RTK_FIXED lat lon h sN sE sD` (UTC), an RTKLIB
/// `.pos` and an NMEA log of the same fixes, with the simulator's IMU text.
#[test]
fn init_on_rover_lines_rtklib_pos_and_nmea() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = sim();
    nav_io::write_imu_text(d.join("imu.txt"), &s.imu).unwrap();
    let mut rover = String::new();
    let mut pos = String::from("%  GPST                  latitude(deg) longitude(deg)  height(m)   Q  ns   sdn(m)   sde(m)   sdu(m)  sdne(m)  sdeu(m)  sdun(m) age(s)  ratio\n");
    let mut nmea = String::new();
    for f in &s.gnss {
        let (y, mo, dd, h, mi, sec) = utc_of_gps(i64::from(WEEK), f.t_s, LEAP);
        let ms = (sec * 1000.0).round() as u32;
        let [sn, se, sd] = f.pos_std_ned_m;
        let (la, lo) = (f.lat_rad.to_degrees(), f.lon_rad.to_degrees());
        let _ = writeln!(rover, "{y}_{mo:02}_{dd:02}_{h:02}_{mi:02}_{:02}_{:03} RTK_FIXED {la:.9} {lo:.9} {:.4} {sn:.4} {se:.4} {sd:.4}", ms / 1000, ms % 1000, f.h_m);
        let _ = writeln!(pos, "{WEEK} {:.3}   {la:.9}  {lo:.9} {:10.4}   1  12   {sn:.4}   {se:.4}   {sd:.4}   0.0000   0.0000   0.0000   0.00    0.0", f.t_s, f.h_m);
        for l in nmea_epoch(f, i64::from(WEEK), LEAP) {
            nmea.push_str(&l);
            nmea.push('\n');
        }
    }
    std::fs::write(d.join("rover.txt"), rover).unwrap();
    std::fs::write(d.join("gnss.pos"), pos).unwrap();
    std::fs::write(d.join("gnss.nmea"), nmea).unwrap();
    let imu = "[imu]\npath = \"imu.txt\"\nformat = \"text\"\n";

    let (cfg, _) = init(d, "imu.txt", "rover.txt");
    let t = text_of(&cfg);
    for want in [
        "format = \"%Y_%m_%d_%H_%M_%S_%3f\"",
        "scale = \"utc\"",
        "column = 2",
        "sigma_ned = [6, 7, 8]",
        "lat = 3",
    ] {
        assert!(t.contains(want), "{want} not in\n{t}");
    }
    same_solution_as_hand(d, &cfg, &format!("{imu}[gnss]\npath = \"rover.txt\"\nformat = \"csv\"\n[gnss.csv]\n[gnss.csv.columns]\ntime = 1\nlat = 3\nlon = 4\nh = 5\nsigma_ned = [6, 7, 8]\n[gnss.csv.time]\nkind = \"text\"\nformat = \"%Y_%m_%d_%H_%M_%S_%3f\"\nscale = \"utc\"\n[gnss.csv.quality]\ncolumn = 2\n"));

    std::fs::remove_file(&cfg).unwrap();
    let (cfg, _) = init(d, "imu.txt", "gnss.pos");
    let t = text_of(&cfg);
    assert!(t.contains("format = \"rtklib_pos\""));
    let n = s.gnss.len();
    assert!(
        t.contains(&format!(
            "max_q = 1  # quality flags of the first {n} records: {n} x Q1;"
        )),
        "{t}"
    );
    same_solution_as_hand(
        d,
        &cfg,
        &format!("{imu}[gnss]\npath = \"gnss.pos\"\nformat = \"rtklib_pos\"\n"),
    );

    // floats in the majority, a few single-point solutions: fixed and float are kept
    std::fs::remove_file(&cfg).unwrap();
    let mixed: String = std::fs::read_to_string(d.join("gnss.pos"))
        .unwrap()
        .lines()
        .enumerate()
        .map(|(i, l)| {
            let q = match i % 10 {
                0 => "1",
                1..=3 => "5",
                _ => "2",
            };
            let l = if i == 0 {
                l.to_string()
            } else {
                l.replacen("   1  12   ", &format!("   {q}  12   "), 1)
            };
            l + "\n"
        })
        .collect();
    std::fs::write(d.join("gnss.pos"), mixed).unwrap();
    let (cfg, _) = init(d, "imu.txt", "gnss.pos");
    let t = text_of(&cfg);
    assert!(t.contains("max_q = 2  # quality flags of the first"), "{t}");
    assert!(
        t.contains(" x Q1, ") && t.contains(" x Q2, ") && t.contains(" x Q5;"),
        "{t}"
    );
    same_solution_as_hand(
        d,
        &cfg,
        &format!("{imu}[gnss]\npath = \"gnss.pos\"\nformat = \"rtklib_pos\"\nmax_q = 2\n"),
    );

    std::fs::remove_file(&cfg).unwrap();
    let (cfg, _) = init(d, "imu.txt", "gnss.nmea");
    assert!(text_of(&cfg).contains("format = \"nmea\""));
    same_solution_as_hand(
        d,
        &cfg,
        &format!("{imu}[gnss]\npath = \"gnss.nmea\"\nformat = \"nmea\"\n"),
    );
}

/// The real drive: `init` on the raw IMU log (with its time tag) and the RTKLIB `.pos`, then
/// `run` with the outage protocol of `configs/drive0708.toml`'s figures.
#[test]
fn init_then_run_on_the_real_drive0708() {
    let Some(data) = test_support::real_data_in(
        "init_then_run_on_the_real_drive0708",
        "rtklibexplorer-drive0708",
    ) else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let cfg = dir.path().join("drive.toml");
    let (ok, text) = host_sim(&[
        "init",
        "--imu",
        data.join("imu_1934.csv").to_str().unwrap(),
        "--gnss",
        data.join("gnss_1934_sf.pos").to_str().unwrap(),
        "-o",
        cfg.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    let t = text_of(&cfg);
    for want in [
        "gyro_unit = \"deg/s\"",
        "accel_unit = \"g\"",
        "kind = \"ticks_ms\"",
        "tag_file = \"imu_1934.csv.tag\"",
        "static_s = 19.0",
        "format = \"rtklib_pos\"",
        // 2,189 fixed, 8 float: as configs/drive0708.toml
        "max_q = 1  # quality flags of the first",
    ] {
        assert!(t.contains(want), "{want} not in\n{t}");
    }
    let out = dir.path().join("out");
    let (ok, text) = host_sim(&[
        "run",
        "--config",
        cfg.to_str().unwrap(),
        "--periodic-outage",
        "120:10:60",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{text}");
    assert!(text.contains("static_alignment"), "{text}");
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("metrics.json")).unwrap()).unwrap();
    println!("{text}\n{m}");
}
