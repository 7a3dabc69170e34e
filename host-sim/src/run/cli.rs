//! `host-sim run --config FILE [--case DIR] ...`: the filter on files.
//!
//! The configuration is the project's run configuration (TOML, [`nav_io::RunConfig`]) or a
//! KF-GINS YAML file (detected by the extension `.yaml`/`.yml`, or by content: a TOML parse
//! failure followed by a successful KF-GINS parse). A KF-GINS file runs KF-GINS's 21 states as
//! KF-GINS's code runs them (`kf-gins-feedback`, `KfGinsConfig::filter_config_feedback`; with
//! `--model kf-gins` the textbook Gauss-Markov reading), its initial state (`initpos` is the IMU position at
//! `starttime`), initial sensor errors and lever arm.
//!
//! `--case DIR` reads a case written by `host-sim simulate` (`case.toml` names the files;
//! its outages are added to the outage list so the metrics cover them). A KF-GINS file inside
//! such a case directory also picks up the case's `truth.nav`, outages and GPS week.
//!
//! Outputs in `--out` (default `run-out`): `nav.txt`, `std.txt`, `bias.txt`,
//! `innovations.txt`, `metrics.json` (against the truth when there is one, else against the
//! withheld fixes; with outages also free-inertial coasting baselines, see
//! [`super::coast`]; and the IMU report: gaps bridged, samples rejected, with file and line).
//!
//! Every output is written as `NAME.partial`, synced, and renamed to `NAME` only when all of
//! them are written: after a full disk or any write error no file under a final name
//! exists (outputs of an earlier run in the folder are removed first). A fault in the middle
//! of the data (a gap longer than `--imu-max-gap`, a numerical failure, an implausible
//! sample with `--imu-strict`) stops the run: the error names the file and line of the
//! sample, the outputs up to it stay as `*.partial` (metrics.json.partial says
//! `"complete": false` and the fault), and the exit code is 1. IMU gaps and plausibility:
//! [`nav_core::imu_guard`], options `--imu-*` and `[imu.checks]`.

use super::coast::{coast_outages, CoastMode};
use super::init::{InitSpec, StaticAlign};
use super::outage::{parse_outage, parse_periodic, Outage, PeriodicOutages};
use super::output;
use super::{run_filter_with_progress, CaseData, Model, Precision, RunOptions, RunOutput};
use crate::metrics::{self, Metrics};
use crate::sim::CaseFile;
use anyhow::{bail, Context};
use nalgebra::Vector3;
use nav_core::config::{FilterConfig, GateProbability, Gating, ScaleFactorNoise};
use nav_core::earth::Llh;
use nav_core::filter::InitialUncertainty;
use nav_core::imu_guard::{GapIncrements, ImuLimits};
use nav_core::model::{Block, BlockKind, ImuCorrection};
use nav_core::strapdown::NavState;
use nav_core::types::NavSolution;
use nav_io::{
    read_gnss_text, read_imu_text, read_kf_gins_yaml, read_nav_text, read_run_config, BiasModel,
    ImuChecksConfig, ImuClassName, ImuTextReader, InitMode, KfGinsConfig, RunConfig, TruthData,
};
use std::path::{Path, PathBuf};

