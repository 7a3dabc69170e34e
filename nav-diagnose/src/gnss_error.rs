//! The prior of the GNSS error state candidate (`gnss_position_gm`), fitted by likelihood
//! jointly with the part of the GNSS white-noise scale the state explains.
//!
//! A Gauss-Markov error of the fixes is a noise model: its sigma and correlation time decide
//! what the state does, and a prior far from the error's own makes the model worse than none.
//! With the default prior (0.5 m horizontal, 1 m vertical, 300 s) beside fixes that carry
//! 5-15 cm with 100-300 s, the state's driving noise is 4-10 times the error's: it follows the
//! white noise of each fix (lag-1 autocorrelation of the normalised innovations -0.17 to
//! -0.40), and loses 71-378 nats against the GNSS noise scale, while at the error's own sigma
//! and correlation time it gains 13-139 nats and whitens the innovations (Ljung-Box Q over
//! 10 lags 99-165 -> 10-16; 10-minute drives, `diagnose_gnss_gm.rs`). So the candidate's
//! sigma (a factor on the default prior) and correlation time are fitted by the innovation
//! likelihood, jointly with a factor on the current GNSS sigma scale: the fixes' white noise
//! beside the error (a model without the state fits it as a larger white noise, nested in
//! the joint model), and a noise scale adopted before the state covers the error's increments,
//! which the state then explains (the configuration's scale is the floor, as for the noise
//! scale itself).
use super::*;
use nav_core::config::{EffectsConfig, GnssErrorNoise};
use nav_engine::run::InnovationRecord;
use stats::in_stats;

/// Grid of the factor on the default prior's horizontal sigma: `2^(k/2)`, k = -12..=4 (0.5 m
/// -> 7.8 mm .. 2 m); the climb starts at 1.
const SIGMA_STEPS: std::ops::RangeInclusive<i32> = -12..=4;
/// Grid of the factor on the default prior's vertical-to-horizontal ratio (2): `2^(k/2)`,
/// k = -4..=2 (ratio 0.5 .. 4).
const RATIO_STEPS: std::ops::RangeInclusive<i32> = -4..=2;
/// Grid of the correlation time, s: `300 * 2^(k/2)`, k = -6..=4 (37.5 .. 1200 s).
const TAU_STEPS: std::ops::RangeInclusive<i32> = -6..=4;
/// Grid of the factor on the current GNSS sigma scale: `2^(k/4)`, k = -8..=12 (1/4 .. 8),
/// kept at or above the configuration's scale; climbed two steps at a time, then refined by
/// one.
const WHITE_STEPS: std::ops::RangeInclusive<i32> = -8..=12;
/// Hyperparameters the fit chooses (horizontal sigma, vertical ratio, correlation time,
/// white-noise factor): the fitted candidate's BIC penalty counts these, not its three
/// states (a random process the filter integrates out of the innovation likelihood).
pub const FITTED_PARAMS: usize = 4;

/// A point of the fit's grids: indices of horizontal sigma, vertical ratio, correlation time,
/// white-noise factor.
type At = [i32; 4];

/// The fitted prior of a GNSS error state candidate and the factor on the GNSS sigma scale
/// that goes with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GnssErrorFit {
    /// Per-axis sigma of the Gauss-Markov error, m (N, E, D).
    pub sigma_m: [f64; 3],
    /// Correlation time, s.
    pub t_s: f64,
    /// Factor on the current model's GNSS sigma scale (horizontal and vertical).
    pub white_factor: f64,
    /// Log-likelihood of the candidate's run at the fit, nats.
    pub log_likelihood: f64,
    /// Runs the fit made (memoised runs included).
    pub runs: usize,
    /// True when the screen stopped the fit ([`fit`]): the prior is the better screen point,
    /// which gains nothing over the current model.
    pub screened: bool,
    /// The nested model without the state: the best factor on the current GNSS sigma scale
    /// for the current model alone and its log-likelihood, nats ([`white_only`]; None when
    /// the screen stopped the fit).
    pub white_only: Option<(f64, f64)>,
    /// Grid indices of the fit.
    at: At,
}

impl GnssErrorFit {
    /// The fit at grid point `k`.
    fn at(k: At) -> Self {
        let d = EffectsConfig::default().gnss_position_gm;
        let f = 2f64.powf(f64::from(k[0]) / 2.0);
        let r = 2f64.powf(f64::from(k[1]) / 2.0);
        Self {
            sigma_m: [d.sigma_m[0] * f, d.sigma_m[1] * f, d.sigma_m[2] * f * r],
            t_s: d.t_s * 2f64.powf(f64::from(k[2]) / 2.0),
            white_factor: 2f64.powf(f64::from(k[3]) / 4.0),
            log_likelihood: f64::NAN,
            runs: 0,
            screened: false,
            white_only: None,
            at: k,
        }
    }

