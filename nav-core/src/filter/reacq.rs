//! Probation of the first fix after an outage (issue 13).
//!
//! After an outage the re-acquisition gate is widened (x100 and more, see
//! [`super::robust`]): the unaided error has grown with whatever the model leaves out, and a
//! single fix cannot tell that drift from an outlier. Such a fix, used beyond the normal gate,
//! is on probation: the covariance before it and the correction it fed back are kept. The next
//! fix decides. Within the normal gate of the corrected state it confirms the first one.
//! Beyond it, the first fix is taken back (its correction undone, the position also by the
//! velocity correction times the time since, and the covariance restored) and the next fix is
//! processed as the first one after the outage. A genuine jump of all fixes is confirmed by the
//! next fix; an outlier costs one fix interval at its error.
//!
//! What the undo leaves: the attitude part of the correction acted on the velocity for one
//! fix interval (the specific force times the tilt correction times the interval), and any
//! aiding update in that interval is dropped with the covariance.

use super::robust::Thresholds;
use super::{Cov, Filter};
use crate::model::{IDX_POS, IDX_VEL};
use crate::scalar::Scalar;

/// A fix used on probation: the covariance before it, the correction it fed back, its time.
#[derive(Debug, Clone, Copy)]
pub(super) struct Tentative<T: Scalar, const N: usize> {
    pub p0: Cov<T, N>,
    pub dx: [T; N],
    pub t_s: f64,
    /// Its position innovation (predicted minus measured antenna, NED m).
    pub z_pos_m: [f64; 3],
}

impl<T: Scalar, const N: usize> Filter<T, N> {
    /// Decides a fix on probation with the next fix (its NIS `nis` and position innovation
    /// `z_pos_m` against the corrected state, at `t_s`). Confirmed when the next fix is within
    /// the normal gate, or when it is closer to the fix on probation than to the state before
    /// it: with `z_b` its innovation against the state without the correction (the correction's
    /// position plus its velocity times the interval added back) and `z_1` the innovation of
    /// the fix on probation, `|z_b - z_1| <= |z_b|` (a jump of all fixes: both fixes agree, while
    /// the velocity correction the first one caused can put the next one beyond the normal
    /// gate). Otherwise it is undone, and true is returned (the caller processes the fix again).
    pub(super) fn settle_tentative(
        &mut self,
        nis: f64,
        th: &Thresholds,
        t_s: f64,
        z_pos_m: [f64; 3],
    ) -> bool {
        let Some(tv) = self.tentative.take() else {
            return false;
        };
        if nis <= th.normal_reject {
            return false;
        }
        let tau = t_s - tv.t_s;
        let tau = if tau.is_finite() && tau > 0.0 {
            T::of_f64(tau)
        } else {
            T::ZERO
        };
        let mut undo = tv.dx.map(|v| -v);
        let (mut to_b, mut to_1) = (0.0, 0.0);
        for (k, (z2, z1)) in z_pos_m.iter().zip(tv.z_pos_m).enumerate() {
            let dv = tv.dx.get(IDX_VEL + k).copied().unwrap_or(T::ZERO);
            let dr = tv.dx.get(IDX_POS + k).copied().unwrap_or(T::ZERO);
            if let Some(x) = undo.get_mut(IDX_POS + k) {
                *x -= dv * tau;
            }
            let zb = z2 + (dr + dv * tau).to_f64();
            to_b += zb * zb;
            to_1 += (zb - z1) * (zb - z1);
        }
        if to_1 <= to_b {
            return false;
        }
        self.feedback(&undo);
        self.p = tv.p0;
        self.gate.stats.reacquisitions_undone =
            self.gate.stats.reacquisitions_undone.saturating_add(1);
        true
    }
}
