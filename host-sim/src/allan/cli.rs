//! `host-sim allan`: Allan statistics per axis of an IMU record, the noise-model fit, a
//! parameter table like the source's Appendix V, `allan_params.toml` (a run configuration's
//! `[noise]` section) and `allan_sim_errors.toml` (`super::params`), plots and JSON.
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use noise_id::fit::{self, Datasheet, FitOptions, FitResult, SensorKind, SlopeResult, Terms};
use noise_id::reader::{self, AccelUnitArg, Channels, ColumnSpec, GyroUnit, XUnit};
use noise_id::{deviation_curve_phase, edf, CurveOptions, DevPoint, Deviation, Phase, Taus};
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

/// Input format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// `--columns` given: generic column file; otherwise the project's IMU text format.
    Auto,
    /// The project's IMU text format (`t dtheta_xyz dv_xyz [temp]`, increments).
    ImuText,
    /// Generic CSV / white-space columns (needs `--columns`).
    Csv,
}

/// Tau selection.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TauArg {
    /// m = 1, 2, 4, 8, ...
    Octave,
    /// m = 1, 2, 4, 10, 20, 40, ...
    Decade,
    /// Every m (slow for long records).
    All,
}

/// Model terms for the fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TermArg {
    /// Quantization 3 Q^2 / tau^2.
    Quant,
    /// White noise S_N / tau.
    White,
    /// First-order Gauss-Markov (S_B, T_B).
    Gm,
    /// Random walk S_K tau / 3.
    Rw,
    /// Flicker floor.
    Flicker,
}

/// Arguments of `host-sim allan`.
#[derive(clap::Args, Debug)]
pub struct AllanArgs {
    /// IMU file to analyse (gzip accepted).
    pub input: PathBuf,
    /// Input format.
    #[arg(long, value_enum, default_value = "auto")]
    pub format: Format,
    /// Column mapping of a generic file, comma separated: gx gy gz ax ay az, x (one generic
    /// channel), t (time in s), _ (ignored). Example: gx,gy,gz,ax,ay,az
    #[arg(long, value_delimiter = ',')]
    pub columns: Vec<String>,
    /// Unit of gyro columns.
    #[arg(long, value_parser = crate::cli_enum::parser::<GyroUnit>(), default_value = "radps")]
    pub gyro_unit: GyroUnit,
    /// Unit of accelerometer columns.
    #[arg(long, value_parser = crate::cli_enum::parser::<AccelUnitArg>(), default_value = "mps2")]
    pub accel_unit: AccelUnitArg,
    /// Sample rate of a file without a time column (Hz).
    #[arg(long)]
    pub rate_hz: Option<f64>,
    /// Lines skipped at the start of a generic file.
    #[arg(long, default_value_t = 0)]
    pub skip_lines: usize,
    /// Scale of an `x` column (applied on top of `--x-unit`).
    #[arg(long, default_value_t = 1.0)]
    pub x_scale: f64,
    /// Unit of an `x` column: a gyro (radps, dps, dph) or accelerometer (mps2, g, ug) unit
    /// makes it that sensor (datasheet units, a `[noise.gyro]`/`[noise.accel]` section);
    /// `si` reports it in SI with SI headings.
    #[arg(long, value_parser = crate::cli_enum::parser::<XUnit>(), default_value = "si")]
    pub x_unit: XUnit,
    /// Deviation to compute and plot (the fit always uses the overlapping Allan variance).
    #[arg(long, value_parser = crate::cli_enum::parser::<Deviation>(), default_value = "oadev")]
    pub dev: Deviation,
    /// Tau selection.
    #[arg(long, value_enum, default_value = "octave")]
    pub taus: TauArg,
    /// Model terms of the fit, comma separated: with term selection (the default) the largest
    /// model, of which the subset the data support is kept.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "quant,white,gm,rw,flicker"
    )]
    pub terms: Vec<TermArg>,
    /// Smallest tau used by the fit (s).
    #[arg(long, default_value_t = 0.0)]
    pub fit_min_tau: f64,
    /// Largest tau used by the fit (s).
    #[arg(long, default_value_t = f64::INFINITY)]
    pub fit_max_tau: f64,
    /// Fit all `--terms` as given instead of selecting the subset the data support
    /// (smallest BIC with a common model-error floor; see `allan::fit::fit_select`).
    #[arg(long)]
    pub no_select: bool,
    /// Accelerometer turn-on bias sigma (ug) written into the `[noise]` section
    /// (`bias_init_ug`); a static record cannot tell it.
    #[arg(long)]
    pub accel_bias_init_ug: Option<f64>,
    /// Gyro turn-on bias sigma (deg/h) written into the `[noise]` section
    /// (`bias_init_deg_per_h`); a static record cannot tell it.
    #[arg(long)]
    pub gyro_bias_init_deg_per_h: Option<f64>,
    /// Output folder for allan_params.toml (a run configuration's `[noise]` section),
    /// allan_sim_errors.toml (the simulator's error model) and the plots.
    #[arg(long, short = 'o', default_value = ".")]
    pub out_dir: PathBuf,
    /// Also write the curves and fits as JSON to this file.
    #[arg(long)]
    pub json: Option<PathBuf>,
    /// Do not draw plots.
    #[arg(long)]
    pub no_plot: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Replace the outliers (Hampel filter: farther from the median of 51 samples than the
    /// threshold of `--outlier-rate`, always reported) by their window median before the
    /// statistics.
    #[arg(long)]
    pub exclude_outliers: bool,
    /// False-positive rate of the outlier test: the fraction of the samples of spike-free
    /// Gaussian noise it flags. The threshold in robust sigmas is calibrated to it (1e-6:
    /// 6.96 sigma; 1e-7: 8.07; 1e-4: 4.83); the output states both.
    #[arg(long, default_value_t = noise_id::outliers::DEFAULT_FALSE_POSITIVE_RATE)]
    pub outlier_rate: f64,
}

