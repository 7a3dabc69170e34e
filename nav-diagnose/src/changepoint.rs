//! Change points of the IMU biases: a bias that steps at one time (a shock, a mode switch)
//! is not a state of the error model, so the effect search cannot name it (it adds effects
//! that absorb part of it). It is found here from the base run's GNSS innovations and fitted
//! with the filter as the model:
//!
//! 1. Onset: a CUSUM of the position innovations' log-likelihood ratio for a variance
//!    inflation ([`CUSUM_INFLATION`]) over the used fixes; the onset is the first fix
//!    after the last zero of the statistic before its peak, when the peak exceeds
//!    [`CUSUM_ALARM_NATS`], and the step is first fitted one fix interval before it, or in
//!    the middle of a gap of the used fixes when the onset is the first fix after it. A step needs a consistent model before it: at least
//!    [`MIN_FIXES_BEFORE`] used fixes before the onset with a mean position NIS below
//!    [`MAX_NIS_BEFORE`] (an effect present from the start, which inflates the innovations
//!    throughout, is left to the effect search). When the fixes before that onset are not
//!    consistent, the CUSUM restarted at each alarm ([`cusum_alarms`]) gives the next
//!    candidates: the first alarm whose fixes since the alarm before it are consistent is the
//!    onset ([`usable_onset`]; an effect that shows when the vehicle starts raises an alarm
//!    too early to fit, and a later step still raises its own).
//! 2. Magnitude: the IMU data after the onset are corrected by a candidate step `c` (body
//!    axes) and the filter re-run. The innovations are linear in `c` to first order,
//!    `nu(c) = nu(c0) + J (c - c0)`, with J from one re-run per axis; `c` minimises
//!    `sum nu^T W nu` (W the inverse innovation variances of the fixes after the onset, the
//!    withheld fixes left out), by Gauss-Newton (two iterations, the first from the base run),
//!    for the accelerometers and the gyros; the sensor whose corrected run gains more
//!    log-likelihood is kept. The 1-sigma of `c` is that of the weighted least squares.
//! 3. Time: the corrected run is repeated with the step moved by up to
//!    [`TIME_SEARCH_S`] in 1 s steps (the scan extended by [`TIME_SEARCH_S`], up to
//!    [`MAX_TIME_EXTENSIONS`] times, while its best time is at an end: the CUSUM's onset lags
//!    a step whose error grows slowly; a step first fitted in a gap is scanned over the whole
//!    gap and [`TIME_SEARCH_S`] beyond its ends); the time of largest log-likelihood is kept.
//!    When the best time is still the scan's earlier end after the extensions, the step time
//!    is scanned back coarsely from there ([`BACK_SCAN_STEP_S`] apart over [`BACK_SCAN_S`],
//!    not before the alarm the CUSUM restarted after) by the gain the linearised innovations
//!    predict for a step refitted at each time, and the 1 s scan repeated around the best
//!    when its fit there is more likely. A step's
//!    time is sharp: moving it by its sensor's span ([`BiasStepSensor::sharpness_span_s`]:
//!    [`TIME_SEARCH_S`] for the accelerometers, [`GYRO_SHARPNESS_SPAN_S`] for the gyros)
//!    either way (beyond the ends of a gap in the used fixes when it lies in one: there it
//!    can only be placed within the gap) must cost at least [`MIN_SHARPNESS_NATS`] (a slowly
//!    growing error, e.g. a drifting clock, that a small step absorbs in part has a flat
//!    profile and is left to the effect search). A gyro step reaches the position one
//!    integration later than an accelerometer step, through the attitude error, and a step
//!    about the vertical axis only under horizontal acceleration: moved by a few seconds it
//!    changes the fit little, least towards a gap of the fixes that follows it closely.
//!
//! A step is reported when the corrected run gains more than the BIC penalty of its four
//! parameters (3 axes and the time) plus [`MIN_GAIN_NATS`]. [`BiasStep::corrected_case`] gives
//! the data with the step removed.
use nav_engine::run::{FixUse, InnovationRecord, RunOptions, RunOutput};
use rayon::prelude::*;
use serde::Serialize;

use super::imu_cache::{Adjust, Case};
use super::search_recording;
use super::stats::{in_stats, residual_stats};
use super::validate::HeldoutComparison;

/// Variance inflation of the CUSUM's alternative hypothesis (4: innovations twice as large).
pub const CUSUM_INFLATION: f64 = 4.0;
/// CUSUM level that signals a change, nats.
pub const CUSUM_ALARM_NATS: f64 = 25.0;
/// Half-width of the search for the step time around the CUSUM onset, s.
pub const TIME_SEARCH_S: f64 = 6.0;
/// Log-likelihood a step must lose when its time is moved either way by its sensor's span
/// ([`BiasStepSensor::sharpness_span_s`]), nats.
pub const MIN_SHARPNESS_NATS: f64 = 20.0;
/// How far a gyro step's time is moved either way to judge that it is sharp, s
/// ([`BiasStepSensor::sharpness_span_s`]).
pub const GYRO_SHARPNESS_SPAN_S: f64 = 24.0;
/// How many times the time scan is extended by [`TIME_SEARCH_S`] while its best time is at an
/// end of it.
pub const MAX_TIME_EXTENSIONS: usize = 4;
/// Used fixes needed before the onset.
pub const MIN_FIXES_BEFORE: usize = 60;
/// Largest mean position NIS (3 dimensions: expected 3) of the fixes before the onset.
pub const MAX_NIS_BEFORE: f64 = 6.0;
/// Log-likelihood gain the corrected run must have beyond the BIC penalty, nats.
pub const MIN_GAIN_NATS: f64 = 10.0;
/// Spacing of the coarse back-scan of the step time beyond the time scan's earlier end, s.
pub const BACK_SCAN_STEP_S: f64 = 10.0;
/// Longest span of the coarse back-scan before the time scan's earlier end, s (the CUSUM's
/// alarm can lag a gyro step by minutes: its position error grows with the square of the
/// time).
pub const BACK_SCAN_S: f64 = 150.0;