    /// Puts the fitted prior and white-noise factor into the options of a model that carries
    /// the GNSS error state.
    pub fn apply(&self, o: &mut RunOptions) {
        o.filter.effects.gnss_position_gm = GnssErrorNoise {
            sigma_m: self.sigma_m,
            t_s: self.t_s,
        };
        o.gnss_sigma_scale.horizontal *= self.white_factor;
        o.gnss_sigma_scale.vertical *= self.white_factor;
    }

    /// The log-likelihood the state gains beyond the GNSS noise scale alone (the fit against
    /// [`GnssErrorFit::white_only`]), nats; None when the screen stopped the fit.
    pub fn gain_beyond_noise_scale(&self) -> Option<f64> {
        self.white_only.map(|(_, l)| self.log_likelihood - l)
    }

    /// The fit in words: sigma (cm), correlation time, the white-noise factor.
    pub fn describe(&self) -> String {
        let nested = self.white_only.map_or(String::new(), |(w, l)| {
            format!(
                "; without the state GNSS sigma scale x{w:.2}: {:.1} nats below",
                self.log_likelihood - l
            )
        });
        format!(
            "prior {}: {:.1}/{:.1}/{:.1} cm, {:.0} s, GNSS sigma scale x{:.2} ({} runs{nested})",
            if self.screened {
                "not fitted (no screen point gains over the current model)"
            } else {
                "fitted"
            },
            self.sigma_m[0] * 100.0,
            self.sigma_m[1] * 100.0,
            self.sigma_m[2] * 100.0,
            self.t_s,
            self.white_factor,
            self.runs
        )
    }
}

/// The current model's side of a fit: its innovations (the search run's) and their
/// log-likelihood, nats.
pub(crate) struct Current<'a> {
    /// Innovation records of the current model's search run.
    pub(crate) innovations: &'a [InnovationRecord],
    /// Their log-likelihood ([`residual_stats`]), nats.
    pub(crate) log_likelihood: f64,
}