/// The analysis of one channel.
#[derive(Clone, Debug)]
pub struct AxisResult {
    /// Key (gx ... az, or x).
    pub name: String,
    /// Sensor kind.
    pub kind: SensorKind,
    /// The requested deviation curve.
    pub curve: Vec<DevPoint>,
    /// The OADEV curve the fit used (same as `curve` for OADEV).
    pub fit_curve: Vec<DevPoint>,
    /// The fit, or the reason it failed.
    pub fit: Result<FitResult, String>,
    /// The slope/minimum method.
    pub slope: Option<SlopeResult>,
    /// The candidate models of the term selection (empty without selection).
    pub candidates: Vec<fit::Candidate>,
    /// Whether the fitted model follows the curve within its confidence band, and the
    /// better-fitting alternative when it does not ([`fit::check_model`]).
    pub check: Option<fit::ModelCheck>,
}

/// The whole analysis.
#[derive(Clone, Debug)]
pub struct Analysis {
    /// Per channel.
    pub axes: Vec<AxisResult>,
    /// Sample time (s).
    pub tau0_s: f64,
    /// Number of samples.
    pub n_samples: usize,
    /// Deviation type of `curve`.
    pub dev: Deviation,
}

/// Analyses channels (no I/O): the curves, the fit (with term selection among
/// `fit_opt.terms` when `select`), the slope method; `progress` gets (done, total) tau
/// evaluations.
pub fn analyse(
    ch: &Channels,
    dev: Deviation,
    taus: &Taus,
    fit_opt: &FitOptions,
    select: bool,
    progress: Option<&ProgressBar>,
) -> Analysis {
    let axes: Vec<AxisResult> = ch
        .data
        .par_iter()
        .zip(ch.names.par_iter())
        .zip(ch.kinds.par_iter())
        .map(|((y, name), kind)| {
            let phase = Phase::from_rate(y);
            let opt = CurveOptions {
                dev,
                taus: taus.clone(),
                confidence: Some(edf::ONE_SIGMA),
                fixed_alpha: None,
            };
            let tick = |_: usize, _: usize| {
                if let Some(pb) = progress {
                    pb.inc(1);
                }
            };
            let curve = deviation_curve_phase(&phase, ch.tau0_s, &opt, tick);
            let fit_curve = if dev == Deviation::Oadev && *taus == Taus::Octave {
                curve.clone()
            } else {
                let o = CurveOptions {
                    dev: Deviation::Oadev,
                    taus: Taus::Octave,
                    ..opt.clone()
                };
                deviation_curve_phase(&phase, ch.tau0_s, &o, tick)
            };
            let (f, candidates) = if select {
                match fit::fit_select(&fit_curve, fit_opt) {
                    Ok(s) => (Ok(s.fit), s.candidates),
                    Err(e) => (Err(e.to_string()), Vec::new()),
                }
            } else {
                (
                    fit::fit(&fit_curve, fit_opt).map_err(|e| e.to_string()),
                    Vec::new(),
                )
            };
            let slope = fit::slope_method(&fit_curve);
            let check = f
                .as_ref()
                .ok()
                .and_then(|r| fit::check_model(&fit_curve, r, fit_opt).ok());
            AxisResult {
                name: name.clone(),
                kind: *kind,
                curve,
                fit_curve,
                fit: f,
                slope,
                candidates,
                check,
            }
        })
        .collect();
    Analysis {
        axes,
        tau0_s: ch.tau0_s,
        n_samples: ch.data.first().map_or(0, Vec::len),
        dev,
    }
}

