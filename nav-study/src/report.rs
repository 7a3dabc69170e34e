//! The study's results: per-cell summaries, the verdicts on the source's claims, the printed
//! table, the `study.json` document and the Markdown report (which names the plots the
//! command line draws).

use super::budget::Budget;
use super::setup::Variant;
use super::setup::{self, Source};
use super::stats::CellStats;
use super::{Case, Cell, StudyResult};
use noise_id::stats as chi2;
use serde::Serialize;
use std::fmt::Write as _;

/// Start of the evaluation window of case 1 (after the initial static period), s.
pub const CASE1_FROM_S: f64 = 180.0;

/// Summary of one cell.
#[derive(Debug, Clone, Serialize)]
pub struct CellSummary {
    /// Variant name.
    pub model: String,
    /// Case.
    pub case: Case,
    /// Runs.
    pub runs: usize,
    /// Evaluation epoch (end of the outage), s after the first IMU epoch.
    pub eval_t_rel_s: f64,
    /// RMS true position error at the evaluation epoch, N, E, D, m.
    pub eval_pos_rms_m: [f64; 3],
    /// Filter position std at the evaluation epoch, N, E, D, m.
    pub eval_pos_std_m: [f64; 3],
    /// RMS true horizontal position error at the evaluation epoch, m.
    pub eval_horizontal_rms_m: f64,
    /// Filter horizontal std (root-sum-square of N and E) at the evaluation epoch, m.
    pub eval_horizontal_std_m: f64,
    /// RMS true velocity error at the evaluation epoch, N, E, D, m/s.
    pub eval_vel_rms_mps: [f64; 3],
    /// Filter velocity std at the evaluation epoch, m/s.
    pub eval_vel_std_mps: [f64; 3],
    /// RMS true attitude error (phi N, E, D) at the evaluation epoch, deg.
    pub eval_att_rms_deg: [f64; 3],
    /// Filter attitude std at the evaluation epoch, deg.
    pub eval_att_std_deg: [f64; 3],
    /// Average NEES at the evaluation epoch (attitude, velocity, position).
    pub eval_nees: [f64; 3],
    /// Time-RMS over the window of the RMS true position error, N, E, D, m.
    pub window_pos_rms_m: [f64; 3],
    /// Time-RMS over the window of the filter position std, N, E, D, m.
    pub window_pos_std_m: [f64; 3],
    /// The window: case 1 from the end of the static start to the end, case 2 the outage, s.
    pub window_rel_s: (f64, f64),
    /// Time mean over the window of the average NEES (attitude, velocity, position).
    pub window_nees_mean: [f64; 3],
    /// Fractions of the window's epochs with the average NEES inside / below / above the 95 %
    /// band, per group (attitude, velocity, position).
    pub window_nees_fractions: [[f64; 3]; 3],
    /// The two-sided 95 % band of the average NEES.
    pub nees_band: (f64, f64),
}

/// Where a NEES lies relative to its band.
fn where_in(x: f64, band: (f64, f64)) -> &'static str {
    if x < band.0 {
        "below (pessimistic)"
    } else if x > band.1 {
        "above (optimistic)"
    } else {
        "inside"
    }
}

impl CellSummary {
    fn of(res: &StudyResult, c: &Cell) -> Self {
        let st: &CellStats = &c.stats;
        let eval = res.config.outage_eval_rel_s();
        let k = st.index_at(eval).unwrap_or(0);
        let pick = |v: &[[f64; 9]], i0: usize, sc: f64| -> [f64; 3] {
            let x = v.get(k).copied().unwrap_or([f64::NAN; 9]);
            [x[i0] * sc, x[i0 + 1] * sc, x[i0 + 2] * sc]
        };
        let deg = 180.0 / std::f64::consts::PI;
        let pos_rms = pick(&st.rms_err, 6, 1.0);
        let pos_std = pick(&st.std, 6, 1.0);
        let window = match c.case {
            Case::Continuous => (CASE1_FROM_S, res.duration_s),
            Case::Outage => (res.config.outage_start_rel_s, eval),
        };
        let mut wr = [0.0; 3];
        let mut ws = [0.0; 3];
        for j in 0..3 {
            let (a, b) = st.rms_over(6 + j, window.0, window.1);
            wr[j] = a;
            ws[j] = b;
        }
        let band = chi2::nees_band_95(st.runs, 3);
        let mut fr = [[0.0; 3]; 3];
        let mut nm = [0.0; 3];
        for g in 0..3 {
            fr[g] = st.nees_fractions(g, band, window.0, window.1);
            nm[g] = st.nees_mean(g, window.0, window.1);
        }
        Self {
            model: c.model.label().into(),
            case: c.case,
            runs: st.runs,
            eval_t_rel_s: st.t_rel_s.get(k).copied().unwrap_or(f64::NAN),
            eval_pos_rms_m: pos_rms,
            eval_pos_std_m: pos_std,
            eval_horizontal_rms_m: (pos_rms[0].powi(2) + pos_rms[1].powi(2)).sqrt(),
            eval_horizontal_std_m: (pos_std[0].powi(2) + pos_std[1].powi(2)).sqrt(),
            eval_vel_rms_mps: pick(&st.rms_err, 3, 1.0),
            eval_vel_std_mps: pick(&st.std, 3, 1.0),
            eval_att_rms_deg: pick(&st.rms_err, 0, deg),
            eval_att_std_deg: pick(&st.std, 0, deg),
            eval_nees: st.nees.get(k).copied().unwrap_or([f64::NAN; 3]),
            window_pos_rms_m: wr,
            window_pos_std_m: ws,
            window_rel_s: window,
            window_nees_mean: nm,
            window_nees_fractions: fr,
            nees_band: band,
        }
    }
}

