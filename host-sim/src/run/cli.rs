//! `host-sim run --config FILE [--case DIR] ...`: the command line over the run engine
//! (`nav_engine`): the arguments ([`RunArgs`], parsed and checked by clap) become a [`RunSpec`]
//! (configuration plus overrides, [`RunArgs::to_spec`]), the engine loads and runs it
//! ([`nav_engine::load`], [`execute_streaming`]) and this module prints the summary. Programs
//! and tests build a [`RunSpec`] and call the engine themselves.
//!
//! The configuration is the project's run configuration (TOML) or a KF-GINS YAML file
//! ([`nav_engine::run::prepare`]). Outputs in `--out` (default `run-out`): `nav.txt`,
//! `std.txt`, `bias.txt`, `innovations.txt`, `metrics.json`, written in a stage folder inside
//! `--out` and moved into place when all are complete ([`nav_engine::run::outdir`]: an `--out`
//! holding one of the run's inputs, or locked by another run, is refused; the previous
//! complete outputs stay until then). SIGINT/SIGTERM stop the run at the next IMU sample with
//! the outputs up to there as `*.partial` ([`nav_engine::run::interrupt`]). A fault in the middle of
//! the data (a gap longer than `--imu-max-gap`, a numerical failure, an implausible sample
//! with `--imu-strict`) stops the run with the outputs up to it as `*.partial` and exit code 1.
//! IMU gaps and plausibility: [`nav_core::imu_guard`], options `--imu-*` and `[imu.checks]`.
//! A run that used no GNSS fix, or fewer than [`nav_engine::run::gnss_use::MIN_USED_FRACTION`]
//! of those offered to the filter, is a dead-reckoning track: its outputs are written, and
//! the run ends with an error naming where the fixes went (exit code 2).

use super::outage::{parse_outage, parse_periodic, Outage, PeriodicOutages};
use super::Model;
use anyhow::Context;
use nav_core::config::{Gating, VelocityGating};
use nav_core::imu_guard::GapIncrements;
use nav_engine::metrics;
pub use nav_engine::run::execute::{
    decimate, execute, execute_case, execute_streaming, imu_summary, metrics_json,
    threaded_imu_reader,
};
use nav_engine::run::outdir::OutDir;
use nav_engine::run::prepare::DEFAULT_STD_RATE_HZ;
pub use nav_engine::run::prepare::{
    read_config, scale_white_noise, CaseIndex, ConfigKind, ImuStream, Loaded, Prepared, RunSpec,
};
use nav_engine::run::prepare::{FilterOverrides, ImuChecksOverrides, Overrides};
use nav_engine::run::{Effect, Precision, RecordOptions};
use nav_io::{ImuChecksConfig, ImuClassName};
use std::path::PathBuf;

