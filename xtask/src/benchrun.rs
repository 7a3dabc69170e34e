//! `cargo xtask bench-run`: wall time, CPU time and peak RSS of `host-sim run` and
//! `host-sim diagnose` on a generated 200 Hz drive (40 min by default, `--hours 4` for the
//! long case; `--long-hours 4` adds rows of `run --smooth` and `diagnose` on a 4-hour drive,
//! one measurement per binary, to the 40-minute table), against a baseline binary measured in the same invocation (ratios, not
//! absolute times), printed beside reference figures of KF-GINS (C++, on the same case size and
//! machine class: 12.6 s wall, at most 11 MiB).
//!
//! The baseline is `host-sim` built from git revision `--baseline` (default `e9a1122`, the
//! main branch before the streaming engine) in `target/bench-base` (source from `git archive`,
//! its own target directory: built once, kept). Each measurement is a whole process:
//! `wait4` gives its CPU time (user + system), its own `VmHWM` (read while it runs) its peak
//! resident set (see [`measure`]). The two
//! binaries alternate, `--repeat` times each, and the median is reported. `nav.txt` of the
//! two runs is compared byte for byte.
//!
//! The case is written by `host-sim simulate --kf-gins` (IMU text, GNSS text, KF-GINS YAML)
//! and run as `host-sim run --config kf-gins.yaml`, as the peer was; its `truth.nav` is moved
//! aside (the peer reads no truth; with it, metrics are against the truth, which both
//! binaries hold in memory). `run --smooth` is measured too (skipped with `--no-smooth`;
//! "n/a" for a baseline without it).
//!
//! `--baseline-bin PATH` uses an already built baseline executable instead of building one
//! from git. `--peer-kfgins PATH` also runs KF-GINS (C++, built from its public source outside
//! the repository; see docs/benchmarks.md) on the same files in the same invocation,
//! alternating with ours, and reports the ratios: its YAML is the case's with `starttime` set
//! to the first IMU time (KF-GINS rejects a start before the first IMU line) and `outputpath`
//! in the bench directory. The last navigation epoch of both is compared (positions in m).

use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// KF-GINS on the 40-min 200 Hz case (reference figures): wall s, peak MiB.
const PEER_WALL_S: f64 = 12.6;
const PEER_RSS_MIB: f64 = 11.0;

/// One whole-process measurement.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Meas {
    /// Wall time, s.
    pub(crate) wall_s: f64,
    /// CPU time (user + system), s.
    pub(crate) cpu_s: f64,
    /// Peak resident set, MiB (0 when the process ended before it could be read).
    pub(crate) rss_mib: f64,
}

/// Longest a measured command may run before it is killed (and the benchmark fails), s.
const MEASURE_LIMIT_S: u64 = 6 * 3600;

/// Runs `cmd` to its end and measures that process alone
/// ([`test_support::cli::try_run_bounded`]): its CPU time (user + system) from `wait4`, its
/// peak resident set from its own `VmHWM`, read while it runs. Not `wait4`'s `ru_maxrss`:
/// that keeps the high-water mark of the address space the child left at `exec`, xtask's
/// own. Returns the figures and the command's standard output; `Err` when the command fails
/// or is still running after [`MEASURE_LIMIT_S`].
pub(crate) fn measure_with_output(cmd: &mut Command) -> Result<(Meas, String)> {
    eprintln!("  $ {}", crate::show(cmd));
    let limit = std::time::Duration::from_secs(MEASURE_LIMIT_S);
    let r = test_support::cli::try_run_bounded(cmd, limit)
        .with_context(|| format!("running {}", crate::show(cmd)))?;
    if r.timed_out() {
        bail!(
            "`{}` still running after {MEASURE_LIMIT_S} s: killed",
            crate::show(cmd)
        );
    }
    if r.code() != Some(0) {
        bail!(
            "`{}` failed ({:?}): {}{}",
            crate::show(cmd),
            r.status,
            r.stdout,
            r.stderr
        );
    }
    let m = Meas {
        wall_s: r.wall_s,
        cpu_s: r.cpu_s,
        rss_mib: r.max_rss_kib as f64 / 1024.0,
    };
    Ok((m, r.stdout))
}