/// Where an average NEES lies relative to its 95 % band.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Consistency {
    /// Below the band: the filter's covariance is too large (pessimistic).
    Below,
    /// Inside the band.
    Inside,
    /// Above the band: the covariance is too small (optimistic, over-confident).
    Above,
}

impl Consistency {
    /// Classifies `x` against `band`.
    pub fn of(x: f64, band: (f64, f64)) -> Self {
        if x < band.0 {
            Self::Below
        } else if x > band.1 {
            Self::Above
        } else {
            Self::Inside
        }
    }

    /// Words for the report.
    pub fn words(self) -> &'static str {
        match self {
            Self::Below => "below the band (pessimistic)",
            Self::Inside => "inside the band",
            Self::Above => "above the band (optimistic)",
        }
    }
}

/// Position-NEES consistency of one variant on case 2.
#[derive(Debug, Clone, Serialize)]
pub struct OutageConsistency {
    /// Variant name.
    pub model: String,
    /// Time mean over the outage of the average position NEES.
    pub pos_nees_outage_mean: f64,
    /// Its classification against the band.
    pub outage_mean: Consistency,
    /// Average position NEES at the end of the outage.
    pub pos_nees_at_end: f64,
    /// Its classification.
    pub at_end: Consistency,
    /// Fraction of the outage's epochs with the position NEES inside the band.
    pub fraction_inside: f64,
    /// Time mean of the average position NEES from 60 s after the outage to the end.
    pub pos_nees_after_outage_mean: f64,
    /// The band.
    pub band: (f64, f64),
}

/// The source's claims and the study's answers, computed from the results.
#[derive(Debug, Clone, Serialize)]
pub struct Verdicts {
    /// Time-RMS over the outage of the NBK horizontal position std divided by N's.
    pub outage_std_ratio_nbk_to_n: f64,
    /// The same for N+id.gyro (N's accelerometer model, identified gyro noise) over NBK.
    pub outage_std_ratio_nidgyro_to_nbk: Option<f64>,
    /// NBK's estimated position std is smaller than N's during the whole outage (every
    /// component, every epoch).
    pub nbk_std_smaller_than_n_during_outage: bool,
    /// RMS true horizontal error at the end of the outage, NBK over N.
    pub true_error_ratio_nbk_to_n: f64,
    /// Position-NEES consistency of every variant on case 2.
    pub outage_consistency: Vec<OutageConsistency>,
    /// Budget of NBK: the contributions add up in variance to the total within 10 %.
    pub budget_adds_up_within_10_percent: Option<bool>,
    /// Budget of NBK: the gyro sources' share exceeds the accelerometer sources' share.
    pub gyros_dominate: Option<bool>,
    /// RMS horizontal error at the outage end, NBK-single over NBK.
    pub single_state_horizontal_ratio: Option<f64>,
    /// RMS vertical error at the outage end, NBK-single over NBK.
    pub single_state_vertical_ratio: Option<f64>,
}

impl Verdicts {
    /// The consistency entry of a variant.
    pub fn consistency(&self, v: Variant) -> Option<&OutageConsistency> {
        self.outage_consistency
            .iter()
            .find(|c| c.model == v.label())
    }
}

/// Time-RMS over the outage of the horizontal position std of a cell.
fn outage_horizontal_std(res: &StudyResult, v: Variant) -> Option<f64> {
    let c = res.cell(v, Case::Outage)?;
    let (t0, t1) = (
        res.config.outage_start_rel_s,
        res.config.outage_eval_rel_s(),
    );
    let (mut a, mut n) = (0.0, 0usize);
    for (t, s) in c.stats.t_rel_s.iter().zip(&c.stats.std) {
        if *t >= t0 && *t <= t1 {
            a += s[6] * s[6] + s[7] * s[7];
            n += 1;
        }
    }
    (n > 0).then(|| (a / n as f64).sqrt())
}

