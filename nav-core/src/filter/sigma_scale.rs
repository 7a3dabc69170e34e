//! The learned GNSS sigma scale of the robust gate: fixes whose declared sigmas are too small
//! by a consistent factor are not outliers. Per fix the estimator keeps a covariance-matching
//! sample of the ratio between the true and the declared measurement variance,
//! `c = (1/dof) sum_i (z_i^2 - (H P H^T)_ii) / R_ii` (declared `R`), divided by the median of
//! chi-square/dof so that its median estimates `c` for white innovations. The window median of
//! the last [`RobustGating::scale_window`] samples (from the median: an isolated outlier moves
//! it by one rank) is the scale; once it reaches [`RobustGating::scale_on`] the gate multiplies
//! R by it before the test and the IGG-III weights, until it drops below
//! [`RobustGating::scale_off`].
//!
//! Only a *white* excess is learned. Next to each sample the estimator keeps the same
//! covariance-matching sample of the difference of consecutive normalised innovations,
//! `(1/dof) sum_i ((u_i,k - u_i,k-1)^2 - h_i,k - h_i,k-1) / 2` (`u = z / sqrt(R)`,
//! `h = (H P H^T)_ii / R_ii`): for white innovations it estimates the same ratio, for a
//! systematic error (a jump of all fixes, an undeclared lever arm in a turn, a multipath bias,
//! the drift after an outage, the transient after a jump) the difference cancels it. While the
//! median of the difference samples is below [`SYSTEMATIC_FRACTION`] of the median of the
//! samples (a mostly systematic excess), the factor is frozen: a model mismatch is the
//! monitor's business (gate widening), not R's. Only fixes used by an update teach the scale
//! (the caller feeds no rejected fix): a diverged filter or a jump of all fixes is rejected
//! and reset, as before.
//!
//! Fixed-size windows, per fix O(K^2) comparisons for the two medians with K <= 16, no
//! allocation, no panic, no unchecked indexing (see `docs/robust-gating.md`).

use crate::config::{RobustGating, MAX_NIS_WINDOW};

/// Median of chi-square with 3 degrees of freedom divided by 3.
const CHI2_MEDIAN_PER_DOF_3: f64 = 2.365_973_6 / 3.0;
/// Median of chi-square with 6 degrees of freedom divided by 6.
const CHI2_MEDIAN_PER_DOF_6: f64 = 5.348_120_6 / 6.0;

/// Fewest samples for a scale: with 3 one outlier is not the median.
const MIN_SAMPLES: usize = 3;

/// The window's excess is called systematic (the factor frozen) when its white part is below
/// this fraction of it.
const SYSTEMATIC_FRACTION: f64 = 0.15;

/// Largest measurement dimension of a GNSS update (position + velocity).
const MAX_DIM: usize = 6;

/// Median of chi-square/dof for `dof` degrees of freedom (the Wilson-Hilferty approximation
/// `(1 - 2/(9 dof))^3` for other than 3 and 6).
fn chi2_median_per_dof(dof: usize) -> f64 {
    match dof {
        3 => CHI2_MEDIAN_PER_DOF_3,
        6 => CHI2_MEDIAN_PER_DOF_6,
        _ => {
            let a = 1.0 - 2.0 / (9.0 * dof.max(1) as f64);
            a * a * a
        }
    }
}

