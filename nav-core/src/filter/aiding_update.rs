//! A generic gated vector measurement update for the aiding sources of [`crate::aiding`]
//! (non-holonomic constraint, zero-velocity and zero-rate updates, ...): the caller gives the
//! residual `z` = predicted minus measured, the Jacobian `H` (`z = H dx + v`, dx = estimate -
//! truth) and a diagonal `R`; the update is gated by a chi-square threshold on the NIS, done in
//! Joseph form, fed back into the nominal state (closed loop).
//!
//! Unlike [`Filter::update_gnss`] it does not touch the GNSS gate's state (consecutive
//! rejections, the NIS monitor, resets) nor the GNSS counters: the aiding sources keep their own
//! counts ([`crate::aiding::AidingCounters`]).

use super::linalg::{all_finite, cholesky_solve, dot, forward_solve};
use super::{diag_nonneg, discrete, get2, Filter, FilterError};
use crate::scalar::Scalar;

/// What an aiding update did.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AidingOutcome {
    /// Normalised innovation squared `z^T S^-1 z` (dimensionless).
    pub nis: f64,
    /// The chi-square threshold that applied (dimensionless; infinite: no gate).
    pub threshold: f64,
    /// Whether the measurement was used.
    pub accepted: bool,
}

impl<T: Scalar, const N: usize> Filter<T, N> {
    /// Gated Kalman update with an M-dimensional measurement: `z` = predicted minus measured
    /// (units of the measurement), `h` its Jacobian with respect to the error state
    /// (dx = estimate - truth), `r` the diagonal measurement variances (units^2, > 0), and the
    /// chi-square `nis_threshold` (NIS above it: not used, nothing changes; use
    /// `f64::INFINITY` for no gate). The covariance is first predicted to the current epoch.
    ///
    /// Errors: [`FilterError::Numerical`] when the innovation covariance is not positive
    /// definite, `z` or `r` is not finite (or an `r` not positive), or the result is not
    /// finite; the filter's state and covariance are then unchanged.
    pub fn update_aiding<const M: usize>(
        &mut self,
        z64: &[f64; M],
        h: &[[T; N]; M],
        r64: &[f64; M],
        nis_threshold: f64,
    ) -> Result<AidingOutcome, FilterError> {
        if !(z64.iter().all(|v| v.is_finite()) && r64.iter().all(|v| v.is_finite() && *v > 0.0)) {
            return Err(self.numerical_failure());
        }
        self.predict_covariance()?;
        let z = z64.map(T::of_f64);
        let r = r64.map(T::of_f64);
        let (pht, _s, l) = self.innovation_cov(h, &r);
        let Some(l) = l else {
            return Err(self.numerical_failure());
        };
        let y = forward_solve(&l, &z);
        let nis = dot(&y, &y).to_f64();
        if !nis.is_finite() {
            return Err(self.numerical_failure());
        }
        let mut out = AidingOutcome {
            nis,
            threshold: nis_threshold,
            accepted: false,
        };
        if nis > nis_threshold {
            return Ok(out);
        }
        // K = P H^T S^-1
        let mut k = [[T::ZERO; M]; N];
        for (krow, phtrow) in k.iter_mut().zip(pht.iter()) {
            *krow = cholesky_solve(&l, phtrow);
        }
        let mut dx = [T::ZERO; N];
        for (d, krow) in dx.iter_mut().zip(k.iter()) {
            *d = dot(krow, &z);
        }
        if !all_finite(&k) || !dx.iter().all(|v| v.finite()) {
            return Err(self.numerical_failure());
        }
        // Joseph form, as in the GNSS update: AP = P - K (P H^T)^T; P = AP - (AP H^T - K R) K^T
        let mut p = self.p;
        for (prow, krow) in p.iter_mut().zip(k.iter()) {
            for (pij, phtj) in prow.iter_mut().zip(pht.iter()) {
                *pij -= dot(krow, phtj);
            }
        }
        let mut y_mat = [[T::ZERO; M]; N];
        for ((yrow, prow), krow) in y_mat.iter_mut().zip(p.iter()).zip(k.iter()) {
            for (((yv, hrow), kv), rv) in yrow.iter_mut().zip(h).zip(krow).zip(r.iter()) {
                *yv = dot(prow, hrow) - *kv * *rv;
            }
        }
        for (i, (prow, yrow)) in p.iter_mut().zip(y_mat.iter()).enumerate() {
            for (pij, kj) in prow.iter_mut().zip(k.iter()).skip(i) {
                *pij -= dot(yrow, kj);
            }
        }
        discrete::mirror_upper(&mut p);
        if !all_finite(&p) || !diag_nonneg(&p) {
            return Err(self.numerical_failure());
        }
        self.p = p;
        self.feedback(&dx);
        out.accepted = true;
        Ok(out)
    }

    /// Variance of error state `i` (units^2 of the state; 0 outside the layout).
    pub fn state_variance(&self, i: usize) -> f64 {
        get2(&self.p, i, i).to_f64()
    }
}
