//! `host-sim init`: a run configuration written from the user's files. It reads the first
//! minutes of the IMU and GNSS files, recognises the formats the readers know (u-blox UBX,
//! NMEA, RTKLIB `.pos`, the project's text) or maps a CSV column by column (separator,
//! header, units from the gravity at rest and the turns, rate, time kind), finds a rest at the
//! start, estimates the mounting (`nav_engine::mounting::estimate_mounting`) and proposes the
//! noise and initial sigmas from the rest. Every guess is written with its evidence as a TOML
//! comment; what could not be determined is printed. The file is checked by the run
//! configuration's own parser before it is written (as `OUT.partial`, then moved into place),
//! and an existing file is kept unless `--force`; an output that is one of the input files (or
//! a link to one) is refused even with `--force`.

mod gnss;
mod imu;
mod table;

use anyhow::Context as _;
use nav_core::types::{GnssFix, ImuSample};
use nav_io::restcheck::{gnss_motion_start, rest_stats, RestStats};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Seconds of the files examined from their start.
pub const PREFIX_S: f64 = 300.0;

/// `host-sim init` arguments.
#[derive(clap::Args, Debug)]
pub struct InitArgs {
    /// IMU file (CSV of rates and specific forces, or the project's increment text).
    #[arg(long)]
    pub imu: PathBuf,
    /// GNSS file (RTKLIB .pos, NMEA, u-blox UBX, the project's text, or a CSV/text log).
    #[arg(long)]
    pub gnss: PathBuf,
    /// Reference trajectory (the navigation text or an RTKLIB .pos), for metrics.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// The configuration to write.
    #[arg(short = 'o', long = "out", default_value = "run.toml")]
    pub out: PathBuf,
    /// Overwrite an existing output file (never one of the input files; a link is replaced).
    #[arg(long)]
    pub force: bool,
}

/// What the detection could not determine, and what it learnt on the way.
#[derive(Debug, Default)]
pub(crate) struct Guess {
    /// Things not determined (printed, and marked GUESS in the file).
    pub unknown: Vec<String>,
    /// IMU sample rate, Hz (CSV).
    pub imu_rate_hz: f64,
}

/// A path as the configuration writes it: relative to the configuration's folder when the
/// file is inside it, else absolute.
fn shown(p: &Path, out_dir: &Path) -> String {
    let abs = std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    let base = std::fs::canonicalize(out_dir).unwrap_or_else(|_| out_dir.to_path_buf());
    abs.strip_prefix(&base)
        .map_or_else(|_| abs.display().to_string(), |r| r.display().to_string())
}

const PLACEHOLDER_NOISE: &str =
    "[noise.accel]\nn_ug_per_sqrt_hz = 100.0\n[noise.gyro]\nn_deg_per_s_per_sqrt_hz = 0.01\n";

/// The first [`PREFIX_S`] of fixes of a `[gnss]` section.
fn read_fixes(gnss_toml: &str, out_dir: &Path, name: &Path) -> anyhow::Result<Vec<GnssFix>> {
    let text =
        format!("[imu]\npath = \"none\"\nformat = \"text\"\n{gnss_toml}\n{PLACEHOLDER_NOISE}");
    let cfg = nav_io::parse_run_config(name, &text)?;
    let mut out = Vec::new();
    for f in cfg.open_gnss(out_dir)? {
        let f = f?;
        if out
            .first()
            .is_some_and(|a: &GnssFix| f.t_s > a.t_s + PREFIX_S)
        {
            break;
        }
        out.push(f);
    }
    Ok(out)
}

