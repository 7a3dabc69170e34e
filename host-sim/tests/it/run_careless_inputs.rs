//! `host-sim run` on inputs written the way a careless user or a broken logger writes them:
//! each case names its cause on stderr (the setting to change, the file and line), and the run
//! gives the right result.
//!
//! - plausibility: an IMU CSV in g declared as m/s^2, one in deg/s declared as rad/s, 100 Hz
//!   increments stamped at 200 Hz, GNSS position outliers (no mounting warning with a correct
//!   mounting), GNSS stamped 0.5 s late (the offset estimated), an all-zero IMU sample;
//! - small damage: a half-written last IMU line, an exact duplicate IMU line, a bad truth
//!   line, a UTF-8 byte-order mark at the start of every text input.
//!
//! The case is the 8-minute urban drive `scenarios/land_stops.toml` (60 s at rest first)
//! simulated once with a tactical IMU; each run takes well under a second.
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use test_support::cli::{Bin, Ran};

const HOST_SIM: Bin = Bin::new(env!("CARGO_BIN_EXE_host-sim"));

/// The simulated case: (folder, IMU lines, GNSS lines).
struct Case {
    dir: PathBuf,
    imu: Vec<Vec<String>>,
    gnss: Vec<Vec<String>>,
}

fn case() -> &'static Case {
    static CASE: OnceLock<(tempfile::TempDir, Case)> = OnceLock::new();
    &CASE
        .get_or_init(|| {
            let tmp = tempfile::tempdir().unwrap();
            let dir = tmp.path().join("case");
            let sc = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenarios/land_stops.toml");
            HOST_SIM.run_ok([
                "simulate",
                "--scenario",
                sc.to_str().unwrap(),
                "--errors",
                "tactical",
                "--seed",
                "4",
                "--out",
                dir.to_str().unwrap(),
            ]);
            let rows = |f: &str| -> Vec<Vec<String>> {
                std::fs::read_to_string(dir.join(f))
                    .unwrap()
                    .lines()
                    .map(|l| l.split_whitespace().map(str::to_string).collect())
                    .collect()
            };
            let c = Case {
                imu: rows("imu.txt"),
                gnss: rows("gnss.txt"),
                dir,
            };
            (tmp, c)
        })
        .1
}

fn join(rows: &[Vec<String>]) -> String {
    let mut s = String::new();
    for r in rows {
        s.push_str(&r.join(" "));
        s.push('\n');
    }
    s
}

/// An `[imu.csv]` mapping of `t,gx,gy,gz,ax,ay,az` with the declared units.
fn csv_mapping(gyro_unit: &str, accel_unit: &str) -> String {
    format!(
        "format = \"csv\"\n[imu.csv]\nskip_lines = 1\ngyro_unit = \"{gyro_unit}\"\n\
         accel_unit = \"{accel_unit}\"\nconvention = \"interval_mean\"\n[imu.csv.columns]\n\
         time = 1\ngyro = [2, 3, 4]\naccel = [5, 6, 7]\n[imu.csv.time]\nkind = \"seconds\"\n"
    )
}

/// A run configuration in `dir` over `imu` (text, or CSV with `csv` the mapping), `gnss`
/// (text) and `truth` (nav text), static alignment over 20 s, the tactical noise.
fn config(dir: &Path, imu: &str, csv: Option<&str>, gnss: &str, truth: &Path) -> PathBuf {
    let imu_fmt = csv.map_or("format = \"text\"\n".to_string(), str::to_string);
    let text = format!(
        "name = \"careless\"\n[imu]\npath = \"{imu}\"\n{imu_fmt}[gnss]\npath = \"{gnss}\"\n\
         format = \"text\"\n[truth]\npath = \"{}\"\nformat = \"nav_text\"\n[init]\n\
         pos_std_m = [0.05, 0.05, 0.1]\nvel_std_mps = [0.05, 0.05, 0.05]\n\
         att_std_deg = [1.0, 1.0, 5.0]\n[init.align]\nstatic_s = 20.0\n{}",
        truth.display(),
        test_support::runcase::TACTICAL_NOISE
    );
    let p = dir.join("run.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// Runs `cfg` into `dir/out`.
fn run(cfg: &Path, dir: &Path) -> Ran {
    let out = dir.join("out");
    HOST_SIM.run([
        "run",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ])
}

/// A fresh folder holding `imu` and `gnss` (texts), and the case's truth.
fn setup(imu_name: &str, imu: &str, gnss: &str) -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join(imu_name), imu).unwrap();
    std::fs::write(tmp.path().join("gnss.txt"), gnss).unwrap();
    let cfg_csv = None;
    let cfg = config(
        tmp.path(),
        imu_name,
        cfg_csv,
        "gnss.txt",
        &case().dir.join("truth.nav"),
    );
    (tmp, cfg)
}

