//! A run from files: a configuration plus overrides ([`RunSpec`]) loaded into the data and
//! options the engine runs ([`load`] -> [`Prepared`]).
//!
//! The configuration is the project's run configuration (TOML, [`nav_io::RunConfig`]) or a
//! KF-GINS YAML file (detected by the extension `.yaml`/`.yml`, or by content: a TOML parse
//! failure followed by a successful KF-GINS parse). A KF-GINS file runs KF-GINS's 21 states as
//! KF-GINS's code runs them (`kf-gins-feedback`, `KfGinsConfig::filter_config_feedback`; with
//! the model `kf-gins` the textbook Gauss-Markov reading), its initial state (`initpos` is the
//! IMU position at `starttime`), initial sensor errors and lever arm.
//!
//! [`RunSpec::case`] names a case directory written by `host-sim simulate` (`case.toml` names
//! the files; its outages are added to the outage list so the metrics cover them). A KF-GINS
//! file inside such a case directory also picks up the case's `truth.nav`, outages and GPS
//! week.
//!
//! [`load`] with streaming leaves the IMU and GNSS files unread but for short passes (the
//! GNSS file checked, the first IMU minutes for the mounting check): they are read while the
//! filter runs ([`super::streams`]); without it (diagnose, study, smoothing) everything is
//! loaded.
//!
//! IMU gaps and plausibility: [`nav_core::imu_guard`], [`RunSpec`]'s `imu_*` fields and
//! `[imu.checks]`. Running a prepared case and writing its outputs: [`super::execute`].

use super::gnss_use::{time_span, GnssAccount};
use super::init::{InitSpec, StaticAlign};
use super::outage::{Outage, PeriodicOutages};
use super::streams::{cut_lines, read_prefix, ConfigFiles, ImuFile, MountingTap, Prefix};
pub use super::streams::{GnssStream, ImuStream};
use super::{CaseData, Effect, Model, Precision, RecordOptions, RunOptions};
use crate::mounting::MountingCheck;
use anyhow::{bail, Context};
use nalgebra::Vector3;
use nav_core::config::{FilterConfig, GateProbability, Gating, ScaleFactorNoise, VelocityGating};
use nav_core::earth::Llh;
use nav_core::filter::InitialUncertainty;
use nav_core::imu_guard::{GapIncrements, ImuLimits};
use nav_core::model::{Block, BlockKind};
use nav_core::strapdown::NavState;
use nav_core::types::{GnssFix, ImuSample};
use nav_io::restcheck::check_config_biases as rest_check;
use nav_io::{
    read_gnss_text, read_imu_text, read_kf_gins_yaml, read_nav_text, read_run_config, BiasModel,
    ImuChecksConfig, InitMode, KfGinsConfig, RunConfig, TruthData,
};
use std::path::{Path, PathBuf};

/// What to run: a configuration file, what a user asked relative to its data (outages, an
/// IMU time offset, output rates), and overrides of the options the configuration gives
/// ([`RunOptions`]' own types, each meaning written there once). [`load`] resolves the
/// relative values against the data and merges the overrides into the configuration's
/// [`RunOptions`] in one place. [`RunSpec::new`] gives the configuration as it is.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSpec {
    /// Run configuration: the project's TOML, or a KF-GINS YAML file.
    pub config: PathBuf,
    /// A case directory written by `host-sim simulate` (its files replace the
    /// configuration's).
    pub case: Option<PathBuf>,
    /// Reference trajectory in the nav format (overrides the configuration's).
    pub truth: Option<PathBuf>,
    /// GNSS outages, start in s after the first IMU epoch (after the start time): resolved
    /// into [`RunOptions::outages`] (absolute times).
    pub outages: Vec<Outage>,
    /// Repeating outages, first start in s after the first IMU epoch: expanded into
    /// [`RunOptions::outages`].
    pub periodic_outages: Vec<PeriodicOutages>,
    /// The KF-GINS paper's protocol: 60 s outages every 180 s, the first at 180 s
    /// ([`PeriodicOutages::KF_GINS`]).
    pub kf_gins_outages: bool,
    /// Extra offset added to the IMU time stamps, s (e.g. a logging-delay correction).
    pub imu_time_offset_s: Option<f64>,
    /// The output rates asked, Hz: [`RecordOptions::epoch_rate_hz`] of std.txt and bias.txt
    /// (the engine's [`RunOptions::record`]), [`RecordOptions::nav_rate_hz`] of nav.txt (the
    /// writer's, [`Loaded::nav_rate_hz`]; the engine records every epoch for the metrics).
    /// Each in (0, IMU rate]; a higher one is clamped to the IMU rate with a warning.
    pub record: RecordOptions,
    /// Overrides of the configuration's options; what they leave unset is the
    /// configuration's.
    pub set: Overrides,
}

/// Overrides of a configuration's [`RunOptions`] (a front end's options): `None`, `false` or
/// empty keeps the configuration's. Merged by [`load`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Overrides {
    /// [`RunOptions::model`] (default: the configuration's; KF-GINS YAML: kf-gins-feedback).
    pub model: Option<Model>,
    /// [`RunOptions::precision`].
    pub precision: Option<Precision>,
    /// The options of [`RunOptions::filter`] a front end sets.
    pub filter: FilterOverrides,
    /// [`RunOptions::imu_checks`] (after the configuration's `[imu.checks]`).
    pub imu_checks: ImuChecksOverrides,
    /// Effects whose blocks are appended, in order, to [`RunOptions::extra_blocks`] (after
    /// the configuration's own).
    pub effects: Vec<Effect>,
    /// Sets [`RunOptions::smoother_history`].
    pub smoother_history: bool,
}

/// Overrides of the configuration's [`FilterConfig`] ([`Overrides::filter`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FilterOverrides {
    /// [`FilterConfig::gating`] but for its velocity gate, which stays the configuration's
    /// ([`parse_gate`]).
    pub gating: Option<Gating>,
    /// The velocity gate of [`FilterConfig::gating`] ([`parse_velocity_gate`]).
    pub velocity_gating: Option<Option<VelocityGating>>,
    /// [`FilterConfig::use_gnss_velocity`].
    pub use_gnss_velocity: Option<bool>,
    /// A factor on the accelerometer and gyro white-noise PSDs ([`scale_white_noise`]), in
    /// [1 / [`MAX_NOISE_SCALE`], [`MAX_NOISE_SCALE`]].
    pub white_noise_scale: Option<f64>,
}

/// Overrides of the IMU checks ([`Overrides::imu_checks`], applied to [`super::ImuChecks`]
/// after the configuration's `[imu.checks]`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImuChecksOverrides {
    /// The fields of `[imu.checks]` ([`ImuChecksConfig`]: class, rate and specific-force
    /// limits, longest gap, stop on an implausible sample), applied the same way; the
    /// longest gap here at most [`MAX_IMU_MAX_GAP_S`].
    pub table: ImuChecksConfig,
    /// No plausibility limits ([`ImuLimits::none`]; only non-finite samples are rejected).
    pub no_limits: bool,
    /// [`super::ImuChecks::increments`].
    pub increments: Option<GapIncrements>,
}

/// Default rate of std.txt and bias.txt ([`RecordOptions::epoch_rate_hz`] of
/// [`RunSpec::record`]), Hz.
pub const DEFAULT_STD_RATE_HZ: f64 = 10.0;

