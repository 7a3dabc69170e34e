//! The families of [`super`]: each writes its inputs, runs its tries and judges them.

use super::{bounded, hashes, Bins, Expect, Tally};
use anyhow::{Context, Result};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;
use test_support::cli::Bounded;

/// The simulated case: its folder and its IMU and GNSS rows.
struct Case {
    dir: PathBuf,
    imu: Vec<Vec<String>>,
    gnss: Vec<Vec<String>>,
}

fn rows(p: &Path) -> Result<Vec<Vec<String>>> {
    Ok(std::fs::read_to_string(p)
        .with_context(|| format!("reading {}", p.display()))?
        .lines()
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect())
}

fn join(rows: &[Vec<String>]) -> String {
    let mut s = String::new();
    for r in rows {
        s.push_str(&r.join(" "));
        s.push('\n');
    }
    s
}

/// A run configuration `run.toml` in `dir` over `imu` (text, or CSV with the mapping `csv`),
/// `gnss.txt` and `truth`, static alignment over 20 s, the tactical noise; `extra` appended
/// to `[gnss]`.
fn config(dir: &Path, imu: &str, csv: Option<&str>, truth: &Path, extra: &str) -> PathBuf {
    let imu_fmt = csv.map_or("format = \"text\"\n".to_string(), str::to_string);
    let text = format!(
        "name = \"hostile\"\n[imu]\npath = \"{imu}\"\n{imu_fmt}[gnss]\npath = \"gnss.txt\"\n\
         format = \"text\"\n{extra}\n[truth]\npath = \"{}\"\nformat = \"nav_text\"\n[init]\n\
         pos_std_m = [0.05, 0.05, 0.1]\nvel_std_mps = [0.05, 0.05, 0.05]\n\
         att_std_deg = [1.0, 1.0, 5.0]\n[init.align]\nstatic_s = 20.0\n{}",
        truth.display(),
        test_support::runcase::TACTICAL_NOISE
    );
    let p = dir.join("run.toml");
    let _ = std::fs::write(&p, text);
    p
}

/// A folder `name` holding `imu` (as `imu.txt`) and `gnss`, with its configuration.
fn folder(
    root: &Path,
    c: &Case,
    name: &str,
    imu: &str,
    gnss: &str,
    extra: &str,
) -> Result<PathBuf> {
    let d = root.join(name);
    std::fs::create_dir_all(&d)?;
    std::fs::write(d.join("imu.txt"), imu)?;
    std::fs::write(d.join("gnss.txt"), gnss)?;
    Ok(config(&d, "imu.txt", None, &c.dir.join("truth.nav"), extra))
}

fn run_cmd(b: &Bins, cfg: &Path, out: &Path) -> Command {
    let mut c = Command::new(&b.host_sim);
    c.args(["run", "--quiet", "--config"])
        .arg(cfg)
        .arg("--out")
        .arg(out);
    c
}

/// Every family.
pub(super) fn all(b: &Bins, root: &Path, t: &mut Tally) -> Result<()> {
    let dir = root.join("case");
    let sc = crate::root().join("scenarios/land_stops.toml");
    let r = bounded(
        Command::new(&b.host_sim)
            .args([
                "simulate",
                "--errors",
                "tactical",
                "--seed",
                "4",
                "--scenario",
            ])
            .arg(&sc)
            .arg("--out")
            .arg(&dir),
    );
    anyhow::ensure!(
        r.code() == Some(0),
        "simulating the case failed: {}",
        r.stderr
    );
    let c = Case {
        imu: rows(&dir.join("imu.txt"))?,
        gnss: rows(&dir.join("gnss.txt"))?,
        dir,
    };
    outputs(b, root, &c, t)?;
    options(b, root, &c, t)?;
    gnss_unusable(b, root, &c, t)?;
    careless(b, root, &c, t)?;
    config_values(b, root, &c, t)?;
    super::captures::captures(b, root, &c.dir, t)?;
    super::captures::record(b, root, t)?;
    Ok(())
}