/// The IMU increments as a CSV of mean rates and specific forces, scaled by `kg` and `ka`.
fn imu_csv(kg: f64, ka: f64) -> String {
    let c = case();
    let mut s = String::from("t,gx,gy,gz,ax,ay,az\n");
    let mut tp: f64 = c.imu[0][0].parse::<f64>().unwrap() - 0.01;
    for r in &c.imu {
        let t: f64 = r[0].parse().unwrap();
        let dt = t - tp;
        tp = t;
        let v: Vec<f64> = r[1..7].iter().map(|x| x.parse::<f64>().unwrap()).collect();
        let _ = write!(s, "{}", r[0]);
        for (k, x) in v.iter().enumerate() {
            let _ = write!(s, ",{}", x / dt * if k < 3 { kg } else { ka });
        }
        s.push('\n');
    }
    s
}

/// Runs the case with the IMU CSV in units scaled by `kg`, `ka` declared as `gyro_unit`,
/// `accel_unit`.
fn run_csv(kg: f64, ka: f64, gyro_unit: &str, accel_unit: &str) -> Ran {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("imu.csv"), imu_csv(kg, ka)).unwrap();
    std::fs::write(d.join("gnss.txt"), join(&case().gnss)).unwrap();
    let cfg = config(
        d,
        "imu.csv",
        Some(&csv_mapping(gyro_unit, accel_unit)),
        "gnss.txt",
        &case().dir.join("truth.nav"),
    );
    run(&cfg, d)
}

fn metrics(dir: &Path) -> serde_json::Value {
    let p = dir.join("out/metrics.json");
    serde_json::from_str(&std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{e}: {p:?}")))
        .unwrap()
}

fn horizontal_rms_m(dir: &Path) -> f64 {
    let m = metrics(dir);
    m["overall"]["pos_horizontal_m"]["rms"]
        .as_f64()
        .unwrap_or_else(|| panic!("no horizontal RMS in {m}"))
}

#[test]
fn accelerometer_data_in_g_declared_as_m_s2_are_named() {
    let r = run_csv(1.0, 1.0 / 9.80665, "rad/s", "m/s^2");
    println!("{}", r.stderr);
    assert!(
        r.stderr.contains("in g but read as m/s^2")
            && r.stderr.contains("accel_unit = \"g\"")
            && r.stderr.contains("1.0"),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("[imu.mounting]"), "{}", r.stderr);
    // and declared right, the same data run clean
    let ok = run_csv(1.0, 1.0 / 9.80665, "rad/s", "g");
    assert!(ok.ok, "{}", ok.stderr);
    assert!(!ok.stderr.contains("warning"), "{}", ok.stderr);
}

#[test]
fn gyro_data_in_deg_s_declared_as_rad_s_are_named() {
    let r = run_csv(180.0 / std::f64::consts::PI, 1.0, "rad/s", "m/s^2");
    println!("{}", r.stderr);
    assert!(
        r.stderr.contains("in deg (deg/s) but read as rad (rad/s)")
            && r.stderr.contains("gyro_unit = \"deg/s\""),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("[imu.mounting]"), "{}", r.stderr);
}

#[test]
fn increments_of_100_hz_stamped_at_200_hz_are_named() {
    let c = case();
    let t0: f64 = c.imu[0][0].parse().unwrap();
    let rows: Vec<Vec<String>> = c
        .imu
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let mut r = r.clone();
            r[0] = format!("{}", t0 + k as f64 * 0.005);
            r
        })
        .collect();
    let (tmp, cfg) = setup("imu.txt", &join(&rows), &join(&c.gnss));
    let r = run(&cfg, tmp.path());
    println!("{}", r.stderr);
    assert!(
        r.stderr.contains("increments of 100 Hz stamped at 200 Hz"),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("[imu.mounting]"), "{}", r.stderr);
}