fn verdicts(res: &StudyResult, sums: &[CellSummary]) -> Verdicts {
    let find = |v: Variant, c: Case| sums.iter().find(|s| s.model == v.label() && s.case == c);
    let n2 = res.cell(Variant::N, Case::Outage);
    let k2 = res.cell(Variant::Nbk, Case::Outage);
    let (t0, t1) = (
        res.config.outage_start_rel_s,
        res.config.outage_eval_rel_s(),
    );
    let mut smaller = n2.is_some() && k2.is_some();
    if let (Some(n), Some(k)) = (n2, k2) {
        for ((t, a), b) in n.stats.t_rel_s.iter().zip(&n.stats.std).zip(&k.stats.std) {
            if *t >= t0 && *t <= t1 && (6..9).any(|i| b[i] >= a[i]) {
                smaller = false;
            }
        }
    }
    let hs = |v| outage_horizontal_std(res, v).unwrap_or(f64::NAN);
    let outage_consistency = res
        .cells
        .iter()
        .filter(|c| c.case == Case::Outage)
        .map(|c| {
            let band = chi2::nees_band_95(c.stats.runs, 3);
            let m = c.stats.nees_mean(2, t0, t1);
            let k = c.stats.index_at(t1).unwrap_or(0);
            let e = c.stats.nees.get(k).map_or(f64::NAN, |n| n[2]);
            OutageConsistency {
                model: c.model.label().into(),
                pos_nees_outage_mean: m,
                outage_mean: Consistency::of(m, band),
                pos_nees_at_end: e,
                at_end: Consistency::of(e, band),
                fraction_inside: c.stats.nees_fractions(2, band, t0, t1)[0],
                pos_nees_after_outage_mean: c.stats.nees_mean(
                    2,
                    res.config.outage_end_rel_s() + 60.0,
                    res.duration_s,
                ),
                band,
            }
        })
        .collect();
    let b = res.budgets.iter().find(|b| b.model == Variant::Nbk);
    let ratio = |a: Variant, b: Variant, f: fn(&CellSummary) -> f64| match (
        find(a, Case::Outage),
        find(b, Case::Outage),
    ) {
        (Some(a), Some(b)) => Some(f(a) / f(b)),
        _ => None,
    };
    Verdicts {
        outage_std_ratio_nbk_to_n: hs(Variant::Nbk) / hs(Variant::N),
        outage_std_ratio_nidgyro_to_nbk: res
            .cell(Variant::NIdGyro, Case::Outage)
            .map(|_| hs(Variant::NIdGyro) / hs(Variant::Nbk)),
        nbk_std_smaller_than_n_during_outage: smaller,
        true_error_ratio_nbk_to_n: ratio(Variant::Nbk, Variant::N, |s| s.eval_horizontal_rms_m)
            .unwrap_or(f64::NAN),
        outage_consistency,
        budget_adds_up_within_10_percent: b
            .map(|b| (b.ratio_sum_to_total_horizontal - 1.0).abs() <= 0.10),
        gyros_dominate: b.map(|b| b.gyro_share > b.accel_share),
        single_state_horizontal_ratio: ratio(Variant::NbkSingle, Variant::Nbk, |s| {
            s.eval_horizontal_rms_m
        }),
        single_state_vertical_ratio: ratio(Variant::NbkSingle, Variant::Nbk, |s| {
            s.eval_pos_rms_m[2]
        }),
    }
}

/// The set-up, as written to `study.json`.
#[derive(Debug, Clone, Serialize)]
pub struct SetupSummary {
    /// Scenario name.
    pub scenario: String,
    /// Duration of the runs, s.
    pub duration_s: f64,
    /// IMU rate, Hz.
    pub imu_rate_hz: f64,
    /// Runs per cell.
    pub runs: usize,
    /// Seeds used.
    pub seeds: (u64, u64),
    /// Outage start and duration, s.
    pub outage_rel_s: (f64, f64),
    /// Evaluation epoch of "the end of the outage", s.
    pub outage_eval_rel_s: f64,
    /// Simulated sensor and GNSS errors (TOML of the error model).
    pub truth_errors_toml: String,
    /// Filter models: name, accelerometer S_N / S_B / T_B / S_K, gyro S_N, initial bias sigmas.
    pub filter_models: Vec<FilterModelSummary>,
    /// Covariance prediction interval of the filter, s.
    pub cov_predict_interval_s: f64,
    /// Initial uncertainty (attitude rad, velocity m/s, position m) given to the filter and
    /// used to draw the initial errors.
    pub initial_sigma: [[f64; 3]; 3],
}