/// Which sensor triad's bias steps.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BiasStepSensor {
    /// Accelerometers: the step in m/s^2.
    Accel,
    /// Gyros: the step in rad/s.
    Gyro,
}

impl BiasStepSensor {
    /// Both sensors.
    pub const ALL: [BiasStepSensor; 2] = [BiasStepSensor::Accel, BiasStepSensor::Gyro];

    /// The name in the diagnosis vocabulary: `accel_bias_step`, `gyro_bias_step`.
    pub const fn name(self) -> &'static str {
        match self {
            BiasStepSensor::Accel => "accel_bias_step",
            BiasStepSensor::Gyro => "gyro_bias_step",
        }
    }

    /// SI unit of the step.
    pub const fn unit(self) -> &'static str {
        match self {
            BiasStepSensor::Accel => "m/s^2",
            BiasStepSensor::Gyro => "rad/s",
        }
    }

    /// How far the step time is moved either way to judge that it is sharp (the move must
    /// cost at least [`MIN_SHARPNESS_NATS`]), s: [`TIME_SEARCH_S`] for the accelerometers,
    /// [`GYRO_SHARPNESS_SPAN_S`] for the gyros (a gyro step reaches the position one
    /// integration later, through the attitude error, and a vertical one only under
    /// horizontal acceleration: its likelihood profile is wider).
    pub const fn sharpness_span_s(self) -> f64 {
        match self {
            BiasStepSensor::Accel => TIME_SEARCH_S,
            BiasStepSensor::Gyro => GYRO_SHARPNESS_SPAN_S,
        }
    }

    /// The perturbation used for the finite-difference columns: 1 mg, 10 deg/h.
    const fn probe(self) -> f64 {
        match self {
            BiasStepSensor::Accel => 1e-3 * nav_core::earth::G0_MPS2,
            BiasStepSensor::Gyro => 10.0 * std::f64::consts::PI / 180.0 / 3600.0,
        }
    }
}

/// A bias step found in the data.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BiasStep {
    /// Which sensor.
    pub sensor: BiasStepSensor,
    /// `accel_bias_step` or `gyro_bias_step`.
    pub name: String,
    /// Time of the step, s (the IMU time stamps' clock).
    pub t_s: f64,
    /// Time of the step after the first IMU sample, s.
    pub t_rel_s: f64,
    /// Time where the CUSUM placed the onset, s.
    pub onset_t_s: f64,
    /// The step per body axis (x, y, z), SI ([`BiasStepSensor::unit`]).
    pub step: [f64; 3],
    /// Its 1-sigma per axis, SI.
    pub sigma: [f64; 3],
    /// Norm of the step, SI.
    pub magnitude: f64,
    /// SI unit.
    pub unit: String,
    /// Log-likelihood gain of the corrected run over the base run, nats.
    pub delta_log_likelihood: f64,
    /// BIC penalty of the four parameters, nats.
    pub bic_penalty: f64,
    /// The held-out windows of the data with the step removed against the recorded data's,
    /// paired (None until judged): the step is kept only when they are significantly lower,
    /// as an effect is added.
    pub heldout: Option<HeldoutComparison>,
    /// The decision on the held-out windows in words (None until judged).
    pub reason: Option<String>,
}

impl BiasStep {
    /// The data with the step removed from every IMU sample at or after the step time.
    pub fn corrected_case(&self, case: &Case) -> Case {
        corrected(case, self.sensor, self.t_s, &self.step)
    }

    /// One line for reports: name, time, magnitude per axis.
    pub fn describe(&self) -> String {
        let (k, u) = match self.sensor {
            BiasStepSensor::Accel => (1.0 / (1e-3 * nav_core::earth::G0_MPS2), "mg"),
            BiasStepSensor::Gyro => (180.0 / std::f64::consts::PI * 3600.0, "deg/h"),
        };
        format!(
            "{} at {:.1} s ({:.1} s into the data): [{:.3}, {:.3}, {:.3}] {u} (1-sigma [{:.3}, \
             {:.3}, {:.3}]), {:.1} nats",
            self.name,
            self.t_s,
            self.t_rel_s,
            self.step[0] * k,
            self.step[1] * k,
            self.step[2] * k,
            self.sigma[0] * k,
            self.sigma[1] * k,
            self.sigma[2] * k,
            self.delta_log_likelihood - self.bic_penalty
        )
    }
}

/// The data with `step` (SI, body axes) subtracted from the `sensor`'s increments of every
/// sample whose interval starts at or after `t_s` (applied as the samples are read,
/// [`Adjust`]).
fn corrected(case: &Case, sensor: BiasStepSensor, t_s: f64, step: &[f64; 3]) -> Case {
    case.adjusted(Adjust {
        bias_step: Some((sensor, t_s, *step)),
        ..*case.imu.adjust()
    })
}