/// Spawns `cmd`, waits until `ready` (at most 30 s), sends `sig`, waits for the end (a hang
/// past the limit is killed): [`test_support::cli::interrupt_when_ready`]. `None`: the run
/// ended before it was ready.
pub(super) fn interrupted(
    cmd: &mut Command,
    ready: &dyn Fn() -> bool,
    sig: i32,
) -> Option<Bounded> {
    let mut ready = ready;
    test_support::cli::interrupt_when_ready(
        cmd,
        &mut ready,
        sig,
        Duration::from_secs(30),
        super::LIMIT,
    )
    .ok()
}

/// The output folder at the inputs, links at output names, two runs at once, SIGTERM.
fn outputs(b: &Bins, root: &Path, c: &Case, t: &mut Tally) -> Result<()> {
    const F: &str = "outputs (run)";
    let cfg = folder(root, c, "out-in", &join(&c.imu), &join(&c.gnss), "")?;
    let d = cfg.parent().context("a folder")?.to_path_buf();
    let before = hashes(&d);
    let r = bounded(&mut run_cmd(b, &cfg, &d));
    t.judge(
        F,
        "--out at the inputs' folder",
        &r,
        &Expect::new(&[1], &["holds the input", "nothing was written"]),
    );
    t.protect(F, "--out at the inputs' folder", &before, &hashes(&d));
    // reference outputs
    let refd = root.join("out-ref");
    let r = bounded(&mut run_cmd(b, &cfg, &refd));
    t.judge(F, "reference run", &r, &Expect::new(&[0], &[]));
    let want = std::fs::read(refd.join("nav.txt")).unwrap_or_default();
    // links at output names
    let victims = root.join("victims");
    let out = root.join("out-links");
    std::fs::create_dir_all(&victims)?;
    std::fs::create_dir_all(&out)?;
    for n in [
        "nav.txt",
        "std.txt",
        "metrics.json",
        "nav.txt.partial",
        "metrics.json.partial",
    ] {
        std::fs::write(victims.join(n), format!("victim {n}\n"))?;
        std::os::unix::fs::symlink(victims.join(n), out.join(n))?;
    }
    let before = hashes(&victims);
    let r = bounded(&mut run_cmd(b, &cfg, &out));
    t.judge(F, "links at output names", &r, &Expect::new(&[0], &[]));
    t.protect(F, "links at output names", &before, &hashes(&victims));
    // two runs at once
    let out = root.join("out-two");
    let (r1, r2) = std::thread::scope(|s| {
        let a = s.spawn(|| bounded(&mut run_cmd(b, &cfg, &out)));
        let b2 = s.spawn(|| bounded(&mut run_cmd(b, &cfg, &out)));
        (a.join(), b2.join())
    });
    for r in [r1, r2].into_iter().flatten() {
        let e = if r.code() == Some(0) {
            Expect::new(&[0], &[])
        } else {
            Expect::new(&[1], &["another run (pid "])
        };
        t.judge(F, "two runs at once", &r, &e);
    }
    if std::fs::read(out.join("nav.txt")).unwrap_or_default() != want {
        t.differs(F, "two runs at once", "nav.txt is not the reference run's");
    }
    // SIGTERM mid-run into the folder of a complete run
    let before = hashes(&refd);
    let ready = || {
        std::fs::read_dir(&refd)
            .into_iter()
            .flatten()
            .flatten()
            .any(|e| {
                e.file_name()
                    .to_string_lossy()
                    .starts_with(".nav-out-stage")
                    && std::fs::metadata(e.path().join("nav.txt.partial"))
                        .is_ok_and(|m| m.len() > 0)
            })
    };
    if let Some(r) = interrupted(&mut run_cmd(b, &cfg, &refd), &ready, libc::SIGTERM) {
        t.judge(
            F,
            "SIGTERM mid-run",
            &r,
            &Expect::new(&[143], &["interrupted by SIGTERM"]),
        );
        let after = hashes(&refd);
        t.protect(F, "SIGTERM mid-run", &before, &after);
        if !after.contains_key("metrics.json.partial") {
            t.differs(F, "SIGTERM mid-run", "no metrics.json.partial");
        }
    }
    Ok(())
}

