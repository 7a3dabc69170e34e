//! A generic gated vector measurement update for the aiding sources of [`crate::aiding`]
//! (non-holonomic constraint, zero-velocity and zero-rate updates, ...): the caller gives the
//! residual `z` = predicted minus measured, the Jacobian `H` (`z = H dx + v`, dx = estimate -
//! truth) and a diagonal `R`; the update is gated by a hard chi-square threshold on the NIS and
//! done by the filter's one gated Joseph-form update ([`super::gated`]), fed back into the
//! nominal state (closed loop).
//!
//! Unlike [`Filter::update_gnss`] it does not touch the GNSS gate's state (consecutive
//! rejections, the NIS monitor, resets) nor the GNSS counters: the aiding sources keep their own
//! counts ([`crate::aiding::AidingCounters`]).

use super::gated::Gate;
use super::{get2, Filter, FilterError};
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
        let g = self.gated_update(z64, h, r64, Gate::hard(nis_threshold), None)?;
        Ok(AidingOutcome {
            nis: g.nis,
            threshold: nis_threshold,
            accepted: g.accepted,
        })
    }

    /// Variance of error state `i` (units^2 of the state; 0 outside the layout).
    pub fn state_variance(&self, i: usize) -> f64 {
        get2(&self.p, i, i).to_f64()
    }
}
