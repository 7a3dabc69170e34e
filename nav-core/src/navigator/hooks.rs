//! Hooks into the [`super::Navigator`]'s loop ([`NavHooks`]): what a host run needs besides
//! the filter (records at every epoch, the smoother's covariance history, fixes withheld
//! inside imposed outages, aiding updates) without a second copy of the loop.
//!
//! The hooks are a generic parameter of [`super::Navigator::push_imu_with`] and
//! [`super::Navigator::flush_with`]: every method has a no-op default, so [`NoHooks`] (what
//! [`super::Navigator::push_imu`] and [`super::Navigator::flush`] pass) compiles to the loop
//! without hooks. Nothing here allocates.
//!
//! # Order of the calls
//!
//! `push_imu_with(s_{k+1})`, with `t_k` the last integrated epoch:
//!
//! 1. for every queued fix due at `t_k` (nearest-epoch rule), in time order:
//!    [`NavHooks::withhold_fix`] (true: the fix is not used, and nothing else is called for
//!    it); else, when [`NavHooks::observes_covariance`], the covariance is predicted to `t_k`
//!    through [`NavHooks::observer`] (the prediction the update would make unobserved);
//!    [`NavHooks::before_gnss`]; the update; [`NavHooks::on_fix`];
//! 2. [`NavHooks::on_epoch_done`] (epoch `t_k` complete: its fixes applied);
//! 3. the sample `s_{k+1}` through the guard and the filter (covariance predictions through
//!    [`NavHooks::observer`]); when it was integrated, [`NavHooks::after_sample`].
//!
//! `flush_with` makes steps 1 and 2 for the last epoch.

use crate::filter::observe::{CovObserver, PredictionRecord};
use crate::filter::Filter;
use crate::scalar::Scalar;
use crate::types::GnssFix;

use super::FixEvent;

/// What a caller adds to the navigator's loop (module notes); every method has a no-op
/// default.
pub trait NavHooks<T: Scalar, const N: usize> {
    /// True when [`Self::observer`] wants every covariance prediction, including the one a
    /// GNSS update makes (the navigator then predicts before the update, observed).
    #[inline(always)]
    fn observes_covariance(&self) -> bool {
        false
    }

    /// The observer of the covariance predictions (see [`CovObserver`]; default: none, the
    /// no-op observer `()`, so that the loop without hooks is the plain `propagate`).
    #[inline(always)]
    fn observer(&mut self) -> impl CovObserver<T, N> + '_ {}

    /// After an integrated sample (not after a rejected or refused one): aiding updates that
    /// follow the IMU. The filter is the hooks' to update.
    #[inline(always)]
    fn after_sample(&mut self, _filter: &mut Filter<T, N>) {}

    /// A fix due at the current epoch: true withholds it (an imposed outage; not used, not
    /// counted as used or rejected). `filter` is at the epoch the fix would be used, after
    /// the fixes before it.
    #[inline(always)]
    fn withhold_fix(&mut self, _filter: &Filter<T, N>, _fix: &GnssFix) -> bool {
        false
    }

    /// Just before a fix's update (after the prediction when [`Self::observes_covariance`]).
    #[inline(always)]
    fn before_gnss(&mut self, _fix: &GnssFix) {}

    /// What a fix's update did (the filter after it).
    #[inline(always)]
    fn on_fix(&mut self, _filter: &Filter<T, N>, _fix: &GnssFix, _event: &FixEvent) {}

    /// The epoch of the last integrated sample is complete (its fixes applied), before the
    /// next sample is integrated, or at [`super::Navigator::flush_with`].
    #[inline(always)]
    fn on_epoch_done(&mut self, _filter: &Filter<T, N>) {}
}

/// No hooks: the plain loop.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct NoHooks;

impl<T: Scalar, const N: usize> NavHooks<T, N> for NoHooks {}

/// An observer held elsewhere, by reference (what [`NavHooks::observer`] returns for an
/// observer the hooks own).
#[derive(Debug)]
pub struct ObserveWith<'a, O>(pub &'a mut O);

impl<T, const N: usize, O: CovObserver<T, N>> CovObserver<T, N> for ObserveWith<'_, O> {
    #[inline(always)]
    fn predicted(&mut self, rec: &PredictionRecord<'_, T, N>) {
        self.0.predicted(rec);
    }
}