impl RunSpec {
    /// The configuration `config` as it is: no overrides, standard deviations at
    /// [`DEFAULT_STD_RATE_HZ`], nav.txt at every IMU epoch.
    pub fn new(config: impl Into<PathBuf>) -> Self {
        Self {
            config: config.into(),
            case: None,
            truth: None,
            outages: Vec::new(),
            periodic_outages: Vec::new(),
            kf_gins_outages: false,
            imu_time_offset_s: None,
            record: RecordOptions {
                nav_rate_hz: None,
                epoch_rate_hz: Some(DEFAULT_STD_RATE_HZ),
            },
            set: Overrides::default(),
        }
    }
}

impl RunSpec {
    /// Everything loaded into memory ([`load`] without streaming), the warnings about the
    /// data dropped: for programs and tests that run the prepared case themselves
    /// ([`super::execute::execute`]).
    pub fn prepare(&self) -> anyhow::Result<Prepared> {
        Ok(load(self, false)?.prepared)
    }
}

/// A run loaded by [`load`]: the case and options, the IMU file to stream (when asked and
/// possible) and the warnings about the data (for the user).
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The data and options.
    pub prepared: Prepared,
    /// The IMU file the run streams instead of loading (then `prepared.case.imu` is empty).
    pub imu_stream: Option<ImuStream>,
    /// Warnings about the data (e.g. the mounting check); the front end shows them.
    pub warnings: Vec<String>,
    /// The truth file the run reads as the solution advances instead of loading it (asked
    /// with `stream_imu`; then `prepared.case.truth` is None), see [`super::truth`].
    pub truth_stream: Option<super::truth::TruthFile>,
    /// Every file (and case folder) the run reads: the configuration, the case folder and its
    /// files, IMU (and its time-tag file), GNSS, truth, aiding. An output folder must hold
    /// none of them ([`super::outdir::check_inputs`]).
    pub inputs: Vec<PathBuf>,
    /// The rate of nav.txt, Hz ([`RecordOptions::nav_rate_hz`] of [`RunSpec::record`]),
    /// checked, and None when clamped to the IMU rate (every epoch).
    pub nav_rate_hz: Option<f64>,
    /// GNSS records the reader dropped by the quality filter (`[gnss] max_q`, no fix).
    pub gnss_dropped_by_quality: u64,
}

impl Loaded {
    /// The warnings of the mounting check made on the run's own reading
    /// ([`load_checking_in_run`]), to be asked once the run has ended; `run_succeeded`: whether
    /// it did. A run that failed, or whose reading has not left a complete check, gets the
    /// check made on a pass of its own over the file's first minutes (as [`load`] makes it),
    /// so that a failed initialisation still hears what the check names (an accelerometer in
    /// g read as m/s^2, increments stamped at the wrong rate). Empty for a run loaded
    /// otherwise (its check's warnings are in [`Self::warnings`]).
    pub fn mounting_warnings(&self, run_succeeded: bool) -> Vec<String> {
        let Some(st) = self.imu_stream.as_ref() else {
            return Vec::new();
        };
        let Some(tap) = st.mounting.as_ref() else {
            return Vec::new();
        };
        match tap.result() {
            Some(m) if run_succeeded => m.warnings,
            _ => match tap.check_on_own_pass(&st.file) {
                Ok(m) => m.warnings,
                Err(e) => vec![format!("mounting check not made: {e:#}")],
            },
        }
    }

    /// Where the run's fixes went ([`GnssAccount`]) from its counters; with `spans` the
    /// time spans of the fixes and of the IMU data too (a pass over each streamed file).
    pub fn gnss_account(&self, counters: &super::RunCounters, spans: bool) -> GnssAccount {
        let mut a = GnssAccount {
            counters: *counters,
            dropped_by_quality: self.gnss_dropped_by_quality,
            ..GnssAccount::default()
        };
        if !spans {
            return a;
        }
        let case = &self.prepared.case;
        a.fix_span_s = match self.imu_stream.as_ref().and_then(|st| st.gnss.as_ref()) {
            Some(g) => g
                .source()
                .ok()
                .and_then(|src| time_span(src.map_while(Result::ok).map(|f| f.t_s))),
            None => time_span(case.gnss.iter().map(|f| f.t_s)),
        };
        a.imu_span_s = match &self.imu_stream {
            Some(st) => st
                .file
                .time_span(true)
                .ok()
                .map(|(x, y)| (x + st.time_offset_s, y + st.time_offset_s)),
            None => time_span(case.imu.iter().map(|s| s.t_s)),
        };
        a
    }

    /// `Err` when the run is not a navigation solution ([`super::gnss_use::check`]), the
    /// causes with the fix and IMU time spans.
    pub fn check_gnss_use(
        &self,
        counters: &super::RunCounters,
    ) -> Result<(), super::gnss_use::NotANavigationSolution> {
        super::gnss_use::check(&self.gnss_account(counters, false))
            .or_else(|_| super::gnss_use::check(&self.gnss_account(counters, true)))
    }

    /// The error of a run that did not start because the static alignment found no valid
    /// GNSS fix in its window ([`super::RunError::NoFixToAlign`]): when no fix of the data is
    /// usable at all, a [`super::gnss_use::NotANavigationSolution`] naming where every fix
    /// went (none in the data, before or after the IMU data, invalid; a pass over the GNSS
    /// file); otherwise, and for any other error, `e` as it was.
    pub fn explain_start_failure(&self, e: anyhow::Error) -> anyhow::Error {
        let Some(&super::RunError::NoFixToAlign { from_s, to_s }) =
            e.chain().find_map(|c| c.downcast_ref::<super::RunError>())
        else {
            return e;
        };
        let mut a = self.gnss_account(&super::RunCounters::default(), true);
        let Some((i0, i1)) = a.imu_span_s else {
            return e;
        };
        let c = &mut a.counters;
        let mut count = |f: &nav_core::types::GnssFix| {
            c.gnss_total += 1;
            if f.t_s < i0 {
                c.gnss_before_run += 1;
                c.gnss_outside_run += 1;
            } else if f.t_s > i1 {
                c.gnss_outside_run += 1;
            } else if !f.is_valid() {
                c.gnss_invalid += 1;
            }
        };
        match self.imu_stream.as_ref().and_then(|st| st.gnss.as_ref()) {
            Some(g) => match g.source() {
                Ok(src) => src.map_while(Result::ok).for_each(|f| count(&f)),
                Err(_) => return e,
            },
            None => self.prepared.case.gnss.iter().for_each(count),
        }
        let why = format!(
            "the static alignment ([init.align]) needs a valid GNSS fix during its window \
             {from_s:.3} .. {to_s:.3} s"
        );
        match super::gnss_use::not_started(&a, &why) {
            Some(n) => anyhow::Error::new(n),
            None => e,
        }
    }
}

/// Most GNSS outages a run accepts (explicit, periodic and the case's together): each one is
/// tracked, coasted and reported on its own.
pub const MAX_OUTAGES: usize = 10_000;

/// Largest `--noise-scale` factor (and 1 / the smallest).
pub const MAX_NOISE_SCALE: f64 = 1e6;