#[test]
fn gnss_position_outliers_do_not_blame_a_correct_mounting() {
    let c = case();
    let m_per_deg = 111_000.0;
    // one outlier per run: 10, 30, 100 m north or east, at rest, cruising and in turns
    let mut tried = 0;
    for (k, size_m, north) in [
        (30, 30.0, true),
        (100, 10.0, true),
        (150, 30.0, true),
        (150, 30.0, false),
        (205, 100.0, false),
        (260, 30.0, true),
        (330, 10.0, false),
        (400, 100.0, true),
    ] {
        let mut g = c.gnss.clone();
        let col = if north { 1 } else { 2 };
        let v: f64 = g[k][col].parse().unwrap();
        g[k][col] = format!("{}", v + size_m / m_per_deg);
        let (tmp, cfg) = setup("imu.txt", &join(&c.imu), &join(&g));
        let r = run(&cfg, tmp.path());
        assert!(r.ok, "{}", r.stderr);
        assert!(
            !r.stderr.contains("warning"),
            "outlier of {size_m} m at fix {k}: {}",
            r.stderr
        );
        tried += 1;
    }
    assert_eq!(tried, 8);
}

#[test]
fn gnss_stamped_half_a_second_late_is_estimated_on_stderr() {
    let c = case();
    let g: Vec<Vec<String>> = c
        .gnss
        .iter()
        .map(|r| {
            let mut r = r.clone();
            r[0] = format!("{}", r[0].parse::<f64>().unwrap() + 0.5);
            r
        })
        .collect();
    let (tmp, cfg) = setup("imu.txt", &join(&c.imu), &join(&g));
    let r = run(&cfg, tmp.path());
    println!("{}", r.stderr);
    let w = r
        .stderr
        .lines()
        .find(|l| l.contains("[gnss] time_offset_s"))
        .unwrap_or_else(|| panic!("no time offset warning: {}", r.stderr));
    // "add -0.50 s to [gnss] time_offset_s"
    let est: f64 = w
        .split("add ")
        .nth(1)
        .and_then(|s| s.split(" s").next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("{w}"));
    assert!((est + 0.5).abs() < 0.1, "{est}: {w}");
    assert!(w.contains("late"), "{w}");
    // on time: no such warning
    let (tmp, cfg) = setup("imu.txt", &join(&c.imu), &join(&c.gnss));
    let r = run(&cfg, tmp.path());
    assert!(!r.stderr.contains("time_offset_s"), "{}", r.stderr);
}

#[test]
fn an_all_zero_imu_sample_is_rejected_and_counted() {
    let c = case();
    let mut rows = c.imu.clone();
    let k = 9000;
    for x in &mut rows[k][1..7] {
        *x = "0".into();
    }
    let (tmp, cfg) = setup("imu.txt", &join(&rows), &join(&c.gnss));
    let r = run(&cfg, tmp.path());
    assert!(r.ok, "{}", r.stderr);
    let m = metrics(tmp.path());
    assert_eq!(m["imu"]["rejected"], 1, "{}", m["imu"]);
    let ev = m["imu"]["events"][0]["what"].as_str().unwrap();
    let at = m["imu"]["events"][0]["location"].as_str().unwrap();
    assert!(ev.contains("all six increments exactly zero"), "{ev}");
    assert!(at.ends_with(&format!("line {}", k + 1)), "{at}");
    assert!(r.stdout.contains("1 sample(s) rejected"), "{}", r.stdout);
    // the result is that of the undamaged file (one sample of 10 ms bridged)
    let (tmp0, cfg0) = setup("imu.txt", &join(&c.imu), &join(&c.gnss));
    assert!(run(&cfg0, tmp0.path()).ok);
    let (h, h0) = (horizontal_rms_m(tmp.path()), horizontal_rms_m(tmp0.path()));
    assert!(h < h0 + 0.01, "{h} vs {h0}");
}

