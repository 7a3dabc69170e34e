//! The one gated Kalman update of the filter: every measurement (GNSS position, GNSS
//! position + velocity, GNSS velocity alone, the aiding sources of [`crate::aiding`]) goes
//! through [`Filter::gated_update`].
//!
//! Measurement `z = H dx + v` with `z` = predicted minus measured, `dx` = estimate - truth,
//! diagonal `R`. The normalised innovation squared `NIS = z^T S^-1 z`, `S = H P H^T + R`, is
//! tested against a [`Gate`]: at or below `downweight` the measurement is used as it is;
//! between `downweight` and `reject` `R` is divided by the IGG-III weight
//! ([`super::robust::igg3_weight`]); beyond `reject` (or with a weight below
//! [`super::robust::MIN_WEIGHT`]) it is not used and nothing changes. The update is done in
//! Joseph form and fed back into the nominal state (closed loop).
//!
//! No allocation (const generic sizes), no panics, no unchecked indexing.

use super::linalg::{all_finite, cholesky_in_place, cholesky_solve, dot, forward_solve};
use super::reacq::FixCheck;
use super::robust::{igg3_weight, MIN_WEIGHT};
use super::{diag_nonneg, discrete, get2, Filter, FilterError};
use crate::scalar::Scalar;

/// The chi-square thresholds of one gated update (dimensionless NIS values).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Gate {
    /// At or below: full weight. Equal to `reject`: a hard gate (no down-weighting).
    pub downweight: f64,
    /// Above: not used (infinite: no gate).
    pub reject: f64,
}

impl Gate {
    /// A hard gate at `threshold` (infinite: every measurement is used).
    pub(crate) const fn hard(threshold: f64) -> Self {
        Self {
            downweight: threshold,
            reject: threshold,
        }
    }
}

/// What a gated update did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Gated<const M: usize> {
    /// NIS `z^T S^-1 z` with the given R.
    pub nis: f64,
    /// Diagonal of `S = H P H^T + R` with the given R (units^2 of the measurement).
    pub s_diag: [f64; M],
    /// The weight used (1 full, in (0, 1) R / weight; 0 when not used).
    pub weight: f64,
    /// Whether the measurement was used.
    pub accepted: bool,
}

impl<T: Scalar, const N: usize> Filter<T, N> {
    /// The gated Joseph-form update (see the module documentation) for the current
    /// covariance (the caller predicts it first). `z64` = predicted minus measured, `h` the
    /// Jacobian rows, `r64` the diagonal variances of the measurement. `fix`: a GNSS position
    /// fix's bookkeeping, done as soon as the NIS is known (before the decision, also when a
    /// later numerical failure returns an error): whether it is within the normal gate, the
    /// probation of the previous fix it decides (undone: the caller processes the fix again
    /// and this update stops there), and, for a first fix after an outage, its own probation
    /// with the covariance before it when it is accepted beyond the normal gate
    /// ([`super::reacq`]).
    ///
    /// Errors: [`FilterError::Numerical`] (counted) when `S` is not positive definite, the
    /// NIS or the result is not finite; the state and covariance are then unchanged.
    // one instance per (N, M) whatever the caller (flash: the bench carries three filter
    // sizes), and its N x N temporaries in its own frame (MCU stack)
    #[inline(never)]
    pub(super) fn gated_update<const M: usize>(
        &mut self,
        z64: &[f64; M],
        h: &[[T; N]; M],
        r64: &[f64; M],
        gate: Gate,
        fix: Option<&FixCheck<T, N>>,
    ) -> Result<Gated<M>, FilterError> {
        let z = z64.map(T::of_f64);
        let mut r = r64.map(T::of_f64);
        let (pht, s, l) = self.innovation_cov(h, &r);
        let mut out = Gated {
            nis: f64::NAN,
            s_diag: [0.0; M],
            weight: 0.0,
            accepted: false,
        };
        for (i, o) in out.s_diag.iter_mut().enumerate() {
            *o = get2(&s, i, i).to_f64();
        }
        let Some(mut l) = l else {
            return Err(self.numerical_failure());
        };
        let y = forward_solve(&l, &z);
        let nis = dot(&y, &y).to_f64();
        out.nis = nis;
        if !nis.is_finite() {
            return Err(self.numerical_failure());
        }
        if let Some(c) = fix {
            self.gate.last_within_normal_gate = nis <= c.normal_reject;
            self.redo = self.settle_tentative(nis, c);
        }
        if self.redo {
            // the fix's probation check undid the previous fix: the caller processes it again
            return Ok(out);
        }
        let weight = if nis <= gate.downweight {
            1.0
        } else {
            igg3_weight(nis, gate.downweight, gate.reject)
        };
        if !(nis <= gate.reject && weight >= MIN_WEIGHT) {
            return Ok(out);
        }
        if weight < 1.0 {
            // R / w: only the diagonal of S changes (P H^T does not)
            let k = T::of_f64(1.0 / weight);
            let mut s2 = s;
            for (i, rv) in r.iter_mut().enumerate() {
                let extra = *rv * k - *rv;
                *rv *= k;
                if let Some(x) = s2.get_mut(i).and_then(|row| row.get_mut(i)) {
                    *x += extra;
                }
            }
            if !cholesky_in_place(&mut s2) {
                return Err(self.numerical_failure());
            }
            l = s2;
        }
        // K = P H^T S^-1 (row i solves S k_i = (P H^T)_i)
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
        // Joseph form P = (I - K H) P (I - K H)^T + K R K^T, in place:
        // AP = P - K (P H^T)^T;  P = AP - (AP H^T - K R) K^T  (upper triangle, mirrored)
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
        match fix.filter(|c| c.fed_back_before.is_some()) {
            Some(c) => {
                // the covariance before the update stays in `p` for the probation
                core::mem::swap(&mut self.p, &mut p);
                self.feedback(&dx);
                self.put_on_probation(c, &p, nis);
            }
            None => {
                self.p = p;
                self.feedback(&dx);
            }
        }
        out.accepted = true;
        out.weight = weight;
        Ok(out)
    }
}