/// One filter model's parameters.
#[derive(Debug, Clone, Serialize)]
pub struct FilterModelSummary {
    /// Name.
    pub name: String,
    /// State count.
    pub states: usize,
    /// Accelerometer white noise, ug/sqrt(Hz).
    pub accel_white_ug_per_sqrt_hz: f64,
    /// Accelerometer S_B, m^2/s^5.
    pub accel_s_b: f64,
    /// Accelerometer T_B, s.
    pub accel_t_b_s: f64,
    /// Accelerometer S_K, m^2/s^5.
    pub accel_s_k: f64,
    /// Gyro white noise, deg/sqrt(h).
    pub gyro_white_deg_per_sqrt_h: f64,
    /// Accelerometer initial bias sigma, ug.
    pub accel_bias_init_ug: f64,
    /// Gyro initial bias sigma, deg/h.
    pub gyro_bias_init_deg_per_h: f64,
}

fn setup_summary(res: &StudyResult) -> SetupSummary {
    use nav_core::config::units;
    let cfg = &res.config;
    let unc = setup::initial_uncertainty();
    SetupSummary {
        scenario: cfg.scenario.name.clone(),
        duration_s: res.duration_s,
        imu_rate_hz: cfg.scenario.imu.rate_hz,
        runs: cfg.runs,
        seeds: (cfg.seed, cfg.seed + cfg.runs as u64 - 1),
        outage_rel_s: (cfg.outage_start_rel_s, cfg.outage_duration_s),
        outage_eval_rel_s: cfg.outage_eval_rel_s(),
        truth_errors_toml: setup::truth_errors().to_toml_string(),
        filter_models: cfg
            .models
            .iter()
            .map(|&m| {
                let f = m.config();
                FilterModelSummary {
                    name: m.label().into(),
                    states: m.model().layout().dim(),
                    accel_white_ug_per_sqrt_hz: units::accel_ug_per_sqrt_hz_from_psd(
                        f.accel.s_n[0],
                    ),
                    accel_s_b: f.accel.s_b[0],
                    accel_t_b_s: f.accel.t_b_s,
                    accel_s_k: f.accel.s_k[0],
                    gyro_white_deg_per_sqrt_h: units::gyro_deg_per_sqrt_h_from_psd(f.gyro.s_n[0]),
                    accel_bias_init_ug: units::ug_from_mps2(f.accel.bias_init_sigma[0]),
                    gyro_bias_init_deg_per_h: units::deg_per_h_from_radps(
                        f.gyro.bias_init_sigma[0],
                    ),
                }
            })
            .collect(),
        cov_predict_interval_s: Variant::Nbk.config().cov_predict_interval_s,
        initial_sigma: [unc.att_sigma_rad, unc.vel_sigma_mps, unc.pos_sigma_m],
    }
}

/// Everything in `study.json`.
#[derive(Debug, Clone, Serialize)]
pub struct StudyJson<'a> {
    /// Set-up.
    pub setup: SetupSummary,
    /// Wall-clock time, s.
    pub elapsed_s: f64,
    /// Filter runs made.
    pub filter_runs: usize,
    /// Per-cell summaries.
    pub summaries: Vec<CellSummary>,
    /// Verdicts on the source's claims.
    pub verdicts: Verdicts,
    /// Error budgets.
    pub budgets: &'a [Budget],
    /// Per-cell time series (1 Hz): model, case, statistics.
    pub series: Vec<(String, Case, &'a CellStats)>,
}

/// Summaries of every cell.
pub fn summaries(res: &StudyResult) -> Vec<CellSummary> {
    res.cells.iter().map(|c| CellSummary::of(res, c)).collect()
}

/// The verdicts.
pub fn compute_verdicts(res: &StudyResult) -> Verdicts {
    verdicts(res, &summaries(res))
}

fn f3(a: [f64; 3], sc: f64, prec: usize) -> String {
    format!(
        "{:.p$} / {:.p$} / {:.p$}",
        a[0] * sc,
        a[1] * sc,
        a[2] * sc,
        p = prec
    )
}