/// Static alignment with every GNSS fix unusable (sigmas zero, all before or after the IMU
/// data, an empty file): no position to align on, no run; the error is "not a navigation
/// solution" (exit 2) naming where every fix went, the output folder not made.
#[test]
fn static_alignment_without_a_usable_fix_names_where_every_fix_went() {
    let c = case();
    let shift = |dt: f64| -> Vec<Vec<String>> {
        let mut g = c.gnss.clone();
        for r in &mut g {
            r[0] = format!("{}", r[0].parse::<f64>().unwrap() + dt);
        }
        g
    };
    let mut sigma0 = c.gnss.clone();
    for r in &mut sigma0 {
        for x in &mut r[4..7] {
            *x = "0".into();
        }
    }
    let n = c.gnss.len();
    for (gnss, says) in [
        (
            join(&sigma0),
            // (the first fix is 10 ms before the first IMU sample)
            format!(
                "{} fix(es) invalid: a position standard deviation zero",
                n - 1
            ),
        ),
        (
            join(&shift(-10_000.0)),
            format!("{n} of {n} fix(es) are before the IMU data"),
        ),
        (
            join(&shift(10_000.0)),
            format!("{n} of {n} fix(es) are after the IMU data"),
        ),
        (String::new(), "the GNSS data hold no fix".to_string()),
    ] {
        let (tmp, cfg) = setup("imu.txt", &join(&c.imu), &gnss);
        let r = run(&cfg, tmp.path());
        assert_eq!(r.status.code(), Some(2), "{says}: {}", r.stderr);
        assert!(
            r.stderr
                .contains("not a navigation solution (nothing run, no output written")
                && r.stderr.contains("[init.align]")
                && r.stderr.contains(&says),
            "{says}: {}",
            r.stderr
        );
        assert!(!tmp.path().join("out/nav.txt").exists());
    }
    // fixes only after the static window, at rest still (usable ones): the alignment's own error, exit 1
    let late: Vec<Vec<String>> = c
        .gnss
        .iter()
        .filter(|r| r[0].parse::<f64>().unwrap() > c.imu[0][0].parse::<f64>().unwrap() + 30.0)
        .cloned()
        .collect();
    let (tmp, cfg) = setup("imu.txt", &join(&c.imu), &join(&late));
    let r = run(&cfg, tmp.path());
    assert_eq!(r.status.code(), Some(1), "{}", r.stderr);
    assert!(
        r.stderr
            .contains("no valid GNSS fix during the static window"),
        "{}",
        r.stderr
    );
}

#[test]
fn a_half_written_last_imu_line_is_dropped_with_a_warning() {
    let c = case();
    let mut s = join(&c.imu);
    let last = c.imu.last().unwrap();
    let t_last: f64 = last[0].parse().unwrap();
    // the logger was writing the next line when the file was copied
    let _ = write!(s, "{} {} 1.2e-6 -3.", t_last + 0.01, last[1]);
    let (tmp, cfg) = setup("imu.txt", &s, &join(&c.gnss));
    let r = run(&cfg, tmp.path());
    assert!(r.ok, "{}", r.stderr);
    assert!(
        r.stderr.contains(&format!(
            "imu.txt: line {}, the last line (byte offset",
            c.imu.len() + 1
        )) && r.stderr.contains("is incomplete")
            && r.stderr.contains("still being written"),
        "{}",
        r.stderr
    );
    // the run went to the end: its last solution is at the last complete sample
    let nav = std::fs::read_to_string(tmp.path().join("out/nav.txt")).unwrap();
    let t_end: f64 = nav
        .lines()
        .last()
        .unwrap()
        .split_whitespace()
        .nth(1)
        .unwrap()
        .parse()
        .unwrap();
    assert!((t_end - t_last).abs() < 1e-6, "{t_end} vs {t_last}");
}

#[test]
fn an_exact_duplicate_imu_line_is_skipped_and_counted() {
    let c = case();
    let mut rows = c.imu.clone();
    let k = 9000;
    rows.insert(k + 1, rows[k].clone());
    let (tmp, cfg) = setup("imu.txt", &join(&rows), &join(&c.gnss));
    let r = run(&cfg, tmp.path());
    assert!(r.ok, "{}", r.stderr);
    let m = metrics(tmp.path());
    assert_eq!(m["imu"]["rejected"], 1, "{}", m["imu"]);
    assert!(
        m["imu"]["events"][0]["what"]
            .as_str()
            .unwrap()
            .contains("exact repeat of the previous sample"),
        "{}",
        m["imu"]
    );
    assert!(
        m["imu"]["events"][0]["location"]
            .as_str()
            .unwrap()
            .ends_with(&format!("line {}", k + 2)),
        "{}",
        m["imu"]
    );
    // the duplicate changes nothing
    let (tmp0, cfg0) = setup("imu.txt", &join(&c.imu), &join(&c.gnss));
    assert!(run(&cfg0, tmp0.path()).ok);
    let a = std::fs::read_to_string(tmp.path().join("out/nav.txt")).unwrap();
    let b = std::fs::read_to_string(tmp0.path().join("out/nav.txt")).unwrap();
    assert!(a == b, "nav.txt differs with the duplicate line");
}

