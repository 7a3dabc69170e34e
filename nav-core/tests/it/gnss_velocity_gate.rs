//! GNSS velocity with its own gate (`Gating::velocity`): a fix's
//! velocity is used by its own 3-dimensional update after the position, gated on its own and
//! counted in `Counters::gnss_vel_*`.
//!
//! * Without gates the two sequential updates give the joint 6-dimensional update's solution.
//! * Wrong Doppler velocities (2.2 m/s on every 7th fix): the joint gate loses those fixes'
//!   positions (rejected or down-weighted together), the separate gate rejects exactly the
//!   bad velocities and keeps every position.
//! * A burst of 15 wrong velocities in a row: the joint robust gate widens and takes them (the
//!   solution is pulled metres away); the separate gate rejects them.
//! * Position outliers (8 m on every 9th fix) with good velocities: the separate gate rejects
//!   the positions and still uses the velocities.
//!
//! Numbers are printed (`--nocapture`).

use nav_core::config::{FilterConfig, GateProbability, Gating, VelocityGating};
use nav_core::earth::{self, Llh};
use nav_core::filter::Filter;
use nav_core::model::LAYOUT_NBK;
use nav_core::types::GnssFix;
use test_support::filter_sim::*;

const N18: usize = LAYOUT_NBK.dim();

fn horiz(d: &[f64; 3]) -> f64 {
    (d[0] * d[0] + d[1] * d[1]).sqrt()
}

fn cfg_with(sc: &SimConfig, gating: Gating) -> FilterConfig {
    FilterConfig {
        lever_arm_body_m: sc.lever_arm_body_m,
        use_gnss_velocity: true,
        gating,
        ..FilterConfig::source_nbk_model()
    }
}

fn sim_config() -> SimConfig {
    let mut sc = SimConfig::nbk(100.0);
    sc.gnss_velocity = true;
    sc.gnss_pos_sigma_m = [0.3, 0.3, 0.6];
    sc.gnss_vel_sigma_mps = [0.05, 0.05, 0.1];
    sc
}

/// Per-fix horizontal position and velocity errors after the update, for two filters on the
/// same data; `corrupt(fix index, fix)` changes the fix both are given.
struct Pair {
    a: Filter<f64, N18>,
    b: Filter<f64, N18>,
    pos_err: [Vec<f64>; 2],
    vel_err: [Vec<f64>; 2],
}

fn run_pair(
    seed: u64,
    fixes: usize,
    gating: [Gating; 2],
    corrupt: impl Fn(usize, &mut GnssFix),
) -> Pair {
    let sc = sim_config();
    let mut sim = Sim::new(sc, seed);
    let unc = test_uncertainty();
    let init = sim.perturbed_initial(&unc);
    let mut a = Filter::new(LAYOUT_NBK, &cfg_with(&sc, gating[0]), init, &unc).unwrap();
    let mut b = Filter::new(LAYOUT_NBK, &cfg_with(&sc, gating[1]), init, &unc).unwrap();
    let mut pos_err = [Vec::new(), Vec::new()];
    let mut vel_err = [Vec::new(), Vec::new()];
    let mut k = 0;
    while k < fixes {
        let e = sim.step();
        a.propagate(&e.imu).unwrap();
        b.propagate(&e.imu).unwrap();
        let Some(mut fix) = e.gnss else { continue };
        k += 1;
        corrupt(k, &mut fix);
        a.update_gnss(&fix).unwrap();
        b.update_gnss(&fix).unwrap();
        for (i, f) in [&a, &b].into_iter().enumerate() {
            let (_, dv, dr) = nav_errors(f.nav_state(), &e.truth);
            pos_err[i].push(horiz(&dr));
            vel_err[i].push(horiz(&dv));
        }
    }
    Pair {
        a,
        b,
        pos_err,
        vel_err,
    }
}