/// [`measure_with_output`] without the output, and an error when the peak resident set
/// could not be read.
fn measure(cmd: &mut Command) -> Result<Meas> {
    let (m, _) = measure_with_output(cmd)?;
    if m.rss_mib == 0.0 {
        bail!(
            "`{}` ended before its resident set could be read",
            crate::show(cmd)
        );
    }
    Ok(m)
}

fn median(v: &mut [Meas]) -> Meas {
    let m = |f: fn(&Meas) -> f64, v: &mut [Meas]| {
        let mut x: Vec<f64> = v.iter().map(f).collect();
        x.sort_by(f64::total_cmp);
        x.get(x.len() / 2).copied().unwrap_or(f64::NAN)
    };
    Meas {
        wall_s: m(|x| x.wall_s, v),
        cpu_s: m(|x| x.cpu_s, v),
        rss_mib: m(|x| x.rss_mib, v),
    }
}

/// Builds `host-sim` in release from the current tree; returns the executable.
fn build_current() -> Result<PathBuf> {
    build_in(&crate::root(), None)
}

fn build_in(dir: &Path, target_dir: Option<&Path>) -> Result<PathBuf> {
    let mut c = Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()));
    c.args([
        "build",
        "--release",
        "-p",
        "host-sim",
        "--bin",
        "host-sim",
        "--message-format=json-render-diagnostics",
    ])
    .current_dir(dir)
    .stderr(Stdio::inherit());
    if let Some(t) = target_dir {
        c.arg("--target-dir").arg(t);
    }
    eprintln!("  $ {}", crate::show(&c));
    let out = c.output().context("running cargo build")?;
    if !out.status.success() {
        bail!(
            "building host-sim in {} failed ({})",
            dir.display(),
            out.status
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines()
        .filter(|l| l.contains("\"name\":\"host-sim\"") && l.contains("\"kind\":[\"bin\"]"))
        .find_map(|l| {
            let i = l.find("\"executable\":\"")? + "\"executable\":\"".len();
            let j = l[i..].find('"')?;
            Some(PathBuf::from(&l[i..i + j]))
        })
        .context("cargo reported no host-sim executable")
}

/// Builds the baseline `host-sim` from git revision `rev` in `target/bench-base`.
fn build_baseline(rev: &str) -> Result<PathBuf> {
    let base = crate::root().join("target").join("bench-base");
    let src = base.join("src");
    let stamp = base.join("src.rev");
    let have = std::fs::read_to_string(&stamp).unwrap_or_default();
    if have.trim() != rev || !src.join("Cargo.toml").exists() {
        let _ = std::fs::remove_dir_all(&src);
        std::fs::create_dir_all(&src)?;
        let sh = format!(
            "git -C {} archive {rev} | tar -x -C {}",
            crate::root().display(),
            src.display()
        );
        let st = Command::new("sh").args(["-c", &sh]).status()?;
        if !st.success() {
            let _ = std::fs::remove_dir_all(&src);
            bail!("git archive {rev} failed");
        }
        std::fs::write(&stamp, rev)?;
    }
    build_in(&src, Some(&base.join("target")))
}

/// A drive of `seconds` at 200 Hz: 3 min static, then blocks of driving with turns, speed
/// changes and stops, 2 min static at the end (the scenario's TOML, built with the
/// simulator's own types).
pub(crate) fn scenario(seconds: f64) -> String {
    let mut b = nav_sim::ScenarioBuilder::new("bench-run")
        .description("generated drive for cargo xtask bench-run")
        .start(48.199, 16.37, 220.0, 120.0)
        .gps_time(2227, 200000.0)
        .imu_rate_hz(200.0)
        .stationary(180.0);
    // one block: 10 + 120 + ~8.4 + 15 + 200 + ~9.4 + 10 + 30 (stop) = ~403 s
    let block_s = 10.0 + 120.0 + 8.4 + 15.0 + 200.0 + 9.4 + 10.0 + 30.0;
    let mut t = 180.0 + 120.0;
    while t + block_s <= seconds {
        b = b
            .accelerate(15.0, 10.0)
            .cruise(120.0)
            .turn(90.0, 80.0)
            .accelerate(25.0, 15.0)
            .cruise(200.0)
            .turn(-90.0, 150.0)
            .brake(0.0, 10.0)
            .stationary(30.0);
        t += block_s;
    }
    // the last static segment to 0.1 s, as the case files have always been written
    let last_s = ((seconds - t + 120.0).max(120.0) * 10.0).round() / 10.0;
    b.stationary(last_s).build()
}

/// What to measure (the command line of `cargo xtask bench-run`).
pub struct Opts {
    /// Length of the drive, hours.
    pub hours: f64,
    /// Git revision of the baseline.
    pub baseline: String,
    /// A prebuilt baseline executable (instead of building `baseline`).
    pub baseline_bin: Option<PathBuf>,
    /// Measurements per binary (median reported).
    pub repeat: usize,
    /// Keep the bench directory.
    pub keep: bool,
    /// Skip `diagnose`.
    pub no_diagnose: bool,
    /// Skip `run --smooth`.
    pub no_smooth: bool,
    /// KF-GINS executable for a paired peer run.
    pub peer_kfgins: Option<PathBuf>,
    /// Also the rows of `run --smooth` and `diagnose` on a drive of this many hours (one
    /// measurement per binary).
    pub long_hours: Option<f64>,
}

/// Runs the benchmark.
pub fn run(o: &Opts) -> Result<()> {
    let hours = o.hours;
    for (flag, h) in [("--hours", Some(hours)), ("--long-hours", o.long_hours)] {
        if let Some(h) = h.filter(|h| !(*h > 0.0 && *h <= 24.0)) {
            bail!("{flag} {h}: expected 0 < hours <= 24");
        }
    }
    let cur = build_current()?;
    let (base, rev) = match &o.baseline_bin {
        Some(b) => (b.clone(), b.display().to_string()),
        None => (build_baseline(&o.baseline)?, o.baseline.clone()),
    };
    let dir = std::env::temp_dir().join(format!("navcore-bench-run-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let r = run_in(&dir, &cur, &base, &rev, o);
    if o.keep {
        eprintln!("  kept {}", dir.display());
    } else {
        let _ = std::fs::remove_dir_all(&dir);
    }
    r
}

/// The peer's YAML: the case's with `starttime` at the first IMU time and `outputpath` `out`.
fn peer_yaml(case: &Path, out: &Path) -> Result<PathBuf> {
    use std::io::BufRead;
    let imu = std::fs::File::open(case.join("imu.txt"))?;
    let mut first = String::new();
    std::io::BufReader::new(imu).read_line(&mut first)?;
    let t0 = first
        .split_whitespace()
        .next()
        .context("empty imu.txt")?
        .to_string();
    let yaml = std::fs::read_to_string(case.join("kf-gins.yaml"))?;
    let mut text = String::new();
    for line in yaml.lines() {
        if line.starts_with("starttime:") {
            text.push_str(&format!("starttime: {t0}\n"));
        } else if line.starts_with("outputpath:") {
            text.push_str(&format!("outputpath: \"{}\"\n", out.display()));
        } else {
            text.push_str(line);
            text.push('\n');
        }
    }
    let p = case.join("kf-gins-peer.yaml");
    std::fs::write(&p, text)?;
    std::fs::create_dir_all(out)?;
    Ok(p)
}

/// lat, lon (deg) and h (m) of the last line of a nav file (KF-GINS or ours: columns 3-5).
fn last_llh(p: &Path) -> Result<[f64; 3]> {
    let text = std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
    let line = text.lines().last().context("empty nav file")?;
    let v: Vec<f64> = line
        .split_whitespace()
        .map(|x| x.parse::<f64>())
        .collect::<Result<_, _>>()
        .context("nav line")?;
    match v.get(2..5) {
        Some(&[a, b, c]) => Ok([a, b, c]),
        _ => bail!("short nav line in {}", p.display()),
    }
}

/// Writes the bench case of `hours` into `dir/name` (`host-sim simulate --kf-gins` of
/// [`scenario`]), its truth moved aside; returns its KF-GINS YAML.
fn write_case(dir: &Path, name: &str, cur: &Path, hours: f64) -> Result<PathBuf> {
    let sc = dir.join(format!("{name}-scenario.toml"));
    std::fs::write(&sc, scenario(hours * 3600.0))?;
    let case = dir.join(name);
    let st = Command::new(cur)
        .args(["simulate", "--scenario"])
        .arg(&sc)
        .args(["--errors", "tactical", "--seed", "1", "--kf-gins", "--out"])
        .arg(&case)
        .stdout(Stdio::null())
        .status()?;
    if !st.success() {
        bail!("host-sim simulate failed");
    }
    let truth = case.join("truth.nav");
    if truth.exists() {
        std::fs::rename(&truth, dir.join(format!("{name}-truth.nav.aside")))?;
    }
    let imu_bytes = std::fs::metadata(case.join("imu.txt"))?.len();
    eprintln!(
        "{}: {hours:.2} h at 200 Hz, imu.txt {:.0} MB",
        case.display(),
        imu_bytes as f64 / 1e6
    );
    Ok(case.join("kf-gins.yaml"))
}

/// `host-sim SUB --config YAML --out OUT --quiet [--smooth]`.
fn host_sim(bin: &Path, sub: &str, yaml: &Path, out: &Path, smooth: bool) -> Command {
    let mut c = Command::new(bin);
    c.arg(sub)
        .arg("--config")
        .arg(yaml)
        .arg("--out")
        .arg(out)
        .arg("--quiet");
    if smooth {
        c.arg("--smooth");
    }
    c
}

/// Measurements of the baseline and of this tree, alternating.
#[derive(Default)]
struct Pair {
    base: Vec<Meas>,
    cur: Vec<Meas>,
}

/// A command measured for a row: `host-sim SUB [--smooth]`, its outputs in `dir/TAG-base`
/// and `dir/TAG-cur`.
struct Job<'a> {
    tag: &'a str,
    sub: &'a str,
    smooth: bool,
    /// A failing baseline (one that predates the command) is noted and left out ("n/a")
    /// instead of an error.
    base_optional: bool,
}

/// The jobs of the table's rows.
const DIAGNOSE: Job<'static> = Job {
    tag: "diag",
    sub: "diagnose",
    smooth: false,
    base_optional: false,
};
const SMOOTH: Job<'static> = Job {
    tag: "smooth",
    sub: "run",
    smooth: true,
    base_optional: true,
};