#[test]
fn a_bad_truth_line_skips_that_epoch_and_the_run_goes_on() {
    let c = case();
    let truth = std::fs::read_to_string(c.dir.join("truth.nav")).unwrap();
    let mut lines: Vec<String> = truth.lines().map(str::to_string).collect();
    let k = 20_000;
    lines[k] = lines[k].replacen(' ', " x", 2);
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::write(d.join("truth.nav"), lines.join("\n") + "\n").unwrap();
    std::fs::write(d.join("imu.txt"), join(&c.imu)).unwrap();
    std::fs::write(d.join("gnss.txt"), join(&c.gnss)).unwrap();
    let cfg = config(d, "imu.txt", None, "gnss.txt", &d.join("truth.nav"));
    let r = run(&cfg, d);
    assert!(r.ok, "{}", r.stderr);
    assert!(
        r.stderr
            .contains(&format!("truth.nav: line {}, column", k + 1))
            && r.stderr.contains("that truth epoch is skipped"),
        "{}",
        r.stderr
    );
    assert!(horizontal_rms_m(d) < 0.1, "{}", metrics(d));
}

#[test]
fn a_utf8_byte_order_mark_is_accepted_at_the_start_of_every_text_input() {
    let c = case();
    let bom = "\u{feff}";
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let truth = std::fs::read_to_string(c.dir.join("truth.nav")).unwrap();
    std::fs::write(d.join("truth.nav"), format!("{bom}{truth}")).unwrap();
    std::fs::write(d.join("imu.txt"), format!("{bom}{}", join(&c.imu))).unwrap();
    std::fs::write(d.join("gnss.txt"), format!("{bom}{}", join(&c.gnss))).unwrap();
    let cfg = config(d, "imu.txt", None, "gnss.txt", &d.join("truth.nav"));
    let text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(&cfg, format!("{bom}{text}")).unwrap();
    let r = run(&cfg, d);
    assert!(r.ok, "{}", r.stderr);
    assert!(horizontal_rms_m(d) < 0.1, "{}", metrics(d));
    // an IMU CSV with a header line
    std::fs::write(d.join("imu.csv"), format!("{bom}{}", imu_csv(1.0, 1.0))).unwrap();
    let cfg = config(
        d,
        "imu.csv",
        Some(&csv_mapping("rad/s", "m/s^2")),
        "gnss.txt",
        &d.join("truth.nav"),
    );
    let r = run(&cfg, d);
    assert!(r.ok, "{}", r.stderr);
}

/// A gap of 200 s in the IMU data (every time from one line on moved 200 s later, 1 Hz GNSS
/// going on through it): the run stops at that line naming the gap too long to bridge, not a
/// GNSS fix the filter could not queue; allowed (`--imu-max-gap 300`), the gap holds more
/// fixes than the filter queues and the error says so, naming the same line.
#[test]
fn an_imu_gap_of_minutes_is_named_with_its_line() {
    let c = case();
    let mut rows = c.imu.clone();
    let k = 30_000;
    for r in &mut rows[k..] {
        let t: f64 = r[0].parse().unwrap();
        r[0] = format!("{:.6}", t + 200.0);
    }
    let (tmp, cfg) = setup("imu.txt", &join(&rows), &join(&c.gnss));
    let r = run(&cfg, tmp.path());
    assert_eq!(r.status.code(), Some(1), "{}", r.stderr);
    assert!(
        r.stderr.contains(&format!("imu.txt line {} (t = ", k + 1))
            && r.stderr
                .contains("exceeds the longest bridged gap (1.000 s)")
            && !r.stderr.contains("fix queue full"),
        "{}",
        r.stderr
    );
    let out = tmp.path().join("out2");
    let r = HOST_SIM.run([
        "run",
        "--config",
        cfg.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
        "--imu-max-gap",
        "300",
    ]);
    assert_eq!(r.status.code(), Some(1), "{}", r.stderr);
    assert!(
        r.stderr
            .contains("one of more than 128 fixes between two IMU samples")
            && r.stderr.contains(&format!("imu.txt line {}", k + 1)),
        "{}",
        r.stderr
    );
}