fn pm(e: fit::Est, prec: usize) -> String {
    if e.value == 0.0 && (e.sigma.is_nan() || e.sigma <= 0.0) {
        return "0".into();
    }
    if e.sigma.is_finite() {
        format!("{:.*e} ± {:.1e}", prec, e.value, e.sigma)
    } else {
        format!("{:.*e}", prec, e.value)
    }
}

fn pmf(e: fit::Est) -> String {
    if !e.value.is_finite() {
        return "-".into();
    }
    if e.sigma.is_finite() {
        format!("{:.3} ± {:.3}", e.value, e.sigma)
    } else {
        format!("{:.3}", e.value)
    }
}

/// The parameter table (like the source's Appendix V, one column per axis).
pub fn table(an: &Analysis) -> String {
    let mut rows: Vec<(String, Vec<String>)> = Vec::new();
    let ds: Vec<Option<(Datasheet, &FitResult)>> = an
        .axes
        .iter()
        .map(|a| a.fit.as_ref().ok().map(|f| (f.datasheet(a.kind), f)))
        .collect();
    let row = |label: &str, f: &dyn Fn(&Datasheet, &FitResult) -> String| {
        (
            label.to_string(),
            ds.iter()
                .map(|d| d.as_ref().map_or("fit failed".into(), |(d, r)| f(d, r)))
                .collect::<Vec<_>>(),
        )
    };
    rows.push(row("Model         terms", &|_, r| r.terms.label()));
    rows.push(row("Quantization  S_A = Q^2 [m^2/s^2],[rad^2]", &|_, r| {
        pm(r.q2, 3)
    }));
    rows.push(row("              Q [m/s],[rad]", &|d, _| pm(d.q, 3)));
    rows.push(row("White noise   S_N [m^2/s^3],[rad^2/s]", &|_, r| {
        pm(r.s_n, 4)
    }));
    rows.push(row(
        "              N [ug/sqrt(Hz)],[deg/sqrt(h)]",
        &|d, _| pmf(d.n),
    ));
    rows.push(row("Gauss-Markov  S_B [m^2/s^5],[rad^2/s^3]", &|_, r| {
        pm(r.s_b, 4)
    }));
    rows.push(row(
        "              B = 0.6572 sqrt(S_B T_B) [ug],[deg/h]",
        &|d, _| pmf(d.b),
    ));
    rows.push(row("              T_B [s]", &|_, r| pmf(r.t_b_s)));
    rows.push(row("Random walk   S_K [m^2/s^5],[rad^2/s^3]", &|_, r| {
        pm(r.s_k, 4)
    }));
    rows.push(row("              K [m/s^2.5],[rad/s^1.5]", &|d, _| {
        pm(d.k_si, 4)
    }));
    rows.push(row(
        "              K [ug/sqrt(h)],[deg/h/sqrt(h)]",
        &|d, _| pmf(d.k),
    ));
    rows.push(row("Flicker       B [ug],[deg/h]", &|d, r| {
        if r.terms.flicker {
            pmf(d.b_flicker)
        } else {
            "0".into()
        }
    }));
    rows.push(row("Fit           chi2 / points", &|_, r| {
        format!("{:.1} / {}", r.chi2, r.n_points)
    }));
    rows.push(row("              model error floor", &|_, r| {
        format!("{:.1} %", 100.0 * r.model_error_rel)
    }));
    rows.push((
        "Slope method  N [ug/sqrt(Hz)],[deg/sqrt(h)]".into(),
        an.axes.iter().map(|a| slope_fmt(a, 'N')).collect(),
    ));
    rows.push((
        "              B = min/0.664 [ug],[deg/h]".into(),
        an.axes.iter().map(|a| slope_fmt(a, 'B')).collect(),
    ));
    rows.push((
        "              K [ug/sqrt(h)],[deg/h/sqrt(h)]".into(),
        an.axes.iter().map(|a| slope_fmt(a, 'K')).collect(),
    ));
    let kinds: Vec<SensorKind> = an.axes.iter().map(|a| a.kind).collect();
    for r in &mut rows {
        r.0 = heading_units(&r.0, &kinds);
    }
    let w0 = rows.iter().map(|r| r.0.chars().count()).max().unwrap_or(0);
    let wc: Vec<usize> = (0..an.axes.len())
        .map(|j| {
            rows.iter()
                .map(|r| r.1[j].chars().count())
                .max()
                .unwrap_or(0)
                .max(an.axes[j].name.len())
        })
        .collect();
    let mut s = String::new();
    let _ = write!(s, "{:w0$}", "Noise term / parameter");
    for (a, w) in an.axes.iter().zip(&wc) {
        let _ = write!(s, " | {:>w$}", a.name);
    }
    s.push('\n');
    s.push_str(&"-".repeat(w0 + wc.iter().map(|w| w + 3).sum::<usize>()));
    s.push('\n');
    for (label, cells) in rows {
        let _ = write!(s, "{label:w0$}");
        for (c, w) in cells.iter().zip(&wc) {
            let _ = write!(s, " | {c:>w$}");
        }
        s.push('\n');
    }
    if kinds.contains(&SensorKind::Other) {
        s.push_str(
            "U: the unit of the generic channel (its column times --x-scale), read as SI; \
             --x-unit radps|dps|dph|mps2|g|ug makes it a gyro or an accelerometer\n",
        );
    }
    s
}