/// The printed (and Markdown) summary tables.
pub fn table(res: &StudyResult) -> String {
    let sums = summaries(res);
    let v = verdicts(res, &sums);
    let band = chi2::nees_band_95(res.config.runs, 3);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "\nCase 1, continuous 1 Hz GNSS: time-RMS from {CASE1_FROM_S:.0} s to the end ({} runs; NEES 95 % band [{:.2}, {:.2}])\n",
        res.config.runs, band.0, band.1
    );
    let _ = writeln!(
        s,
        "| model | pos RMS error N/E/D [cm] | pos filter std N/E/D [cm] | mean NEES att / vel / pos | epochs with pos NEES in band / below / above |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|");
    for x in sums.iter().filter(|x| x.case == Case::Continuous) {
        let fr = x.window_nees_fractions[2];
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {:.0} % / {:.0} % / {:.0} % |",
            x.model,
            f3(x.window_pos_rms_m, 100.0, 2),
            f3(x.window_pos_std_m, 100.0, 2),
            f3(x.window_nees_mean, 1.0, 2),
            100.0 * fr[0],
            100.0 * fr[1],
            100.0 * fr[2]
        );
    }
    let _ = writeln!(
        s,
        "\nCase 2, {:.0}-s GNSS outage from {:.0} s: at its end (t = {:.0} s, {:.0} s after the last fix used)\n",
        res.config.outage_duration_s,
        res.config.outage_start_rel_s,
        res.config.outage_eval_rel_s(),
        res.config.outage_duration_s
    );
    let _ = writeln!(
        s,
        "| model | pos RMS error N/E/D [m] | pos filter std N/E/D [m] | horiz. RMS / std [m] | NEES att / vel / pos at the end | pos NEES over the outage: mean, % epochs in band |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    for x in sums.iter().filter(|x| x.case == Case::Outage) {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} / {:.2} | {} ({}) | {:.2} ({}), {:.0} % |",
            x.model,
            f3(x.eval_pos_rms_m, 1.0, 2),
            f3(x.eval_pos_std_m, 1.0, 2),
            x.eval_horizontal_rms_m,
            x.eval_horizontal_std_m,
            f3(x.eval_nees, 1.0, 2),
            where_in(x.eval_nees[2], x.nees_band),
            x.window_nees_mean[2],
            where_in(x.window_nees_mean[2], x.nees_band),
            100.0 * x.window_nees_fractions[2][0]
        );
    }
    for b in &res.budgets {
        budget_section(&mut s, b);
    }
    verdict_lines(&mut s, &v);
    s
}

/// The error-budget table of one model: each source alone at the end of the outage, the sum
/// against all sources together, and the sources' shares.
fn budget_section(s: &mut String, b: &Budget) {
    let _ = writeln!(
        s,
        "\nError budget, {} model: position error at the end of the outage with each source alone ({} runs)\n",
        b.model.label(),
        b.runs
    );
    let _ = writeln!(
        s,
        "| source | RMS N / E / D [m] | RMS horizontal [m] | share of variance |"
    );
    let _ = writeln!(s, "|---|---|---|---|");
    for e in &b.entries {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {} |",
            e.label,
            f3(e.mse_ned_m2.map(f64::sqrt), 1.0, 3),
            e.rms_horizontal_m,
            percent(e.share_horizontal)
        );
    }
    let _ = writeln!(
        s,
        "| **all sources together** | {} | {:.3} | sum of contributions / total = {:.3} (+- {:.3} sampling), superposition residual {:.1e} |",
        f3(b.total_mse_ned_m2.map(f64::sqrt), 1.0, 3),
        b.total_rms_horizontal_m,
        b.ratio_sum_to_total_horizontal,
        b.ratio_std_error,
        b.superposition_residual
    );
    let _ = writeln!(
        s,
        "\n- gyro sources {:.1} % of the variance, accelerometer sources {}, largest: {}",
        100.0 * b.gyro_share,
        percent(b.accel_share),
        b.largest.label()
    );
    if let Some(n) = b.total_pos_nees {
        let _ = writeln!(
            s,
            "- position NEES of the {} all-sources runs at the end of the outage: {:.2}, {} [{:.2}, {:.2}]",
            b.runs,
            n,
            Consistency::of(n, b.total_pos_nees_band).words(),
            b.total_pos_nees_band.0,
            b.total_pos_nees_band.1
        );
    }
}

/// The study's verdicts (model comparison, consistency, budget), one line each.
fn verdict_lines(s: &mut String, v: &Verdicts) {
    let yes = |b: bool| if b { "yes" } else { "NO" };
    let _ = writeln!(s, "\nVerdicts");
    let _ = writeln!(
        s,
        "- NBK's estimated position std smaller than N's during the whole outage: {} (horizontal std NBK/N = {:.2}); true RMS horizontal error at the end NBK/N = {:.2}",
        yes(v.nbk_std_smaller_than_n_during_outage),
        v.outage_std_ratio_nbk_to_n,
        v.true_error_ratio_nbk_to_n
    );
    if let Some(r) = v.outage_std_ratio_nidgyro_to_nbk {
        let _ = writeln!(
            s,
            "- N's accelerometer model with the identified gyro noise (N+id.gyro): horizontal std over the outage {r:.2} x NBK's"
        );
    }
    for c in &v.outage_consistency {
        let _ = writeln!(
            s,
            "- {} position NEES during the outage: mean {:.2} {}; at its end {:.2} {}",
            c.model,
            c.pos_nees_outage_mean,
            c.outage_mean.words(),
            c.pos_nees_at_end,
            c.at_end.words()
        );
    }
    if let (Some(a), Some(g)) = (v.budget_adds_up_within_10_percent, v.gyros_dominate) {
        let _ = writeln!(
            s,
            "- budget (NBK) adds up in variance within 10 %: {}; gyros contribute more than accelerometers: {}",
            yes(a),
            yes(g)
        );
    }
    if let (Some(h), Some(d)) = (
        v.single_state_horizontal_ratio,
        v.single_state_vertical_ratio,
    ) {
        let _ = writeln!(
            s,
            "- single-state NBK vs two-state NBK at the outage end: RMS horizontal x{h:.2}, RMS down x{d:.2}"
        );
    }
}