/// Arguments of `host-sim run`.
#[derive(clap::Args, Debug, Clone)]
pub struct RunArgs {
    /// Run configuration: the project's TOML, or a KF-GINS YAML file.
    #[arg(long)]
    pub config: PathBuf,
    /// A case directory written by `host-sim simulate` (its files replace the configuration's).
    #[arg(long)]
    pub case: Option<PathBuf>,
    /// Reference trajectory in the nav format (overrides the configuration's).
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Error-state model (default: from the configuration; KF-GINS YAML: kf-gins-feedback).
    #[arg(long, value_enum)]
    pub model: Option<Model>,
    /// GNSS outage START:DURATION, seconds, START after the first IMU epoch (repeatable).
    #[arg(long = "outage", value_parser = parse_outage)]
    pub outages: Vec<Outage>,
    /// Repeating outages FIRST:DURATION:PERIOD, seconds, FIRST after the first IMU epoch
    /// (repeatable), e.g. 120:30:60.
    #[arg(long = "periodic-outage", value_parser = parse_periodic)]
    pub periodic_outages: Vec<PeriodicOutages>,
    /// The KF-GINS paper's protocol: 60 s outages every 180 s, the first at 180 s.
    #[arg(long)]
    pub kf_gins_outages: bool,
    /// Rate of nav.txt, Hz (default: every IMU epoch).
    #[arg(long)]
    pub nav_rate: Option<f64>,
    /// Rate of std.txt and bias.txt, Hz.
    #[arg(long, default_value_t = 10.0)]
    pub std_rate: f64,
    /// Output directory.
    #[arg(long, default_value = "run-out")]
    pub out: PathBuf,
    /// f32 covariance (as on the MCU) instead of f64.
    #[arg(long)]
    pub f32: bool,
    /// Extra offset added to the IMU time stamps, s (e.g. a logging-delay correction).
    #[arg(long, allow_hyphen_values = true)]
    pub imu_time_offset: Option<f64>,
    /// Innovation gate: robust (default: IGG-III down-weighting and a model-mismatch
    /// monitor, docs/robust-gating.md), off, or a hard gate at the acceptance probability
    /// 0.95, 0.99, 0.999, 0.9999.
    #[arg(long)]
    pub gate: Option<String>,
    /// Use the GNSS velocities: on/off (default: the configuration's).
    #[arg(long)]
    pub gnss_velocity: Option<bool>,
    /// Multiply the accelerometer and gyro white-noise PSDs by this factor (model tuning).
    #[arg(long)]
    pub noise_scale: Option<f64>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Effect blocks to append to the model, comma-separated names of the vocabulary
    /// (`accel_scale_factor,...,gyro_g_sensitivity`; e.g. what `host-sim diagnose` added).
    #[arg(long, value_delimiter = ',')]
    pub effects: Vec<String>,
    /// IMU class giving the plausibility limits (its full-scale range + 10 %; default: the
    /// configuration's `[imu.checks] class`, else consumer-mems, the widest).
    #[arg(long, value_enum)]
    pub imu_class: Option<ImuClassName>,
    /// Largest plausible angular rate, deg/s on any axis (overrides the class).
    #[arg(long)]
    pub imu_max_rate_dps: Option<f64>,
    /// Largest plausible specific force, g on any axis (overrides the class).
    #[arg(long)]
    pub imu_max_accel_g: Option<f64>,
    /// No plausibility limits (only non-finite samples are rejected).
    #[arg(long)]
    pub no_imu_limits: bool,
    /// Longest IMU time gap bridged, s (default 1; a longer gap ends the run with an error).
    #[arg(long)]
    pub imu_max_gap: Option<f64>,
    /// What the IMU increment after a time gap covers: auto (decided per gap from the
    /// specific force), span (the whole gap), sample (one nominal interval: the missing
    /// increments are lost and filled by interpolation). Default: span for CSV rate logs
    /// (converted over the true interval), auto for increment files.
    #[arg(long, value_parser = parse_gap_increments)]
    pub imu_gaps: Option<GapIncrements>,
    /// Stop at the first implausible IMU sample (outputs up to it kept as *.partial, exit
    /// code 1) instead of skipping it.
    #[arg(long)]
    pub imu_strict: bool,
    /// Post-processing: run the Rauch-Tung-Striebel smoother after the forward filter;
    /// nav.txt / std.txt are then smoothed, the forward solution is nav_forward.txt, and
    /// metrics.json has the smoothed metrics under `smoothed` (see host_sim::smooth).
    #[arg(long)]
    pub smooth: bool,
}

/// Parses `--imu-gaps`.
pub fn parse_gap_increments(s: &str) -> anyhow::Result<GapIncrements> {
    Ok(match s.trim() {
        "auto" => GapIncrements::Auto,
        "span" => GapIncrements::Span,
        "sample" => GapIncrements::Sample,
        other => bail!("--imu-gaps {other}: expected auto, span or sample"),
    })
}

/// Applies `[imu.checks]` of a run configuration to the run options.
fn apply_imu_checks(ch: &ImuChecksConfig, opts: &mut RunOptions) -> anyhow::Result<()> {
    if let Some(c) = ch.class {
        opts.imu_checks.limits = ImuLimits::for_class(c.class());
    }
    set_limits(&mut opts.imu_checks, ch.max_rate_deg_s, ch.max_accel_g)?;
    if let Some(g) = ch.max_gap_s {
        if !(g.is_finite() && g > 0.0) {
            bail!("imu.checks.max_gap_s = {g}: must be positive");
        }
        opts.imu_checks.max_gap_s = g;
    }
    opts.imu_checks.stop_on_implausible |= ch.stop_on_implausible;
    Ok(())
}

fn set_limits(
    c: &mut super::ImuChecks,
    rate_dps: Option<f64>,
    accel_g: Option<f64>,
) -> anyhow::Result<()> {
    if let Some(r) = rate_dps {
        if !(r.is_finite() && r > 0.0) {
            bail!("IMU rate limit {r} deg/s: must be positive");
        }
        c.limits.max_rate_radps = r.to_radians();
    }
    if let Some(a) = accel_g {
        if !(a.is_finite() && a > 0.0) {
            bail!("IMU specific-force limit {a} g: must be positive");
        }
        c.limits.max_accel_mps2 = a * 9.806_65;
    }
    Ok(())
}

/// Parses a `--gate` value.
pub fn parse_gate(s: &str) -> anyhow::Result<Gating> {
    let max_rej = Gating::default().max_consecutive_rejections;
    Ok(match s.trim() {
        "robust" | "default" => Gating::robust(),
        "off" | "none" => Gating::disabled(),
        "0.95" | "95" => Gating::with_probability(GateProbability::P95, max_rej),
        "0.99" | "99" => Gating::with_probability(GateProbability::P99, max_rej),
        "0.999" | "99.9" => Gating::with_probability(GateProbability::P999, max_rej),
        "0.9999" | "99.99" => Gating::with_probability(GateProbability::P9999, max_rej),
        other => bail!("--gate {other}: expected robust, off, 0.95, 0.99, 0.999 or 0.9999"),
    })
}