/// Longest `--imu-max-gap`, s.
pub const MAX_IMU_MAX_GAP_S: f64 = 3600.0;

/// The IMU sampling interval: the median of the first 200 positive time steps, s (`None`
/// with fewer than two samples).
fn imu_interval_s(times: impl Iterator<Item = f64>) -> Option<f64> {
    let mut prev: Option<f64> = None;
    let mut steps = Vec::new();
    for t in times.take(201) {
        if let Some(p) = prev {
            let d = t - p;
            if d.is_finite() && d > 0.0 {
                steps.push(d);
            }
        }
        prev = Some(t);
    }
    steps.sort_by(f64::total_cmp);
    steps.get(steps.len() / 2).copied()
}

/// An output rate option checked against the IMU rate `1 / dt_s`: `Err` outside (0, inf);
/// above the IMU rate clamped to it with a warning, returned as `None` (every IMU epoch, which
/// is what any rate above the IMU's writes; the measured IMU rate itself carries rounding
/// noise and would drop epochs as a decimation rate).
fn check_rate(
    name: &str,
    hz: f64,
    dt_s: Option<f64>,
    warnings: &mut Vec<String>,
) -> anyhow::Result<Option<f64>> {
    let imu_hz = dt_s.map(|d| 1.0 / d);
    // the value as a user would type it: 1e300, not three hundred digits
    let given = if hz.abs() >= 1e6 || (hz != 0.0 && hz.abs() < 1e-4) {
        format!("{hz:e}")
    } else {
        format!("{hz}")
    };
    // shown to the millihertz: the median interval of text time tags carries rounding noise
    let shown = |r: f64| (r * 1e3).round() / 1e3;
    let range = imu_hz.map_or("(0, IMU rate]".to_string(), |r| {
        format!("(0, {}] Hz", shown(r))
    });
    if !(hz.is_finite() && hz > 0.0) {
        bail!("{name} {given}: an output rate must be in {range}");
    }
    match imu_hz {
        Some(r) if hz > r * (1.0 + 1e-6) => {
            warnings.push(format!(
                "{name} {given} Hz is above the IMU rate, {} Hz: clamped to it (every IMU epoch; allowed {range})",
                shown(r)
            ));
            Ok(None)
        }
        _ => Ok(Some(hz)),
    }
}

/// A time in seconds as a user typed it: to the nanosecond, trailing zeros dropped (the
/// parsed value carries binary rounding, e.g. 99999.00000000001; a typed 1e-4 stays 0.0001).
fn show_s(x: f64) -> String {
    if !x.is_finite() {
        return x.to_string();
    }
    let s = format!("{x:.9}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0" } else { s }.to_string()
}