/// The Markdown report (images by relative file name).
pub fn markdown(res: &StudyResult, plots: &[String]) -> String {
    let cfg = &res.config;
    let su = setup_summary(res);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# The bias-model study (Teodori & Neuner, FIG 2022), re-run with true errors\n"
    );
    let _ = writeln!(
        s,
        "Generated by `host-sim study` in {:.1} s ({} filter runs, {} threads). Scenario `{}` ({:.1} min, IMU {} Hz), {} Monte Carlo runs per model and case (seeds {}..{}).\n",
        res.elapsed_s,
        res.filter_runs,
        rayon::current_num_threads(),
        cfg.scenario.name,
        res.duration_s / 60.0,
        cfg.scenario.imu.rate_hz,
        cfg.runs,
        su.seeds.0,
        su.seeds.1
    );
    let _ = writeln!(s, "## Set-up\n");
    let _ = writeln!(
        s,
        "- **Simulated IMU** (the source's Appendix V, no quantization): accelerometer white noise S_N = 6.2865e-9 m²/s³ (8.1 µg/√Hz), first-order Gauss-Markov S_B = 2.4360e-11 m²/s⁵ with T_B = 45 s, random walk S_K = 2.6731e-12 m²/s⁵; gyro white noise S_N = 5.3079e-10 rad²/s (0.079 °/√h). Turn-on biases (random constants per run; the source states none): accelerometer {} µg, gyro {} °/h (the manufacturer's gyro bias specification), 1σ per axis.",
        setup::ACCEL_TURN_ON_UG,
        setup::GYRO_TURN_ON_DEG_PER_H
    );
    let _ = writeln!(
        s,
        "- **GNSS**: 1 Hz RTK-level positions, white errors {} / {} / {} m (N/E/D), reported with each fix.",
        setup::GNSS_SIGMA_NED_M[0],
        setup::GNSS_SIGMA_NED_M[1],
        setup::GNSS_SIGMA_NED_M[2]
    );
    let u = setup::initial_uncertainty();
    let _ = writeln!(
        s,
        "- **Initial state**: truth plus errors drawn with the filter's initial sigmas (roll/pitch {:.2}°, heading {:.2}°, velocity {} m/s, position {} m) at the start of a 3-minute static period.",
        u.att_sigma_rad[0].to_degrees(),
        u.att_sigma_rad[2].to_degrees(),
        u.vel_sigma_mps[0],
        u.pos_sigma_m[0]
    );
    let _ = writeln!(
        s,
        "- **Filters** (loosely coupled error-state filter of `nav-core`, covariance predicted every {} s, position updates):\n",
        su.cov_predict_interval_s
    );
    let _ = writeln!(
        s,
        "| model | states | accel white [µg/√Hz] | S_B [m²/s⁵] | T_B [s] | S_K [m²/s⁵] | gyro white [°/√h] | initial bias σ accel [µg] / gyro [°/h] |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|");
    for m in &su.filter_models {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.4e} | {} | {:.4e} | {:.3} | {} / {} |",
            m.name,
            m.states,
            m.accel_white_ug_per_sqrt_hz,
            m.accel_s_b,
            m.accel_t_b_s,
            m.accel_s_k,
            m.gyro_white_deg_per_sqrt_h,
            tidy(m.accel_bias_init_ug),
            tidy(m.gyro_bias_init_deg_per_h)
        );
    }
    let _ = writeln!(
        s,
        "\nN: the manufacturer's white-noise specification with constant biases. NBK: the identified parameters with separate Gauss-Markov and random-walk accelerometer bias states. NBK-single: the source's form, one accelerometer bias state decaying with 1/T_B driven by S_B + S_K. Both bias sigmas are set to the simulated turn-on biases, so the models differ only in their noise model.\n"
    );
    let _ = writeln!(
        s,
        "- **Cases**: 1 = continuous 1 Hz GNSS; 2 = one {:.0}-s outage from {:.0} s (fixes with tags in [{:.0}, {:.0}) s withheld). \"End of the outage\" = t = {:.0} s, {:.0} s after the last fix used.",
        cfg.outage_duration_s,
        cfg.outage_start_rel_s,
        cfg.outage_start_rel_s,
        cfg.outage_end_rel_s(),
        cfg.outage_eval_rel_s(),
        cfg.outage_duration_s
    );
    let man = outage_manoeuvres(res);
    if !man.is_empty() {
        let _ = writeln!(
            s,
            "  During the outage the vehicle does: {}.",
            man.join(", ")
        );
    }
    let _ = writeln!(
        s,
        "- **NEES**: per epoch and run, `sum e_i² / P_ii` over the three components of a group (attitude, velocity, position) from the filter's standard deviations; its expectation is 3 for a consistent filter, as for the full-matrix NEES. The average over R runs is compared with the two-sided 95 % chi-square band for 3R degrees of freedom.\n"
    );
    let _ = writeln!(s, "## Results\n");
    s += &table(res);
    let _ = writeln!(s, "\n## Plots\n");
    for p in plots {
        let cap = plot_caption(p);
        let _ = writeln!(s, "### {cap}\n\n![{cap}]({p})\n");
    }
    let _ = writeln!(s, "## Reading the results\n");
    s += &discussion(res);
    s
}