/// A lever arm of 65 m (centimetres written as metres) is run as configured, with a warning
/// on stderr naming its length and key; a lever arm of a metre or two draws none.
#[test]
fn an_implausible_lever_arm_is_warned_about() {
    let c = case();
    let (tmp, cfg) = setup("imu.txt", &join(&c.imu), &join(&c.gnss));
    let base = std::fs::read_to_string(&cfg).unwrap();
    let with_lever = |lever: &str| {
        let text = base.replace(
            "format = \"text\"\n[truth]",
            &format!("format = \"text\"\nlever_arm_m = {lever}\n[truth]"),
        );
        assert!(text.contains("lever_arm_m"), "{text}");
        std::fs::write(&cfg, text).unwrap();
        run(&cfg, tmp.path())
    };
    let r = with_lever("[65.0, 0.0, 0.0]");
    assert_ne!(r.status.code(), Some(1), "{}", r.stderr);
    assert!(
        r.stderr.contains(
            "warning: lever arm 65.0 m ([gnss] lever_arm_m = [65, 0, 0]): a vehicle's antenna is \
             usually within a few metres of the IMU; check the units\n"
        ),
        "{}",
        r.stderr
    );
    let r = with_lever("[0.0, 1.2, -1.5]");
    assert!(r.ok && !r.stderr.contains("lever arm"), "{}", r.stderr);
}

/// A folder given where a data file is read is named so, with the key or flag that gives it
/// (not the system's "Is a directory"): the IMU and the GNSS path of a run configuration
/// (`run` and `diagnose`), `init --imu` / `--gnss`, and the IMU file of `allan`; nothing is
/// written.
#[test]
fn a_folder_given_as_a_data_file_is_named_with_its_key() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    std::fs::create_dir(d.join("imu.txt")).unwrap();
    std::fs::create_dir(d.join("gnss.txt")).unwrap();
    std::fs::write(d.join("i.txt"), "").unwrap();
    std::fs::write(d.join("g.txt"), "").unwrap();
    let truth = d.join("truth.nav");
    let out = d.join("out");
    let cfg = config(d, "imu.txt", None, "g.txt", &truth);
    let shown = |p: &str| d.join(p).display().to_string();
    for cmd in ["run", "diagnose"] {
        let r = HOST_SIM.run([cmd, "--config", s(&cfg), "--out", s(&out)]);
        assert_eq!(r.status.code(), Some(1), "{}", r.stderr);
        assert_eq!(
            r.stderr,
            format!(
                "error: {} is a folder, not a data file (given as `[imu] path` in {})\n",
                shown("imu.txt"),
                cfg.display()
            )
        );
    }
    let cfg = config(d, "i.txt", None, "gnss.txt", &truth);
    let r = run(&cfg, d);
    assert_eq!(
        r.stderr,
        format!(
            "error: {} is a folder, not a data file (given as `[gnss] path` in {})\n",
            shown("gnss.txt"),
            cfg.display()
        )
    );
    let init = d.join("init.toml");
    for (imu, gnss, flag, folder) in [
        ("imu.txt", "g.txt", "--imu", "imu.txt"),
        ("i.txt", "gnss.txt", "--gnss", "gnss.txt"),
    ] {
        let (imu, gnss) = (d.join(imu), d.join(gnss));
        let r = HOST_SIM.run(["init", "--imu", s(&imu), "--gnss", s(&gnss), "-o", s(&init)]);
        assert_eq!(
            r.stderr,
            format!(
                "error: {} is a folder, not a data file (given as {flag})\n",
                shown(folder)
            )
        );
    }
    let r = HOST_SIM.run(["allan", s(&d.join("imu.txt")), "--out-dir", s(&out)]);
    assert_eq!(
        r.stderr,
        format!("error: {} is a folder, not a data file\n", shown("imu.txt"))
    );
    assert!(!out.exists() && !init.exists());
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}