/// A heading's units for the sensors in the table: `name [accel],[gyro]` keeps the unit of
/// each kind present, in that order, and adds the SI form (`U` = the channel's unit) for a
/// channel of unknown quantity (`--columns x` without a sensor `--x-unit`).
fn heading_units(label: &str, kinds: &[SensorKind]) -> String {
    let Some((name, units)) = label.split_once(" [") else {
        return label.to_string();
    };
    let Some((a, g)) = units.trim_end_matches(']').split_once("],[") else {
        return label.to_string();
    };
    let si = match a {
        "m^2/s^2" => "U^2 s^2",
        "m/s" => "U s",
        "m^2/s^3" => "U^2 s",
        "ug/sqrt(Hz)" => "U sqrt(s)",
        "m^2/s^5" => "U^2/s",
        "ug" => "U",
        "m/s^2.5" | "ug/sqrt(h)" => "U/sqrt(s)",
        _ => "SI",
    };
    let mut parts = Vec::new();
    for (k, u) in [
        (SensorKind::Accel, a),
        (SensorKind::Gyro, g),
        (SensorKind::Other, si),
    ] {
        if kinds.contains(&k) {
            parts.push(format!("[{u}]"));
        }
    }
    format!("{name} {}", parts.join(","))
}

fn slope_fmt(a: &AxisResult, which: char) -> String {
    let Some(sl) = &a.slope else {
        return "-".into();
    };
    use nav_core::config::units;
    let (n_f, b_f, k_f) = match a.kind {
        SensorKind::Accel => (
            1.0 / units::UG_MPS2,
            1.0 / units::UG_MPS2,
            units::SQRT_HOUR_S / units::UG_MPS2,
        ),
        SensorKind::Gyro => (
            units::SQRT_HOUR_S / units::DEG,
            units::HOUR_S / units::DEG,
            units::HOUR_S * units::SQRT_HOUR_S / units::DEG,
        ),
        SensorKind::Other => (1.0, 1.0, 1.0),
    };
    match which {
        'N' => format!("{:.3}", sl.n * n_f),
        'B' => format!("{:.3}", sl.b * b_f),
        _ if sl.k.is_finite() => format!("{:.3}", sl.k * k_f),
        _ => "-".into(),
    }
}

