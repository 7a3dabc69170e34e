//! The covariance-prediction observer (`filter::observe`, for the host's smoother): on a
//! simulated NBK drive with GNSS, every prediction is handed over, in a chain of intervals
//! (each starts where the previous ended), with P before equal to the filter's covariance
//! before the call, P after equal to it afterwards, P after = Phi (P before + ...) consistent
//! with a pure prediction when no update came between, and the correction equal to the sum
//! of what the updates fed back (read from the nominal-state jump); the observed and plain
//! calls give bit-identical filters.

use nav_core::config::FilterConfig;
use nav_core::filter::observe::{CovObserver, PredictionRecord};
use nav_core::filter::Filter;
use nav_core::model::discrete::Cov;
use nav_core::model::LAYOUT_NBK;
use test_support::filter_sim::*;

const N: usize = LAYOUT_NBK.dim();

#[derive(Default)]
struct Log {
    t: Vec<(f64, f64)>,
    before: Vec<Cov<f64, N>>,
    after: Vec<Cov<f64, N>>,
    corr: Vec<[f64; N]>,
    phi_dense: Vec<Cov<f64, N>>,
}

impl CovObserver<f64, N> for Log {
    fn predicted(&mut self, r: &PredictionRecord<'_, f64, N>) {
        self.t.push((r.t_start_s, r.t_end_s));
        self.before.push(*r.p_before);
        self.after.push(*r.p_after);
        self.corr.push(*r.correction);
        self.phi_dense.push(r.phi.to_dense());
    }
}

#[test]
fn every_prediction_is_observed_in_a_chain_with_its_corrections() {
    let sc = SimConfig::nbk(100.0);
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = sc.lever_arm_body_m;
    let mut sim = Sim::new(sc, 5);
    let unc = test_uncertainty();
    let mut f: Filter<f64, N> = start_filter(&mut sim, LAYOUT_NBK, &cfg, &unc);
    let mut plain = f.clone();
    let mut log = Log::default();
    let mut updates_since = 0usize;
    let mut update_corr_sum = [0.0f64; N];
    let mut checked_corr = 0;
    for _ in 0..6000 {
        let ep = sim.step();
        let n_before = log.t.len();
        let p_prev = *f.covariance();
        f.propagate_observed(&ep.imu, &mut log).unwrap();
        plain.propagate(&ep.imu).unwrap();
        if log.t.len() > n_before {
            // the prediction of this call: P before = the covariance before the call
            assert_eq!(log.before[n_before], p_prev);
            assert_eq!(&log.after[n_before], f.covariance());
            let c = log.corr[n_before];
            if updates_since > 0 {
                for (a, b) in c.iter().zip(&update_corr_sum) {
                    assert!((a - b).abs() <= 1e-12 * b.abs().max(1e-9), "{a} vs {b}");
                }
                checked_corr += 1;
            } else {
                assert!(c.iter().all(|v| *v == 0.0));
            }
            updates_since = 0;
            update_corr_sum = [0.0; N];
        }
        if let Some(fix) = ep.gnss {
            f.predict_covariance_observed(&mut log).unwrap();
            let v0 = f.nav_state().vel_ned_mps;
            let o = f.update_gnss(&fix).unwrap();
            plain.update_gnss(&fix).unwrap();
            if !o.accepted {
                continue;
            }
            // the velocity part of the fed-back correction: v <- v - dv
            let dv = v0 - f.nav_state().vel_ned_mps;
            let pend = f.pending_correction();
            for i in 0..3 {
                assert!((pend[3 + i] - dv[i]).abs() < 1e-12, "{pend:?} {dv}");
            }
            update_corr_sum = *pend;
            updates_since += 1;
        }
    }
    assert_eq!(log.t.len() as u32, f.counters().cov_predictions);
    assert!(log.t.len() > 500);
    assert!(checked_corr > 50, "{checked_corr}");
    for w in log.t.windows(2) {
        assert!((w[1].0 - w[0].1).abs() < 1e-9, "{w:?}");
        assert!(w[1].1 > w[1].0);
    }
    // without an update between, P before(k+1) = P after(k); Phi is the filter's transition
    // (core rows dense, identity-like diagonal below)
    let mut chained = 0;
    for k in 0..log.t.len() - 1 {
        if log.corr[k + 1].iter().all(|v| *v == 0.0) {
            assert_eq!(log.before[k + 1], log.after[k]);
            chained += 1;
        }
        let phi = &log.phi_dense[k];
        for (i, row) in phi.iter().enumerate() {
            assert!(row[i] > 0.9 && row[i] <= 1.0 + 1e-3, "{i}: {}", row[i]);
        }
    }
    assert!(chained > 100);
    // the observer changes nothing
    assert_eq!(f.covariance(), plain.covariance());
    assert_eq!(f.nav_state(), plain.nav_state());
}