impl RunArgs {
    /// Arguments with defaults for a configuration file (for programmatic use).
    pub fn new(config: impl Into<PathBuf>) -> Self {
        Self {
            config: config.into(),
            case: None,
            truth: None,
            model: None,
            outages: Vec::new(),
            periodic_outages: Vec::new(),
            kf_gins_outages: false,
            nav_rate: None,
            std_rate: 10.0,
            out: PathBuf::from("run-out"),
            f32: false,
            imu_time_offset: None,
            gate: None,
            gnss_velocity: None,
            noise_scale: None,
            quiet: true,
            effects: Vec::new(),
            imu_class: None,
            imu_max_rate_dps: None,
            imu_max_accel_g: None,
            no_imu_limits: false,
            imu_max_gap: None,
            imu_gaps: None,
            imu_strict: false,
            smooth: false,
        }
    }
}

/// A case loaded from files, ready to run.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The data.
    pub case: CaseData,
    /// The options.
    pub opts: RunOptions,
    /// GPS week of the data (0 when unknown).
    pub week: u16,
    /// What was loaded (for the report).
    pub description: String,
}

/// Which kind of configuration a file is.
pub enum ConfigKind {
    /// The project's TOML.
    Run(Box<RunConfig>),
    /// A KF-GINS YAML file.
    KfGins(Box<KfGinsConfig>),
}

/// Reads a configuration: `.yaml`/`.yml` as KF-GINS, otherwise the project's TOML (and a TOML
/// that does not parse is tried as KF-GINS YAML before its error is reported).
pub fn read_config(path: &Path) -> anyhow::Result<ConfigKind> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    if ext == "yaml" || ext == "yml" {
        return Ok(ConfigKind::KfGins(Box::new(read_kf_gins_yaml(path)?)));
    }
    match read_run_config(path) {
        Ok(c) => Ok(ConfigKind::Run(Box::new(c))),
        Err(e) => match read_kf_gins_yaml(path) {
            Ok(k) => Ok(ConfigKind::KfGins(Box::new(k))),
            Err(_) => Err(e.into()),
        },
    }
}

struct CaseDir {
    imu: PathBuf,
    gnss: PathBuf,
    truth: PathBuf,
    outages: Vec<Outage>,
    week: u16,
}

fn read_case_dir(dir: &Path) -> anyhow::Result<CaseDir> {
    let cf = CaseFile::from_file(&dir.join("case.toml"))?;
    Ok(CaseDir {
        imu: dir.join(&cf.files.imu),
        gnss: dir.join(&cf.files.gnss),
        truth: dir.join(&cf.files.truth),
        outages: cf
            .outages
            .iter()
            .map(|o| Outage {
                start_s: o.start_sow,
                duration_s: o.duration_s,
            })
            .collect(),
        week: cf.summary.gps_week,
    })
}

fn rpy_sigma_to_phi(att_std_rad: [f64; 3]) -> [f64; 3] {
    // small angles: roll/pitch/yaw sigmas as phi N/E/D sigmas (exact at zero roll/pitch)
    att_std_rad
}

struct ExecRef<'a> {
    case: &'a CaseData,
    opts: &'a RunOptions,
}

/// An IMU text file the run streams instead of loading ([`prepare_streaming`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ImuStream {
    /// The IMU text file (plain or gzip).
    pub path: PathBuf,
    /// Offset added to every time stamp, s (`--imu-time-offset`).
    pub time_offset_s: f64,
}

/// Loads everything a run needs from the arguments.
pub fn prepare(args: &RunArgs) -> anyhow::Result<Prepared> {
    Ok(prepare_inner(args, false)?.0)
}

/// [`prepare`] without loading the IMU when it is a text file (KF-GINS configurations and
/// case directories): the case's IMU list stays empty and the file is returned, to be read
/// while the filter runs ([`execute_streaming`]). Other IMU formats are loaded as before.
pub fn prepare_streaming(args: &RunArgs) -> anyhow::Result<(Prepared, Option<ImuStream>)> {
    prepare_inner(args, true)
}