/// Median of the first `n` values of `v` (at most [`MAX_NIS_WINDOW`]; insertion sort into a
/// fixed array). NaN for none.
pub(super) fn median_of(v: &[f64; MAX_NIS_WINDOW], n: usize) -> f64 {
    let mut a = [0.0f64; MAX_NIS_WINDOW];
    let n = n.min(MAX_NIS_WINDOW);
    for (i, x) in v.iter().take(n).enumerate() {
        let mut j = i;
        while j > 0 && a.get(j - 1).is_some_and(|p| *p > *x) {
            if let Some(p) = a.get(j - 1).copied() {
                if let Some(y) = a.get_mut(j) {
                    *y = p;
                }
            }
            j -= 1;
        }
        if let Some(y) = a.get_mut(j) {
            *y = *x;
        }
    }
    let mid = n / 2;
    let hi = a.get(mid).copied().unwrap_or(f64::NAN);
    if n == 0 {
        f64::NAN
    } else if n & 1 == 1 {
        hi
    } else {
        0.5 * (a.get(mid.wrapping_sub(1)).copied().unwrap_or(hi) + hi)
    }
}

/// One fix as the estimator sees it (slices of the measurement dimension).
#[derive(Debug, Clone, Copy)]
pub(super) struct ScaleInput<'a> {
    /// Innovation, predicted minus measured (units of the measurement).
    pub z: &'a [f64],
    /// Diagonal of `S = H P H^T + R_used`.
    pub s_diag: &'a [f64],
    /// Diagonal of the R used (the declared R times [`SigmaScale::factor`]).
    pub r_used: &'a [f64],
}

/// The estimator's state: the windows of samples and difference samples, the last normalised
/// innovation and the factor in use.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SigmaScale {
    samples: [f64; MAX_NIS_WINDOW],
    diffs: [f64; MAX_NIS_WINDOW],
    len: usize,
    next: usize,
    /// Previous fix's innovation over the declared sigma, and its dimension (0: none).
    prev_u: [f64; MAX_DIM],
    /// Its H P H^T over the declared R.
    prev_h: [f64; MAX_DIM],
    prev_dim: usize,
    /// R multiplier in use (1 = none).
    factor: f64,
    /// The last window median of the samples, the estimated variance ratio (NaN: too few).
    pub estimate: f64,
    /// Whether the last window's excess was mostly systematic (a mismatch, not noise).
    pub systematic: bool,
}

impl Default for SigmaScale {
    fn default() -> Self {
        Self {
            samples: [0.0; MAX_NIS_WINDOW],
            diffs: [0.0; MAX_NIS_WINDOW],
            len: 0,
            next: 0,
            prev_u: [0.0; MAX_DIM],
            prev_h: [0.0; MAX_DIM],
            prev_dim: 0,
            factor: 1.0,
            estimate: f64::NAN,
            systematic: false,
        }
    }
}

impl SigmaScale {
    /// The factor R is multiplied by for the next fix (1 = none).
    pub fn factor(&self) -> f64 {
        self.factor
    }