/// Checks the outage options against the record `[t0, t_end]` and the IMU interval `dt_s`:
/// every outage starts inside the record and lasts at least one IMU interval, and the
/// periodic ones expand to at most [`MAX_OUTAGES`] in all (`existing` already present).
fn check_outages(
    args: &RunSpec,
    periodic: &[PeriodicOutages],
    t0: f64,
    t_end: f64,
    dt_s: Option<f64>,
    existing: usize,
) -> anyhow::Result<()> {
    let record = (t_end - t0).max(0.0);
    let dt = dt_s.unwrap_or(0.0);
    // as a user reads them: to the millisecond (an IMU interval to the microsecond)
    let span = format!("the data span {record:.3} s (IMU time {t0:.3} to {t_end:.3} s)");
    let interval = format!("one IMU interval, {:.3} ms", dt * 1e3);
    for o in &args.outages {
        let given = format!("--outage {}:{}", show_s(o.start_s), show_s(o.duration_s));
        if !(0.0..record).contains(&o.start_s) {
            let why = if o.start_s.is_nan() {
                "START is not a number"
            } else if o.start_s < 0.0 {
                "START is before the first IMU epoch"
            } else {
                "START is at or beyond the end of the data"
            };
            bail!("{given}: {why}: {span}, so START must be in [0, {record:.3}) s");
        }
        if !o.duration_s.is_finite() || o.duration_s < dt {
            bail!("{given}: DURATION must be finite and at least {interval}");
        }
    }
    let mut n = existing + args.outages.len();
    for p in periodic {
        let what = if *p == PeriodicOutages::KF_GINS {
            "--kf-gins-outages (180:60:180)".to_string()
        } else {
            format!(
                "--periodic-outage {}:{}:{}",
                show_s(p.first_start_s),
                show_s(p.duration_s),
                show_s(p.period_s)
            )
        };
        let inside = (0.0..record).contains(&p.first_start_s);
        if !inside
            || !p.duration_s.is_finite()
            || p.duration_s < dt
            || !p.period_s.is_finite()
            || p.period_s < p.duration_s
        {
            bail!(
                "{what}: FIRST must be in [0, {record:.3}) s ({span}), DURATION finite and at \
                 least {interval}, and PERIOD finite and at least DURATION"
            );
        }
        // outages ending inside the record ([`PeriodicOutages::expand`])
        let room = record - p.first_start_s - p.duration_s;
        let count = if room < 0.0 {
            0.0
        } else {
            (room / p.period_s).floor() + 1.0
        };
        if count > (MAX_OUTAGES - n.min(MAX_OUTAGES)) as f64 {
            bail!(
                "{what}: {count} outages over the {record:.3} s record; at most {MAX_OUTAGES} outages in a run (use a longer PERIOD)"
            );
        }
        n += count as usize;
    }
    Ok(())
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

/// Applies `[imu.checks]` of a run configuration (or the same fields of
/// [`ImuChecksOverrides::table`]) to the checks `c`.
fn apply_imu_checks(ch: &ImuChecksConfig, c: &mut super::ImuChecks) -> anyhow::Result<()> {
    if let Some(class) = ch.class {
        c.limits = ImuLimits::for_class(class.class());
    }
    set_limits(c, ch.max_rate_deg_s, ch.max_accel_g)?;
    if let Some(g) = ch.max_gap_s {
        if !(g.is_finite() && g > 0.0) {
            bail!("imu.checks.max_gap_s = {g}: must be positive");
        }
        c.max_gap_s = g;
    }
    c.stop_on_implausible |= ch.stop_on_implausible;
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

/// Parses a `--velocity-gate` value (`[gnss] velocity_gate`): `joint` (None: position and
/// velocity in one update), `robust`, `hard` (= 0.9999), `0.95`, `0.99`, `0.999`, `0.9999`,
/// `off` (a separate velocity update without a gate).
pub fn parse_velocity_gate(s: &str) -> anyhow::Result<Option<VelocityGating>> {
    Ok(Some(match s.trim() {
        "joint" => return Ok(None),
        "robust" => VelocityGating::ROBUST,
        "off" | "none" => VelocityGating::OFF,
        "hard" | "0.9999" | "99.99" => VelocityGating::hard(GateProbability::P9999),
        "0.95" | "95" => VelocityGating::hard(GateProbability::P95),
        "0.99" | "99" => VelocityGating::hard(GateProbability::P99),
        "0.999" | "99.9" => VelocityGating::hard(GateProbability::P999),
        other => bail!(
            "velocity gate {other}: expected joint, robust, hard, off, 0.95, 0.99, 0.999 or 0.9999"
        ),
    }))
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
    odometer: Option<PathBuf>,
    heading: Option<PathBuf>,
    outages: Vec<Outage>,
    week: u16,
}

fn read_case_dir(dir: &Path) -> anyhow::Result<CaseDir> {
    let cf = CaseIndex::from_file(&dir.join("case.toml"))?;
    Ok(CaseDir {
        imu: dir.join(&cf.files.imu),
        gnss: dir.join(&cf.files.gnss),
        truth: dir.join(&cf.files.truth),
        odometer: cf.files.odometer.as_ref().map(|p| dir.join(p)),
        heading: cf.files.heading.as_ref().map(|p| dir.join(p)),
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

/// The files a run of `spec` reads (as [`Loaded::inputs`] lists them), from its
/// configuration and case folder alone, without loading any data: for a front end that must
/// check its output folder before it writes anything (`hw-bridge replay --config`). A
/// configuration that cannot be read is an error.
pub fn run_inputs(spec: &RunSpec) -> anyhow::Result<Vec<PathBuf>> {
    let kind = read_config(&spec.config).context("reading the run configuration")?;
    let cfg_dir = spec
        .config
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_default();
    let case_dir = match &spec.case {
        Some(d) => Some(read_case_dir(d)?),
        None if cfg_dir.join("case.toml").exists() && matches!(kind, ConfigKind::KfGins(_)) => {
            Some(read_case_dir(&cfg_dir)?)
        }
        None => None,
    };
    Ok(input_files(spec, &kind, &cfg_dir, case_dir.as_ref()))
}

/// The files a run of `args` reads, as [`Loaded::inputs`] lists them.
fn input_files(
    args: &RunSpec,
    kind: &ConfigKind,
    cfg_dir: &Path,
    case_dir: Option<&CaseDir>,
) -> Vec<PathBuf> {
    let mut v = vec![args.config.clone()];
    v.extend(args.truth.iter().cloned());
    if let Some(d) = &args.case {
        v.push(d.clone());
        v.push(d.join("case.toml"));
    }
    if let Some(c) = case_dir {
        v.extend([c.imu.clone(), c.gnss.clone(), c.truth.clone()]);
        v.extend(c.odometer.iter().chain(c.heading.iter()).cloned());
    }
    match kind {
        ConfigKind::Run(r) => {
            let imu = RunConfig::resolve(cfg_dir, &r.imu.path);
            if let Some(nav_io::imucsv::CsvTime::TicksMs {
                tag_file: Some(t), ..
            }) = r.imu.csv.as_ref().map(|c| &c.time)
            {
                let csv_dir = imu.parent().map(Path::to_path_buf).unwrap_or_default();
                v.push(RunConfig::resolve(&csv_dir, t));
            }
            v.push(imu);
            v.push(RunConfig::resolve(cfg_dir, &r.gnss.path));
            v.extend(r.truth.iter().map(|t| RunConfig::resolve(cfg_dir, &t.path)));
            if let Some(a) = &r.aiding {
                let files = a.odometer.file.iter().chain(a.heading.file.iter());
                v.extend(files.map(|f| RunConfig::resolve(cfg_dir, f)));
            }
        }
        ConfigKind::KfGins(k) => {
            v.push(k.resolve_path(&k.imupath, cfg_dir));
            v.push(k.resolve_path(&k.gnsspath, cfg_dir));
        }
    }
    v
}

/// Longest lever arm taken without a warning, m: a vehicle's GNSS antenna is within a few
/// metres of its IMU; a longer one is most often a unit slip (cm or mm written as m). Up to
/// [`nav_io::MAX_LEVER_ARM_M`] it is used; beyond, the configuration is refused.
pub const PLAUSIBLE_LEVER_ARM_M: f64 = 10.0;

/// The warning about a lever arm (`lever_m`, body FRD, m, given as `key`) longer than
/// [`PLAUSIBLE_LEVER_ARM_M`].
pub fn lever_arm_warning(lever_m: [f64; 3], key: &str) -> Option<String> {
    let norm = lever_m.iter().map(|v| v * v).sum::<f64>().sqrt();
    (norm > PLAUSIBLE_LEVER_ARM_M).then(|| {
        format!(
            "lever arm {norm:.1} m ({key} = [{}, {}, {}]): a vehicle's antenna is usually within \
             a few metres of the IMU; check the units",
            lever_m[0], lever_m[1], lever_m[2]
        )
    })
}

/// Refuses a data file of the run that is a folder ([`nav_io::IoError::Folder`]), naming the
/// configuration key (and file) or the flag that gives it, before anything is read: a reader
/// would otherwise fail at its first read with the system's "Is a directory".
fn check_no_folder(
    args: &RunSpec,
    kind: &ConfigKind,
    cfg_dir: &Path,
) -> Result<(), nav_io::IoError> {
    let cfg = args.config.display();
    let mut named: Vec<(PathBuf, String)> = args
        .truth
        .iter()
        .map(|t| (t.clone(), "--truth".to_string()))
        .collect();
    let key = |k: &str| format!("`{k}` in {cfg}");
    match kind {
        ConfigKind::Run(r) => {
            named.push((RunConfig::resolve(cfg_dir, &r.imu.path), key("[imu] path")));
            named.push((
                RunConfig::resolve(cfg_dir, &r.gnss.path),
                key("[gnss] path"),
            ));
            if let Some(t) = &r.truth {
                named.push((RunConfig::resolve(cfg_dir, &t.path), key("[truth] path")));
            }
            if let Some(a) = &r.aiding {
                if let Some(f) = &a.odometer.file {
                    named.push((
                        RunConfig::resolve(cfg_dir, f),
                        key("[aiding.odometer] file"),
                    ));
                }
                if let Some(f) = &a.heading.file {
                    named.push((RunConfig::resolve(cfg_dir, f), key("[aiding.heading] file")));
                }
            }
        }
        ConfigKind::KfGins(k) => {
            named.push((k.resolve_path(&k.imupath, cfg_dir), key("imupath")));
            named.push((k.resolve_path(&k.gnsspath, cfg_dir), key("gnsspath")));
        }
    }
    match named.into_iter().find(|(p, _)| p.is_dir()) {
        Some((path, given_as)) => Err(nav_io::IoError::Folder {
            path,
            given_as: Some(given_as),
        }),
        None => Ok(()),
    }
}

fn rpy_sigma_to_phi(att_std_rad: [f64; 3]) -> [f64; 3] {
    // small angles: roll/pitch/yaw sigmas as phi N/E/D sigmas (exact at zero roll/pitch)
    att_std_rad
}

/// Loads everything a run needs. With `stream_imu`, the IMU file is not loaded (a case
/// directory's or a KF-GINS configuration's text file, or whatever file a run configuration
/// names, through [`RunConfig::open_imu`]): the case's IMU list stays empty and the file is
/// returned in [`Loaded::imu_stream`], to be read while the filter runs
/// ([`super::execute::execute_streaming`]). The GNSS file of such a run is streamed too
/// ([`ImuStream::gnss`]: checked here, its week and warnings taken, the case's fix list left
/// empty), and the mounting check reads the first minutes of both
/// ([`super::streams::read_prefix`]). Without `stream_imu` everything is loaded.
/// With `stream_imu` the truth is never loaded (`case.truth` stays None): its file is checked
/// and returned in [`Loaded::truth_stream`], to be read as the solution advances.
pub fn load(args: &RunSpec, stream_imu: bool) -> anyhow::Result<Loaded> {
    load_with(args, stream_imu, false)
}

/// [`load`] with the IMU and GNSS files streamed, the mounting check made on the run's own
/// reading of the IMU file ([`super::streams::MountingTap`] in [`ImuStream::mounting`])
/// instead of a pass over the first minutes of the files before the run: [`Loaded::warnings`]
/// do not hold the check's warnings; [`Loaded::mounting_warnings`] gives them once the run
/// has read the first [`super::streams::MOUNTING_PREFIX_S`] of IMU data (or stopped before).
pub fn load_checking_in_run(args: &RunSpec) -> anyhow::Result<Loaded> {
    load_with(args, true, true)
}

fn load_with(args: &RunSpec, stream_imu: bool, check_in_run: bool) -> anyhow::Result<Loaded> {
    let stream = stream_imu;
    let mut warnings = Vec::new();
    let mut dropped_by_quality = 0u64;
    // the readers' errors name the file (and line/column): not repeated here
    let kind = read_config(&args.config).context("reading the run configuration")?;
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
    check_no_folder(args, &kind, &cfg_dir)?;
    let lever_key = match &kind {
        ConfigKind::Run(_) => "[gnss] lever_arm_m",
        ConfigKind::KfGins(_) => "antlever",
    };
    let mut inputs = input_files(args, &kind, &cfg_dir, case_dir.as_ref());
    // streamed, the truth is not loaded: it is read as the solution advances
    let truth_stream = if stream {
        let cd_truth = case_dir.as_ref().map(|c| c.truth.as_path());
        let cfg_truth = match &kind {
            ConfigKind::Run(r) => r.truth.as_ref(),
            ConfigKind::KfGins(_) => None,
        };
        super::truth::run_truth_file(args.truth.as_deref(), cd_truth, cfg_truth, &cfg_dir)?
    } else {
        None
    };
    let (mut case, mut opts, mut week, mut description, streams) = match kind {
        ConfigKind::KfGins(k) => {
            prepare_kf_gins(&k, &cfg_dir, case_dir.as_ref(), args.set.model, stream)?
        }
        ConfigKind::Run(mut r) => {
            if stream {
                r.truth = None;
            }
            prepare_run_config(
                &r,
                &cfg_dir,
                case_dir.as_ref(),
                stream,
                &mut warnings,
                &mut dropped_by_quality,
            )?
        }
    };
    let mut imu_stream = streams;
    // the data against the configured mounting (z gyro vs GNSS course, gravity at rest): a
    // streamed run checks the first minutes of its files (and learns its first IMU time)
    let prefix = prefix_of(imu_stream.as_mut(), &case.gnss, check_in_run)?;
    warnings.extend(match &prefix {
        Some(p) => p.mounting.warnings.clone(),
        None => crate::mounting::check_mounting(&case.imu, &case.gnss).warnings,
    });
    if let Some(cd) = &case_dir {
        week = cd.week;
        opts.outages.extend(cd.outages.iter().copied());
    }
    add_truth(args, case_dir.as_ref(), stream, &mut case, &mut description)?;
    apply_time_offset(args, &mut case, imu_stream.as_mut(), &mut description)?;
    // a given state timed at the first IMU sample (no start_s) moves with the IMU times
    if let (Some(dt), None, InitSpec::Given(state, _)) =
        (args.imu_time_offset_s, opts.start_s, &mut opts.init)
    {
        state.t_s += dt;
    }
    args.set.apply(&mut opts, &mut description)?;
    warnings.extend(lever_arm_warning(opts.lever_arm_m, lever_key));
    let nav_rate_hz = schedule(
        args,
        &case,
        imu_stream.as_ref(),
        prefix.as_ref(),
        &mut opts,
        &mut warnings,
    )?;
    inputs.extend(opts.aiding.odometer_file.iter().cloned());
    inputs.extend(opts.aiding.heading_file.iter().cloned());
    if let Some(st) = &imu_stream {
        inputs.push(st.file.path());
        inputs.extend(st.gnss.as_ref().map(|g| g.file.path()));
    }
    inputs.extend(truth_stream.as_ref().map(|t| t.path.clone()));
    Ok(Loaded {
        prepared: Prepared {
            case,
            opts,
            week,
            description,
        },
        imu_stream,
        warnings,
        truth_stream,
        inputs,
        nav_rate_hz,
        gnss_dropped_by_quality: dropped_by_quality,
    })
}

/// The start of a streamed run's files (None when the run is loaded): the first IMU time and
/// the mounting check, made here ([`read_prefix`]) or, with `check_in_run`, left to the run's
/// own reading (a [`MountingTap`] set in `st`; the check here holds only the warnings about
/// a last line cut short).
fn prefix_of(
    imu_stream: Option<&mut ImuStream>,
    fixes_in_memory: &[GnssFix],
    check_in_run: bool,
) -> anyhow::Result<Option<Prefix>> {
    Ok(match imu_stream {
        Some(st) if check_in_run => {
            let gnss = st.gnss.as_ref().map(|g| &g.file);
            let (first_t_s, _) = st.file.time_span(false)?;
            st.mounting = Some(MountingTap::new(&st.file, first_t_s, gnss, fixes_in_memory));
            // the cut last lines now, the check's own warnings after the run
            let mounting = MountingCheck {
                turn_slope: None,
                rest_f_body_mps2: None,
                rest_dt_s: None,
                gnss_lag_s: None,
                warnings: cut_lines(&st.file, gnss),
            };
            Some(Prefix {
                first_t_s,
                mounting,
            })
        }
        Some(st) => Some(read_prefix(
            &st.file,
            st.gnss.as_ref().map(|g| &g.file),
            fixes_in_memory,
        )?),
        None => None,
    })
}

/// The truth of the case folder or `--truth` (loaded unless `stream`: then read as the
/// solution advances) named in the description.
fn add_truth(
    args: &RunSpec,
    case_dir: Option<&CaseDir>,
    stream: bool,
    case: &mut CaseData,
    description: &mut String,
) -> anyhow::Result<()> {
    if let Some(cd) = case_dir {
        if case.truth.is_none() && args.truth.is_none() && cd.truth.exists() {
            if !stream {
                case.truth = Some(read_nav_text(&cd.truth)?);
            }
            description.push_str(&format!("; truth {}", cd.truth.display()));
        }
    }
    if let Some(t) = &args.truth {
        if !stream {
            case.truth = Some(read_nav_text(t)?);
        }
        description.push_str(&format!("; truth {}", t.display()));
    }
    Ok(())
}

/// `--imu-time-offset`: added to every IMU time (loaded samples, or the stream's).
fn apply_time_offset(
    args: &RunSpec,
    case: &mut CaseData,
    imu_stream: Option<&mut ImuStream>,
    description: &mut String,
) -> anyhow::Result<()> {
    if let Some(dt) = args.imu_time_offset_s {
        if dt.is_nan() || dt.abs() > nav_io::MAX_TIME_OFFSET_S {
            bail!(
                "--imu-time-offset {dt}: must be in [-{m}, {m}] s",
                m = nav_io::MAX_TIME_OFFSET_S
            );
        }
        for s in &mut case.imu {
            s.t_s += dt;
        }
        if let Some(st) = imu_stream {
            st.time_offset_s = dt;
        }
        description.push_str(&format!("; IMU time offset {dt:+} s"));
    }
    Ok(())
}

impl Overrides {
    /// Merges the overrides into the configuration's options `opts` (the one place a front
    /// end's options reach [`RunOptions`]), checked; the effects and the noise scale are
    /// named in the run's `description`.
    fn apply(&self, opts: &mut RunOptions, description: &mut String) -> anyhow::Result<()> {
        if let Some(m) = self.model {
            opts.model = m;
        }
        for e in &self.effects {
            opts.add_effect_block(e.block());
        }
        if !self.effects.is_empty() {
            description.push_str(&format!("; effects {}", Effect::join(&self.effects)));
        }
        if let Some(p) = self.precision {
            opts.precision = p;
        }
        self.imu_checks.apply(&mut opts.imu_checks)?;
        self.filter.apply(&mut opts.filter, description)?;
        opts.smoother_history |= self.smoother_history;
        Ok(())
    }
}

impl FilterOverrides {
    /// Merges the overrides into the configuration's `filter`, checked (the noise scale
    /// named in `description`).
    fn apply(&self, filter: &mut FilterConfig, description: &mut String) -> anyhow::Result<()> {
        if let Some(g) = self.gating {
            let v = filter.gating.velocity;
            filter.gating = g;
            filter.gating.velocity = v;
        }
        if let Some(v) = self.velocity_gating {
            filter.gating.velocity = v;
        }
        if let Some(v) = self.use_gnss_velocity {
            filter.use_gnss_velocity = v;
        }
        if let Some(k) = self.white_noise_scale {
            if !((1.0 / MAX_NOISE_SCALE..=MAX_NOISE_SCALE).contains(&k)) {
                bail!(
                    "--noise-scale {k}: must be in [{}, {MAX_NOISE_SCALE}]",
                    1.0 / MAX_NOISE_SCALE
                );
            }
            scale_white_noise(filter, k);
            description.push_str(&format!("; white-noise PSDs x{k}"));
        }
        Ok(())
    }
}

impl ImuChecksOverrides {
    /// Merges the overrides into the checks `c` (the configuration's), checked.
    fn apply(&self, c: &mut super::ImuChecks) -> anyhow::Result<()> {
        if let Some(g) = self.table.max_gap_s {
            if !(g > 0.0 && g <= MAX_IMU_MAX_GAP_S) {
                bail!("--imu-max-gap {g}: must be in (0, {MAX_IMU_MAX_GAP_S}] s");
            }
        }
        apply_imu_checks(&self.table, c)?;
        if self.no_limits {
            c.limits = ImuLimits::none();
        }
        if self.increments.is_some() {
            c.increments = self.increments;
        }
        Ok(())
    }
}

/// The run's time window and rates: the epoch rate set in `opts`, the outages of the
/// command line (relative to the first IMU epoch) checked and added; returns the checked
/// rate of `nav.txt`.
fn schedule(
    args: &RunSpec,
    case: &CaseData,
    imu_stream: Option<&ImuStream>,
    prefix: Option<&super::streams::Prefix>,
    opts: &mut RunOptions,
    warnings: &mut Vec<String>,
) -> anyhow::Result<Option<f64>> {
    // the last IMU time only when outages are checked against it (a pass over the file)
    let periodic_wanted =
        !args.periodic_outages.is_empty() || args.kf_gins_outages || !args.outages.is_empty();
    let (t0, t_end) = match (imu_stream, case.imu.first(), case.imu.last()) {
        (Some(st), _, _) => {
            // the last time only when periodic outages need it (a pass over the whole file)
            let (a, b) = match prefix {
                Some(p) if !periodic_wanted => (p.first_t_s, p.first_t_s),
                _ => st.file.time_span(periodic_wanted)?,
            };
            (a + st.time_offset_s, b + st.time_offset_s)
        }
        (None, Some(a), Some(b)) => (a.t_s, b.t_s),
        _ => bail!("no IMU samples in the data"),
    };
    let t0 = opts.start_s.map_or(t0, |s| s.max(t0));
    let t_end = opts.end_s.map_or(t_end, |e| e.min(t_end));
    let dt_s = match imu_stream {
        Some(st) => imu_interval_s(st.file.open()?.map_while(Result::ok).map(|(s, _)| s.t_s)),
        None => imu_interval_s(case.imu.iter().map(|s| s.t_s)),
    };
    // the engine records every navigation epoch (the metrics see them all); nav.txt's rate
    // is the writer's
    let rate = |name: &str, hz: Option<f64>, warnings: &mut Vec<String>| {
        hz.map(|r| check_rate(name, r, dt_s, warnings))
            .transpose()
            .map(Option::flatten)
    };
    opts.record = RecordOptions {
        nav_rate_hz: None,
        epoch_rate_hz: rate("--std-rate", args.record.epoch_rate_hz, warnings)?,
    };
    let nav_rate_hz = rate("--nav-rate", args.record.nav_rate_hz, warnings)?;
    let mut periodic = args.periodic_outages.clone();
    if args.kf_gins_outages {
        periodic.push(PeriodicOutages::KF_GINS);
    }
    check_outages(args, &periodic, t0, t_end, dt_s, opts.outages.len())?;
    opts.outages
        .extend(args.outages.iter().map(|o| o.shifted(t0)));
    for p in &periodic {
        opts.outages.extend(p.expand(t0, t_end));
    }
    Ok(nav_rate_hz)
}

fn prepare_kf_gins(
    k: &KfGinsConfig,
    dir: &Path,
    case_dir: Option<&CaseDir>,
    model: Option<Model>,
    stream: bool,
) -> anyhow::Result<(CaseData, RunOptions, u16, String, Option<ImuStream>)> {
    k.validate()
        .map_err(|e| anyhow::anyhow!("KF-GINS configuration: {e}"))?;
    let (imu_p, gnss_p) = match case_dir {
        Some(c) => (c.imu.clone(), c.gnss.clone()),
        None => (
            k.resolve_path(&k.imupath, dir),
            k.resolve_path(&k.gnsspath, dir),
        ),
    };
    // streamed: the IMU and the GNSS text files are read while the filter runs
    let (imu_rec, gnss, imu_stream) = if stream {
        let g = GnssStream::check(&gnss_p)?;
        let mut st = ImuStream::new(ImuFile::Text(imu_p.clone()));
        st.gnss = Some(g);
        (nav_io::ImuRecord::default(), Vec::new(), Some(st))
    } else {
        (read_imu_text(&imu_p)?, read_gnss_text(&gnss_p)?, None)
    };
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

/// The filter configuration and model of a run configuration (`[noise]`, `[gnss]` gates).
fn run_config_filter(r: &RunConfig) -> anyhow::Result<(FilterConfig, Model)> {
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
    if let Some(v) = &r.gnss.velocity_gate {
        filter.gating.velocity = parse_velocity_gate(v).context("gnss.velocity_gate")?;
    }
    let model = match r.noise.model {
        BiasModel::N => Model::N,
        BiasModel::Nbk => Model::Nbk,
        BiasModel::NbkSingleState => Model::NbkSingle,
    };
    Ok((filter, model))
}

/// The initialisation of a run configuration (`[init]`): a given state at the start time (or
/// the first IMU time), or a static alignment.
fn run_config_init(
    r: &RunConfig,
    imu: &[ImuSample],
    imu_stream: Option<&ImuStream>,
) -> anyhow::Result<InitSpec> {
    let ic = &r.init;
    let att_std = ic.att_std_deg.map(f64::to_radians);
    let unc = InitialUncertainty {
        att_sigma_rad: rpy_sigma_to_phi(att_std),
        vel_sigma_mps: ic.vel_std_mps,
        pos_sigma_m: ic.pos_std_m,
    };
    Ok(match ic.mode().map_err(|e| anyhow::anyhow!(e))? {
        InitMode::Given(g) => {
            let [lat, lon, h] = g.pos_deg_deg_m;
            let t = r
                .start_s
                .or_else(|| imu.first().map(|s| s.t_s))
                .or_else(|| {
                    let st = imu_stream?;
                    st.file.time_span(false).ok().map(|(a, _)| a)
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
    })
}

fn prepare_run_config(
    r: &RunConfig,
    dir: &Path,
    case_dir: Option<&CaseDir>,
    stream: bool,
    warnings: &mut Vec<String>,
    dropped_by_quality: &mut u64,
) -> anyhow::Result<(CaseData, RunOptions, u16, String, Option<ImuStream>)> {
    let mut week = 0u16;
    let mut imu_stream: Option<ImuStream> = None;
    let imu_p = case_dir.map_or_else(|| RunConfig::resolve(dir, &r.imu.path), |c| c.imu.clone());
    let gnss_p = case_dir.map_or_else(|| RunConfig::resolve(dir, &r.gnss.path), |c| c.gnss.clone());
    let mut gaps = String::new();
    let (imu_rec, gnss, truth) = match case_dir {
        Some(c) => (
            if stream {
                let mut st = ImuStream::new(ImuFile::Text(c.imu.clone()));
                st.gnss = Some(GnssStream::check(&c.gnss)?);
                imu_stream = Some(st);
                nav_io::ImuRecord::default()
            } else {
                read_imu_text(&c.imu)?
            },
            if stream {
                Vec::new()
            } else {
                read_gnss_text(&c.gnss)?
            },
            if !stream && c.truth.exists() {
                Some(read_nav_text(&c.truth)?)
            } else {
                None
            },
        ),
        None if stream => {
            // the configuration's own files read while the filter runs: the IMU opened here
            // (its errors before the run), the GNSS checked to its end (errors, count, week,
            // warnings), nothing kept
            let files = ConfigFiles {
                config: std::sync::Arc::new(r.clone()),
                dir: dir.to_path_buf(),
            };
            let mut st = ImuStream::new(ImuFile::Config(files.clone()));
            let g = GnssStream::check_config(files)?;
            warnings.extend(g.summary.warnings.iter().cloned().chain(rest_check(r, dir)));
            *dropped_by_quality = g.summary.dropped_by_quality as u64;
            if let Some(w) = g.summary.week {
                week = u16::try_from(w).unwrap_or(0);
            }
            st.gnss = Some(g);
            imu_stream = Some(st);
            // the truth of a streamed run is read as the solution advances (`load` takes the
            // `[truth]` table for `Loaded::truth_stream` before calling here)
            (nav_io::ImuRecord::default(), Vec::new(), None)
        }
        None => {
            let inp = r.load_inputs(dir)?;
            warnings.extend(inp.warnings.iter().cloned().chain(rest_check(r, dir)));
            *dropped_by_quality = inp.gnss_dropped_by_quality as u64;
            if let Some(w) = inp.gnss_week {
                week = u16::try_from(w).unwrap_or(0);
            }
            if inp.imu.gaps.count() > 0 {
                gaps = format!("; IMU time gaps: {}", inp.imu.gaps);
            }
            let truth = inp.truth.map(truth_solutions);
            (inp.imu, inp.gnss, truth)
        }
    };
    let imu = imu_rec.samples;
    let (filter, model) = run_config_filter(r)?;
    let init = run_config_init(r, &imu, imu_stream.as_ref())?;
    let mut opts = RunOptions::new(model, filter, init);
    opts.gnss_sigma_scale = r.gnss.sigma_scale;
    if let Some(e) = &r.gnss.error_state {
        opts.filter.effects.gnss_position_gm = e.noise();
    }
    if let Some(ch) = &r.imu.checks {
        apply_imu_checks(ch, &mut opts.imu_checks).context("[imu.checks]")?;
    }
    opts.lever_arm_m = r.gnss.lever_arm_m;
    if let Some(a) = &r.aiding {
        apply_aiding(a, dir, case_dir, &mut opts)?;
    }
    opts.start_s = r.start_s;
    opts.end_s = r.end_s;
    for name in &r.effects {
        let e: Effect = name.parse().context("effects")?;
        opts.add_effect_block(e.block());
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

/// A configuration's truth as navigation records (RTKLIB positions: velocity when the file
/// has one, attitude unknown).
fn truth_solutions(t: TruthData) -> Vec<nav_core::types::NavSolution> {
    match t {
        TruthData::Nav(v) => v,
        TruthData::Positions(f) => f.iter().map(super::truth::truth_from_fix).collect(),
    }
}

/// `[aiding]` into the run options: the filter side, the input files (a case directory's own
/// files first), the odometer's scale-factor state and its prior.
fn apply_aiding(
    a: &nav_io::AidingSection,
    dir: &Path,
    case_dir: Option<&CaseDir>,
    opts: &mut RunOptions,
) -> anyhow::Result<()> {
    let filter = a
        .to_config()
        .map_err(|e| anyhow::anyhow!(e))
        .context("[aiding]")?;
    let file = |case_file: Option<&PathBuf>, cfg_file: &Option<PathBuf>| {
        case_file
            .cloned()
            .or_else(|| cfg_file.as_ref().map(|p| RunConfig::resolve(dir, p)))
    };
    let o = &a.odometer;
    opts.aiding = super::aiding::RunAidingConfig {
        filter,
        odometer_file: file(case_dir.and_then(|c| c.odometer.as_ref()), &o.file),
        odometer_max_gap_s: o
            .max_gap_s
            .unwrap_or(nav_io::aidingcfg::OdometerSection::DEFAULT_MAX_GAP_S),
        heading_file: file(case_dir.and_then(|c| c.heading.as_ref()), &a.heading.file),
        // a case's own heading.txt is text whatever the configuration's format
        heading_format: match case_dir.and_then(|c| c.heading.as_ref()) {
            Some(_) => nav_io::heading::HeadingFormat::Text,
            None => a
                .heading
                .file_format()
                .map_err(|e| anyhow::anyhow!(e))
                .context("[aiding]")?,
        },
    };
    if o.estimates_scale() {
        opts.add_effect_block(Block::OdometerScale);
        if let Some(s) = o.scale_sigma {
            opts.filter.effects.odometer_scale.init_sigma = s;
        }
    }
    Ok(())
}

/// What a run reads of a case directory's `case.toml` (written by `host-sim simulate`): the
/// data files, the GPS week and the outages. Other tables of the file are not read here.
#[derive(Debug, Clone, serde::Deserialize)]
pub struct CaseIndex {
    /// Data files, relative to the case directory.
    pub files: CaseIndexFiles,
    /// Summary numbers (the GPS week).
    pub summary: CaseIndexSummary,
    /// All GNSS outages of the case (explicit and periodic).
    #[serde(default)]
    pub outages: Vec<CaseIndexOutage>,
}

/// The data files of a case ([`CaseIndex::files`]).
#[derive(Debug, Clone, serde::Deserialize)]
pub struct CaseIndexFiles {
    /// IMU text file.
    pub imu: String,
    /// GNSS text file.
    pub gnss: String,
    /// Truth in the nav format at the IMU rate.
    pub truth: String,
    /// Wheel speed, when simulated.
    #[serde(default)]
    pub odometer: Option<String>,
    /// Dual-antenna heading, when simulated.
    #[serde(default)]
    pub heading: Option<String>,
}

/// The summary of a case ([`CaseIndex::summary`]).
#[derive(Debug, Clone, serde::Deserialize)]
pub struct CaseIndexSummary {
    /// GPS week.
    pub gps_week: u16,
}

/// One outage of a case ([`CaseIndex::outages`]).
#[derive(Debug, Clone, serde::Deserialize)]
pub struct CaseIndexOutage {
    /// Start, GPS seconds of week.
    pub start_sow: f64,
    /// Duration, s.
    pub duration_s: f64,
}

impl CaseIndex {
    /// Reads the index of a `case.toml`.
    pub fn from_file(path: &Path) -> anyhow::Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A lever arm beyond 10 m draws the warning with its length and key; one of a few
    /// metres does not.
    #[test]
    fn a_lever_arm_beyond_ten_metres_is_warned_about() {
        assert_eq!(
            lever_arm_warning([65.0, 0.0, 0.0], "antlever").as_deref(),
            Some(
                "lever arm 65.0 m (antlever = [65, 0, 0]): a vehicle's antenna is usually within \
                 a few metres of the IMU; check the units"
            )
        );
        assert!(lever_arm_warning([6.0, 6.0, 6.0], "k").is_some());
        assert!(lever_arm_warning([0.5, -1.2, -1.9], "k").is_none());
        assert!(lever_arm_warning([10.0, 0.0, 0.0], "k").is_none());
    }

    /// Every override lands in the option it names, once, over the configuration's value;
    /// unset ones keep the configuration's.
    #[test]
    fn overrides_merge_into_the_configurations_options() {
        let mut filter = FilterConfig::source_nbk_model();
        filter.gating.velocity = Some(VelocityGating::ROBUST);
        let config = || {
            let mut o = RunOptions::new(
                Model::Nbk,
                filter,
                InitSpec::StaticAlignment(StaticAlign::new(10.0)),
            );
            o.imu_checks.max_gap_s = 0.2;
            o
        };
        let (mut kept, mut d) = (config(), String::new());
        Overrides::default().apply(&mut kept, &mut d).unwrap();
        assert_eq!(format!("{kept:?}"), format!("{:?}", config()));
        assert!(d.is_empty());

        let set = Overrides {
            model: Some(Model::N),
            precision: Some(Precision::F32),
            filter: FilterOverrides {
                gating: Some(Gating::disabled()),
                velocity_gating: None,
                use_gnss_velocity: Some(true),
                white_noise_scale: Some(4.0),
            },
            imu_checks: ImuChecksOverrides {
                table: ImuChecksConfig {
                    max_rate_deg_s: Some(100.0),
                    stop_on_implausible: true,
                    ..ImuChecksConfig::default()
                },
                no_limits: false,
                increments: Some(GapIncrements::Sample),
            },
            effects: vec![Effect::LeverArm],
            smoother_history: true,
        };
        let mut o = config();
        set.apply(&mut o, &mut d).unwrap();
        assert_eq!((o.model, o.precision), (Model::N, Precision::F32));
        // the gate replaced but for the configuration's velocity gate
        assert_eq!(o.filter.gating.max_consecutive_rejections, 0);
        assert_eq!(o.filter.gating.velocity, Some(VelocityGating::ROBUST));
        assert!(o.filter.use_gnss_velocity);
        assert_eq!(o.filter.accel.s_n[0], 4.0 * filter.accel.s_n[0]);
        assert_eq!(o.imu_checks.limits.max_rate_radps, 100f64.to_radians());
        assert_eq!(o.imu_checks.max_gap_s, 0.2);
        assert_eq!(o.imu_checks.increments, Some(GapIncrements::Sample));
        assert!(o.imu_checks.stop_on_implausible && o.smoother_history);
        assert_eq!(o.extra_blocks, [Block::LeverArm]);
        assert_eq!(d, "; effects lever_arm; white-noise PSDs x4");

        // a bad value names the option
        let mut bad = Overrides::default();
        bad.imu_checks.table.max_gap_s = Some(5000.0);
        let e = bad.apply(&mut config(), &mut d).unwrap_err().to_string();
        assert!(e.starts_with("--imu-max-gap 5000"), "{e}");
    }

    #[test]
    fn streamed_gnss_is_the_loaded_list_and_errors_before_the_run() {
        let dir = std::env::temp_dir().join(format!("gnssstream-prep-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ok = dir.join("gnss.txt");
        std::fs::write(
            &ok,
            "100.0 30.5 114.3 20.0 0.5 0.6 1.1\n\
             101.0 30.50001 114.30001 20.5 0.4 0.3 0.9 1.0 2.0 -0.5 0.05 0.06 0.07\n",
        )
        .unwrap();
        let st = GnssStream::check(&ok).unwrap();
        assert_eq!(st.fixes, 2);
        let streamed: Vec<_> = st.source().unwrap().map(Result::unwrap).collect();
        assert_eq!(streamed, read_gnss_text(&ok).unwrap());
        // the scale applied once, per axis: north/east horizontal, down vertical
        let mut g = streamed[1];
        nav_io::SigmaScale {
            horizontal: 1.7,
            vertical: 3.0,
        }
        .apply(&mut g);
        assert_eq!(g.pos_std_ned_m[1].to_bits(), (0.3 * 1.7f64).to_bits());
        assert_eq!(g.pos_std_ned_m[2].to_bits(), (0.9 * 3.0f64).to_bits());
        assert_eq!(g.vel_std_ned_mps[2].to_bits(), (0.07 * 3.0f64).to_bits());
        // a file that does not parse is refused by the check, naming file and line
        let bad = dir.join("bad.txt");
        std::fs::write(
            &bad,
            "100.0 30.5 114.3 20.0 0.5 0.6 1.1\n99.0 30.5 114.3 20.0 0.5\n",
        )
        .unwrap();
        let e = format!("{:#}", GnssStream::check(&bad).unwrap_err());
        assert!(e.contains("bad.txt") && e.contains('2'), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Times in option messages read as typed: no binary rounding digits, small values kept.
    #[test]
    fn option_times_are_shown_as_typed() {
        let cases = [
            (99999.00000000001, "99999"),
            (1e-4, "0.0001"),
            (1e9, "1000000000"),
            (0.3, "0.3"),
            (-0.0, "0"),
            (548.5799999999872, "548.58"),
        ];
        for (x, want) in cases {
            assert_eq!(super::show_s(x), want, "{x}");
        }
        assert_eq!(super::show_s(f64::NAN), "NaN");
    }
}