/// Arguments of `host-sim run` (a `clap::Parser` too, so that a test can parse a command line
/// with `RunArgs::try_parse_from(["run", "--config", ...])`).
#[derive(clap::Parser, Debug, Clone)]
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
    #[arg(long, value_parser = crate::cli_enum::parser::<Model>())]
    pub model: Option<Model>,
    /// GNSS outage START:DURATION, seconds, START after the first IMU epoch (repeatable);
    /// START inside the record, DURATION at least one IMU interval.
    #[arg(long = "outage", value_parser = parse_outage)]
    pub outages: Vec<Outage>,
    /// Repeating outages FIRST:DURATION:PERIOD, seconds, FIRST after the first IMU epoch
    /// (repeatable), e.g. 120:30:60; FIRST inside the record, DURATION at least one IMU
    /// interval, PERIOD at least DURATION, at most 10000 outages in a run.
    #[arg(long = "periodic-outage", value_parser = parse_periodic)]
    pub periodic_outages: Vec<PeriodicOutages>,
    /// The KF-GINS paper's protocol: 60 s outages every 180 s, the first at 180 s.
    #[arg(long)]
    pub kf_gins_outages: bool,
    /// Rate of nav.txt, Hz (default: every IMU epoch); in (0, IMU rate], a higher rate is
    /// clamped to the IMU rate with a warning.
    #[arg(long, allow_negative_numbers = true)]
    pub nav_rate: Option<f64>,
    /// Rate of std.txt and bias.txt, Hz; in (0, IMU rate], a higher rate is clamped to the
    /// IMU rate with a warning.
    #[arg(long, default_value_t = DEFAULT_STD_RATE_HZ, allow_negative_numbers = true)]
    pub std_rate: f64,
    /// Output directory.
    #[arg(long, default_value = "run-out")]
    pub out: PathBuf,
    /// f32 covariance (as on the MCU) instead of f64.
    #[arg(long)]
    pub f32: bool,
    /// Extra offset added to the IMU time stamps, s (e.g. a logging-delay correction), in
    /// [-60, 60].
    #[arg(long, allow_hyphen_values = true)]
    pub imu_time_offset: Option<f64>,
    /// Innovation gate: robust (default: IGG-III down-weighting and a model-mismatch
    /// monitor, docs/robust-gating.md), off, or a hard gate at the acceptance probability
    /// 0.95, 0.99, 0.999, 0.9999.
    #[arg(long, value_parser = parse_gate)]
    pub gate: Option<Gating>,
    /// The GNSS velocity's own gate (with GNSS velocities): joint (position and velocity in
    /// one update under --gate), or a separate velocity update gated robust, hard (0.9999),
    /// 0.95, 0.99, 0.999, 0.9999, or off (no gate). Default: the configuration's
    /// `[gnss] velocity_gate`, else joint.
    #[arg(long, value_parser = parse_velocity_gate)]
    pub velocity_gate: Option<VelocityGate>,
    /// Use the GNSS velocities: on/off (default: the configuration's).
    #[arg(long)]
    pub gnss_velocity: Option<bool>,
    /// Multiply the accelerometer and gyro white-noise PSDs by this factor (model tuning).
    #[arg(long, allow_negative_numbers = true)]
    pub noise_scale: Option<f64>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Effect blocks to append to the model, comma-separated names of the vocabulary
    /// (accel_scale_factor, gyro_scale_factor, accel_misalignment, gyro_misalignment,
    /// lever_arm, time_offset, accel_temperature_bias, gyro_temperature_bias,
    /// gyro_g_sensitivity, imu_clock_drift, gnss_position_gm; e.g. what `host-sim diagnose`
    /// added).
    #[arg(long, value_delimiter = ',', value_parser = parse_effect)]
    pub effects: Vec<Effect>,
    /// IMU class giving the plausibility limits (its full-scale range + 10 %; default: the
    /// configuration's `[imu.checks] class`, else consumer-mems, the widest).
    #[arg(long, value_parser = crate::cli_enum::parser::<ImuClassName>())]
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

/// A `--velocity-gate` value ([`parse_velocity_gate`]): `None` joint position + velocity
/// updates, `Some(g)` a separate velocity update gated by `g`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VelocityGate(pub Option<VelocityGating>);

impl RunArgs {
    /// The engine's run specification of these arguments (the output options, `--out` and
    /// `--quiet`, stay with the command line; `--smooth` asks the engine for the smoother's
    /// history).
    pub fn to_spec(&self) -> RunSpec {
        RunSpec {
            config: self.config.clone(),
            case: self.case.clone(),
            truth: self.truth.clone(),
            outages: self.outages.clone(),
            periodic_outages: self.periodic_outages.clone(),
            kf_gins_outages: self.kf_gins_outages,
            imu_time_offset_s: self.imu_time_offset,
            record: RecordOptions {
                nav_rate_hz: self.nav_rate,
                epoch_rate_hz: Some(self.std_rate),
            },
            set: Overrides {
                model: self.model,
                precision: self.f32.then_some(Precision::F32),
                filter: FilterOverrides {
                    gating: self.gate,
                    velocity_gating: self.velocity_gate.map(|v| v.0),
                    use_gnss_velocity: self.gnss_velocity,
                    white_noise_scale: self.noise_scale,
                },
                imu_checks: ImuChecksOverrides {
                    table: ImuChecksConfig {
                        class: self.imu_class,
                        max_rate_deg_s: self.imu_max_rate_dps,
                        max_accel_g: self.imu_max_accel_g,
                        max_gap_s: self.imu_max_gap,
                        stop_on_implausible: self.imu_strict,
                    },
                    no_limits: self.no_imu_limits,
                    increments: self.imu_gaps,
                },
                effects: self.effects.clone(),
                smoother_history: self.smooth,
            },
        }
    }
}