/// Measures `job` of `base` and `cur` on `yaml`, alternating, `repeat` times each.
fn measure_pair(
    (base, cur): (&Path, &Path),
    yaml: &Path,
    dir: &Path,
    job: &Job<'_>,
    repeat: usize,
) -> Result<Pair> {
    let Job {
        tag,
        sub,
        smooth,
        base_optional,
    } = *job;
    let mut p = Pair::default();
    let mut base_ok = true;
    let (out_base, out_cur) = (
        dir.join(format!("{tag}-base")),
        dir.join(format!("{tag}-cur")),
    );
    for _ in 0..repeat {
        if base_ok {
            match measure(&mut host_sim(base, sub, yaml, &out_base, smooth)) {
                Ok(m) => p.base.push(m),
                Err(e) if base_optional => {
                    eprintln!("  baseline {tag}: {e:#} (n/a)");
                    base_ok = false;
                }
                Err(e) => return Err(e),
            }
        }
        p.cur
            .push(measure(&mut host_sim(cur, sub, yaml, &out_cur, smooth))?);
    }
    Ok(p)
}

/// Prints the table's row of `p` (medians; the ratios now / base) and returns this tree's
/// median.
fn row(name: &str, p: &mut Pair) -> Meas {
    let c = median(&mut p.cur);
    if p.base.is_empty() {
        println!(
            "{name:<13} {:>9} {:>9.2} {:>7} | {:>8} {:>8.2} {:>7} | {:>9} {:>9.1} {:>7}",
            "n/a", c.wall_s, "", "n/a", c.cpu_s, "", "n/a", c.rss_mib, ""
        );
        return c;
    }
    let b = median(&mut p.base);
    println!(
        "{name:<13} {:>9.2} {:>9.2} {:>7.3} | {:>8.2} {:>8.2} {:>7.3} | {:>9.1} {:>9.1} {:>7.3}",
        b.wall_s,
        c.wall_s,
        c.wall_s / b.wall_s,
        b.cpu_s,
        c.cpu_s,
        c.cpu_s / b.cpu_s,
        b.rss_mib,
        c.rss_mib,
        c.rss_mib / b.rss_mib
    );
    c
}

