//! What a covariance prediction did, for a fixed-interval smoother on the host.
//!
//! A Rauch-Tung-Striebel backward pass over the closed-loop error-state filter needs, per
//! prediction interval `[t_start, t_end]`: the transition matrix Phi, the covariance before
//! the prediction (the posterior at `t_start`, after every update made at `t_start`), the
//! predicted covariance at `t_end`, and the error-state correction fed back into the nominal
//! state at `t_start` (the sum over the updates made there). Every update predicts the
//! covariance first, so the corrections fed back since the previous prediction were all made
//! at `t_start`. The derivation is in `docs/derivations/rts_smoother.md`.
//!
//! [`super::Filter::propagate_observed`] and [`super::Filter::predict_covariance_observed`]
//! hand a [`PredictionRecord`] to a [`CovObserver`] at every prediction; the plain
//! `propagate` / `predict_covariance` use the no-op observer `()` (nothing is stored, nothing
//! allocates).

use crate::model::discrete::{Cov, Transition};

/// One covariance prediction (borrowed from the filter for the duration of the call).
#[derive(Debug, Clone, Copy)]
pub struct PredictionRecord<'a, T, const N: usize> {
    /// Start of the prediction interval (the previous prediction's end), GPS s of week.
    pub t_start_s: f64,
    /// End of the interval (the nominal state's time), GPS s of week.
    pub t_end_s: f64,
    /// Transition matrix over the interval (units of the states: rad, m/s, m, sensor units).
    pub phi: &'a Transition<T, N>,
    /// Covariance before the prediction: the posterior at `t_start_s`.
    pub p_before: &'a Cov<T, N>,
    /// Predicted covariance at `t_end_s` (process noise included).
    pub p_after: &'a Cov<T, N>,
    /// Error-state correction fed back at `t_start_s` (estimate minus truth, summed over the
    /// updates made there; zero without updates), state units.
    pub correction: &'a [T; N],
}

/// Receives every covariance prediction of a filter run through the `*_observed` calls.
pub trait CovObserver<T, const N: usize> {
    /// Called after a successful prediction, before the filter stores the predicted
    /// covariance.
    fn predicted(&mut self, rec: &PredictionRecord<'_, T, N>);
}

/// The no-op observer.
impl<T, const N: usize> CovObserver<T, N> for () {
    #[inline(always)]
    fn predicted(&mut self, _rec: &PredictionRecord<'_, T, N>) {}
}