/// The scenario segments overlapping the outage, as `kind (t0-t1 s)`.
pub fn outage_manoeuvres(res: &StudyResult) -> Vec<String> {
    let cfg = &res.config;
    let Ok(p) = cfg.scenario.compile() else {
        return Vec::new();
    };
    let (a, b) = (cfg.outage_start_rel_s, cfg.outage_end_rel_s());
    (0..p.num_segments())
        .filter_map(|i| {
            let (t0, t1) = p.segment_span_s(i)?;
            let kind = cfg.scenario.segments.get(i)?.kind();
            (t1 > a && t0 < b).then(|| format!("{kind} ({:.0}-{:.0} s)", t0.max(a), t1.min(b)))
        })
        .collect()
}

fn plot_caption(name: &str) -> String {
    match name {
        "errors_case1.png" => "Case 1: filter standard deviation (dashed) and Monte Carlo RMS true error (solid), every component".into(),
        "errors_case2.png" => "Case 2: filter standard deviation (dashed) and Monte Carlo RMS true error (solid), outage shaded".into(),
        "bands_case1.png" => "Case 1: position ±1σ bands of N and NBK with true-error traces".into(),
        "bands_case2.png" => "Case 2: position ±1σ bands of N and NBK with true-error traces around the outage".into(),
        "nees_case1.png" => "Case 1: average NEES against the 95 % band".into(),
        "nees_case2.png" => "Case 2: average NEES against the 95 % band".into(),
        "budget.png" => "Error budget at the end of the outage".into(),
        other => other.into(),
    }
}

