//! Odometer / wheel speed (`nav_core::aiding::odometer`): on the simulated
//! 100 s drive (test-support, 100 Hz, 1 Hz RTK fixes) with four 60 s GNSS outages, a wheel
//! speed with an undeclared 2 % scale factor and 0.02 m/s of noise at 10 Hz:
//!
//! * with the scale-factor state (`Block::OdometerScale`) the scale factor is estimated to
//!   within 0.1 % (and within 3 sigma);
//! * the 60 s outage drift is at most a third of GNSS-only;
//! * without the state the undeclared 2 % is a velocity error of 2 %: the outage drift is
//!   larger than with it.
//!
//! Numbers are printed (`--nocapture`).

use nav_core::aiding::{Aiding, AidingConfig, AidingInputs};
use nav_core::config::FilterConfig;
use nav_core::filter::Filter;
use nav_core::model::{Block, BlockKind, Layout, LAYOUT_NBK};
use nav_core::strapdown::NavState;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use test_support::filter_sim::*;

const N18: usize = LAYOUT_NBK.dim();
const L_ODO: Layout = LAYOUT_NBK.with(Block::OdometerScale);
const N19: usize = L_ODO.dim();
const K_TRUE: f64 = 0.02;

fn wheel_speed(truth: &NavState) -> f64 {
    let c = truth.q_nb.to_rotation_matrix().into_inner();
    (c.transpose() * truth.vel_ned_mps).x
}

/// Per-outage maximum horizontal error of one filter (with or without the odometer).
struct Run<const N: usize> {
    f: Filter<f64, N>,
    aid: Option<Aiding<f64, 64>>,
    max_err: Vec<f64>,
}

impl<const N: usize> Run<N> {
    fn new(layout: Layout, cfg: &FilterConfig, init: NavState, odometer: bool) -> Self {
        let unc = test_uncertainty();
        let mut a = AidingConfig::OFF;
        a.odometer.enabled = odometer;
        a.odometer.sigma_mps = 0.02;
        Self {
            f: Filter::new(layout, cfg, init, &unc).unwrap(),
            aid: odometer.then(|| Aiding::new(&a).unwrap()),
            max_err: Vec::new(),
        }
    }
}

#[test]
fn odometer_scale_factor_is_estimated_and_outage_drift_shrinks() {
    let mut sc = SimConfig::nbk(100.0);
    sc.gnss_pos_sigma_m = [0.02, 0.02, 0.04];
    let cfg = FilterConfig {
        lever_arm_body_m: sc.lever_arm_body_m,
        ..FilterConfig::source_nbk_model()
    };
    let mut sim = Sim::new(sc, 81);
    let init = sim.perturbed_initial(&test_uncertainty());
    let mut gnss_only: Run<N18> = Run::new(LAYOUT_NBK, &cfg, init, false);
    let mut odo_fixed: Run<N18> = Run::new(LAYOUT_NBK, &cfg, init, true);
    let mut odo_sf: Run<N19> = Run::new(L_ODO, &cfg, init, true);
    let outages = outage_plan(150.0, 120.0, 60.0, 4);
    let mut rng = ChaCha8Rng::seed_from_u64(82);
    let t0 = sim.truth().t_s;
    let mut k_at_first_outage = f64::NAN;
    for _ in 0..(630.0 * 100.0) as usize {
        let e = sim.step();
        let tau = e.truth.t_s - t0;
        let outage = outages.iter().position(|(a, b)| tau >= *a && tau < *b);
        let speed = (1.0 + K_TRUE) * wheel_speed(&e.truth) + 0.02 * randn(&mut rng);
        let inputs = AidingInputs {
            gnss_speed: None,
            odometer_speed_mps: Some(speed),
        };
        macro_rules! step {
            ($r:expr) => {{
                let r = &mut $r;
                r.f.propagate(&e.imu).unwrap();
                if let Some(a) = r.aid.as_mut() {
                    a.on_imu_with(&mut r.f, &inputs);
                }
                if let (None, Some(fix)) = (outage, e.gnss) {
                    r.f.update_gnss(&fix).unwrap();
                }
                if let Some(k) = outage {
                    let (_, _, dr) = nav_errors(r.f.nav_state(), &e.truth);
                    let h = (dr[0] * dr[0] + dr[1] * dr[1]).sqrt();
                    if r.max_err.len() <= k {
                        r.max_err.push(0.0);
                    }
                    r.max_err[k] = r.max_err[k].max(h);
                }
            }};
        }
        step!(gnss_only);
        step!(odo_fixed);
        step!(odo_sf);
        if k_at_first_outage.is_nan() && outage.is_some() {
            k_at_first_outage = odo_sf.f.block_estimate(BlockKind::OdometerScale).unwrap()[0];
        }
    }
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let v = odo_sf.f.block_value(BlockKind::OdometerScale).unwrap();
    let (k_hat, k_sigma) = (v.estimate[0], v.sigma[0]);
    let counts = odo_sf.aid.as_ref().unwrap().counters().odometer;
    println!(
        "odometer scale factor: true {K_TRUE}, estimated {k_hat:.5} +- {k_sigma:.5} (at the \
         first outage {k_at_first_outage:.5}); odometer updates {counts:?}"
    );
    println!(
        "60 s outages, RMS of per-outage max horizontal error: GNSS only {:.3} m {:?}, odometer \
         without scale state {:.3} m, with it {:.3} m {:?}",
        rms(&gnss_only.max_err),
        gnss_only.max_err,
        rms(&odo_fixed.max_err),
        rms(&odo_sf.max_err),
        odo_sf.max_err,
    );
    assert_eq!(gnss_only.max_err.len(), 4);
    assert!((k_hat - K_TRUE).abs() < 1e-3, "{k_hat}");
    assert!(
        (k_hat - K_TRUE).abs() < 3.0 * k_sigma,
        "{k_hat} +- {k_sigma}"
    );
    assert!((k_at_first_outage - K_TRUE).abs() < 1e-3);
    assert!(counts.used > 5000 && counts.failed == 0);
    assert!(rms(&odo_sf.max_err) <= rms(&gnss_only.max_err) / 3.0);
    assert!(rms(&odo_sf.max_err) < rms(&odo_fixed.max_err));
}