/// Parses `--imu-gaps`.
pub fn parse_gap_increments(s: &str) -> anyhow::Result<GapIncrements> {
    nav_engine::run::prepare::parse_gap_increments(s)
}

/// Parses a `--gate` value.
pub fn parse_gate(s: &str) -> anyhow::Result<Gating> {
    nav_engine::run::prepare::parse_gate(s)
}

/// Parses a `--velocity-gate` value.
pub fn parse_velocity_gate(s: &str) -> anyhow::Result<VelocityGate> {
    nav_engine::run::prepare::parse_velocity_gate(s).map(VelocityGate)
}

/// Parses one `--effects` name (blanks around it ignored): an unknown name lists the
/// vocabulary and suggests the nearest.
pub fn parse_effect(s: &str) -> Result<Effect, nav_engine::run::UnknownEffect> {
    s.parse()
}

/// Loads a run from the arguments ([`nav_engine::load`] of [`RunArgs::to_spec`]; `stream`:
/// the IMU, GNSS and truth files are read while the filter runs, [`execute_streaming`]) and
/// prints the warnings about the data to stderr; the files it reads are in
/// [`Loaded::inputs`].
pub(crate) fn load(args: &RunArgs, stream: bool) -> anyhow::Result<Loaded> {
    let l = nav_engine::load(&args.to_spec(), stream)?;
    for w in &l.warnings {
        eprintln!("warning: {w}");
    }
    Ok(l)
}

/// `run --smooth`: the inputs streamed as by `run`, the forward pass, the backward pass and
/// the smoothed outputs in bounded memory ([`super::smoothed::finish`]). The outputs are
/// written in the stage folder of `--out` ([`OutDir`]) and moved into place at the end; a
/// smoothed run stopped by SIGINT/SIGTERM leaves `--out` as it was.
fn run_smoothed(args: &RunArgs) -> anyhow::Result<()> {
    let t = std::time::Instant::now();
    let l = load(args, true)?;
    let od = OutDir::open(&args.out, &l.inputs)?;
    println!("{}", l.prepared.description);
    // no fix to align on and none usable: not a navigation solution (exit 2), naming why
    let c = super::smoothed::finish(&l, &args.out, od.stage(), t)
        .map_err(|e| l.explain_start_failure(e))?;
    {
        let _moving = nav_engine::run::interrupt::Stoppable::enter();
        od.commit()
            .with_context(|| format!("moving the outputs into {}", args.out.display()))?;
    }
    println!("{}", l.gnss_account(&c, false).summary_line());
    // a dead-reckoning track is not a navigation solution: an error (exit 2) naming why
    l.check_gnss_use(&c)?;
    Ok(())
}

/// Runs `host-sim run` (streaming: see [`execute_streaming`]).
pub fn run(args: RunArgs) -> anyhow::Result<()> {
    if args.smooth {
        return run_smoothed(&args);
    }
    let t = std::time::Instant::now();
    // the mounting check on the run's own reading of the IMU file: its warnings after the run
    let loaded = nav_engine::load_checking_in_run(&args.to_spec())?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    let Loaded {
        prepared: p,
        imu_stream: imu,
        truth_stream: truth,
        inputs,
        nav_rate_hz,
        ..
    } = &loaded;
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
    let res = execute_streaming(
        p,
        imu.as_ref(),
        truth.as_ref(),
        dir,
        inputs,
        *nav_rate_hz,
        &mut |done, _| pb.set_position(done as u64),
    );
    pb.finish_and_clear();
    for w in loaded.mounting_warnings(res.is_ok()) {
        eprintln!("warning: {w}");
    }
    let t_run = t.elapsed().as_secs_f64();
    // no fix to align on and none usable: not a navigation solution (exit 2), naming why
    let (out, m) = res.map_err(|e| loaded.explain_start_failure(e))?;
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
    if c.gnss_vel_rejected > 0 {
        println!(
            "GNSS velocity gate: {} velocit(ies) rejected",
            c.gnss_vel_rejected
        );
    }
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
    println!("{}", loaded.gnss_account(c, false).summary_line());
    // a dead-reckoning track is not a navigation solution: an error (exit 2) naming why
    loaded.check_gnss_use(c)?;
    Ok(())
}