/// The interpretation paragraph, with every number taken from the results.
pub fn discussion(res: &StudyResult) -> String {
    let sums = summaries(res);
    let v = verdicts(res, &sums);
    let get = |m: Variant, c: Case| sums.iter().find(|s| s.model == m.label() && s.case == c);
    let mut s = String::new();
    if let (Some(n), Some(k)) = (
        get(Variant::N, Case::Outage),
        get(Variant::Nbk, Case::Outage),
    ) {
        let _ = writeln!(
            s,
            "- **What the source shows (estimated standard deviations).** During the outage NBK's horizontal position std is {:.2} times N's (time-RMS over the outage); at its end {:.1} m against {:.1} m. {}",
            v.outage_std_ratio_nbk_to_n,
            k.eval_horizontal_std_m,
            n.eval_horizontal_std_m,
            if v.nbk_std_smaller_than_n_during_outage {
                "NBK's std is below N's in every component at every epoch of the outage."
            } else {
                "NBK's std is NOT below N's at every epoch and component of the outage."
            }
        );
        if let Some(r) = v.outage_std_ratio_nidgyro_to_nbk {
            let why = if (r - 1.0).abs() <= 0.1 {
                "so the difference between N's and NBK's std comes from the gyro specification (0.15 against the identified 0.079 deg/sqrt(h)), not from the accelerometer bias model"
            } else if r > 1.0 {
                "so the accelerometer model also contributes to the difference between N's and NBK's std"
            } else {
                "so with the identified gyro noise N's accelerometer model gives an even smaller std than NBK"
            };
            let _ = writeln!(
                s,
                "  The diagnostic variant N+id.gyro (N's accelerometer model, the identified gyro white noise) has {r:.2} times NBK's horizontal std over the outage, {why}."
            );
        }
        let _ = writeln!(
            s,
            "- **True errors (the source's outlook).** The RMS true horizontal error at the end of the outage is {:.1} m for N and {:.1} m for NBK (ratio {:.2}; the runs use the same seeds, so this compares the filters on identical data).",
            n.eval_horizontal_rms_m, k.eval_horizontal_rms_m, v.true_error_ratio_nbk_to_n
        );
    }
    if !v.outage_consistency.is_empty() {
        let _ = write!(s, "- **Consistency (position NEES during the outage).**");
        for c in &v.outage_consistency {
            let _ = write!(
                s,
                " {}: mean {:.2}, {}, {:.0} % of the epochs inside;",
                c.model,
                c.pos_nees_outage_mean,
                c.outage_mean.words(),
                100.0 * c.fraction_inside
            );
        }
        let band = v.outage_consistency.first().map_or((0.0, 0.0), |c| c.band);
        let _ = writeln!(
            s,
            " band [{:.2}, {:.2}]. Below the band the filter overstates its error (pessimistic), above it the filter is over-confident.",
            band.0, band.1
        );
    }
    for b in &res.budgets {
        let _ = writeln!(
            s,
            "- **Error budget ({}).** Gyro sources: {:.1} % of the variance, accelerometer sources: {}; largest: {}. The contributions add up to {:.3} of the all-sources variance (sampling standard error {:.3}; the per-run superposition residual is {:.1e}, so the filter is linear in the errors to that level and the difference from 1 is the sampling noise of the cross terms). The source's conclusion that the gyros, not the accelerometers, dominate {}.",
            b.model.label(),
            100.0 * b.gyro_share,
            percent(b.accel_share),
            b.largest.label(),
            b.ratio_sum_to_total_horizontal,
            b.ratio_std_error,
            b.superposition_residual,
            if b.gyro_share > b.accel_share {
                "holds here"
            } else {
                "does NOT hold here"
            }
        );
        let acc: f64 = b
            .entries
            .iter()
            .filter(|e| e.source.is_accel())
            .map(|e| e.mse_ned_m2[0] + e.mse_ned_m2[1])
            .sum::<f64>()
            .sqrt();
        let _ = writeln!(
            s,
            "  All accelerometer sources together give {:.2} m RMS horizontally; {} alone gives {:.2} m.",
            acc,
            Source::GyroWhite.label(),
            b.entries
                .iter()
                .find(|e| e.source == Source::GyroWhite)
                .map_or(f64::NAN, |e| e.rms_horizontal_m)
        );
    }
    if let (Some(k), Some(sg)) = (
        get(Variant::Nbk, Case::Outage),
        get(Variant::NbkSingle, Case::Outage),
    ) {
        let after = v
            .consistency(Variant::NbkSingle)
            .map_or(f64::NAN, |c| c.pos_nees_after_outage_mean);
        let _ = writeln!(
            s,
            "- **Single-state NBK (the source's form) against two states.** At the end of the outage RMS down error {:.2} m (single) against {:.2} m (two states), position NEES {:.1} against {:.1}; from 60 s after the outage to the end the single-state position NEES averages {:.1}. The single state decays with 1/T_B = 1/45 s: its estimate of the turn-on and random-walk bias is pulled towards zero (during the outage nothing pulls it back), while its variance stays near the small stationary value (S_B + S_K) T_B / 2, so the filter is over-confident in the vertical channel.",
            sg.eval_pos_rms_m[2], k.eval_pos_rms_m[2], sg.eval_nees[2], k.eval_nees[2], after
        );
    }
    s
}

/// The `study.json` document: the set-up, the per-cell summaries, the verdicts, the error
/// budgets and the per-epoch series of every cell.
pub fn study_json(res: &StudyResult) -> StudyJson<'_> {
    let sums = summaries(res);
    let v = verdicts(res, &sums);
    StudyJson {
        setup: setup_summary(res),
        elapsed_s: res.elapsed_s,
        filter_runs: res.filter_runs,
        summaries: sums,
        verdicts: v,
        budgets: &res.budgets,
        series: res
            .cells
            .iter()
            .map(|c| (c.model.label().to_string(), c.case, &c.stats))
            .collect(),
    }
}

/// A share (0..1) as a percentage with two significant digits for small values.
pub fn percent(x: f64) -> String {
    let p = 100.0 * x;
    if p >= 10.0 {
        format!("{p:.1} %")
    } else if p >= 0.1 {
        format!("{p:.2} %")
    } else {
        format!("{p:.1e} %")
    }
}

/// `x` with at most 6 significant decimals and no trailing zeros (unit conversions leave
/// `0.10000000000000002`).
fn tidy(x: f64) -> String {
    let r = format!("{:.6}", x);
    let r = r.trim_end_matches('0').trim_end_matches('.');
    r.to_string()
}