#[derive(Serialize)]
struct JsonAxis<'a> {
    deviation: &'a str,
    tau_s: Vec<f64>,
    adev: Vec<f64>,
    adev_lo: Vec<f64>,
    adev_hi: Vec<f64>,
    n_terms: Vec<usize>,
    alpha: Vec<i32>,
    edf: Vec<f64>,
    fit: Option<JsonFit>,
    slope_method: Option<&'a SlopeResult>,
    candidates: &'a [fit::Candidate],
    model_check: Option<&'a fit::ModelCheck>,
    model_warning: Option<String>,
}

#[derive(Serialize)]
struct JsonFit {
    q2: fit::Est,
    s_n: fit::Est,
    s_b: fit::Est,
    t_b_s: fit::Est,
    s_k: fit::Est,
    flicker_b2: fit::Est,
    datasheet: Datasheet,
    chi2: f64,
    n_points: usize,
    terms: Terms,
    model_error_rel: f64,
    /// First minimum of the model's Allan deviation (tau_s, adev in SI).
    model_adev_minimum: (f64, f64),
    /// (tau_s, measured AVAR, model AVAR, normalized residual)
    residuals: Vec<(f64, f64, f64, f64)>,
}

/// JSON of the analysis (keys per axis, SI).
pub fn to_json(an: &Analysis) -> anyhow::Result<String> {
    let mut map = BTreeMap::new();
    for a in &an.axes {
        let c = &a.curve;
        let ja = JsonAxis {
            deviation: an.dev.name(),
            tau_s: c.iter().map(|p| p.tau_s).collect(),
            adev: c.iter().map(|p| p.dev).collect(),
            adev_lo: c.iter().map(|p| p.lo).collect(),
            adev_hi: c.iter().map(|p| p.hi).collect(),
            n_terms: c.iter().map(|p| p.n_terms).collect(),
            alpha: c.iter().map(|p| p.alpha).collect(),
            edf: c.iter().map(|p| p.edf).collect(),
            fit: a.fit.as_ref().ok().map(|f| JsonFit {
                q2: f.q2,
                s_n: f.s_n,
                s_b: f.s_b,
                t_b_s: f.t_b_s,
                s_k: f.s_k,
                flicker_b2: f.flicker_b2,
                datasheet: f.datasheet(a.kind),
                chi2: f.chi2,
                n_points: f.n_points,
                terms: f.terms,
                model_error_rel: f.model_error_rel,
                model_adev_minimum: f.model_adev_minimum(),
                residuals: f.residuals.clone(),
            }),
            slope_method: a.slope.as_ref(),
            candidates: &a.candidates,
            model_check: a.check.as_ref(),
            model_warning: a.model_warning(),
        };
        map.insert(a.name.clone(), serde_json::to_value(ja)?);
    }
    Ok(serde_json::to_string_pretty(&map)?)
}