/// The GNSS hints for the IMU detection: the fixes' span, the course rate in turns.
fn hints(fixes: &[GnssFix]) -> imu::GnssHints {
    let mut rates = Vec::new();
    let course = |a: &GnssFix, b: &GnssFix| -> Option<f64> {
        let v = if b.has_velocity {
            (b.vel_ned_mps[0], b.vel_ned_mps[1])
        } else {
            let d = nav_core::earth::ned_offset_m(&llh(a), &llh(b));
            let dt = b.t_s - a.t_s;
            (d.x / dt, d.y / dt)
        };
        (v.0.hypot(v.1) > 3.0).then(|| v.1.atan2(v.0))
    };
    for w in fixes.windows(3) {
        let dt = w[2].t_s - w[1].t_s;
        if !(dt > 0.0 && dt <= 2.0) {
            continue;
        }
        if let (Some(c1), Some(c2)) = (course(&w[0], &w[1]), course(&w[1], &w[2])) {
            let d = (c2 - c1 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            rates.push((d / dt).abs().to_degrees());
        }
    }
    rates.sort_by(f64::total_cmp);
    imu::GnssHints {
        span_s: fixes.first().zip(fixes.last()).map(|(a, b)| (a.t_s, b.t_s)),
        course_rate_degps: rates.get(rates.len() * 95 / 100).copied(),
    }
}

fn llh(f: &GnssFix) -> nav_core::earth::Llh {
    nav_core::earth::Llh {
        lat_rad: f.lat_rad,
        lon_rad: f.lon_rad,
        h_m: f.h_m,
    }
}

/// The first [`PREFIX_S`] of IMU increments (sensor axes) of a draft configuration.
fn read_imu(cfg: &nav_io::RunConfig, out_dir: &Path) -> anyhow::Result<Vec<ImuSample>> {
    let mut out: Vec<ImuSample> = Vec::new();
    for s in cfg.open_imu(out_dir)? {
        let (s, _) = s?;
        if out.first().is_some_and(|a| s.t_s > a.t_s + PREFIX_S) {
            break;
        }
        out.push(s);
    }
    Ok(out)
}

/// The `[truth]` section of a reference file.
fn truth_section(p: &Path, out_dir: &Path) -> anyhow::Result<String> {
    let t = table::Table::read(p)?;
    let pos = t.head.iter().any(|l| l.starts_with('%'));
    let (kind, why) = if pos {
        ("rtklib_pos", "`%` header: an RTKLIB .pos")
    } else if t.width == 11 {
        (
            "nav_text",
            "11 columns `week sow lat lon h vn ve vd roll pitch yaw`",
        )
    } else {
        anyhow::bail!(
            "{}: neither an RTKLIB .pos nor the navigation text (11 columns)",
            p.display()
        );
    };
    Ok(format!(
        "[truth]\npath = {:?}\nformat = \"{kind}\"  # {why}\n",
        shown(p, out_dir)
    ))
}

/// `[init]` and `[noise]` from the rest at the start (or the defaults, said so).
fn init_and_noise(rest: Option<&RestStats>, fixes: &[GnssFix], t0: f64, g: &mut Guess) -> String {
    let mut s = String::from("[init]\npos_std_m = [1.0, 1.0, 2.0]\nvel_std_mps = [0.1, 0.1, 0.1]\natt_std_deg = [2.0, 2.0, 10.0]\n");
    let speed0 = fixes
        .iter()
        .find(|f| f.is_valid() && f.t_s >= t0 - 1.0)
        .filter(|f| f.has_velocity)
        .map(|f| f.vel_ned_mps[0].hypot(f.vel_ned_mps[1]));
    match rest {
        Some(r) => {
            let static_s = r.duration_s.min(30.0).floor().max(2.0);
            let mis = r.gravity_mismatch_mps2();
            let _ = write!(
                s,
                "[init.align]\nstatic_s = {static_s:.1}  # at rest for {:.1} s from the first IMU sample (ended by {})\n\
                 max_gravity_mismatch_mps2 = {:.2}  # |f| at rest {:.4} m/s^2 = {:.4} g against normal gravity {:.4}: {:+.4} m/s^2\n",
                r.duration_s,
                r.ended_by,
                (2.0 * mis.abs()).max(0.1),
                norm(r.mean_f_mps2),
                norm(r.mean_f_mps2) / 9.806_65,
                r.gravity_mps2,
                mis
            );
        }
        None => match speed0 {
            Some(v) if v >= 2.0 => {
                let _ = writeln!(s, "# the first fix moves at {v:.1} m/s: in-motion alignment (the default when [init.align] is absent)");
            }
            _ => {
                let _ = writeln!(s, "# GUESS: no rest at the start found and no GNSS speed of 2 m/s or more at the first fix: default alignment");
                g.unknown.push("start: neither at rest nor moving at 2 m/s or more; the default alignment may fail ([init.given] or start_s)".into());
            }
        },
    }
    s.push_str(&noise_section(rest, g));
    s
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn noise_section(rest: Option<&RestStats>, g: &mut Guess) -> String {
    let Some(r) = rest else {
        g.unknown.push("noise: no rest at the start; consumer-MEMS figures written (run `host-sim allan` on a static record)".into());
        return "[noise]\nmodel = \"nbk\"\n# GUESS: no rest to measure: consumer-MEMS figures\n[noise.accel]\nn_ug_per_sqrt_hz = 150.0\nk_ug_per_sqrt_hz = 1.5\nbias_init_sigma = 0.1\n[noise.gyro]\nn_deg_per_s_per_sqrt_hz = 0.01\nk_deg_per_s_per_sqrt_hz = 1.0e-4\nbias_init_deg_per_s = 0.1\n".into();
    };
    let sq = r.dt_s.sqrt();
    let max = |v: [f64; 3]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let ng = max(r.std_rate_radps).to_degrees() * sq;
    let na = max(r.std_f_mps2) * sq / 9.806_65e-6;
    let bg = (2.0 * max(r.mean_rate_radps).to_degrees()).max(1e-3);
    let ba = (2.0 * r.gravity_mismatch_mps2().abs()).max(0.01);
    format!(
        "[noise]\nmodel = \"nbk\"\n\
         [noise.accel]\n\
         n_ug_per_sqrt_hz = {na:.1}  # largest std at rest {:.4} m/s^2 at {:.1} Hz over {:.1} s\n\
         k_ug_per_sqrt_hz = {:.3}  # GUESS: 1 % of the white noise (a few minutes cannot show it: `host-sim allan` on a long static record)\n\
         bias_init_sigma = {ba:.3}  # twice |f| - g at rest ({:+.4} m/s^2), at least 0.01\n\
         [noise.gyro]\n\
         n_deg_per_s_per_sqrt_hz = {ng:.3e}  # largest std at rest {:.4} deg/s\n\
         k_deg_per_s_per_sqrt_hz = {:.3e}  # GUESS: 1 % of the white noise\n\
         bias_init_deg_per_s = {bg:.4}  # twice the largest mean rate at rest (mean rates {:.4} {:.4} {:.4} deg/s), at least 0.001\n",
        max(r.std_f_mps2),
        1.0 / r.dt_s,
        r.duration_s,
        na / 100.0,
        r.gravity_mismatch_mps2(),
        max(r.std_rate_radps).to_degrees(),
        ng / 100.0,
        r.mean_rate_radps[0].to_degrees(),
        r.mean_rate_radps[1].to_degrees(),
        r.mean_rate_radps[2].to_degrees(),
    )
}

/// The mounting section: estimated when the record moves enough, else identity (said so).
fn mounting_section(imu: &[ImuSample], fixes: &[GnssFix], g: &mut Guess) -> String {
    match nav_engine::mounting::estimate_mounting(imu, fixes) {
        Ok(est) => est.toml_section(),
        Err(e) => {
            g.unknown.push(format!(
                "mounting: {e}; identity written (`host-sim mounting` on a longer drive)"
            ));
            "[imu.mounting]\nrpy_deg = [0.0, 0.0, 0.0]  # GUESS: not estimated\n".into()
        }
    }
}

/// `host-sim init`: writes the configuration and prints what it could not determine.
pub fn run(a: InitArgs) -> anyhow::Result<()> {
    if a.out.exists() && !a.force {
        anyhow::bail!(
            "{} exists: give --force to overwrite it, or another -o",
            a.out.display()
        );
    }
    // never over one of the files it reads, even with --force (a link to one included)
    let mut tag = a.imu.clone().into_os_string();
    tag.push(".tag");
    let inputs = [Some(&a.imu), Some(&a.gnss), a.truth.as_ref()];
    for input in inputs.into_iter().flatten().chain([&PathBuf::from(tag)]) {
        nav_engine::run::outdir::check_not_input(&a.out, input)?;
    }
    // a folder given as a data file: named with its flag (else the system's "Is a directory")
    let flagged = [
        ("--imu", Some(&a.imu)),
        ("--gnss", Some(&a.gnss)),
        ("--truth", a.truth.as_ref()),
    ];
    for (flag, p) in flagged {
        if let Some(p) = p.filter(|p| p.is_dir()) {
            return Err(nav_io::IoError::Folder {
                path: p.clone(),
                given_as: Some(flag.to_string()),
            }
            .into());
        }
    }
    let out_dir = match a.out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut g = Guess::default();
    let gnss_toml = gnss::detect(&a.gnss, &shown(&a.gnss, &out_dir), &mut g)
        .with_context(|| format!("recognising the GNSS file {}", a.gnss.display()))?;
    let fixes = read_fixes(&gnss_toml, &out_dir, &a.out)
        .with_context(|| format!("reading the GNSS file {} as recognised", a.gnss.display()))?;
    let imu_toml = imu::detect(&a.imu, &shown(&a.imu, &out_dir), &hints(&fixes), &mut g)
        .with_context(|| format!("recognising the IMU file {}", a.imu.display()))?;
    let draft = format!("{imu_toml}{gnss_toml}{PLACEHOLDER_NOISE}");
    let cfg = nav_io::parse_run_config(&a.out, &draft)?;
    let imu = read_imu(&cfg, &out_dir)
        .with_context(|| format!("reading the IMU file {} as recognised", a.imu.display()))?;
    let t0 = imu.first().map_or(0.0, |s| s.t_s);
    let grav = fixes.iter().find(|f| f.is_valid()).map_or(9.806_65, |f| {
        nav_core::earth::gravity_mps2(f.lat_rad, f.h_m)
    });
    let rest = rest_stats(imu.iter().copied(), gnss_motion_start(&fixes), grav);
    let mut text = format!(
        "# Written by `host-sim init` from {} and {}; every guess is commented with its evidence.\n\
         # Check the lines marked GUESS. Keys: nav-io/src/runcfg.rs; guide: docs/your-data.md.\n\
         name = {:?}\n\n",
        a.imu.display(),
        a.gnss.display(),
        a.out.file_stem().unwrap_or_default().to_string_lossy()
    );
    text.push_str(&imu_toml);
    text.push_str(&mounting_section(&imu, &fixes, &mut g));
    text.push('\n');
    text.push_str(&gnss_toml);
    text.push('\n');
    if let Some(t) = &a.truth {
        text.push_str(&truth_section(t, &out_dir)?);
        text.push('\n');
    }
    text.push_str(&init_and_noise(rest.as_ref(), &fixes, t0, &mut g));
    nav_io::parse_run_config(&a.out, &text)
        .context("the written configuration does not parse (a defect of init)")?;
    // written as OUT.partial and moved into place: a link at OUT is replaced, never written
    // through, and an interrupted init leaves no half configuration under OUT
    let staged = nav_engine::run::outdir::StagedFile::create(&a.out, a.force)?;
    let mut f = staged.writer()?;
    std::io::Write::write_all(&mut f, text.as_bytes())
        .with_context(|| format!("writing {}", staged.partial().display()))?;
    drop(f);
    staged.commit()?;
    println!("wrote {}", a.out.display());
    for u in &g.unknown {
        eprintln!("not determined: {u}");
    }
    Ok(())
}
