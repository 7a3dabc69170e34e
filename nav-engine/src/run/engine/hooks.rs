//! The engine's hooks into the navigator's loop ([`EngineHooks`], see the module notes of
//! [`super`]).

use super::ahead::FixAhead;
use super::{Coaster, RunSink};
use crate::run::coast::CoastMode;
use crate::run::{
    all_estimates, block_estimates, outage, position_innovation, record_of, Decimator, EpochRecord,
    FixUse, InnovationRecord, OutageSnapshot, RunCounters, RunError,
};
use nav_core::filter::observe::CovObserver;
use nav_core::filter::{Filter, FilterError};
use nav_core::model::ImuCorrection;
use nav_core::navigator::{FixEvent, NavHooks, ObserveWith};
use nav_core::scalar::Scalar;
use nav_core::types::{FixQuality, GnssFix, ImuSample, NavSolution};

/// The host run's additions to the navigator's loop ([`NavHooks`]): records at every epoch,
/// innovations, fixes withheld inside outages, outage snapshots and the coasters they start,
/// the smoother's recorder and the land-vehicle aiding.
pub(super) struct EngineHooks<'a, 'g, T: Scalar> {
    pub(super) sink: &'a mut dyn RunSink,
    /// A sink error (the run returns it after the call).
    pub(super) err: Option<RunError>,
    /// A fault in a fix's update (the run stops after the call; later fixes are withheld).
    pub(super) fault: Option<(String, f64, super::super::FaultCause)>,
    pub(super) rec: crate::smooth::Recorder,
    pub(super) aid: crate::run::aiding::RunAiding<T>,
    pub(super) outages: &'a [outage::Outage],
    pub(super) next_outage: usize,
    pub(super) counters: RunCounters,
    pub(super) status_seen: u32,
    /// Fixes processed (withheld or given to the filter).
    pub(super) processed: usize,
    pub(super) nav_dec: Decimator,
    pub(super) ep_dec: Decimator,
    pub(super) want_epochs: bool,
    /// The sink reads the navigation records' standard deviations
    /// ([`RunSink::wants_nav_std`]).
    pub(super) want_nav_std: bool,
    pub(super) coast_modes: &'a [CoastMode],
    pub(super) coasters: Vec<Coaster>,
    /// The raw sample being pushed and the next sample's time (the coasters step on it after
    /// the epoch before it is complete).
    pub(super) raw: Option<(ImuSample, Option<f64>)>,
    /// Index in the record of the sample being pushed (an outage snapshot's `next_imu`).
    pub(super) next_index: usize,
    /// The run's fixes (those not yet given to the navigator, and those of the next outage
    /// its snapshot may take).
    pub(super) gnss: FixAhead<'g>,
    pub(super) gi0: usize,
    pub(super) lever_arm_m: [f64; 3],
}

impl<T: Scalar> EngineHooks<'_, '_, T> {
    /// Drops the fixes before index `given` (given to the navigator) that no snapshot will
    /// take (before the next outage's start, or all when there is no coasting).
    pub(super) fn release_fixes(&mut self, given: usize) {
        let keep_s = match self.outages.get(self.next_outage) {
            Some(o) if !self.coast_modes.is_empty() => o.start_s,
            _ => f64::INFINITY,
        };
        self.gnss.release(given, keep_s);
    }

    pub(super) fn stopped(&self) -> bool {
        self.err.is_some() || self.fault.is_some()
    }

    fn put(&mut self, r: Result<(), RunError>) {
        if let Err(e) = r {
            self.err.get_or_insert(e);
        }
    }

    /// The nav and epoch records of the filter's current epoch (by their rates).
    pub(super) fn record<const N: usize>(&mut self, f: &Filter<T, N>) {
        let t = f.nav_state().t_s;
        let take_nav = self.nav_dec.take(t);
        let take_ep = self.ep_dec.take(t) && self.want_epochs;
        if take_nav || take_ep {
            let s = if take_ep || self.want_nav_std {
                f.solution()
            } else {
                // the same position, velocity, attitude and status; sigmas NaN (unread)
                NavSolution {
                    status: f.status(),
                    ..f.nav_state().to_solution()
                }
            };
            if take_nav {
                let r = self.sink.nav(&s);
                self.put(r);
            }
            if take_ep {
                let r = self.sink.epoch(EpochRecord {
                    t_s: t,
                    nav: s,
                    state_std: f.state_std().to_vec(),
                    estimates: all_estimates(f),
                    blocks: block_estimates(f),
                });
                self.put(r);
            }
        }
    }

    /// Steps the coasters on the raw sample being pushed (once).
    pub(super) fn step_coasters(&mut self) {
        let Some((s, next_t)) = self.raw.take() else {
            return;
        };
        let mut i = 0;
        while let Some(c) = self.coasters.get_mut(i) {
            if c.step(&s, next_t) {
                let (m, t) = self.coasters.swap_remove(i).finish();
                self.sink.coast(m, t);
            } else {
                i += 1;
            }
        }
    }