/// The rows of the long drive (`--long-hours`): `run --smooth` and `diagnose`, once per
/// binary.
struct LongRows {
    hours: f64,
    smooth: Option<Pair>,
    diagnose: Option<Pair>,
}

/// Measures the long drive's rows (`o.long_hours`), each binary once, alternating.
fn long_rows(dir: &Path, bins: (&Path, &Path), o: &Opts) -> Result<Option<LongRows>> {
    let Some(hours) = o.long_hours else {
        return Ok(None);
    };
    let yaml = write_case(dir, "long", bins.1, hours)?;
    let smooth = (!o.no_smooth)
        .then(|| {
            let job = Job {
                tag: "long-smooth",
                ..SMOOTH
            };
            measure_pair(bins, &yaml, dir, &job, 1)
        })
        .transpose()?;
    let diagnose = (!o.no_diagnose)
        .then(|| {
            let job = Job {
                tag: "long-diag",
                ..DIAGNOSE
            };
            measure_pair(bins, &yaml, dir, &job, 1)
        })
        .transpose()?;
    Ok(Some(LongRows {
        hours,
        smooth,
        diagnose,
    }))
}

fn run_in(dir: &Path, cur: &Path, base: &Path, rev: &str, o: &Opts) -> Result<()> {
    let (hours, repeat) = (o.hours, o.repeat.max(1));
    let yaml = write_case(dir, "case", cur, hours)?;
    let peer = match &o.peer_kfgins {
        Some(p) => Some((
            p.clone(),
            peer_yaml(&dir.join("case"), &dir.join("peer-out"))?,
        )),
        None => None,
    };
    let (mut run, mut pk) = (Pair::default(), Vec::new());
    for _ in 0..repeat {
        let out = dir.join("out-base");
        run.base
            .push(measure(&mut host_sim(base, "run", &yaml, &out, false))?);
        let out = dir.join("out-cur");
        run.cur
            .push(measure(&mut host_sim(cur, "run", &yaml, &out, false))?);
        if let Some((bin, y)) = &peer {
            pk.push(measure(Command::new(bin).arg(y))?);
        }
    }
    let same =
        std::fs::read(dir.join("out-base/nav.txt"))? == std::fs::read(dir.join("out-cur/nav.txt"))?;
    let bins = (base, cur);
    let mut diag = (!o.no_diagnose)
        .then(|| measure_pair(bins, &yaml, dir, &DIAGNOSE, repeat))
        .transpose()?;
    // run --smooth: the baseline may predate it (then n/a)
    let mut smooth = (!o.no_smooth)
        .then(|| measure_pair(bins, &yaml, dir, &SMOOTH, repeat))
        .transpose()?;
    let long = long_rows(dir, bins, o)?;
    println!(
        "\nbench-run: {hours} h at 200 Hz, median of {repeat}; baseline = host-sim at {rev}\n\
         {:<13} {:>9} {:>9} {:>7} | {:>8} {:>8} {:>7} | {:>9} {:>9} {:>7}",
        "",
        "wall base",
        "wall now",
        "ratio",
        "cpu base",
        "cpu now",
        "ratio",
        "MiB base",
        "MiB now",
        "ratio"
    );
    let c = row("run", &mut run);
    if let Some(p) = diag.as_mut() {
        row("diagnose", p);
    }
    if let Some(p) = smooth.as_mut() {
        row("run-smooth", p);
    }
    if let Some(mut l) = long {
        println!("{} h at 200 Hz, one measurement each:", l.hours);
        if let Some(p) = l.smooth.as_mut() {
            row("run-smooth", p);
        }
        if let Some(p) = l.diagnose.as_mut() {
            row("diagnose", p);
        }
    }
    println!(
        "nav.txt of run: {}",
        if same {
            "byte-identical to the baseline's"
        } else {
            "DIFFERS from the baseline's"
        }
    );
    match peer {
        Some(_) => print_peer(dir, &c, &mut pk)?,
        None => print_peer_reference(hours, &c),
    }
    if !same {
        bail!("nav.txt differs from the baseline's");
    }
    Ok(())
}