fn rms(v: &[f64]) -> f64 {
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

fn separate(g: Gating, v: VelocityGating) -> Gating {
    Gating {
        velocity: Some(v),
        ..g
    }
}

#[test]
fn ungated_separate_velocity_updates_equal_the_joint_update() {
    let p = run_pair(
        71,
        300,
        [
            Gating::disabled(),
            separate(Gating::disabled(), VelocityGating::OFF),
        ],
        |_, _| {},
    );
    let (sa, sb) = (p.a.nav_state(), p.b.nav_state());
    let dr = earth::ned_offset_m(&sb.pos, &sa.pos);
    let dv = (sa.vel_ned_mps - sb.vel_ned_mps).norm();
    let dq = sa.q_nb.angle_to(&sb.q_nb);
    println!(
        "joint vs separate after 300 fixes: {:.3e} m, {:.3e} m/s, {:.3e} rad; error RMS {:.4} vs {:.4} m",
        dr.norm(),
        dv,
        dq,
        rms(&p.pos_err[0]),
        rms(&p.pos_err[1])
    );
    // equal to first order: the velocity residual is taken again at the state the position
    // update left (relinearised), so the difference is second order in the corrections, far
    // below the errors themselves
    assert!(dr.norm() < 1e-4 * rms(&p.pos_err[0]), "{dr}");
    assert!(dv < 1e-4 * rms(&p.vel_err[0]) && dq < 1e-6, "{dv} {dq}");
    let c = p.b.counters();
    assert_eq!((c.gnss_vel_accepted, c.gnss_vel_rejected), (300, 0));
    assert_eq!(p.a.counters().gnss_vel_accepted, 0);
    assert_eq!(p.a.counters().gnss_accepted, 300);
    assert_eq!(c.gnss_accepted, 300);
}

#[test]
fn wrong_doppler_velocities_are_rejected_alone_and_positions_kept() {
    let bad = |k: usize| k > 30 && k.is_multiple_of(7);
    let p = run_pair(
        72,
        400,
        [
            Gating::robust(),
            separate(Gating::robust(), VelocityGating::ROBUST),
        ],
        |k, fix| {
            if bad(k) {
                fix.vel_ned_mps[0] += 2.0;
                fix.vel_ned_mps[1] -= 1.0;
            }
        },
    );
    let n_bad = (1..=400).filter(|k| bad(*k)).count() as u32;
    let (ca, cb) = (p.a.counters(), p.b.counters());
    let dw_a = p.a.robust_stats().downweighted;
    println!(
        "joint: {} used ({dw_a} down-weighted), {} rejected; separate: positions {} used / {} \
         rejected, velocities {} used ({} down-weighted) / {} rejected of {n_bad} bad; \
         position error RMS {:.3} vs {:.3} m, velocity {:.4} vs {:.4} m/s",
        ca.gnss_accepted,
        ca.gnss_rejected,
        cb.gnss_accepted,
        cb.gnss_rejected,
        cb.gnss_vel_accepted,
        cb.gnss_vel_downweighted,
        cb.gnss_vel_rejected,
        rms(&p.pos_err[0]),
        rms(&p.pos_err[1]),
        rms(&p.vel_err[0]),
        rms(&p.vel_err[1]),
    );
    // the separate gate: every bad velocity and nothing else rejected, every position used
    assert_eq!(cb.gnss_vel_rejected, n_bad);
    assert_eq!(cb.gnss_vel_accepted, 400 - n_bad);
    assert_eq!((cb.gnss_accepted, cb.gnss_rejected), (400, 0));
    // the joint gate cannot keep the positions of those fixes
    assert!(ca.gnss_rejected + dw_a >= n_bad, "{ca:?}");
    assert_eq!(ca.gnss_vel_accepted + ca.gnss_vel_rejected, 0);
}

/// A burst of 15 wrong Doppler velocities in a row (multipath along a wall): the joint robust
/// gate rejects the first fixes, then its NIS monitor follows the persistent innovations,
/// widens the gate and takes the wrong velocities (measured: 7.8 m, 1.03 m/s off); the
/// separate gate rejects the 15 velocities and keeps using the positions (0.23 m, 0.03 m/s).
#[test]
fn a_burst_of_wrong_velocities_does_not_pull_the_solution() {
    let bad = |k: usize| (100..115).contains(&k);
    let p = run_pair(
        74,
        200,
        [
            Gating::robust(),
            separate(Gating::robust(), VelocityGating::ROBUST),
        ],
        |k, fix| {
            if bad(k) {
                fix.vel_ned_mps[0] += 2.0;
                fix.vel_ned_mps[1] -= 1.0;
            }
        },
    );
    let (ca, cb) = (p.a.counters(), p.b.counters());
    let max = |v: &[f64]| v.iter().skip(99).take(30).fold(0.0f64, |m, x| m.max(*x));
    println!(
        "burst: joint {} rejected, {} reset(s), max position error {:.3} m, velocity {:.3} m/s; \
         separate {} velocities rejected, {} reset(s), {:.3} m, {:.3} m/s",
        ca.gnss_rejected,
        ca.gnss_forced,
        max(&p.pos_err[0]),
        max(&p.vel_err[0]),
        cb.gnss_vel_rejected,
        cb.gnss_forced,
        max(&p.pos_err[1]),
        max(&p.vel_err[1]),
    );
    assert_eq!(cb.gnss_vel_rejected, 15);
    assert_eq!((cb.gnss_rejected, cb.gnss_forced), (0, 0));
    assert!(max(&p.vel_err[1]) < 0.5 * max(&p.vel_err[0]), "{ca:?}");
    assert!(max(&p.pos_err[1]) < 0.5 * max(&p.pos_err[0]));
}

#[test]
fn position_outliers_are_rejected_while_their_velocities_are_used() {
    let bad = |k: usize| k > 30 && k.is_multiple_of(9);
    let p = run_pair(
        73,
        300,
        [
            Gating::with_probability(GateProbability::P9999, 0),
            separate(
                Gating::with_probability(GateProbability::P9999, 0),
                VelocityGating::hard(GateProbability::P9999),
            ),
        ],
        |k, fix| {
            if bad(k) {
                let p = earth::displace(
                    &Llh {
                        lat_rad: fix.lat_rad,
                        lon_rad: fix.lon_rad,
                        h_m: fix.h_m,
                    },
                    &nalgebra::Vector3::new(6.0, -5.3, 0.0),
                );
                fix.lat_rad = p.lat_rad;
                fix.lon_rad = p.lon_rad;
            }
        },
    );
    let n_bad = (1..=300).filter(|k| bad(*k)).count() as u32;
    let c = p.b.counters();
    println!(
        "joint: {} fixes rejected (their velocities with them); separate: positions {} used / \
         {} rejected of {n_bad} outliers, velocities {} used / {} rejected; velocity error RMS \
         {:.4} vs {:.4} m/s",
        p.a.counters().gnss_rejected,
        c.gnss_accepted,
        c.gnss_rejected,
        c.gnss_vel_accepted,
        c.gnss_vel_rejected,
        rms(&p.vel_err[0]),
        rms(&p.vel_err[1]),
    );
    assert_eq!(p.a.counters().gnss_rejected, n_bad);
    assert_eq!(c.gnss_rejected, n_bad);
    assert_eq!(c.gnss_vel_accepted, 300);
    assert_eq!(c.gnss_vel_rejected, 0);
}