fn prepare_inner(args: &RunArgs, stream: bool) -> anyhow::Result<(Prepared, Option<ImuStream>)> {
    let kind = read_config(&args.config)
        .with_context(|| format!("reading the configuration {}", args.config.display()))?;
    let cfg_dir = args
        .config
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    // a case directory: given, or the configuration's own folder when it holds a case.toml
    let case_dir = match &args.case {
        Some(d) => Some(read_case_dir(d)?),
        None if cfg_dir.join("case.toml").exists() && matches!(kind, ConfigKind::KfGins(_)) => {
            Some(read_case_dir(&cfg_dir)?)
        }
        None => None,
    };
    let (mut case, mut opts, mut week, mut description, imu_stream) = match kind {
        ConfigKind::KfGins(k) => {
            prepare_kf_gins(&k, &cfg_dir, case_dir.as_ref(), args.model, stream)?
        }
        ConfigKind::Run(r) => prepare_run_config(&r, &cfg_dir, case_dir.as_ref(), stream)?,
    };
    let mut imu_stream = imu_stream.map(|path| ImuStream {
        path,
        time_offset_s: 0.0,
    });
    if let Some(cd) = &case_dir {
        week = cd.week;
        if case.truth.is_none() && args.truth.is_none() && cd.truth.exists() {
            case.truth = Some(read_nav_text(&cd.truth)?);
            description.push_str(&format!("; truth {}", cd.truth.display()));
        }
        opts.outages.extend(cd.outages.iter().copied());
    }
    if let Some(t) = &args.truth {
        case.truth = Some(read_nav_text(t)?);
        description.push_str(&format!("; truth {}", t.display()));
    }
    if let Some(dt) = args.imu_time_offset {
        for s in &mut case.imu {
            s.t_s += dt;
        }
        if let Some(st) = &mut imu_stream {
            st.time_offset_s = dt;
        }
        description.push_str(&format!("; IMU time offset {dt:+} s"));
    }
    if let Some(m) = args.model {
        opts.model = m;
    }
    for name in &args.effects {
        add_effect(&mut opts, name).with_context(|| {
            format!("--effects {name}: not an effect name (see host-sim diagnose)")
        })?;
    }
    if !args.effects.is_empty() {
        description.push_str(&format!("; effects {}", args.effects.join(",")));
    }
    if args.f32 {
        opts.precision = Precision::F32;
    }
    if let Some(g) = &args.gate {
        opts.filter.gating = parse_gate(g)?;
    }
    if let Some(c) = args.imu_class {
        opts.imu_checks.limits = ImuLimits::for_class(c.class());
    }
    set_limits(
        &mut opts.imu_checks,
        args.imu_max_rate_dps,
        args.imu_max_accel_g,
    )?;
    if args.no_imu_limits {
        opts.imu_checks.limits = ImuLimits::none();
    }
    if let Some(g) = args.imu_max_gap {
        if !(g.is_finite() && g > 0.0) {
            bail!("--imu-max-gap {g}: must be positive");
        }
        opts.imu_checks.max_gap_s = g;
    }
    if args.imu_gaps.is_some() {
        opts.imu_checks.increments = args.imu_gaps;
    }
    opts.imu_checks.stop_on_implausible |= args.imu_strict;
    if let Some(v) = args.gnss_velocity {
        opts.filter.use_gnss_velocity = v;
    }
    if let Some(k) = args.noise_scale {
        if !(k.is_finite() && k > 0.0) {
            bail!("--noise-scale {k}: must be positive");
        }
        scale_white_noise(&mut opts.filter, k);
        description.push_str(&format!("; white-noise PSDs x{k}"));
    }
    let periodic_wanted = !args.periodic_outages.is_empty() || args.kf_gins_outages;
    let (t0, t_end) = match (&imu_stream, case.imu.first(), case.imu.last()) {
        (Some(st), _, _) => {
            let (a, b) = imu_text_time_span(&st.path, periodic_wanted)?;
            (a + st.time_offset_s, b + st.time_offset_s)
        }
        (None, Some(a), Some(b)) => (a.t_s, b.t_s),
        _ => bail!("no IMU samples in the data"),
    };
    let t0 = opts.start_s.map_or(t0, |s| s.max(t0));
    let t_end = opts.end_s.map_or(t_end, |e| e.min(t_end));
    opts.outages
        .extend(args.outages.iter().map(|o| o.shifted(t0)));
    let mut periodic = args.periodic_outages.clone();
    if args.kf_gins_outages {
        periodic.push(PeriodicOutages::KF_GINS);
    }
    for p in &periodic {
        opts.outages.extend(p.expand(t0, t_end));
    }
    opts.record.nav_rate_hz = None;
    opts.record.epoch_rate_hz = Some(args.std_rate);
    opts.smoother_history = args.smooth;
    Ok((
        Prepared {
            case,
            opts,
            week,
            description,
        },
        imu_stream,
    ))
}

/// Time of the first IMU sample of a text file and, when `last` is asked, of its last one
/// (the whole file is read then; otherwise the second value is the first time too).
fn imu_text_time_span(path: &Path, last: bool) -> anyhow::Result<(f64, f64)> {
    let mut rd = ImuTextReader::open(path)?;
    let Some(first) = rd.next().transpose()? else {
        bail!("no IMU samples in {}", path.display());
    };
    let t0 = first.0.t_s;
    let mut t1 = t0;
    if last {
        for r in rd {
            t1 = r?.0.t_s;
        }
    }
    Ok((t0, t1))
}