/// Unbounded option values: refused, naming the option.
fn options(b: &Bins, root: &Path, c: &Case, t: &mut Tally) -> Result<()> {
    const F: &str = "unbounded options";
    let cfg = folder(root, c, "opts", &join(&c.imu), &join(&c.gnss), "")?;
    let out = root.join("opts-out");
    for args in [
        ["--outage", "1e9:10"],
        ["--outage", "10:1e-4"],
        ["--periodic-outage", "0:1e-5:1e-5"],
        ["--nav-rate", "NaN"],
        ["--nav-rate", "0"],
        ["--std-rate", "-1"],
        ["--imu-time-offset", "1e300"],
        ["--noise-scale", "1e300"],
        ["--imu-max-gap", "1e300"],
        ["--imu-time-offset", "inf"],
    ] {
        let r = bounded(run_cmd(b, &cfg, &out).arg(format!("{}={}", args[0], args[1])));
        t.judge(F, &args.join(" "), &r, &Expect::new(&[1], &[args[0]]));
    }
    Ok(())
}

/// Every fix unusable: not a navigation solution (exit 2), the cause named.
fn gnss_unusable(b: &Bins, root: &Path, c: &Case, t: &mut Tally) -> Result<()> {
    const F: &str = "all GNSS unusable";
    let shift = |dt: f64| -> Vec<Vec<String>> {
        c.gnss
            .iter()
            .map(|r| {
                let mut r = r.clone();
                r[0] = format!("{}", r[0].parse::<f64>().unwrap_or(0.0) + dt);
                r
            })
            .collect()
    };
    let sigma0: Vec<Vec<String>> = c
        .gnss
        .iter()
        .map(|r| {
            let mut r = r.clone();
            for x in r.iter_mut().take(7).skip(4) {
                *x = "0".into();
            }
            r
        })
        .collect();
    for (name, gnss, says) in [
        ("sigmas 0", join(&sigma0), "standard deviation zero"),
        (
            "fixes before the IMU span",
            join(&shift(-10_000.0)),
            "before the IMU data",
        ),
        (
            "fixes after the IMU span",
            join(&shift(10_000.0)),
            "after the IMU data",
        ),
        ("empty GNSS file", String::new(), "hold no fix"),
    ] {
        let cfg = folder(
            root,
            c,
            &format!("gnss-{}", name.replace(' ', "-")),
            &join(&c.imu),
            &gnss,
            "",
        )?;
        let out = cfg.with_file_name("out");
        let r = bounded(&mut run_cmd(b, &cfg, &out));
        t.judge(
            F,
            name,
            &r,
            &Expect::new(&[2], &["not a navigation solution", says]),
        );
    }
    Ok(())
}

/// The IMU increments as a CSV of mean rates and specific forces, scaled by `kg` and `ka`.
fn imu_csv(c: &Case, kg: f64, ka: f64) -> String {
    let mut s = String::from("t,gx,gy,gz,ax,ay,az\n");
    let num = |x: &str| x.parse::<f64>().unwrap_or(f64::NAN);
    let mut tp = c.imu.first().map_or(0.0, |r| num(&r[0])) - 0.01;
    for r in &c.imu {
        let tt = num(&r[0]);
        let dt = tt - tp;
        tp = tt;
        let _ = write!(s, "{}", r[0]);
        for (k, x) in r.iter().skip(1).take(6).enumerate() {
            let _ = write!(s, ",{}", num(x) / dt * if k < 3 { kg } else { ka });
        }
        s.push('\n');
    }
    s
}