fn terms_from(args: &[TermArg]) -> Terms {
    Terms {
        quant: args.contains(&TermArg::Quant),
        white: args.contains(&TermArg::White),
        gm: args.contains(&TermArg::Gm),
        rw: args.contains(&TermArg::Rw),
        flicker: args.contains(&TermArg::Flicker),
    }
}

/// Reads the input described by `args`.
fn read_input(args: &AllanArgs) -> anyhow::Result<Channels> {
    let fmt = match args.format {
        Format::Auto if !args.columns.is_empty() => Format::Csv,
        Format::Auto => Format::ImuText,
        f => f,
    };
    let ch = match fmt {
        Format::Csv => {
            if args.columns.is_empty() {
                anyhow::bail!("--format csv needs --columns (e.g. gx,gy,gz,ax,ay,az)");
            }
            reader::read_columns(
                &args.input,
                &ColumnSpec {
                    columns: args.columns.clone(),
                    gyro_unit: args.gyro_unit,
                    accel_unit: args.accel_unit,
                    rate_hz: args.rate_hz,
                    skip_lines: args.skip_lines,
                    x_scale: args.x_scale,
                    x_unit: args.x_unit,
                },
            )?
        }
        _ => reader::read_imu_text_rates(&args.input)?,
    };
    Ok(ch)
}

/// Finds the outliers of each channel (Hampel, threshold from `--outlier-rate`) and prints
/// them.
fn report_outliers(
    args: &AllanArgs,
    ch: &Channels,
) -> anyhow::Result<(
    noise_id::outliers::HampelOptions,
    Vec<noise_id::outliers::Outliers>,
)> {
    let n = ch.data.first().map_or(0, Vec::len);
    if !(args.outlier_rate > 0.0 && args.outlier_rate < 0.5) {
        anyhow::bail!(
            "--outlier-rate {}: a fraction of the samples, above 0 and below 0.5",
            args.outlier_rate
        );
    }
    let hopt = if args.outlier_rate == noise_id::outliers::DEFAULT_FALSE_POSITIVE_RATE {
        noise_id::outliers::HampelOptions::default()
    } else {
        noise_id::outliers::HampelOptions::with_false_positive_rate(
            noise_id::outliers::DEFAULT_HALF_WINDOW,
            args.outlier_rate,
        )
    };
    let outliers: Vec<noise_id::outliers::Outliers> = ch
        .data
        .par_iter()
        .map(|y| noise_id::outliers::hampel(y, &hopt))
        .collect();
    println!(
        "Outliers (Hampel: > {:.2} robust sigma from the median of {} samples, a threshold that \
         flags {:.0e} of the samples of spike-free Gaussian noise, {:.1} expected here){}:",
        hopt.n_sigma,
        2 * hopt.half_window + 1,
        args.outlier_rate,
        args.outlier_rate * n as f64,
        if args.exclude_outliers {
            ", replaced by the window median"
        } else {
            "; --exclude-outliers removes them"
        }
    );
    for (name, o) in ch.names.iter().zip(&outliers) {
        let times: Vec<String> = o
            .indices
            .iter()
            .take(5)
            .map(|&i| format!("{:.3}", i as f64 * ch.tau0_s))
            .collect();
        println!(
            "  {name:3} {:8} ({:.4} %){}",
            o.indices.len(),
            100.0 * o.fraction(),
            if times.is_empty() {
                String::new()
            } else {
                format!(
                    " at {} s from the start{}",
                    times.join(", "),
                    if o.indices.len() > 5 { ", ..." } else { "" }
                )
            }
        );
    }
    Ok((hopt, outliers))
}