fn prepare_kf_gins(
    k: &KfGinsConfig,
    dir: &Path,
    case_dir: Option<&CaseDir>,
    model: Option<Model>,
    stream: bool,
) -> anyhow::Result<(CaseData, RunOptions, u16, String, Option<PathBuf>)> {
    k.validate()
        .map_err(|e| anyhow::anyhow!("KF-GINS configuration: {e}"))?;
    let (imu_p, gnss_p) = match case_dir {
        Some(c) => (c.imu.clone(), c.gnss.clone()),
        None => (
            k.resolve_path(&k.imupath, dir),
            k.resolve_path(&k.gnsspath, dir),
        ),
    };
    let (imu_rec, imu_stream) = if stream {
        (nav_io::ImuRecord::default(), Some(imu_p.clone()))
    } else {
        (read_imu_text(&imu_p)?, None)
    };
    let gnss = read_gnss_text(&gnss_p)?;
    // the model: what KF-GINS's code does unless the command line asks for another layout
    let model = model.unwrap_or(Model::KfGinsFeedback);
    let filter = match model {
        Model::KfGinsFeedback => k.filter_config_feedback(),
        _ => k.filter_config_gauss_markov(),
    };
    let [lat, lon, h] = k.initpos;
    let state = NavState::from_rpy(
        k.starttime,
        Llh::from_deg(lat, lon, h),
        Vector3::from(k.initvel),
        k.init_rpy_rad(),
    );
    let unc = InitialUncertainty {
        att_sigma_rad: rpy_sigma_to_phi(k.init_att_std_rad()),
        vel_sigma_mps: k.initvelstd,
        pos_sigma_m: k.initposstd,
    };
    let mut opts = RunOptions::new(model, filter, InitSpec::Given(state, unc));
    opts.lever_arm_m = k.antlever;
    opts.start_s = Some(k.starttime);
    opts.end_s = k.end_time_s();
    opts.initial_estimates = vec![
        (BlockKind::GyroBias, k.init_gyr_bias_radps()),
        (BlockKind::AccelBias, k.init_acc_bias_mps2()),
        (BlockKind::GyroScaleFactor, k.init_gyr_scale()),
        (BlockKind::AccelScaleFactor, k.init_acc_scale()),
    ];
    let week = case_dir.map_or(0, |c| c.week);
    let d = format!(
        "KF-GINS configuration: IMU {}, GNSS {}",
        imu_p.display(),
        gnss_p.display()
    );
    Ok((
        CaseData {
            imu: imu_rec.samples,
            gnss,
            truth: None,
            imu_origin: imu_rec.origin,
        },
        opts,
        week,
        d,
        imu_stream,
    ))
}

/// Multiplies the accelerometer and gyro white-noise PSDs (`s_n`) of `filter` by `k`.
pub fn scale_white_noise(filter: &mut FilterConfig, k: f64) {
    for s in filter
        .accel
        .s_n
        .iter_mut()
        .chain(filter.gyro.s_n.iter_mut())
    {
        *s *= k;
    }
}

/// Appends the effect block named `name` (vocabulary name) with
/// [`RunOptions::add_effect_block`]. None: not an effect name.
fn add_effect(opts: &mut RunOptions, name: &str) -> Option<()> {
    opts.add_effect_block(Block::effect_from_name(name.trim())?);
    Some(())
}

