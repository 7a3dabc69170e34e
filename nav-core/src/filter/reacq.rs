//! Probation of the first fix after an outage.
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

use super::{Cov, Filter};
use crate::model::{IDX_POS, IDX_VEL};
use crate::scalar::Scalar;

/// A fix used on probation: the covariance before it, the correction it fed back, its time.
/// Kept in place in the filter (`armed` false: no fix is on probation and the other fields
/// are stale), so that neither putting a fix on probation nor deciding it copies the
/// covariance through the stack (the MCU's RAM + stack budget).
#[derive(Debug, Clone, Copy)]
pub(super) struct Tentative<T: Scalar, const N: usize> {
    pub p0: Cov<T, N>,
    pub dx: [T; N],
    pub t_s: f64,
    /// Its position innovation (predicted minus measured antenna, NED m).
    pub z_pos_m: [f64; 3],
    /// A fix is on probation (the fields above describe it).
    pub armed: bool,
}

impl<T: Scalar, const N: usize> Tentative<T, N> {
    /// No fix on probation.
    pub(super) fn none() -> Self {
        Self {
            p0: [[T::ZERO; N]; N],
            dx: [T::ZERO; N],
            t_s: 0.0,
            z_pos_m: [0.0; 3],
            armed: false,
        }
    }
}

/// A GNSS position fix's part of the gated update ([`Filter::gated_update`]): the NIS
/// against the normal gate, the probation of the previous fix it decides, and (a first fix
/// after an outage) what it needs to go on probation itself besides the covariance before it,
/// which the gated update hands over ([`Filter::put_on_probation`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct FixCheck<T: Scalar, const N: usize> {
    /// The normal (not widened) rejection threshold of the fix's NIS.
    pub normal_reject: f64,
    /// The fix time, s.
    pub t_s: f64,
    /// Its position innovation (predicted minus measured antenna, NED m).
    pub z_pos_m: [f64; 3],
    /// A first fix after an outage: the corrections fed back since the last prediction
    /// before it (`fed_back`); None otherwise (it cannot go on probation).
    pub fed_back_before: Option<[T; N]>,
}

impl<T: Scalar, const N: usize> Filter<T, N> {
    /// Decides a fix on probation with the next fix `c` (its NIS `nis` and position innovation
    /// against the corrected state). Confirmed when the next fix is within
    /// the normal gate, or when it is closer to the fix on probation than to the state before
    /// it: with `z_b` its innovation against the state without the correction (the correction's
    /// position plus its velocity times the interval added back) and `z_1` the innovation of
    /// the fix on probation, `|z_b - z_1| <= |z_b|` (a jump of all fixes: both fixes agree, while
    /// the velocity correction the first one caused can put the next one beyond the normal
    /// gate). Otherwise it is undone, and true is returned (the caller processes the fix again).
    pub(super) fn settle_tentative(&mut self, nis: f64, c: &FixCheck<T, N>) -> bool {
        if !self.tentative.armed {
            return false;
        }
        self.tentative.armed = false;
        if nis <= c.normal_reject {
            return false;
        }
        let tv = &self.tentative;
        let tau = c.t_s - tv.t_s;
        let tau = if tau.is_finite() && tau > 0.0 {
            T::of_f64(tau)
        } else {
            T::ZERO
        };
        let mut undo = tv.dx.map(|v| -v);
        let (mut to_b, mut to_1) = (0.0, 0.0);
        for (k, (z2, z1)) in c.z_pos_m.iter().zip(tv.z_pos_m).enumerate() {
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
        self.p = self.tentative.p0;
        self.gate.stats.reacquisitions_undone =
            self.gate.stats.reacquisitions_undone.saturating_add(1);
        true
    }

    /// Puts the fix `c` just used (NIS `nis`) on probation when it is a first fix after an
    /// outage and was beyond the normal gate: `p0` is the covariance before its update (the
    /// gated update's own copy, handed over), the correction it fed back is what `fed_back`
    /// gained since `c.fed_back_before`.
    pub(super) fn put_on_probation(&mut self, c: &FixCheck<T, N>, p0: &Cov<T, N>, nis: f64) {
        let Some(before) = c.fed_back_before.as_ref() else {
            return;
        };
        if nis <= c.normal_reject {
            return;
        }
        let tv = &mut self.tentative;
        tv.p0 = *p0;
        for ((d, after), b) in tv.dx.iter_mut().zip(self.fed_back.iter()).zip(before) {
            *d = *after - *b;
        }
        tv.t_s = c.t_s;
        tv.z_pos_m = c.z_pos_m;
        tv.armed = true;
    }
}