/// The CUSUM onset of a variance increase of the position innovations: `(onset time, peak
/// level in nats)`, or None when the statistic never reaches [`CUSUM_ALARM_NATS`]. The fixes
/// of the [`SETTLE_S`] after a gap in the used fixes (a gap of the file, an outage, a
/// withheld window) are left out: the prediction error across a gap is not a change of the
/// model. The statistic runs on across a gap (a change that persists, such as a gyro bias
/// step the filter's bias state cannot follow, accumulates over every stretch of fixes after
/// it; restarted at each gap, its largest stretch would be the last and the onset placed
/// after the last gap).
pub fn cusum_onset(innovations: &[InnovationRecord]) -> Option<(f64, f64)> {
    let mut best: Option<(f64, f64)> = None;
    cusum_walk(innovations, |start_t, _, s| {
        if *s > best.map_or(0.0, |b| b.1) {
            best = Some((start_t, *s));
        }
    });
    best.filter(|b| b.1 >= CUSUM_ALARM_NATS)
}

/// The CUSUM of [`cusum_onset`] over the settled used fixes: after each fix, `step(onset_t_s,
/// t_s, s)` with the first fix after the statistic's last zero, the fix's time and the
/// statistic (nats), which `step` may reset.
fn cusum_walk(innovations: &[InnovationRecord], mut step: impl FnMut(f64, f64, &mut f64)) {
    let lam = CUSUM_INFLATION;
    let mut s = 0.0f64;
    let mut start_t = f64::NAN;
    let used: Vec<&InnovationRecord> = innovations.iter().filter(|r| in_stats(r)).collect();
    let keep = settled(&used);
    for (r, k) in used.iter().zip(&keep) {
        if !*k {
            continue;
        }
        let (nis, d) = position_nis(r);
        let llr = 0.5 * nis * (1.0 - 1.0 / lam) - 0.5 * d as f64 * lam.ln();
        if s <= 0.0 {
            start_t = r.t_s;
        }
        s = (s + llr).max(0.0);
        step(start_t, r.t_s, &mut s);
    }
}

/// An alarm of the CUSUM restarted at each alarm ([`cusum_alarms`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CusumAlarm {
    /// First fix of the stretch that raised the alarm (after the statistic's last zero), s.
    pub onset_t_s: f64,
    /// The fix at which the statistic reached [`CUSUM_ALARM_NATS`], s.
    pub alarm_t_s: f64,
}

/// The alarms of the CUSUM of [`cusum_onset`] restarted at each alarm: the statistic is set
/// to zero at the fix where it reaches [`CUSUM_ALARM_NATS`] and runs on, so a change after
/// an early one (an effect that shows when the vehicle starts) raises an alarm of its own.
pub fn cusum_alarms(innovations: &[InnovationRecord]) -> Vec<CusumAlarm> {
    let mut out = Vec::new();
    cusum_walk(innovations, |start_t, t_s, s| {
        if *s >= CUSUM_ALARM_NATS {
            out.push(CusumAlarm {
                onset_t_s: start_t,
                alarm_t_s: t_s,
            });
            *s = 0.0;
        }
    });
    out
}

/// Whether the settled used fixes in `(from, onset)` are a consistent model before a step:
/// at least [`MIN_FIXES_BEFORE`] with a mean position NIS of at most [`MAX_NIS_BEFORE`].
fn consistent_before(used: &[&InnovationRecord], keep: &[bool], from: f64, onset: f64) -> bool {
    let before: Vec<f64> = used
        .iter()
        .zip(keep)
        .filter(|(r, k)| **k && r.t_s > from && r.t_s < onset)
        .map(|(r, _)| position_nis(r).0)
        .collect();
    before.len() >= MIN_FIXES_BEFORE
        && before.iter().sum::<f64>() / before.len() as f64 <= MAX_NIS_BEFORE
}

/// The onset a step is fitted from and the earliest time it may be placed at, s: the onset
/// of [`cusum_onset`] when the fixes before it are consistent (at least
/// [`MIN_FIXES_BEFORE`] settled used fixes with a mean position NIS of at most
/// [`MAX_NIS_BEFORE`]); otherwise the first alarm of the restarted CUSUM ([`cusum_alarms`]) whose fixes since the
/// alarm before it are consistent (an alarm too early to fit restarts the search; the step
/// is then placed after that alarm). None when no alarm is usable.
pub fn usable_onset(innovations: &[InnovationRecord]) -> Option<(f64, f64)> {
    let (onset, _) = cusum_onset(innovations)?;
    let used: Vec<&InnovationRecord> = innovations.iter().filter(|r| in_stats(r)).collect();
    let keep = settled(&used);
    if consistent_before(&used, &keep, f64::NEG_INFINITY, onset) {
        return Some((onset, f64::NEG_INFINITY));
    }
    let mut from = f64::NEG_INFINITY;
    for a in cusum_alarms(innovations) {
        if consistent_before(&used, &keep, from, a.onset_t_s) {
            return Some((a.onset_t_s, from));
        }
        from = a.alarm_t_s;
    }
    None
}

/// Time after a gap in the used fixes whose fixes the CUSUM and the consistency check before
/// the onset leave out, s: the filter's error grown across the gap shows in them.
pub const SETTLE_S: f64 = 10.0;

/// Per used fix (in time order), whether it is outside the [`SETTLE_S`] after a gap: two
/// consecutive used fixes more than 5 nominal intervals and 5 s apart
/// ([`super::validate::fix_gaps`]).
fn settled(used: &[&InnovationRecord]) -> Vec<bool> {
    let times: Vec<f64> = used.iter().map(|r| r.t_s).collect();
    let gaps = super::validate::fix_gaps(&times);
    let mut g = gaps.iter().peekable();
    let mut settle_until = f64::NEG_INFINITY;
    times
        .iter()
        .map(|&t| {
            while let Some(&&(_, end)) = g.peek() {
                if end > t {
                    break;
                }
                settle_until = end + SETTLE_S;
                g.next();
            }
            t >= settle_until
        })
        .collect()
}