fn prepare_run_config(
    r: &RunConfig,
    dir: &Path,
    case_dir: Option<&CaseDir>,
    stream: bool,
) -> anyhow::Result<(CaseData, RunOptions, u16, String, Option<PathBuf>)> {
    let mut week = 0u16;
    let mut imu_stream = None;
    let imu_p = case_dir.map_or_else(|| RunConfig::resolve(dir, &r.imu.path), |c| c.imu.clone());
    let gnss_p = case_dir.map_or_else(|| RunConfig::resolve(dir, &r.gnss.path), |c| c.gnss.clone());
    let mut gaps = String::new();
    let (imu_rec, mut gnss, truth) = match case_dir {
        Some(c) => (
            if stream {
                imu_stream = Some(c.imu.clone());
                nav_io::ImuRecord::default()
            } else {
                read_imu_text(&c.imu)?
            },
            read_gnss_text(&c.gnss)?,
            if c.truth.exists() {
                Some(read_nav_text(&c.truth)?)
            } else {
                None
            },
        ),
        None => {
            let inp = r.load_inputs(dir)?;
            for w in &inp.warnings {
                eprintln!("warning: {w}");
            }
            if let Some(w) = inp.gnss_week {
                week = u16::try_from(w).unwrap_or(0);
            }
            if inp.imu.gaps.count() > 0 {
                gaps = format!("; IMU time gaps: {}", inp.imu.gaps);
            }
            let truth = inp.truth.map(|t| match t {
                TruthData::Nav(v) => v,
                TruthData::Positions(f) => f
                    .iter()
                    .map(|f| NavSolution {
                        t_s: f.t_s,
                        lat_rad: f.lat_rad,
                        lon_rad: f.lon_rad,
                        h_m: f.h_m,
                        vel_ned_mps: if f.has_velocity {
                            f.vel_ned_mps
                        } else {
                            [f64::NAN; 3]
                        },
                        rpy_rad: [f64::NAN; 3],
                        ..NavSolution::default()
                    })
                    .collect(),
            });
            (inp.imu, inp.gnss, truth)
        }
    };
    let imu = imu_rec.samples;
    // the data against the configured [imu.mounting] (z gyro vs GNSS course, gravity at rest)
    for w in crate::mounting::check_mounting(&imu, &gnss).warnings {
        eprintln!("warning: {w}");
    }
    for g in &mut gnss {
        for s in &mut g.pos_std_ned_m {
            *s *= r.gnss.sigma_scale;
        }
        for s in &mut g.vel_std_ned_mps {
            *s *= r.gnss.sigma_scale;
        }
    }
    let accel = r
        .noise
        .accel
        .to_sensor_noise()
        .map_err(|e| anyhow::anyhow!(e))?;
    let gyro = r
        .noise
        .gyro
        .to_sensor_noise()
        .map_err(|e| anyhow::anyhow!(e))?;
    let mut filter = FilterConfig::with_noise(accel, gyro);
    if let Some(k) = r.noise.white_noise_scale {
        if !(k.is_finite() && k > 0.0) {
            bail!("noise.white_noise_scale = {k}: must be positive");
        }
        scale_white_noise(&mut filter, k);
    }
    if let Some(s) = &r.noise.accel_scale {
        filter.accel_scale = ScaleFactorNoise::from_ppm(s.sigma_ppm, s.t_s);
    }
    if let Some(s) = &r.noise.gyro_scale {
        filter.gyro_scale = ScaleFactorNoise::from_ppm(s.sigma_ppm, s.t_s);
    }
    filter.use_gnss_velocity = r.gnss.use_velocity;
    if let Some(g) = &r.gnss.gate {
        filter.gating = parse_gate(g).context("gnss.gate")?;
    }
    let model = match r.noise.model {
        BiasModel::N => Model::N,
        BiasModel::Nbk => Model::Nbk,
        BiasModel::NbkSingleState => Model::NbkSingle,
    };
    let ic = &r.init;
    let att_std = ic.att_std_deg.map(f64::to_radians);
    let unc = InitialUncertainty {
        att_sigma_rad: rpy_sigma_to_phi(att_std),
        vel_sigma_mps: ic.vel_std_mps,
        pos_sigma_m: ic.pos_std_m,
    };
    let init = match ic.mode().map_err(|e| anyhow::anyhow!(e))? {
        InitMode::Given(g) => {
            let [lat, lon, h] = g.pos_deg_deg_m;
            let t = r
                .start_s
                .or_else(|| imu.first().map(|s| s.t_s))
                .or_else(|| {
                    let p = imu_stream.as_ref()?;
                    imu_text_time_span(p, false).ok().map(|(a, _)| a)
                })
                .unwrap_or(0.0);
            InitSpec::Given(
                NavState::from_rpy(
                    t,
                    Llh::from_deg(lat, lon, h),
                    Vector3::from(g.vel_ned_mps),
                    g.rpy_deg.map(f64::to_radians),
                ),
                unc,
            )
        }
        InitMode::Align(a) => {
            let mut sa = StaticAlign::new(a.static_s);
            sa.heading_rad = a.yaw_deg.map(f64::to_radians);
            sa.heading_std_rad = att_std[2];
            sa.course_min_speed_mps = Some(a.yaw_from_gnss_min_speed_mps);
            sa.align.max_gravity_mismatch_mps2 = a.max_gravity_mismatch_mps2;
            sa.vel_sigma_mps = ic.vel_std_mps.iter().fold(0.0, |m, v| m.max(*v));
            sa.tilt_std_rad = Some(att_std[0].max(att_std[1]));
            InitSpec::StaticAlignment(sa)
        }
    };
    let mut opts = RunOptions::new(model, filter, init);
    if let Some(ch) = &r.imu.checks {
        apply_imu_checks(ch, &mut opts).context("[imu.checks]")?;
    }
    opts.lever_arm_m = r.gnss.lever_arm_m;
    if let Some(a) = &r.aiding {
        opts.aiding = a
            .to_config()
            .map_err(|e| anyhow::anyhow!(e))
            .context("[aiding]")?;
    }
    opts.start_s = r.start_s;
    opts.end_s = r.end_s;
    for name in &r.effects {
        add_effect(&mut opts, name).with_context(|| {
            format!("effects: `{name}` is not an effect name (see host-sim diagnose --help)")
        })?;
    }
    let mut d = format!(
        "run configuration `{}`: IMU {}, GNSS {}{gaps}",
        r.name,
        imu_p.display(),
        gnss_p.display()
    );
    if !r.effects.is_empty() {
        d.push_str(&format!("; effects {}", r.effects.join(",")));
    }
    Ok((
        CaseData {
            imu,
            gnss,
            truth,
            imu_origin: imu_rec.origin,
        },
        opts,
        week,
        d,
        imu_stream,
    ))
}