/// Fits the prior of the GNSS error state in the model `with_state` (the current model with
/// the block appended, as the search runs it) by the likelihood of its innovations.
///
/// First a screen of one or two runs: the state nearly absent (the bottom of the sigma grid)
/// and at the moment estimate of its horizontal sigma ([`sigma_start`], from the current
/// model's innovations), each with the previous round's vertical ratio and correlation time
/// (`from`, or the default prior's) at the current GNSS sigma scale. When neither run's
/// log-likelihood is above the current model's, the innovations carry no correlated misfit
/// for the state to take and the better screen point is the fit (on the sweep's drives the
/// whole climb then gained at most 2 nats, against a penalty of 23 or more). Otherwise a
/// climb from the best of `from` (or the default prior) and the screen points: over the
/// white-noise factor (steps of 2^(1/2)) with the horizontal sigma climbed at every point (a
/// lower white noise pays only with a larger Gauss-Markov sigma, a ridge a climb one
/// coordinate at a time does not follow), then the correlation time, the white-noise factor
/// refined (steps of 2^(1/4)), the vertical ratio and the horizontal sigma once more. Every
/// grid point is run once ([`Points`]); each coordinate is probed first in the direction it
/// last moved in ([`climb`]).
/// `floor`: the smallest white-noise factor (the configuration's sigma scale over the
/// current one, per component, the larger). After a climb, the nested model without the
/// state (`without_state`, the current model) is fitted over the white-noise factor alone
/// ([`white_only`]).
pub(crate) fn fit(
    ctx: &Ctx<'_>,
    (with_state, without_state): (&RunOptions, &RunOptions),
    floor: f64,
    from: Option<&GnssErrorFit>,
    current: &Current<'_>,
) -> Option<GnssErrorFit> {
    let run = |k: At| -> f64 { innovation_log_likelihood(ctx, with_state, &GnssErrorFit::at(k)) };
    let white_min = (4.0 * floor.max(1e-9).log2()).ceil() as i32;
    let ranges = [
        SIGMA_STEPS,
        RATIO_STEPS,
        TAU_STEPS,
        *WHITE_STEPS.start().max(&white_min)..=*WHITE_STEPS.end(),
    ];
    let clamp = |mut k: At| {
        for (a, r) in k.iter_mut().zip(&ranges) {
            *a = (*a).clamp(*r.start(), *r.end());
        }
        k
    };
    let prev = from.map(|f| f.at);
    let [_, ratio, tau, _] = prev.unwrap_or([0; 4]);
    // the screen: the state nearly absent (the bottom of the sigma grid) and at the moment
    // estimate of its sigma, at the current GNSS sigma scale
    let bottom = clamp([*SIGMA_STEPS.start(), ratio, tau, 0]);
    let moment = clamp([sigma_start(current.innovations), ratio, tau, 0]);
    let pts = Points::new(&run);
    if moment == bottom {
        pts.remember(bottom, run(bottom));
    } else {
        let (b, m) = rayon::join(|| run(bottom), || run(moment));
        pts.remember(bottom, b);
        pts.remember(moment, m);
    }
    let (at, screen) = pts.best()?;
    if screen <= current.log_likelihood {
        return Some(GnssErrorFit {
            log_likelihood: screen,
            runs: pts.runs(),
            screened: true,
            ..GnssErrorFit::at(at)
        });
    }
    let point = |k: At| pts.ll(k);
    // the horizontal sigma climbed at the white-noise factor of a point
    let sigma_at = |cur: (At, f64)| climb(cur, (0, 1), &ranges[0], &pts, &point);
    let sigma = |k: At| sigma_at(pts.ll(k));
    // the climb starts where the previous fit (or the default prior) or a screen point is best
    let first = pts.ll(clamp(prev.unwrap_or([0; 4])));
    let start = if first.1 >= screen {
        first
    } else {
        (at, screen)
    };
    let mut best = climb(sigma_at(start), (3, 2), &ranges[3], &pts, &sigma);
    // then the correlation time, the white-noise factor refined, the vertical ratio and the
    // horizontal sigma
    for (axis, stride) in [(2, 1), (3, 1), (1, 1), (0, 1)] {
        best = climb(best, (axis, stride), &ranges[axis], &pts, &point);
    }
    let (at, best) = best;
    if !best.is_finite() {
        return None;
    }
    let (white, white_runs) = white_only(ctx, without_state, &ranges[3], at[3], current);
    Some(GnssErrorFit {
        log_likelihood: best,
        runs: pts.runs() + white_runs,
        white_only: Some(white),
        ..GnssErrorFit::at(at)
    })
}

/// The log-likelihood of the innovations (nats) of a search run of `o` with the fit's prior
/// and white-noise factor applied (the prior is unused when `o` has no GNSS error state).
fn innovation_log_likelihood(ctx: &Ctx<'_>, o: &RunOptions, fit: &GnssErrorFit) -> f64 {
    let mut o = ctx.searching(o);
    // the likelihood reads the used fixes' innovations only: no epoch records, no predicted
    // withheld fixes
    o.record.epoch_rate_hz = Some(0.0);
    fit.apply(&mut o);
    spill::run_innovations(&ctx.p.case, &o).map_or(f64::NAN, |out| {
        residual_stats(&out.innovations).log_likelihood
    })
}

/// The nested model of a fit: the current model (`without_state`) with only the factor on
/// its GNSS sigma scale fitted, climbed from the fit's factor (grid index `from`, steps of
/// 2^(1/4) within `range`; factor 1 is the current model, `current`). A white-noise scale
/// is part of the noise model, so the state is named only for what it gains beyond this
/// model (`round::beyond_noise_scale`): on drives whose fixes carry white noise 3-8 times the
/// declared sigmas and nothing else the fitted state took the scale's thousands of nats and
/// was named in its place. Returns the best factor with its log-likelihood (nats) and the
/// runs made.
fn white_only(
    ctx: &Ctx<'_>,
    without_state: &RunOptions,
    range: &std::ops::RangeInclusive<i32>,
    from: i32,
    current: &Current<'_>,
) -> ((f64, f64), usize) {
    let run =
        |k: At| -> f64 { innovation_log_likelihood(ctx, without_state, &GnssErrorFit::at(k)) };
    let pts = Points::new(&run);
    if range.contains(&0) {
        pts.remember([0; 4], current.log_likelihood);
    }
    let start = pts.ll([0, 0, 0, from.clamp(*range.start(), *range.end())]);
    climb(start, (3, 1), range, &pts, &|k| pts.ll(k));
    let best = pts.best().map_or((1.0, current.log_likelihood), |(k, l)| {
        (GnssErrorFit::at(k).white_factor, l)
    });
    (best, pts.runs() - usize::from(range.contains(&0)))
}