/// The normalised squared position innovation of a fix (diagonal variances) and its dimension.
fn position_nis(r: &InnovationRecord) -> (f64, usize) {
    let d = r.dim.min(3);
    let nis = r
        .innovation
        .iter()
        .zip(&r.innovation_var)
        .take(d)
        .map(|(z, v)| z * z / v)
        .sum();
    (nis, d)
}

/// The fixes a fit uses: the used fixes (not withheld) at or after `t_from`.
fn fit_records(out: &RunOutput, t_from: f64) -> Vec<&InnovationRecord> {
    out.innovations
        .iter()
        .filter(|r| r.t_s >= t_from && in_stats(r))
        .collect()
}

/// Position innovations (3) and their weights of `out` at the times of `recs`.
fn innovations_at(out: &RunOutput, times: &[f64]) -> Vec<Option<[f64; 3]>> {
    let mut it = out.innovations.iter().peekable();
    times
        .iter()
        .map(|t| {
            while it.peek().is_some_and(|r| r.t_s < *t) {
                it.next();
            }
            it.peek()
                .filter(|r| r.t_s == *t && r.dim >= 3 && !matches!(r.used, FixUse::Invalid))
                .map(|r| [r.innovation[0], r.innovation[1], r.innovation[2]])
        })
        .collect()
}

fn run_ll(case: &Case, opts: &RunOptions) -> Option<(RunOutput, f64)> {
    let out = super::spill::run_innovations(case, &search_recording(opts)).ok()?;
    let ll = residual_stats(&out.innovations).log_likelihood;
    Some((out, ll))
}

/// The normal equations `(A, g)` of the weighted least squares of the innovations after
/// `t_s` in the step correction, linearised at the run `at` (correction `c0`) from the runs
/// with `c0 + probe e_j`: the Gauss-Newton step is `-A^-1 g`.
fn normal_equations(
    case: &Case,
    opts: &RunOptions,
    sensor: BiasStepSensor,
    t_s: f64,
    c0: &[f64; 3],
    at: &RunOutput,
) -> Option<(nalgebra::Matrix3<f64>, nalgebra::Vector3<f64>)> {
    let recs = fit_records(at, t_s);
    if recs.len() < 10 {
        return None;
    }
    let times: Vec<f64> = recs.iter().map(|r| r.t_s).collect();
    let h = sensor.probe();
    let cols: Vec<Vec<Option<[f64; 3]>>> = (0..3)
        .into_par_iter()
        .map(|j| {
            let mut c = *c0;
            c[j] += h;
            super::spill::run_innovations(
                &corrected(case, sensor, t_s, &c),
                &search_recording(opts),
            )
            .map(|o| innovations_at(&o, &times))
            .unwrap_or_default()
        })
        .collect();
    let mut a = nalgebra::Matrix3::<f64>::zeros();
    let mut g = nalgebra::Vector3::<f64>::zeros();
    for (k, r) in recs.iter().enumerate() {
        let js: Vec<[f64; 3]> = cols
            .iter()
            .filter_map(|c| c.get(k).copied().flatten())
            .collect();
        if js.len() != 3 {
            continue;
        }
        for (i, (nu, var)) in r
            .innovation
            .iter()
            .zip(&r.innovation_var)
            .take(3)
            .enumerate()
        {
            let (nu, w) = (*nu, 1.0 / var);
            let col = |j: usize| {
                js.get(j)
                    .and_then(|v| v.get(i))
                    .map_or(0.0, |x| (x - nu) / h)
            };
            let row = nalgebra::Vector3::new(col(0), col(1), col(2));
            a += row * row.transpose() * w;
            g += row * (w * nu);
        }
    }
    Some((a, g))
}

/// One Gauss-Newton step from the run `at` (correction `c0`): the correction minimising the
/// weighted innovations after `t_s` and its 1-sigma ([`normal_equations`]).
fn gauss_newton(
    case: &Case,
    opts: &RunOptions,
    sensor: BiasStepSensor,
    t_s: f64,
    c0: &[f64; 3],
    at: &RunOutput,
) -> Option<([f64; 3], [f64; 3])> {
    let (a, g) = normal_equations(case, opts, sensor, t_s, c0, at)?;
    let ai = a.try_inverse()?;
    let dc = -(ai * g);
    let c = [c0[0] + dc[0], c0[1] + dc[1], c0[2] + dc[2]];
    let sig = [0, 1, 2].map(|i| ai[(i, i)].max(0.0).sqrt());
    c.iter().all(|x| x.is_finite()).then_some((c, sig))
}

/// Fits a step of `sensor` at `t_s`: two Gauss-Newton iterations from the base run; returns
/// the step, its 1-sigma, and the corrected run's log-likelihood.
fn fit(
    case: &Case,
    opts: &RunOptions,
    base: &RunOutput,
    sensor: BiasStepSensor,
    t_s: f64,
) -> Option<([f64; 3], [f64; 3], f64)> {
    let (c1, _) = gauss_newton(case, opts, sensor, t_s, &[0.0; 3], base)?;
    let (r1, _) = run_ll(&corrected(case, sensor, t_s, &c1), opts)?;
    let (c2, s2) = gauss_newton(case, opts, sensor, t_s, &c1, &r1)?;
    let (_, ll2) = run_ll(&corrected(case, sensor, t_s, &c2), opts)?;
    Some((c2, s2, ll2))
}