    /// Feeds one fix (accepted or not) and updates the factor.
    pub fn learn(&mut self, r: &RobustGating, inp: &ScaleInput<'_>) {
        let k = r.scale_window.min(MAX_NIS_WINDOW);
        if k == 0 {
            self.factor = 1.0;
            return;
        }
        let dim = inp.z.len().min(MAX_DIM);
        let norm = chi2_median_per_dof(dim);
        let mut u = [0.0; MAX_DIM];
        let mut h = [0.0; MAX_DIM];
        let mut c = 0.0;
        let mut d = 0.0;
        let pair = self.prev_dim == dim;
        for (i, ((z, s), ru)) in inp
            .z
            .iter()
            .zip(inp.s_diag.iter())
            .zip(inp.r_used.iter())
            .take(dim)
            .enumerate()
        {
            // the declared variance: R used divided by the factor it was used with
            let r0 = ru / self.factor;
            if r0.is_nan() || r0 <= 0.0 || !z.is_finite() || !s.is_finite() {
                return;
            }
            // H P H^T over the declared R, and the innovation over the declared sigma
            let hi = (s - ru).max(0.0) / r0;
            let ui = z / libm::sqrt(r0);
            c += ui * ui - hi;
            if pair {
                let up = self.prev_u.get(i).copied().unwrap_or(0.0);
                let hp = self.prev_h.get(i).copied().unwrap_or(0.0);
                let du = ui - up;
                d += 0.5 * (du * du - hi - hp);
            }
            if let Some(x) = u.get_mut(i) {
                *x = ui;
            }
            if let Some(x) = h.get_mut(i) {
                *x = hi;
            }
        }
        let dof = dim.max(1) as f64;
        let sample = c / dof / norm;
        // without a previous fix of the same dimension the white part is unknown: taken as
        // the sample itself (one rank of the window)
        let diff = if pair { d / dof / norm } else { sample };
        self.prev_u = u;
        self.prev_h = h;
        self.prev_dim = dim;
        if let Some(x) = self.samples.get_mut(self.next) {
            *x = sample.min(f64::MAX);
        }
        if let Some(x) = self.diffs.get_mut(self.next) {
            *x = diff.min(f64::MAX);
        }
        self.next = if self.next + 1 >= k { 0 } else { self.next + 1 };
        self.len = (self.len + 1).min(k);
        if self.len < MIN_SAMPLES.min(k) {
            return;
        }
        let total = median_of(&self.samples, self.len);
        let white = median_of(&self.diffs, self.len);
        // mostly systematic (a jump, a transient, a mismatch): the factor stays as it is
        self.systematic = white < SYSTEMATIC_FRACTION * total;
        self.estimate = total;
        if self.systematic || !total.is_finite() {
            return;
        }
        let est = total;
        let on = self.factor > 1.0;
        self.factor = if est >= r.scale_on || (on && est >= r.scale_off) {
            est.min(r.max_scale).max(1.0)
        } else {
            1.0
        };
    }

    /// Forgets the samples (after a re-initialisation the innovations before it say nothing
    /// about the fixes' noise); the factor in use stays until the window has samples again.
    pub fn clear(&mut self) {
        self.len = 0;
        self.next = 0;
        self.prev_dim = 0;
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, StandardNormal};

    /// The robust gate's parameters with the learning on (16 fixes; off by default).
    fn on() -> RobustGating {
        RobustGating {
            scale_window: 16,
            ..RobustGating::default()
        }
    }

    /// Feeds `n` position fixes with white innovations of `true_sigma` against a declared
    /// sigma of 1 (H P H^T negligible), `bad(k)` added to fix k; returns the factors after
    /// each fix.
    fn feed(
        s: &mut SigmaScale,
        r: &RobustGating,
        rng: &mut ChaCha8Rng,
        n: usize,
        true_sigma: f64,
        bad: impl Fn(usize) -> [f64; 3],
    ) -> [f64; 64] {
        let mut out = [0.0; 64];
        for (k, o) in out.iter_mut().enumerate().take(n) {
            let f = s.factor();
            let b = bad(k);
            let z: [f64; 3] = core::array::from_fn(|i| {
                let g: f64 = StandardNormal.sample(rng);
                true_sigma * g + b[i]
            });
            let ru = [f; 3];
            let sd = ru.map(|x| x + 1e-6);
            s.learn(
                r,
                &ScaleInput {
                    z: &z,
                    s_diag: &sd,
                    r_used: &ru,
                },
            );
            *o = s.factor();
        }
        out
    }

    #[test]
    fn persistent_10x_understatement_gives_a_scale_near_100_after_the_window() {
        let r = on();
        let mut all = [0.0; 200];
        let mut early = 0;
        for (seed, a) in all.iter_mut().enumerate() {
            let mut rng = ChaCha8Rng::seed_from_u64(seed as u64);
            let mut s = SigmaScale::default();
            let f = feed(&mut s, &r, &mut rng, 16, 10.0, |_| [0.0; 3]);
            *a = f[15];
            // two fixes are not a scale (one could be an outlier); from the third on it is
            assert_eq!(f[..2], [1.0, 1.0]);
            early += usize::from(f[2] > 4.0);
            let k = f[15];
            assert!((30.0..=300.0).contains(&k), "seed {seed}: factor {k}");
            assert!(!s.systematic);
        }
        // most streams are scaled from the third fix on
        assert!(early >= 180, "{early} of 200 scaled at the third fix");
        all.sort_by(f64::total_cmp);
        assert!(all[10] >= 50.0 && all[190] <= 200.0, "{all:?}");
        std::println!(
            "factor after 16 fixes, 200 seeds: min {:.1}, 5 % {:.1}, median {:.1}, 95 % {:.1}, \
             max {:.1}; {early} of 200 scaled at the third fix",
            all[0],
            all[10],
            all[100],
            all[190],
            all[199]
        );
    }