/// The grid points a fit has run, each once: their log-likelihoods (nats) by point, and the
/// direction each coordinate last moved in (a climb probes it first).
struct Points<'a> {
    /// The run of a point: its log-likelihood, nats (NaN when the run failed).
    run: &'a dyn Fn(At) -> f64,
    /// Points run and their log-likelihoods.
    seen: std::cell::RefCell<Vec<(At, f64)>>,
    /// Per coordinate, the direction (+1 or -1) of its last gaining move.
    dir: std::cell::Cell<At>,
}

impl<'a> Points<'a> {
    fn new(run: &'a dyn Fn(At) -> f64) -> Self {
        Self {
            run,
            seen: Default::default(),
            dir: std::cell::Cell::new([1; 4]),
        }
    }

    /// Records the log-likelihood `l` of point `k`, run outside.
    fn remember(&self, k: At, l: f64) {
        self.seen.borrow_mut().push((k, l));
    }

    /// The log-likelihood of point `k`: remembered, or run.
    fn ll(&self, k: At) -> (At, f64) {
        let known = self.seen.borrow().iter().find(|p| p.0 == k).map(|p| p.1);
        let l = known.unwrap_or_else(|| {
            let l = (self.run)(k);
            self.remember(k, l);
            l
        });
        (k, l)
    }