/// Runs `host-sim allan`.
pub fn run(args: AllanArgs) -> anyhow::Result<()> {
    let spinner = (!args.quiet).then(|| {
        let pb = ProgressBar::new_spinner();
        pb.set_message(format!("reading {}", args.input.display()));
        pb.enable_steady_tick(std::time::Duration::from_millis(120));
        pb
    });
    let mut ch = read_input(&args)?;
    if let Some(pb) = spinner {
        pb.finish_and_clear();
    }
    let n = ch.data.first().map_or(0, Vec::len);
    if n < 16 {
        anyhow::bail!("{}: only {n} samples", args.input.display());
    }
    for note in &ch.notes {
        eprintln!("{note}");
    }
    // outliers: reported always, removed with --exclude-outliers
    let (hopt, outliers) = report_outliers(&args, &ch)?;
    if args.exclude_outliers {
        for (y, o) in ch.data.iter_mut().zip(&outliers) {
            *y = o.replaced(y);
        }
    }
    let taus = match args.taus {
        TauArg::Octave => Taus::Octave,
        TauArg::Decade => Taus::Decade,
        TauArg::All => Taus::All,
    };
    let fit_opt = FitOptions {
        terms: terms_from(&args.terms),
        tau_range_s: (args.fit_min_tau, args.fit_max_tau),
        ..FitOptions::default()
    };
    let per_axis = taus.factors(n, args.dev).len()
        + if args.dev == Deviation::Oadev && taus == Taus::Octave {
            0
        } else {
            Taus::Octave.factors(n, Deviation::Oadev).len()
        };
    let pb = (!args.quiet && n >= 100_000).then(|| {
        let pb = ProgressBar::new((per_axis * ch.data.len()) as u64);
        pb.set_style(
            ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} taus ({eta})")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        pb.set_message(format!("{} on {} channels", args.dev.name(), ch.data.len()));
        pb
    });
    let an = analyse(&ch, args.dev, &taus, &fit_opt, !args.no_select, pb.as_ref());
    if let Some(pb) = pb {
        pb.finish_and_clear();
    }
    println!(
        "{}: {} samples, tau0 = {:.6} s, {} ({}), fit on OADEV octave taus",
        args.input.display(),
        n,
        ch.tau0_s,
        args.dev.name(),
        match args.taus {
            TauArg::Octave => "octave",
            TauArg::Decade => "decade",
            TauArg::All => "all taus",
        }
    );
    println!("{}", table(&an));
    for a in &an.axes {
        if let Err(e) = &a.fit {
            eprintln!("{}: {e}", a.name);
        }
        if let Some(w) = a.model_warning() {
            eprintln!("warning: {w}");
        }
    }
    if !args.no_select {
        print_selection(&an);
    }
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("creating {}", args.out_dir.display()))?;
    write_params(&args, &an)?;
    if let Some(j) = &args.json {
        write_json(j, &an, &ch, &outliers, &hopt, &args)?;
    }
    if !args.no_plot {
        write_plots(&args, &an)?;
    }
    Ok(())
}

impl AxisResult {
    /// The warning when the fitted model misses the curve beyond its confidence band.
    pub fn model_warning(&self) -> Option<String> {
        let f = self.fit.as_ref().ok()?;
        self.check.as_ref()?.warning(&self.name, &f.terms)
    }

    fn curve_title(&self, dev: Deviation) -> &'static str {
        match dev {
            Deviation::Adev => "Allan deviation",
            Deviation::Oadev => "overlapping Allan deviation",
            Deviation::Mdev => "modified Allan deviation",
            Deviation::Hdev => "Hadamard deviation",
            Deviation::Ohdev => "overlapping Hadamard deviation",
        }
    }
}

