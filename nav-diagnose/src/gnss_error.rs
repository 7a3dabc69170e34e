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
/// white-noise factor): counted in the candidate's BIC penalty beside its three states.
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

    /// The fit in words: sigma (cm), correlation time, the white-noise factor.
    pub fn describe(&self) -> String {
        format!(
            "prior fitted: {:.1}/{:.1}/{:.1} cm, {:.0} s, GNSS sigma scale x{:.2} ({} runs)",
            self.sigma_m[0] * 100.0,
            self.sigma_m[1] * 100.0,
            self.sigma_m[2] * 100.0,
            self.t_s,
            self.white_factor,
            self.runs
        )
    }
}

/// Fits the prior of the GNSS error state in the model `with_state` (the current model with
/// the block appended, as the search runs it) by the likelihood of its innovations, from
/// `from` (the previous round's fit) or the default prior: a climb over the white-noise
/// factor (steps of 2^(1/2)) in which every point has its Gauss-Markov prior climbed
/// (horizontal sigma, then correlation time: a lower white noise pays only with a larger
/// Gauss-Markov sigma, a ridge a climb one coordinate at a time does not follow), then the
/// white-noise factor refined (steps of 2^(1/4)), the vertical ratio and the horizontal sigma
/// once more.
/// `floor`: the smallest white-noise factor (the configuration's sigma scale over the
/// current one, per component, the larger).
pub(crate) fn fit(
    ctx: &Ctx<'_>,
    with_state: &RunOptions,
    floor: f64,
    from: Option<&GnssErrorFit>,
) -> Option<GnssErrorFit> {
    let runs = std::sync::atomic::AtomicUsize::new(0);
    let ll = |k: At| -> (At, f64) {
        runs.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let mut o = ctx.searching(with_state);
        GnssErrorFit::at(k).apply(&mut o);
        let l = spill::run_innovations(&ctx.p.case, &o).map_or(f64::NAN, |out| {
            residual_stats(&out.innovations).log_likelihood
        });
        (k, l)
    };
    let white_min = (4.0 * floor.max(1e-9).log2()).ceil() as i32;
    let ranges = [
        SIGMA_STEPS,
        RATIO_STEPS,
        TAU_STEPS,
        *WHITE_STEPS.start().max(&white_min)..=*WHITE_STEPS.end(),
    ];
    let mut at = from.map_or([0; 4], |f| f.at);
    for (a, r) in at.iter_mut().zip(&ranges) {
        *a = (*a).clamp(*r.start(), *r.end());
    }
    // the horizontal sigma and the correlation time climbed at the white-noise factor of `k`
    let prior = |k: At| -> (At, f64) {
        let mut cur = ll(k);
        for axis in [0, 2] {
            cur = climb(cur, (axis, 1), &ranges[axis], &ll);
        }
        cur
    };
    let mut best = climb(prior(at), (3, 2), &ranges[3], &prior);
    // then the white-noise factor refined, the vertical ratio and the horizontal sigma
    for (axis, stride) in [(3, 1), (1, 1), (0, 1)] {
        best = climb(best, (axis, stride), &ranges[axis], &ll);
    }
    let (at, best) = best;
    best.is_finite().then(|| GnssErrorFit {
        log_likelihood: best,
        runs: runs.into_inner(),
        ..GnssErrorFit::at(at)
    })
}

/// One coordinate of a climb: from `cur` (a point and its log-likelihood), both neighbours
/// `stride` grid steps away along `axis` (in parallel), then onwards from the one that gains while the log-likelihood
/// rises, within `range`. `ll` gives a point's log-likelihood and the point it reached (an
/// inner climb may move the other coordinates). Returns the best point and its
/// log-likelihood.
fn climb(
    cur: (At, f64),
    (axis, stride): (usize, i32),
    range: &std::ops::RangeInclusive<i32>,
    ll: &(dyn Fn(At) -> (At, f64) + Sync),
) -> (At, f64) {
    let moved = |k: At, d: i32| {
        let mut k = k;
        k[axis] += d * stride;
        range.contains(&k[axis]).then_some(k)
    };
    let probe = |d: i32| moved(cur.0, d).map(ll);
    let (lo, hi) = rayon::join(|| probe(-1), || probe(1));
    let gain = |p: &Option<(At, f64)>| p.filter(|(_, l)| l.is_finite() && *l > cur.1);
    let (mut best, step) = match (gain(&lo), gain(&hi)) {
        (Some(l), Some(h)) if l.1 > h.1 => (l, -1),
        (_, Some(h)) => (h, 1),
        (Some(l), None) => (l, -1),
        (None, None) => return cur,
    };
    while let Some(k) = moved(best.0, step) {
        let next = ll(k);
        if !(next.1.is_finite() && next.1 > best.1) {
            break;
        }
        best = next;
    }
    best
}