/// The paired peer run's figures and the last epoch's difference.
fn print_peer(dir: &Path, c: &Meas, pk: &mut [Meas]) -> Result<()> {
    let p = median(pk);
    println!(
        "peer (KF-GINS, same files, this invocation): wall {:.2} s, cpu {:.2} s, peak {:.1} MiB; \
         run/peer: wall {:.3} (target <= 1/15 = 0.067), cpu {:.3}, peak {:.2}",
        p.wall_s,
        p.cpu_s,
        p.rss_mib,
        c.wall_s / p.wall_s,
        c.cpu_s / p.cpu_s,
        c.rss_mib / p.rss_mib
    );
    let ours = last_llh(&dir.join("out-cur/nav.txt"))?;
    let theirs = last_llh(&dir.join("peer-out/KF_GINS_Navresult.nav"))?;
    let r = 6_371_000.0_f64;
    let dn = (ours[0] - theirs[0]).to_radians() * r;
    let de = (ours[1] - theirs[1]).to_radians() * r * ours[0].to_radians().cos();
    println!(
        "last epoch, ours - peer: north {:.2} mm, east {:.2} mm, height {:.2} mm",
        dn * 1e3,
        de * 1e3,
        (ours[2] - theirs[2]) * 1e3
    );
    Ok(())
}