/// The step `step` refitted at its time under another model `opts` (an effect added beside
/// it): two Gauss-Newton iterations from its magnitude, `at` being that model's run on the
/// data with `step` removed. Returns the step, its 1-sigma and the corrected run's
/// log-likelihood. A step fitted under a model that lacks an effect present throughout
/// absorbs part of that effect's misfit after the step time, and the effect then no longer
/// shows on the data with the step removed.
pub(crate) fn refit_magnitude(
    case: &Case,
    opts: &RunOptions,
    at: &RunOutput,
    step: &BiasStep,
) -> Option<([f64; 3], [f64; 3], f64)> {
    let (sensor, t_s) = (step.sensor, step.t_s);
    let (c1, _) = gauss_newton(case, opts, sensor, t_s, &step.step, at)?;
    let (r1, _) = run_ll(&corrected(case, sensor, t_s, &c1), opts)?;
    let (c2, s2) = gauss_newton(case, opts, sensor, t_s, &c1, &r1)?;
    let (_, ll2) = run_ll(&corrected(case, sensor, t_s, &c2), opts)?;
    Some((c2, s2, ll2))
}

/// The log-likelihood a step of `sensor` at `t_s` is predicted to gain over the run `base`
/// by the linearised innovations ([`normal_equations`] from no correction): `g^T A^-1 g / 2`,
/// nats.
fn predicted_gain(
    case: &Case,
    opts: &RunOptions,
    base: &RunOutput,
    sensor: BiasStepSensor,
    t_s: f64,
) -> Option<f64> {
    let (a, g) = normal_equations(case, opts, sensor, t_s, &[0.0; 3], base)?;
    let ai = a.try_inverse()?;
    let q = 0.5 * (g.transpose() * ai * g)[(0, 0)];
    q.is_finite().then_some(q)
}

/// The coarse back-scan of the step time from the earlier end `t_end` of a time scan whose
/// best time stayed there ([`time_scan`]): the times [`BACK_SCAN_STEP_S`] apart before
/// `t_end`, back over [`BACK_SCAN_S`] and after `from` (the alarm the CUSUM restarted after,
/// [`usable_onset`]), the step of `sensor` at each time by its predicted gain
/// ([`predicted_gain`]: three runs per time); the time of the largest, the step fitted there
/// ([`fit`]): `(step, 1-sigma, log-likelihood, time)`.
fn back_scan(
    case: &Case,
    opts: &RunOptions,
    base: &RunOutput,
    sensor: BiasStepSensor,
    (t_end, from): (f64, f64),
) -> Option<([f64; 3], [f64; 3], f64, f64)> {
    let n = (BACK_SCAN_S / BACK_SCAN_STEP_S).round() as i32;
    let times: Vec<f64> = (1..=n)
        .map(|k| t_end - f64::from(k) * BACK_SCAN_STEP_S)
        .filter(|&t| t > from)
        .collect();
    let (t_s, _) = times
        .into_par_iter()
        .filter_map(|t| predicted_gain(case, opts, base, sensor, t).map(|q| (t, q)))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    fit(case, opts, base, sensor, t_s).map(|(c, sg, ll)| (c, sg, ll, t_s))
}

/// The corrected run's log-likelihood `(t, ll)` with the step `step` of `sensor` moved from
/// `t_s` over [`first_scan`]'s offsets in 1 s steps, the scan extended by [`TIME_SEARCH_S`],
/// up to [`MAX_TIME_EXTENSIONS`] times, while its best time is at an end (the CUSUM's onset
/// lags a step whose position error grows slowly); and whether the best time is still at the
/// scan's earlier end after the extensions.
fn time_scan(
    case: &Case,
    opts: &RunOptions,
    sensor: BiasStepSensor,
    step: &[f64; 3],
    t_s: f64,
    gap: Option<(f64, f64)>,
) -> (Vec<(f64, f64)>, bool) {
    let n = TIME_SEARCH_S as i32;
    let ll_at = |k: i32| {
        let t = t_s + f64::from(k);
        run_ll(&corrected(case, sensor, t, step), opts).map(|(_, ll)| (t, ll))
    };
    let (mut lo_k, mut hi_k) = first_scan(t_s, gap);
    let mut profile: Vec<(f64, f64)> = (lo_k..=hi_k).into_par_iter().filter_map(ll_at).collect();
    let best_t = |p: &[(f64, f64)]| {
        p.iter()
            .copied()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|b| b.0)
    };
    for _ in 0..MAX_TIME_EXTENSIONS {
        let Some(tb) = best_t(&profile) else { break };
        let more: Vec<i32> = if tb <= t_s + f64::from(lo_k) {
            lo_k -= n;
            (lo_k..lo_k + n).collect()
        } else if tb >= t_s + f64::from(hi_k) {
            hi_k += n;
            (hi_k - n + 1..=hi_k).collect()
        } else {
            break;
        };
        profile.extend(more.into_par_iter().filter_map(ll_at).collect::<Vec<_>>());
    }
    let at_lower_end = best_t(&profile).is_some_and(|tb| tb <= t_s + f64::from(lo_k));
    (profile, at_lower_end)
}