/// Careless data: each cause named on stderr, or (damage that must change nothing) the
/// undamaged solution.
fn careless(b: &Bins, root: &Path, c: &Case, t: &mut Tally) -> Result<()> {
    const F: &str = "careless data";
    let (imu, gnss) = (join(&c.imu), join(&c.gnss));
    let cfg = folder(root, c, "careless-ref", &imu, &gnss, "")?;
    let r = bounded(&mut run_cmd(b, &cfg, &cfg.with_file_name("out")));
    t.judge(F, "undamaged", &r, &Expect::new(&[0], &[]));
    let want = std::fs::read(cfg.with_file_name("out").join("nav.txt")).unwrap_or_default();
    let mut tries: Vec<(&str, PathBuf, Expect)> = Vec::new();
    // g read as m/s^2
    let d = root.join("careless-g");
    std::fs::create_dir_all(&d)?;
    std::fs::write(d.join("imu.csv"), imu_csv(c, 1.0, 1.0 / 9.80665))?;
    std::fs::write(d.join("gnss.txt"), &gnss)?;
    let csv = "format = \"csv\"\n[imu.csv]\nskip_lines = 1\ngyro_unit = \"rad/s\"\n\
               accel_unit = \"m/s^2\"\nconvention = \"interval_mean\"\n[imu.csv.columns]\n\
               time = 1\ngyro = [2, 3, 4]\naccel = [5, 6, 7]\n[imu.csv.time]\nkind = \"seconds\"\n";
    let g = config(&d, "imu.csv", Some(csv), &c.dir.join("truth.nav"), "");
    tries.push((
        "accelerations in g read as m/s^2",
        g,
        Expect::new(&[0, 1, 2], &["in g but read as m/s^2"]),
    ));
    // 100 Hz increments stamped at 200 Hz
    let t0 = c
        .imu
        .first()
        .and_then(|r| r[0].parse::<f64>().ok())
        .unwrap_or(0.0);
    let fast: Vec<Vec<String>> = c
        .imu
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let mut r = r.clone();
            r[0] = format!("{}", t0 + k as f64 * 0.005);
            r
        })
        .collect();
    let p = folder(root, c, "careless-200", &join(&fast), &gnss, "")?;
    tries.push((
        "100 Hz increments stamped at 200 Hz",
        p,
        Expect::new(&[0, 1, 2], &["increments of 100 Hz stamped at 200 Hz"]),
    ));
    // GNSS 0.5 s late
    let late: Vec<Vec<String>> = c
        .gnss
        .iter()
        .map(|r| {
            let mut r = r.clone();
            r[0] = format!("{}", r[0].parse::<f64>().unwrap_or(0.0) + 0.5);
            r
        })
        .collect();
    let p = folder(root, c, "careless-late", &imu, &join(&late), "")?;
    tries.push((
        "GNSS 0.5 s late",
        p,
        Expect::new(&[0, 2], &["time_offset_s", "late"]),
    ));
    // a half-written last IMU line
    let mut half = imu.clone();
    let t_last = c
        .imu
        .last()
        .and_then(|r| r[0].parse::<f64>().ok())
        .unwrap_or(0.0);
    let _ = write!(half, "{} 1.5e-5 1.2e-6 -3.", t_last + 0.01);
    let p = folder(root, c, "careless-half", &half, &gnss, "")?;
    let n = c.imu.len() + 1;
    tries.push((
        "half-written last IMU line",
        p,
        Expect::new(&[0], &["is incomplete"]).at(&["imu.txt", &format!("line {n}")]),
    ));
    // a bad truth line
    let d = root.join("careless-truth");
    std::fs::create_dir_all(&d)?;
    let truth = std::fs::read_to_string(c.dir.join("truth.nav"))?;
    let mut lines: Vec<String> = truth.lines().map(str::to_string).collect();
    if let Some(l) = lines.get_mut(20_000) {
        *l = l.replacen(' ', " x", 2);
    }
    std::fs::write(d.join("truth.nav"), lines.join("\n") + "\n")?;
    std::fs::write(d.join("imu.txt"), &imu)?;
    std::fs::write(d.join("gnss.txt"), &gnss)?;
    let p = config(&d, "imu.txt", None, &d.join("truth.nav"), "");
    tries.push((
        "bad truth line",
        p,
        Expect::new(&[0], &["that truth epoch is skipped"]).at(&["truth.nav: line 20001, column"]),
    ));
    for (name, cfg, e) in &tries {
        let r = bounded(&mut run_cmd(b, cfg, &cfg.with_file_name("out")));
        t.judge(F, name, &r, e);
    }
    unchanged(b, root, c, t, &want)
}