    /// The best point run (finite log-likelihood).
    fn best(&self) -> Option<(At, f64)> {
        self.seen
            .borrow()
            .iter()
            .copied()
            .filter(|p| p.1.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// Points run.
    fn runs(&self) -> usize {
        self.seen.borrow().len()
    }
}

/// The screen's horizontal sigma as a grid index of [`SIGMA_STEPS`]: a Gauss-Markov error of
/// correlation time `T` beside white noise makes the position innovations of consecutive
/// fixes (`dt` << `T`) covary by about its variance, while a white error makes them
/// uncorrelated; so the sigma is the square root of the lag-1 autocovariance of the
/// horizontal position innovations (N and E averaged; pairs of the used fixes at most 1.5
/// times the median spacing apart), rounded to the grid (its bottom when the autocovariance
/// is not positive or there are fewer than 3 such pairs).
pub(crate) fn sigma_start(innovations: &[InnovationRecord]) -> i32 {
    let used: Vec<&InnovationRecord> = innovations.iter().filter(|r| in_stats(r)).collect();
    let mut dts: Vec<f64> = used.windows(2).map(|w| w[1].t_s - w[0].t_s).collect();
    dts.sort_by(f64::total_cmp);
    let Some(&median) = dts.get(dts.len() / 2) else {
        return *SIGMA_STEPS.start();
    };
    let pairs: Vec<[&InnovationRecord; 2]> = used
        .windows(2)
        .filter(|w| w[1].t_s - w[0].t_s <= 1.5 * median)
        .map(|w| [w[0], w[1]])
        .collect();
    if pairs.len() < 3 {
        return *SIGMA_STEPS.start();
    }
    let n = pairs.len() as f64;
    let cov = |c: usize| {
        let mean = used.iter().map(|r| r.innovation[c]).sum::<f64>() / used.len() as f64;
        pairs
            .iter()
            .map(|[a, b]| (a.innovation[c] - mean) * (b.innovation[c] - mean))
            .sum::<f64>()
            / n
    };
    let var = 0.5 * (cov(0) + cov(1));
    let default = EffectsConfig::default().gnss_position_gm.sigma_m[0];
    if !(var > 0.0 && default > 0.0) {
        return *SIGMA_STEPS.start();
    }
    // sigma = default * 2^(k/2): k = 2 log2(sigma / default) = log2(var / default^2)
    let k = (var / (default * default)).log2().round();
    k.clamp(
        f64::from(*SIGMA_STEPS.start()),
        f64::from(*SIGMA_STEPS.end()),
    ) as i32
}

/// One coordinate of a climb: from `cur` (a point and its log-likelihood), the neighbour
/// `stride` grid steps away along `axis` in the direction the coordinate last moved in
/// (`pts`), the other neighbour only when that one does not gain, then onwards from the one
/// that gains while the log-likelihood rises, within `range`. `ll` gives a point's
/// log-likelihood and the point it reached (an inner climb may move the other coordinates).
/// Returns the best point and its log-likelihood.
fn climb(
    cur: (At, f64),
    (axis, stride): (usize, i32),
    range: &std::ops::RangeInclusive<i32>,
    pts: &Points<'_>,
    ll: &dyn Fn(At) -> (At, f64),
) -> (At, f64) {
    let moved = |k: At, d: i32| {
        let mut k = k;
        k[axis] += d * stride;
        range.contains(&k[axis]).then_some(k)
    };
    let gain = |d: i32| {
        moved(cur.0, d)
            .map(ll)
            .filter(|(_, l)| l.is_finite() && *l > cur.1)
            .map(|p| (p, d))
    };
    let first = pts.dir.get().get(axis).copied().unwrap_or(1);
    let Some((mut best, step)) = gain(first).or_else(|| gain(-first)) else {
        return cur;
    };
    let mut dir = pts.dir.get();
    if let Some(d) = dir.get_mut(axis) {
        *d = step;
    }
    pts.dir.set(dir);
    while let Some(k) = moved(best.0, step) {
        let next = ll(k);
        if !(next.1.is_finite() && next.1 > best.1) {
            break;
        }
        best = next;
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use nav_engine::run::FixUse;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    /// Innovation records at 1 Hz of N and E position innovations `x` (m), used.
    fn records(x: &[[f64; 2]]) -> Vec<InnovationRecord> {
        x.iter()
            .enumerate()
            .map(|(i, v)| InnovationRecord {
                t_s: i as f64,
                used: FixUse::Accepted,
                outage: None,
                dim: 3,
                innovation: [v[0], v[1], 0.0, 0.0, 0.0, 0.0],
                innovation_var: [1e-4, 1e-4, 4e-4, 0.0, 0.0, 0.0],
                nis: 1.0,
                nis_threshold: f64::NAN,
                quality: 1,
            })
            .collect()
    }

    #[test]
    fn sigma_start_is_the_bottom_for_white_innovations_and_near_a_gauss_markov_sigma() {
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut n = || -> f64 { StandardNormal.sample(&mut r) };
        // 2,400 fixes of 3 cm white noise: the lag-1 autocovariance is noise, |c1| about
        // 9e-4 / 49 m^2, below the grid's smallest sigma squared (7.8 mm: 6.1e-5 m^2)
        let white: Vec<[f64; 2]> = (0..2400).map(|_| [0.03 * n(), 0.03 * n()]).collect();
        assert!(sigma_start(&records(&white)) <= -11);
        // a Gauss-Markov error of 10 cm and 300 s beside the same white noise: sigma
        // 0.5 * 2^(k/2) = 0.1 m at k = -4.6
        let phi = (-1.0f64 / 300.0).exp();
        let q = 0.1 * (1.0 - phi * phi).sqrt();
        let mut gm = [0.1 * n(), 0.1 * n()];
        let correlated: Vec<[f64; 2]> = (0..2400)
            .map(|_| {
                gm = [phi * gm[0] + q * n(), phi * gm[1] + q * n()];
                [gm[0] + 0.03 * n(), gm[1] + 0.03 * n()]
            })
            .collect();
        let k = sigma_start(&records(&correlated));
        assert!((-7..=-3).contains(&k), "{k}");
    }

    #[test]
    fn climb_reaches_the_maximum_along_a_coordinate_with_each_point_run_once() {
        // one maximum along the axis, at 5: from -6 the neighbour in the direction last moved
        // in (+1) gains, so the other is not run: -5..=6 beside the start
        let runs = std::cell::Cell::new(0);
        let f = |k: At| -> f64 {
            runs.set(runs.get() + 1);
            -f64::from((k[0] - 5) * (k[0] - 5))
        };
        let pts = Points::new(&f);
        let ll = |k: At| pts.ll(k);
        let start = pts.ll([-6, 0, 0, 0]);
        let best = climb(start, (0, 1), &(-12..=8), &pts, &ll);
        assert_eq!(best, ([5, 0, 0, 0], 0.0));
        assert_eq!(pts.runs(), 13);
        assert_eq!(runs.get(), pts.runs());
        // at the maximum: both neighbours known, nothing run again
        let again = climb(best, (0, 1), &(-12..=8), &pts, &ll);
        assert_eq!(again.0, [5, 0, 0, 0]);
        assert_eq!(runs.get(), 13);
        // the maximum at the range's end, below the start: +1 tried first and lost, then -1
        let g = |k: At| -> f64 { -f64::from(k[2] + 6).abs() };
        let down = Points::new(&g);
        let ll = |k: At| down.ll(k);
        let best = climb(down.ll([0, 0, 3, 0]), (2, 1), &(-6..=4), &down, &ll);
        assert_eq!(best.0, [0, 0, -6, 0]);
        assert_eq!(down.dir.get()[2], -1);
        assert_eq!(down.runs(), 11);
    }
}