/// Prints the term selection table: every candidate model per axis, the selected one starred.
fn print_selection(an: &Analysis) {
    println!("Term selection (BIC = chi2 + p ln n with the model-error floor; * = selected):");
    for a in &an.axes {
        let sel = a.fit.as_ref().ok().map(|f| f.terms);
        for c in &a.candidates {
            println!(
                "  {:3} {}{:26} chi2 {:10.1} p {} BIC {:10.1}  {}",
                a.name,
                if Some(c.terms) == sel { '*' } else { ' ' },
                c.terms.label(),
                c.chi2,
                c.n_params,
                c.bic,
                c.rejected.as_deref().unwrap_or("")
            );
        }
    }
}

/// Writes `allan_params.toml` (the run configuration's noise section) and
/// `allan_sim_errors.toml` (the simulator's error model) into the output folder.
fn write_params(args: &AllanArgs, an: &Analysis) -> anyhow::Result<()> {
    let bias = super::params::BiasInit {
        accel_ug: args.accel_bias_init_ug,
        gyro_deg_per_h: args.gyro_bias_init_deg_per_h,
    };
    for (name, text) in [
        (
            "allan_params.toml",
            super::params::noise_section_toml(an, &args.input, &bias),
        ),
        (
            "allan_sim_errors.toml",
            super::params::sim_errors_toml(an, &args.input),
        ),
    ] {
        let path = args.out_dir.join(name);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        println!("wrote {}", path.display());
    }
    Ok(())
}

/// Writes the analysis as JSON to `path`, with each channel's outliers (times, sizes, the
/// detector's settings) under `outliers`.
fn write_json(
    path: &std::path::Path,
    an: &Analysis,
    ch: &Channels,
    outliers: &[noise_id::outliers::Outliers],
    hopt: &noise_id::outliers::HampelOptions,
    args: &AllanArgs,
) -> anyhow::Result<()> {
    let mut v: serde_json::Value = serde_json::from_str(&to_json(an)?)?;
    if let Some(obj) = v.as_object_mut() {
        let mut o = serde_json::Map::new();
        for (name, out) in ch.names.iter().zip(outliers) {
            o.insert(
                name.clone(),
                serde_json::json!({
                    "count": out.indices.len(),
                    "fraction": out.fraction(),
                    "excluded": args.exclude_outliers,
                    "times_s": out.indices.iter().map(|&i| i as f64 * ch.tau0_s).collect::<Vec<_>>(),
                    "sizes_sigma": out.sizes_sigma,
                    "half_window": hopt.half_window,
                    "n_sigma": hopt.n_sigma,
                    "gaussian_false_positive_rate": args.outlier_rate,
                }),
            );
        }
        obj.insert("outliers".into(), serde_json::Value::Object(o));
    }
    std::fs::write(path, serde_json::to_string_pretty(&v)?)
        .with_context(|| format!("writing {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}

/// Plots each axis's deviation curve with its fitted model (`allan_AXIS.png` and `.svg`).
fn write_plots(args: &AllanArgs, an: &Analysis) -> anyhow::Result<()> {
    for a in &an.axes {
        let (unit, scale) = match a.kind {
            SensorKind::Gyro => ("deg/s", 180.0 / std::f64::consts::PI),
            SensorKind::Accel => ("m/s^2", 1.0),
            SensorKind::Other => ("input unit", 1.0),
        };
        let stem = args.out_dir.join(format!("allan_{}", a.name));
        let input = super::plot::PlotInput {
            title: format!(
                "{}: {} ({})",
                a.name,
                a.curve_title(an.dev),
                args.input.display()
            ),
            unit: unit.into(),
            scale,
            points: &a.curve,
            fit: a.fit.as_ref().ok(),
        };
        super::plot::plot_allan(&input, &stem)
            .with_context(|| format!("plotting {}", stem.display()))?;
        println!("wrote {}.png and .svg", stem.display());
    }
    Ok(())
}