/// Damage that must change nothing: a duplicated IMU line (counted, named in metrics.json
/// with its line), UTF-8 byte-order marks; `want` is the undamaged run's `nav.txt`.
fn unchanged(b: &Bins, root: &Path, c: &Case, t: &mut Tally, want: &[u8]) -> Result<()> {
    const F: &str = "careless data";
    let (imu, gnss) = (join(&c.imu), join(&c.gnss));
    let mut dup = c.imu.clone();
    if let Some(r) = dup.get(9000).cloned() {
        dup.insert(9001, r);
    }
    let bom = "\u{feff}";
    let p_dup = folder(root, c, "careless-dup", &join(&dup), &gnss, "")?;
    let p_bom = folder(
        root,
        c,
        "careless-bom",
        &format!("{bom}{imu}"),
        &format!("{bom}{gnss}"),
        "",
    )?;
    let text = std::fs::read_to_string(&p_bom)?;
    std::fs::write(&p_bom, format!("{bom}{text}"))?;
    for (name, cfg, says) in [
        ("duplicated IMU line", &p_dup, "1 sample(s) rejected"),
        ("UTF-8 byte-order marks", &p_bom, ""),
    ] {
        let out = cfg.with_file_name("out");
        let r = bounded(&mut run_cmd(b, cfg, &out));
        let e = Expect::new(
            &[0],
            if says.is_empty() {
                &[]
            } else {
                std::slice::from_ref(&says)
            },
        );
        t.judge(F, name, &r, &e);
        if std::fs::read(out.join("nav.txt")).unwrap_or_default() != want {
            t.differs(F, name, "nav.txt differs from the undamaged run's");
        }
        if name.starts_with("duplicated") {
            let m = std::fs::read_to_string(out.join("metrics.json")).unwrap_or_default();
            if !m.contains("exact repeat of the previous sample") || !m.contains("line 9002") {
                t.differs(F, name, "metrics.json does not name the repeated line 9002");
            }
        }
    }
    Ok(())
}

/// Bad configuration values: refused naming the file, the line and the key.
fn config_values(b: &Bins, root: &Path, c: &Case, t: &mut Tally) -> Result<()> {
    const F: &str = "bad config values";
    for (name, extra, at) in [
        (
            "lever arm 1e300",
            "lever_arm_m = [1e300, 0.0, 0.0]",
            "gnss.lever_arm_m",
        ),
        (
            "lever arm nan",
            "lever_arm_m = [nan, 0.0, 0.0]",
            "gnss.lever_arm_m",
        ),
        (
            "GNSS time offset 1e300",
            "time_offset_s = 1e300",
            "gnss.time_offset_s",
        ),
        (
            "GNSS time offset as a string",
            "time_offset_s = \"0.5\"",
            "time_offset_s",
        ),
        (
            "leap seconds -100000",
            "[gnss.log]\nleap_seconds = -100000",
            "gnss.log.leap_seconds",
        ),
        ("TOML syntax error", "lever_arm_m = [0.1, 0.2", "line"),
        ("unknown key", "lever_arm = [0.1, 0.2, 0.3]", "lever_arm"),
    ] {
        let cfg = folder(root, c, "cfg", &join(&c.imu), &join(&c.gnss), extra)?;
        let r = bounded(&mut run_cmd(b, &cfg, &root.join("cfg-out")));
        t.judge(
            F,
            name,
            &r,
            &Expect::new(&[1], &[]).at(&["run.toml", "line ", at]),
        );
    }
    Ok(())
}
