//! Free-inertial coasting from the filter's state at the start of each outage: the baseline the
//! filter's outage errors are compared with.
//!
//! What "free inertial coasting from the same points" means here: at the first IMU epoch at or
//! after an outage start, the filter's nominal state (position, velocity, attitude) is taken
//! ([`super::OutageSnapshot`]) and the raw IMU samples are integrated by the same
//! mechanisation with NO further corrections until the outage ends. [`CoastMode`] says which
//! sensor-error correction the coasting applies:
//!
//! - [`CoastMode::Raw`]: none: the honest "INS without error estimation" baseline. The
//!   filter's advantage over it is what the bias estimation buys.
//! - [`CoastMode::Fixed`]: a given correction (e.g. the gyro bias from the static start-up
//!   window only: what a calibration without a filter would give).
//! - [`CoastMode::Held`]: the filter's estimates at the outage start, held. This is (up to the
//!   Gauss-Markov decay of the estimates) exactly what the filter itself does inside an outage,
//!   so it is a consistency check, not a baseline.

use super::{position_innovation, CaseData, FixUse, InnovationRecord, RunOutput};
use nav_core::model::ImuCorrection;
use nav_core::navigator::nearest_epoch_horizon;
use nav_core::strapdown::Strapdown;
use nav_core::types::{GnssFix, ImuSample, NavSolution};

/// The sensor-error correction applied while coasting (see the module notes).
#[derive(Debug, Clone, PartialEq)]
pub enum CoastMode {
    /// No correction of the raw IMU samples.
    Raw,
    /// The filter's estimates at the outage start, held.
    Held,
    /// A fixed correction.
    Fixed(Box<ImuCorrection>),
}

/// A coasting solution through one outage.
#[derive(Debug, Clone)]
pub struct CoastTrack {
    /// Index into [`RunOutput::outages`].
    pub outage: usize,
    /// Solution at every IMU epoch from the outage start to its end (standard deviations NaN).
    pub nav: Vec<NavSolution>,
    /// The withheld fixes of the outage against the coasting antenna position (same rules as
    /// the run: nearest IMU epoch, bridged with the velocity).
    pub fixes: Vec<InnovationRecord>,
}

/// Coasts through every outage the run reached (one track per snapshot).
pub fn coast_outages(case: &CaseData, run: &RunOutput, mode: CoastMode) -> Vec<CoastTrack> {
    coast_outages_with(&case.gnss, run, mode, |k| {
        case.imu.get(k..).unwrap_or_default().iter().copied()
    })
}

/// [`coast_outages`] on IMU samples read as needed: `imu_from(k)` yields the case's samples
/// from index `k` on (a snapshot's `next_imu`) in time order, for data not held in memory
/// (the coasting reads each outage's span and one sample beyond); `gnss`: the case's fixes.
pub fn coast_outages_with<I: Iterator<Item = ImuSample>>(
    gnss: &[GnssFix],
    run: &RunOutput,
    mode: CoastMode,
    mut imu_from: impl FnMut(usize) -> I,
) -> Vec<CoastTrack> {
    let mut tracks = Vec::new();
    for snap in &run.snapshots {
        let Some(o) = run.outages.get(snap.outage) else {
            continue;
        };
        let corr = match &mode {
            CoastMode::Raw => ImuCorrection::default(),
            CoastMode::Held => snap.correction,
            CoastMode::Fixed(c) => **c,
        };
        let withheld: Vec<&InnovationRecord> = run
            .innovations
            .iter()
            .filter(|r| r.used == FixUse::Withheld && r.outage == Some(snap.outage))
            .collect();
        let fixes_by_t: Vec<_> = withheld
            .iter()
            .filter_map(|r| {
                gnss.binary_search_by(|g| g.t_s.total_cmp(&r.t_s))
                    .ok()
                    .and_then(|i| gnss.get(i))
            })
            .collect();
        let mut mech = Strapdown::new(snap.state);
        let mut nav = vec![snap.state.to_solution()];
        let mut fixes = Vec::new();
        let mut fi = 0;
        let mut samples = imu_from(snap.next_imu).peekable();
        while let Some(mut s) = samples.next() {
            let dt = s.t_s - mech.state().t_s;
            corr.apply(&mut s.dtheta_rad, &mut s.dv_mps, dt);
            if mech.update(&s).is_err() {
                continue;
            }
            let st = *mech.state();
            nav.push(st.to_solution());
            let dt_next = samples.peek().map_or(dt, |n| n.t_s - st.t_s);
            while let Some(f) = fixes_by_t.get(fi) {
                if f.t_s >= nearest_epoch_horizon(st.t_s, dt_next) {
                    break;
                }
                fi += 1;
                let inn = position_innovation(&st, &run.lever_arm_m, f);
                fixes.push(InnovationRecord::withheld(f, snap.outage, inn));
            }
            if st.t_s >= o.end_s() && fi >= fixes_by_t.len() {
                break;
            }
        }
        tracks.push(CoastTrack {
            outage: snap.outage,
            nav,
            fixes,
        });
    }
    tracks
}