/// `run` against the peer's reference figures (scaled by length).
fn print_peer_reference(hours: f64, c: &Meas) {
    let scale = hours / (40.0 / 60.0);
    println!(
        "peer (KF-GINS reference, 40-min case: {PEER_WALL_S} s, <= {PEER_RSS_MIB} MiB{}): run \
         wall {:.3}x the peer's (target <= 1/15 = 0.067), peak {:.1} MiB (target <= 32)",
        if (scale - 1.0).abs() > 1e-9 {
            format!(
                "; scaled x{scale:.1} by length: {:.1} s",
                PEER_WALL_S * scale
            )
        } else {
            String::new()
        },
        c.wall_s / (PEER_WALL_S * scale),
        c.rss_mib
    );
}

#[cfg(test)]
mod tests {
    /// Environment variable asking [`child_holding_memory`] to hold that many MiB.
    const CHILD_MIB: &str = "XTASK_BENCH_CHILD_MIB";

    /// Not a test of its own: the child process of
    /// [`the_peak_memory_is_the_measured_childs_own`] (this test binary run again), holding
    /// `XTASK_BENCH_CHILD_MIB` MiB, touched, for 0.3 s.
    #[test]
    #[ignore = "run as a child process by the_peak_memory_is_the_measured_childs_own"]
    fn child_holding_memory() {
        let Some(mib) = std::env::var(CHILD_MIB)
            .ok()
            .and_then(|v| v.parse::<usize>().ok())
        else {
            return;
        };
        let v = vec![1u8; mib << 20];
        std::thread::sleep(std::time::Duration::from_millis(300));
        assert!(v.iter().step_by(4096).all(|&b| b == 1));
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn the_peak_memory_is_the_measured_childs_own() {
        // xtask holds 256 MiB, touched; the child 64 MiB (plus its test harness)
        let big = vec![1u8; 256 << 20];
        let mut cmd = std::process::Command::new(std::env::current_exe().expect("test binary"));
        cmd.args([
            "--exact",
            "benchrun::tests::child_holding_memory",
            "--ignored",
            "--test-threads=1",
        ])
        .env(CHILD_MIB, "64");
        let m = super::measure(&mut cmd).expect("the child runs");
        assert!(big.iter().step_by(4096).all(|&b| b == 1));
        assert!(m.rss_mib > 64.0 && m.rss_mib < 96.0, "{m:?}");
        assert!(m.cpu_s >= 0.0 && m.wall_s >= 0.3, "{m:?}");
    }

    #[test]
    fn the_bench_scenario_parses_and_has_the_asked_length() {
        for hours in [0.6666666666666666, 4.0] {
            let text = super::scenario(hours * 3600.0);
            let sc = nav_sim::Scenario::from_toml_str(&text, "bench-run").expect("parses");
            assert_eq!(sc.imu.rate_hz, 200.0);
            assert!(sc.segments.len() > 8, "{} segments", sc.segments.len());
        }
    }
}