/// The time a step is first fitted at, from the CUSUM onset `onset` and the used fixes: one
/// fix interval before the onset, or, when the onset is the first fix the CUSUM takes after a
/// gap in the used fixes (within [`SETTLE_S`] + 2 s of its end), the middle of the gap: the
/// step can be anywhere in it, and the time scan from there ([`TIME_SEARCH_S`] extended
/// [`MAX_TIME_EXTENSIONS`] times) covers a 60 s gap.
fn initial_step_time(used: &[&InnovationRecord], onset: f64) -> (f64, Option<(f64, f64)>) {
    let times: Vec<f64> = used.iter().map(|r| r.t_s).collect();
    let gap = super::validate::fix_gaps(&times)
        .into_iter()
        .find(|&(_, b)| b <= onset && onset <= b + SETTLE_S + 2.0);
    (gap.map_or(onset - 1.0, |(a, b)| 0.5 * (a + b)), gap)
}

/// The first time scan's offsets from the first fitted time `t_s`, s: +-[`TIME_SEARCH_S`],
/// or, for a step first fitted in a gap of the used fixes (`gap`), the whole gap and
/// [`TIME_SEARCH_S`] beyond its ends (the likelihood profile across a gap has local maxima:
/// the vehicle's manoeuvres change how a step shows).
fn first_scan(t_s: f64, gap: Option<(f64, f64)>) -> (i32, i32) {
    let n = TIME_SEARCH_S;
    gap.map_or((-n as i32, n as i32), |(a, b)| {
        (
            (a - t_s - n).floor().max(-600.0) as i32,
            (b - t_s + n).ceil().min(600.0) as i32,
        )
    })
}

/// The step `(step, 1-sigma, log-likelihood, time)` refitted at a time other than where its
/// magnitude was first fitted: the time scanned again ([`time_scan`]) with the refitted
/// magnitude and, when its best moves and is more likely, the magnitude refitted there
/// ([`fit`]). A step's magnitude and time trade off (a gyro step's attitude error grows as
/// the step times the time since it: a smaller step placed earlier), so the time found with
/// the magnitude fitted elsewhere is biased towards it.
fn rescan(
    case: &Case,
    opts: &RunOptions,
    base: &RunOutput,
    sensor: BiasStepSensor,
    (step, sigma, ll, t_s): ([f64; 3], [f64; 3], f64, f64),
) -> ([f64; 3], [f64; 3], f64, f64) {
    let (profile, _) = time_scan(case, opts, sensor, &step, t_s, None);
    let best = profile
        .into_iter()
        .filter(|p| p.0 != t_s && p.1 > ll)
        .max_by(|a, b| a.1.total_cmp(&b.1));
    let Some((t2, ll2)) = best else {
        return (step, sigma, ll, t_s);
    };
    fit(case, opts, base, sensor, t2)
        .filter(|f| f.2 >= ll2)
        .map_or((step, sigma, ll2, t2), |(c, sg, l)| (c, sg, l, t2))
}

/// Looks for a bias step in the data of `case` under the model `opts`, from the base run
/// `base` (its innovations): see the module notes. None when the CUSUM sees no change or the
/// corrected run does not pay.
pub fn find_bias_step(case: &Case, opts: &RunOptions, base: &RunOutput) -> Option<BiasStep> {
    find_bias_step_after(case, opts, base, f64::NEG_INFINITY)
}

/// The end of the stretch a step was found from, s ([`find_bias_step_after`] with it gives
/// the next candidate): the step's time or the first alarm of the restarted CUSUM
/// ([`cusum_alarms`]) at or after the step's onset, whichever is later (the last fix when no
/// alarm follows the onset).
pub fn stretch_end(innovations: &[InnovationRecord], step: &BiasStep) -> f64 {
    let alarm = cusum_alarms(innovations)
        .into_iter()
        .map(|a| a.alarm_t_s)
        .find(|&t| t >= step.onset_t_s)
        .or_else(|| innovations.last().map(|r| r.t_s))
        .unwrap_or(f64::INFINITY);
    alarm.max(step.t_s)
}

/// [`usable_onset`] on the fixes after `after` (s) only: the onset and the earliest time the
/// step may be placed at (not before `after`).
pub fn usable_onset_after(innovations: &[InnovationRecord], after: f64) -> Option<(f64, f64)> {
    if after == f64::NEG_INFINITY {
        return usable_onset(innovations);
    }
    let later: Vec<InnovationRecord> = innovations
        .iter()
        .filter(|r| r.t_s > after)
        .copied()
        .collect();
    let (onset, from) = usable_onset(&later)?;
    Some((onset, from.max(after)))
}