    #[test]
    fn an_isolated_outlier_does_not_move_the_scale_and_good_sigmas_get_none() {
        let r = on();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let mut s = SigmaScale::default();
        // consistent fixes with a 30-sigma outlier at fix 20: no scale, before and after
        let f = feed(&mut s, &r, &mut rng, 40, 1.0, |k| {
            if k == 20 {
                [30.0, 0.0, 0.0]
            } else {
                [0.0; 3]
            }
        });
        assert!(f[..40].iter().all(|x| *x == 1.0), "{f:?}");
        // understated 10x: the outlier moves the median by one rank only
        let mut s = SigmaScale::default();
        let f = feed(&mut s, &r, &mut rng, 40, 10.0, |k| {
            if k == 30 {
                [300.0, 0.0, 0.0]
            } else {
                [0.0; 3]
            }
        });
        let (before, after) = (f[29], f[30]);
        assert!((after / before - 1.0).abs() < 0.25, "{before} -> {after}");
    }

    #[test]
    fn a_burst_or_a_jump_is_not_learned() {
        let r = on();
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        // 5 bad fixes (independent 30-sigma errors) among 16: the median stays with the good
        let mut s = SigmaScale::default();
        let f = feed(&mut s, &r, &mut rng, 40, 1.0, |k| {
            if (20..25).contains(&k) {
                [30.0 * if k % 2 == 0 { 1.0 } else { -1.0 }, 20.0, 0.0]
            } else {
                [0.0; 3]
            }
        });
        assert!(f[..40].iter().all(|x| *x == 1.0), "{f:?}");
        // every fix from 10 on jumps by 100 sigma: systematic (the differences cancel it), no
        // scale
        let mut s = SigmaScale::default();
        let f = feed(&mut s, &r, &mut rng, 40, 1.0, |k| {
            if k >= 10 {
                [100.0, 0.0, 0.0]
            } else {
                [0.0; 3]
            }
        });
        assert!(f[..40].iter().all(|x| *x == 1.0), "{f:?}");
        assert!(s.systematic);
    }

    #[test]
    fn the_scale_is_given_up_when_the_sigmas_become_right() {
        let r = on();
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let mut s = SigmaScale::default();
        feed(&mut s, &r, &mut rng, 20, 10.0, |_| [0.0; 3]);
        assert!(s.factor() > 50.0);
        let f = feed(&mut s, &r, &mut rng, 20, 1.0, |_| [0.0; 3]);
        assert_eq!(f[19], 1.0, "{f:?}");
        // off: no learning at all
        let off = RobustGating::default();
        assert_eq!(off.scale_window, 0);
        let mut s = SigmaScale::default();
        let f = feed(&mut s, &off, &mut rng, 20, 10.0, |_| [0.0; 3]);
        assert!(f[..20].iter().all(|x| *x == 1.0));
    }

    #[test]
    fn median_of_odd_even_and_empty() {
        let mut v = [0.0; MAX_NIS_WINDOW];
        v[..5].copy_from_slice(&[5.0, 1.0, 4.0, 2.0, 3.0]);
        assert_eq!(median_of(&v, 5), 3.0);
        assert_eq!(median_of(&v, 4), 3.0);
        assert!(median_of(&v, 0).is_nan());
    }
}