/// Runs the filter and computes the metrics (with coasting baselines when there are outages).
pub fn execute(
    p: &Prepared,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<(RunOutput, Metrics)> {
    execute_case(&p.case, &p.opts, progress)
}

/// [`execute`] on a case and options apart (the case is not copied).
pub fn execute_case(
    case: &CaseData,
    opts: &RunOptions,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<(RunOutput, Metrics)> {
    let p = ExecRef { case, opts };
    let out = run_filter_with_progress(p.case, p.opts, progress)?;
    let truth = p.case.truth.as_deref();
    let mut m = metrics::compute(&out, truth);
    if !out.snapshots.is_empty() {
        let raw = coast_outages(p.case, &out, CoastMode::Raw);
        m.coasting.push(metrics::coasting_metrics(
            "raw: no sensor-error correction",
            &raw,
            &out.outages,
            truth,
        ));
        if let Some(b) = out.init.static_gyro_bias_radps {
            let c = ImuCorrection {
                gyro_bias_radps: b,
                ..ImuCorrection::default()
            };
            let st = coast_outages(p.case, &out, CoastMode::Fixed(Box::new(c)));
            m.coasting.push(metrics::coasting_metrics(
                "static gyro bias only",
                &st,
                &out.outages,
                truth,
            ));
        }
    }
    Ok((out, m))
}

/// Runs the filter on a prepared case with the IMU streamed from `imu` (or from the case's
/// samples in memory when `None`), writing the outputs in `dir` as it goes
/// ([`super::sink::FileSink`]: `*.partial`, renamed when complete) and computing the metrics
/// online, with the coasting baselines. `nav_rate_hz`: rate of `nav.txt` (None: every IMU
/// epoch). A fault mid-run leaves the outputs up to it as `*.partial` and returns
/// [`super::RunError::Fault`] (its `partial` holds the summary, no records); other errors
/// leave no output.
pub fn execute_streaming(
    p: &Prepared,
    imu: Option<&ImuStream>,
    dir: &Path,
    nav_rate_hz: Option<f64>,
    progress: &mut dyn FnMut(usize, usize),
) -> anyhow::Result<(RunOutput, Metrics)> {
    let opts = p.opts.clone();
    let truth = p.case.truth.as_deref();
    let mut sink = super::sink::FileSink::create(dir, p.week, nav_rate_hz, &opts.outages, truth)?;
    let data = super::RunData {
        gnss: &p.case.gnss,
        truth,
    };
    let coast = super::CoastPlan {
        raw: true,
        static_gyro_bias: true,
    };
    let res = match imu {
        Some(st) => {
            let info = super::ImuSourceInfo {
                path: Some(st.path.clone()),
                increments_span_gaps: false,
            };
            let mut it = threaded_imu_reader(st.path.clone(), st.time_offset_s);
            super::run_stream(&mut it, info, data, &opts, coast, &mut sink, progress)
        }
        None => {
            let (mut it, info) = super::case_imu_stream(&p.case);
            super::run_stream(&mut it, info, data, &opts, coast, &mut sink, progress)
        }
    };
    match res {
        Ok(out) => {
            let m = sink
                .finish(&out, None, |m| metrics_json(m, &out, None))
                .with_context(|| {
                    format!(
                        "writing the outputs in {}: incomplete, left as *{} (no file under its \
                         final name)",
                        dir.display(),
                        output::PARTIAL_SUFFIX
                    )
                })?;
            Ok((out, m))
        }
        Err(super::RunError::Fault {
            location,
            t_s,
            msg,
            partial,
        }) => {
            let fault = format!("{location} (t = {t_s:.6} s): {msg}");
            let t_last = sink.last_nav_t();
            let written = sink.finish(&partial, Some(&fault), |m| {
                metrics_json(m, &partial, Some(&fault))
            });
            Err(match written {
                Ok(_) => anyhow::anyhow!(
                    "{fault}; the run stopped there. Outputs up to t = {t_last:.3} s are in \
                     {}/*{} (incomplete)",
                    dir.display(),
                    output::PARTIAL_SUFFIX
                ),
                Err(w) => anyhow::anyhow!(
                    "{fault}; the run stopped there, and writing the partial outputs failed \
                     too: {w:#}"
                ),
            })
        }
        Err(e @ super::RunError::Output(_)) => Err(anyhow::Error::new(e).context(format!(
            "writing the outputs in {}: incomplete, left as *{} (no file under its final name)",
            dir.display(),
            output::PARTIAL_SUFFIX
        ))),
        Err(e) => {
            drop(sink);
            for n in output::OUTPUT_NAMES {
                let _ = std::fs::remove_file(output::partial_path(dir, n));
            }
            Err(e.into())
        }
    }
}

/// Samples per message from the reader thread.
const READ_CHUNK: usize = 2048;
/// Messages in flight between the reader thread and the filter.
const READ_QUEUE: usize = 4;

/// The samples of an IMU text file read and parsed by a thread of their own and handed over
/// in chunks through a bounded channel (at most [`READ_QUEUE`] x [`READ_CHUNK`] samples in
/// flight): reading and parsing overlap the filter. The thread stops at the first error
/// (passed on) or when the receiver is dropped.
pub fn threaded_imu_reader(
    path: PathBuf,
    time_offset_s: f64,
) -> impl Iterator<Item = Result<super::ImuItem, super::RunError>> {
    type Msg = Result<Vec<super::ImuItem>, super::RunError>;
    let (tx, rx) = std::sync::mpsc::sync_channel::<Msg>(READ_QUEUE);
    std::thread::spawn(move || {
        let rd = match ImuTextReader::open(&path) {
            Ok(r) => r,
            Err(e) => {
                let _ = tx.send(Err(super::RunError::Input(e)));
                return;
            }
        };
        let mut chunk = Vec::with_capacity(READ_CHUNK);
        for r in rd {
            match r {
                Ok((mut s, line)) => {
                    s.t_s += time_offset_s;
                    chunk.push(super::ImuItem { sample: s, line });
                    if chunk.len() == READ_CHUNK {
                        let full = std::mem::replace(&mut chunk, Vec::with_capacity(READ_CHUNK));
                        if tx.send(Ok(full)).is_err() {
                            return;
                        }
                    }
                }
                Err(e) => {
                    if !chunk.is_empty() {
                        let _ = tx.send(Ok(std::mem::take(&mut chunk)));
                    }
                    let _ = tx.send(Err(super::RunError::Input(e)));
                    return;
                }
            }
        }
        if !chunk.is_empty() {
            let _ = tx.send(Ok(chunk));
        }
    });
    rx.into_iter().flat_map(|m| {
        let (items, err) = match m {
            Ok(v) => (v, None),
            Err(e) => (Vec::new(), Some(Err(e))),
        };
        items.into_iter().map(Ok).chain(err)
    })
}

/// `run --smooth`: the backward pass needs the whole forward run, so the case is run in memory
/// ([`execute`]) and the smoother writes the outputs (`crate::smooth::apply::finish`).
fn run_smoothed(args: &RunArgs) -> anyhow::Result<()> {
    let t = std::time::Instant::now();
    let p = prepare(args)?;
    println!("{}", p.description);
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let (out, m) = execute(&p, &mut |_, _| {})?;
    let t_run = t.elapsed().as_secs_f64();
    crate::smooth::apply::finish(args, &p, out, m, t_run)
}

/// Runs `host-sim run` (streaming: see [`execute_streaming`]).
pub fn run(args: RunArgs) -> anyhow::Result<()> {
    if args.smooth {
        return run_smoothed(&args);
    }
    let t = std::time::Instant::now();
    let (p, imu) = prepare_streaming(&args)?;
    println!("{}", p.description);
    let pb = if args.quiet {
        indicatif::ProgressBar::hidden()
    } else {
        indicatif::ProgressBar::new_spinner()
    };
    pb.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {pos} IMU samples {elapsed}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    let dir = &args.out;
    let res = execute_streaming(&p, imu.as_ref(), dir, args.nav_rate, &mut |done, _| {
        pb.set_position(done as u64)
    });
    pb.finish_and_clear();
    let t_run = t.elapsed().as_secs_f64();
    let (out, m) = res?;
    let c = &out.counters;
    println!(
        "model {} ({} states), init: {} ({})",
        out.model.name(),
        out.state_names.len(),
        out.init.method,
        out.init.heading_source
    );
    println!(
        "{} IMU epochs, GNSS: {} used ({} reset), {} rejected, {} withheld in {} outage(s), {} invalid; {:.2} s",
        c.imu_epochs,
        c.gnss_accepted,
        c.gnss_forced,
        c.gnss_rejected,
        c.gnss_withheld,
        out.outages.len(),
        c.gnss_invalid,
        t_run
    );
    println!("gate ({}): {}", out.gating.mode, out.gating.message);
    let ir = &out.imu_report;
    if ir.rejected > 0 || ir.gaps > 0 {
        eprintln!(
            "warning: IMU data: {} time gap(s) bridged ({} sample(s) missing), {} implausible \
             sample(s) rejected; see the summary and metrics.json (imu.events)",
            ir.gaps, ir.missing_samples, ir.rejected
        );
    }
    print!("{}", imu_summary(&out));
    let al = out.aiding.summary_line();
    if !al.is_empty() {
        println!("{al}");
    }
    print!("{}", metrics::summary_table(&m));
    println!(
        "wrote {}/{{nav.txt, std.txt, bias.txt, innovations.txt, metrics.json}}",
        dir.display()
    );
    Ok(())
}

/// `metrics.json`: the metrics, the IMU report (gaps, rejected samples) and, after a fault,
/// `"complete": false` with the fault.
pub fn metrics_json(m: &Metrics, out: &RunOutput, fault: Option<&str>) -> anyhow::Result<String> {
    #[derive(serde::Serialize)]
    struct File<'a> {
        #[serde(flatten)]
        metrics: &'a Metrics,
        imu: &'a super::ImuReport,
        complete: bool,
        #[serde(skip_serializing_if = "Option::is_none")]
        fault: Option<&'a str>,
    }
    Ok(serde_json::to_string_pretty(&File {
        metrics: m,
        imu: &out.imu_report,
        complete: fault.is_none(),
        fault,
    })?)
}

/// Lines of the run summary about the IMU data (empty when nothing happened).
pub fn imu_summary(out: &RunOutput) -> String {
    let r = &out.imu_report;
    let mut s = String::new();
    if r.gaps > 0 {
        s.push_str(&format!(
            "IMU: {} time gap(s) bridged ({} sample(s) missing at {:.4} s nominal; {} filled by \
             interpolation, {} spanned by the next increment)\n",
            r.gaps, r.missing_samples, r.nominal_dt_s, r.gaps_filled, r.gaps_spanned
        ));
    }
    if r.rejected > 0 {
        s.push_str(&format!(
            "IMU: {} sample(s) rejected as physically implausible\n",
            r.rejected
        ));
    }
    for e in r.events.iter().take(10) {
        s.push_str(&format!("  {}: {}\n", e.location, e.what));
    }
    if r.events.len() > 10 {
        s.push_str(&format!(
            "  ... {} more in metrics.json\n",
            r.events.len() - 10
        ));
    }
    s
}

/// Keeps the first record at or after each multiple of `1 / rate_hz` from the first record.
pub fn decimate(nav: &[NavSolution], rate_hz: f64) -> Vec<NavSolution> {
    let Some(first) = nav.first() else {
        return Vec::new();
    };
    let p = 1.0 / rate_hz;
    let mut next = first.t_s;
    let mut out = Vec::new();
    for s in nav {
        if s.t_s + 1e-6 * p >= next {
            out.push(*s);
            while next <= s.t_s + 1e-6 * p {
                next += p;
            }
        }
    }
    out
}
