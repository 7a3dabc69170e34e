//! Covariance widening over the filled part of an IMU gap ([`Filter::widen_for_fill`]).

use super::Filter;
use crate::imu_guard::FillUncertainty;
use crate::model::{add3, IDX_ATT, IDX_POS, IDX_VEL};
use crate::scalar::Scalar;
use nalgebra::UnitQuaternion;

impl<T: Scalar, const N: usize> Filter<T, N> {
    /// Widens the covariance for the filled part of an IMU gap: the error of the synthetic
    /// increments ([`crate::imu_guard::GapFill::uncertainty`], body axes) is added, rotated to
    /// NED, to the attitude and velocity variances, and the velocity sigma times half the span
    /// to the position's, as process noise of the next covariance prediction (so an observer
    /// of the predictions sees it). Call it after integrating the fill. Non-finite or
    /// negative sigmas are ignored.
    pub fn widen_for_fill(&mut self, u: &FillUncertainty) {
        let half = 0.5 * u.span_s;
        if !(half.is_finite() && half > 0.0) {
            return;
        }
        for k in 0..3 {
            let (a, v) = (
                u.dtheta_rad.get(k).copied().unwrap_or(0.0),
                u.dv_mps.get(k).copied().unwrap_or(0.0),
            );
            if !(a.is_finite() && v.is_finite() && a >= 0.0 && v >= 0.0) {
                continue;
            }
            for (i, s) in [(k, a), (3 + k, v), (6 + k, v * half)] {
                if let Some(x) = self.fill_var.get_mut(i) {
                    *x += s * s;
                }
            }
        }
    }

    /// Adds the pending fill noise ([`Self::widen_for_fill`]) to a predicted covariance.
    pub(super) fn add_fill_noise(&mut self, p: &mut super::Cov<T, N>) {
        if self.fill_var.iter().all(|v| *v == 0.0) {
            return;
        }
        let m = fill_noise_ned(&self.mech.state().q_nb, &self.fill_var);
        self.fill_var = [0.0; 9];
        for (idx, b) in [IDX_ATT, IDX_VEL, IDX_POS].into_iter().zip(m.iter()) {
            add3(p, idx, idx, &b.map(|r| r.map(T::of_f64)));
        }
    }
}

/// `C diag(v) C^T` for the attitude, velocity and position variances `v` (body axes, 3 each),
/// each block exactly symmetric (upper triangle computed, mirrored).
#[inline(never)]
fn fill_noise_ned(q_nb: &UnitQuaternion<f64>, var: &[f64; 9]) -> [[[f64; 3]; 3]; 3] {
    let c = q_nb.to_rotation_matrix();
    let c = c.matrix();
    let mut out = [[[0.0; 3]; 3]; 3];
    for (b, o) in out.iter_mut().enumerate() {
        for (i, row) in o.iter_mut().enumerate() {
            for (j, x) in row.iter_mut().enumerate().skip(i) {
                let mut acc = 0.0;
                for k in 0..3 {
                    let v = var.get(3 * b + k).copied().unwrap_or(0.0);
                    acc += c.get((i, k)).copied().unwrap_or(0.0)
                        * v
                        * c.get((j, k)).copied().unwrap_or(0.0);
                }
                *x = acc;
            }
        }
        *o = crate::model::discrete::symmetric_from_upper3(*o);
    }
    out
}