    /// Snapshots at the first IMU epoch at or after an outage start (and its coasters).
    fn snapshots<const N: usize>(&mut self, f: &Filter<T, N>) {
        let t_k = f.nav_state().t_s;
        while let Some(o) = self.outages.get(self.next_outage) {
            if t_k < o.start_s {
                break;
            }
            if t_k < o.end_s() {
                let snap = OutageSnapshot {
                    outage: self.next_outage,
                    next_imu: self.next_index,
                    state: *f.nav_state(),
                    correction: f.imu_correction(),
                };
                self.sink.snapshot(&snap);
                if !self.coast_modes.is_empty() {
                    // the fixes the run withholds in this outage (all reached so far or later:
                    // read ahead to the outage's end; the fixes in time order)
                    let mut fixes = (Vec::new(), Vec::new());
                    // (those released before cannot be in it: before its start)
                    let mut i = self.gi0.max(self.gnss.first_held());
                    while let Some(g) = self.gnss.get(i) {
                        if g.t_s >= o.end_s() {
                            break;
                        }
                        if outage::find(self.outages, g.t_s) == Some(self.next_outage) {
                            fixes.0.push(g);
                            fixes.1.push(i);
                        }
                        i += 1;
                    }
                    for (m, mode) in self.coast_modes.iter().enumerate() {
                        let corr = match mode {
                            CoastMode::Raw => ImuCorrection::default(),
                            CoastMode::Held => snap.correction,
                            CoastMode::Fixed(c) => **c,
                        };
                        self.coasters.push(Coaster::new(
                            m,
                            self.next_outage,
                            o.end_s(),
                            corr,
                            snap.state,
                            fixes.clone(),
                            self.lever_arm_m,
                        ));
                    }
                }
            }
            self.next_outage += 1;
        }
    }
}

impl<T: Scalar, const N: usize> NavHooks<T, N> for EngineHooks<'_, '_, T> {
    fn observes_covariance(&self) -> bool {
        self.rec.is_enabled()
    }

    fn observer(&mut self) -> impl CovObserver<T, N> + '_ {
        ObserveWith(&mut self.rec)
    }

    fn after_sample(&mut self, filter: &mut Filter<T, N>) {
        if !self.stopped() {
            self.aid.after_imu(filter, &mut self.rec);
        }
    }

    fn withhold_fix(&mut self, filter: &Filter<T, N>, fix: &GnssFix) -> bool {
        if self.fault.is_some() {
            // the run stops at this epoch: no later fix is used
            return true;
        }
        let Some(oi) = outage::find(self.outages, fix.t_s) else {
            return false;
        };
        self.processed += 1;
        self.counters.gnss_withheld += 1;
        // the antenna as the filter models it: configured lever arm plus any lever-arm
        // estimate, at IMU time t_fix + the estimated time offset
        let shifted = GnssFix {
            t_s: fix.t_s + filter.time_offset_s(),
            ..*fix
        };
        let inn = position_innovation(filter.nav_state(), &filter.lever_arm_body_m(), &shifted);
        let r = self
            .sink
            .innovation(&InnovationRecord::withheld(fix, oi, inn));
        self.put(r);
        true
    }

    fn before_gnss(&mut self, fix: &GnssFix) {
        self.processed += 1;
        self.aid.note_fix(fix);
    }

    fn on_fix(&mut self, filter: &Filter<T, N>, fix: &GnssFix, ev: &FixEvent) {
        let r = match ev {
            FixEvent::Refused {
                error:
                    FilterError::InvalidGnss | FilterError::GnssTime { .. } | FilterError::Numerical,
                ..
            } => {
                self.counters.gnss_invalid += 1;
                if matches!(
                    ev,
                    FixEvent::Refused {
                        error: FilterError::GnssTime { .. },
                        ..
                    }
                ) {
                    self.counters.gnss_mistimed += 1;
                }
                InnovationRecord {
                    t_s: fix.t_s,
                    used: FixUse::Invalid,
                    outage: None,
                    dim: 0,
                    innovation: [f64::NAN; 6],
                    innovation_var: [f64::NAN; 6],
                    nis: f64::NAN,
                    nis_threshold: f64::NAN,
                    quality: if fix.quality == FixQuality::NoFix {
                        0
                    } else {
                        fix.quality.rtklib_q()
                    },
                }
            }
            FixEvent::Refused { error, .. } => {
                self.fault.get_or_insert((
                    format!("GNSS fix at t = {:.3} s", fix.t_s),
                    fix.t_s,
                    super::super::FaultCause::Filter(*error),
                ));
                return;
            }
            FixEvent::Accepted(o)
            | FixEvent::Downweighted(o)
            | FixEvent::Rejected(o)
            | FixEvent::Reset(o) => {
                self.status_seen |= filter.status();
                let r = record_of(o, fix);
                match r.used {
                    FixUse::Accepted => self.counters.gnss_accepted += 1,
                    FixUse::Forced => {
                        self.counters.gnss_accepted += 1;
                        self.counters.gnss_forced += 1
                    }
                    _ => self.counters.gnss_rejected += 1,
                }
                r
            }
        };
        if self.err.is_none() {
            let res = self.sink.innovation(&r);
            self.put(res);
        }
    }

    fn on_epoch_done(&mut self, filter: &Filter<T, N>) {
        if self.stopped() {
            return;
        }
        self.snapshots(filter);
        self.record(filter);
        self.step_coasters();
    }
}