/// [`find_bias_step`] with the change point looked for in the fixes after `after` (s) only:
/// the CUSUM and the consistency check before the onset see none before it, and the step is
/// placed after it. A step refused on the held-out windows (a constant effect's misfit that
/// a step absorbs for a while) ends its stretch ([`stretch_end`]); a later true step raises
/// an alarm of its own there.
pub fn find_bias_step_after(
    case: &Case,
    opts: &RunOptions,
    base: &RunOutput,
    after: f64,
) -> Option<BiasStep> {
    let (onset, from) = usable_onset_after(&base.innovations, after)?;
    let used: Vec<&InnovationRecord> = base.innovations.iter().filter(|r| in_stats(r)).collect();
    let t0 = case.imu.first_t_s()?;
    let rs = residual_stats(&base.innovations);
    let base_ll = rs.log_likelihood;
    let penalty = 0.5 * 4.0 * (rs.scalar_measurements.max(2) as f64).ln();
    // the step is placed one fix interval before the first fix that shows it, or in the
    // middle of the gap that fix follows
    let (t_start, gap) = initial_step_time(&used, onset);
    let (sensor, mut step, mut sigma, mut ll, mut t_s) = BiasStepSensor::ALL
        .par_iter()
        .filter_map(|&s| {
            fit(case, opts, base, s, t_start).map(|(c, sg, ll)| (s, c, sg, ll, t_start))
        })
        .max_by(|a, b| a.3.total_cmp(&b.3))?;
    if ll - base_ll <= penalty + MIN_GAIN_NATS {
        return None;
    }
    // the time: the corrected run's likelihood over +-TIME_SEARCH_S in 1 s steps, extended
    // by TIME_SEARCH_S while the best time is at an end of the scan (the CUSUM's onset lags
    // a step whose position error grows slowly)
    let (mut profile, at_lower_end) = time_scan(case, opts, sensor, &step, t_s, gap);
    // still rising at the scan's earlier end: the onset lags the step by more than the
    // extensions reach; the step time scanned back coarsely from there
    let ll_scan = profile
        .iter()
        .map(|p| p.1)
        .fold(f64::NEG_INFINITY, f64::max);
    if at_lower_end {
        let lo_t = profile.iter().map(|p| p.0).fold(f64::INFINITY, f64::min);
        let back = back_scan(case, opts, base, sensor, (lo_t, from)).filter(|f| f.2 > ll_scan);
        if let Some(f) = back {
            (step, sigma, ll, t_s) = f;
            (profile, _) = time_scan(case, opts, sensor, &step, t_s, None);
        }
    }
    let (t_best, ll_best) = profile
        .iter()
        .copied()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap_or((t_s, ll));
    // sharp in time: the best time moved by the sensor's span either way loses at least
    // MIN_SHARPNESS_NATS (the profile's value there when the run fails)
    let at = |t: f64| {
        profile
            .iter()
            .min_by(|a, b| (a.0 - t).abs().total_cmp(&(b.0 - t).abs()))
            .map_or(f64::INFINITY, |p| p.1)
    };
    // moved by the sensor's span either way; a step inside a gap of the used fixes can only
    // be placed within the gap: moved by the span beyond the gap's ends
    let used: Vec<f64> = used.iter().map(|r| r.t_s).collect();
    let span = sensor.sharpness_span_s();
    let (lo_t, hi_t) = super::validate::fix_gaps(&used)
        .into_iter()
        .find(|&(a, b)| a < t_best && t_best < b)
        .map_or((t_best - span, t_best + span), |(a, b)| {
            (a - span, b + span)
        });
    let ll_or_profile = |t: f64| {
        run_ll(&corrected(case, sensor, t, &step), opts).map_or_else(|| at(t), |(_, ll)| ll)
    };
    let (lo, hi) = (ll_or_profile(lo_t), ll_or_profile(hi_t));
    if ll_best - lo.max(hi) < MIN_SHARPNESS_NATS {
        return None;
    }
    // refit the magnitude at the chosen time, then the time with that magnitude
    let (step, sigma, ll, t_best) = if t_best != t_s {
        let (step, sigma, ll) = fit(case, opts, base, sensor, t_best)
            .filter(|f| f.2 >= ll_best)
            .unwrap_or((step, sigma, ll_best));
        rescan(case, opts, base, sensor, (step, sigma, ll, t_best))
    } else {
        (step, sigma, ll, t_best)
    };
    Some(BiasStep {
        sensor,
        name: sensor.name().to_string(),
        t_s: t_best,
        t_rel_s: t_best - t0,
        onset_t_s: onset,
        step,
        sigma,
        magnitude: step.iter().map(|x| x * x).sum::<f64>().sqrt(),
        unit: sensor.unit().to_string(),
        delta_log_likelihood: ll - base_ll,
        bic_penalty: penalty,
        heldout: None,
        reason: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::imu_cache::ImuCache;
    use nav_core::types::ImuSample;
    use nav_engine::run::CaseData;

    fn rec(t_s: f64, z: f64) -> InnovationRecord {
        InnovationRecord {
            t_s,
            used: FixUse::Accepted,
            outage: None,
            dim: 3,
            innovation: [z, -z, z, 0.0, 0.0, 0.0],
            innovation_var: [1.0, 1.0, 1.0, 0.0, 0.0, 0.0],
            nis: 3.0 * z * z,
            nis_threshold: 16.0,
            quality: 4,
        }
    }

    #[test]
    fn cusum_places_the_onset_at_the_first_inflated_fix() {
        // unit-variance innovations up to 100 s, three times larger from 100 s on
        let mut v: Vec<InnovationRecord> = (0..100)
            .map(|k| rec(f64::from(k), if k % 2 == 0 { 1.0 } else { -0.8 }))
            .collect();
        v.extend((100..130).map(|k| rec(f64::from(k), 3.0)));
        let (onset, peak) = cusum_onset(&v).unwrap();
        assert_eq!(onset, 100.0);
        // 30 fixes of llr 0.5 * 27 * 0.75 - 1.5 ln 4
        let llr = 0.5 * 27.0 * 0.75 - 1.5 * 4f64.ln();
        assert!((peak - 30.0 * llr).abs() < 1e-9, "{peak}");
        // white innovations only: no alarm
        assert!(cusum_onset(&v[..100]).is_none());
    }

    #[test]
    fn cusum_leaves_out_the_fixes_just_after_a_gap() {
        // white innovations at 1 Hz, a 60 s gap, five fixes three times larger within
        // SETTLE_S of its end (the prediction error across the gap), then white again
        let white = |k: i32| rec(f64::from(k), if k % 2 == 0 { 1.0 } else { -0.8 });
        let mut v: Vec<InnovationRecord> = (0..100).map(white).collect();
        v.extend((160..165).map(|k| rec(f64::from(k), 3.0)));
        v.extend((165..260).map(white));
        assert!(cusum_onset(&v).is_none());
        // the same five fixes without the gap: a change
        let mut w: Vec<InnovationRecord> = (0..100).map(white).collect();
        w.extend((100..105).map(|k| rec(f64::from(k), 3.0)));
        assert_eq!(cusum_onset(&w).map(|o| o.0), Some(100.0));
    }

    #[test]
    fn an_alarm_too_early_to_fit_restarts_the_search() {
        // inflated innovations over the first 6 fixes (an effect that shows when the vehicle
        // starts), white ones to 200 s, inflated again from 200 s on (the step)
        let white = |k: i32| rec(f64::from(k), if k % 2 == 0 { 1.0 } else { -0.8 });
        let mut v: Vec<InnovationRecord> = (0..6).map(|k| rec(f64::from(k), 20.0)).collect();
        v.extend((6..200).map(white));
        v.extend((200..240).map(|k| rec(f64::from(k), 3.0)));
        // the peak stretch starts at the first fix (the early fixes' 2690 nats decay by about
        // 1.2 nats a white fix): no fixes before it
        let (onset, _) = cusum_onset(&v).unwrap();
        assert_eq!(onset, 0.0);
        // restarted at each alarm: one alarm per early fix, then the step's
        let alarms = cusum_alarms(&v);
        let early: Vec<f64> = alarms.iter().take(6).map(|a| a.alarm_t_s).collect();
        assert_eq!(early, [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(
            alarms.get(6),
            Some(&CusumAlarm {
                onset_t_s: 200.0,
                alarm_t_s: 203.0
            })
        );
        // the first usable alarm: the step's, the step placed after the last early alarm
        assert_eq!(usable_onset(&v), Some((200.0, 5.0)));
        // a usable peak onset is kept as it was
        let mut w: Vec<InnovationRecord> = (0..100).map(white).collect();
        w.extend((100..130).map(|k| rec(f64::from(k), 3.0)));
        assert_eq!(usable_onset(&w), Some((100.0, f64::NEG_INFINITY)));
        // only the early alarm: nothing usable
        assert!(usable_onset(&v[..200]).is_none());
    }

    #[test]
    fn a_refused_stretch_ends_and_the_next_onset_is_looked_for_after_it() {
        // a strong misfit from 100 s to 130 s (the CUSUM's peak), white to 400 s, a weaker
        // change from 400 s on (the step)
        let white = |k: i32| rec(f64::from(k), if k % 2 == 0 { 1.0 } else { -0.8 });
        let mut v: Vec<InnovationRecord> = (0..100).map(white).collect();
        v.extend((100..130).map(|k| rec(f64::from(k), 5.0)));
        v.extend((130..400).map(white));
        v.extend((400..440).map(|k| rec(f64::from(k), 3.0)));
        assert_eq!(usable_onset(&v), Some((100.0, f64::NEG_INFINITY)));
        // the step fitted there and refused: its stretch ends at the first alarm after its
        // onset (each misfit fix alone passes the alarm level)
        let refused = BiasStep {
            sensor: BiasStepSensor::Gyro,
            name: BiasStepSensor::Gyro.name().into(),
            t_s: 99.0,
            t_rel_s: 99.0,
            onset_t_s: 100.0,
            step: [0.0; 3],
            sigma: [1.0; 3],
            magnitude: 0.0,
            unit: BiasStepSensor::Gyro.unit().into(),
            delta_log_likelihood: 0.0,
            bic_penalty: 0.0,
            heldout: None,
            reason: None,
        };
        let end = stretch_end(&v, &refused);
        assert_eq!(end, 100.0);
        // after it: the misfit's own alarms have no consistent fixes before them, the step's
        // has, placed after the misfit's last alarm
        assert_eq!(usable_onset_after(&v, end), Some((400.0, 129.0)));
        assert_eq!(usable_onset_after(&v, f64::NEG_INFINITY), usable_onset(&v));
    }

    #[test]
    fn correction_removes_the_step_from_the_samples_after_it() {
        let imu: Vec<ImuSample> = (0..10)
            .map(|k| ImuSample {
                t_s: 100.0 + 0.1 * f64::from(k),
                dtheta_rad: [0.0; 3],
                dv_mps: [1.0, 0.0, 0.0],
                temperature_c: f64::NAN,
            })
            .collect();
        let data = CaseData {
            imu,
            ..CaseData::default()
        };
        let folder = crate::spill::temp_folder().unwrap();
        let cache = ImuCache::from_case(&folder, &data).unwrap();
        let case = Case::new(data, std::sync::Arc::new(cache));
        let c = corrected(&case, BiasStepSensor::Accel, 100.45, &[2.0, 0.0, -1.0]);
        let samples: Vec<ImuSample> = c.imu.samples_from(0).collect();
        assert_eq!(samples.len(), 10);
        for (k, s) in samples.iter().enumerate() {
            // sample k covers (t_k - 0.1, t_k]: corrected when it starts at or after 100.45
            let start = 100.0 + 0.1 * (k as f64 - 1.0);
            if k > 0 && start >= 100.45 {
                assert!((s.dv_mps[0] - 0.8).abs() < 1e-12 && (s.dv_mps[2] - 0.1).abs() < 1e-12);
            } else {
                assert_eq!(s.dv_mps, [1.0, 0.0, 0.0]);
            }
            assert_eq!(s.dtheta_rad, [0.0; 3]);
        }
    }
}
