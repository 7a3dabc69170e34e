//! On-target unit tests of the numerically delicate parts, run on the emulated Cortex-M4F
//! (`cargo xtask fw test`; CI runs it): a semihosting test runner (each test prints
//! `test <name> ... ok|FAILED: <why>`, the exit code is the verdict). defmt-test would need
//! the defmt transport in every build of this binary; the runner below is the same idea with
//! the firmware's own log macros.
//!
//! - the f32 covariance stays exactly symmetric and positive definite (Cholesky in f32) over
//!   a long run of the 21-state filter, through a 60 s GNSS outage and the update after it;
//! - the innovation gate rejects an outlier fix without touching the state, and accepts the
//!   next good one;
//! - reset: after `max_consecutive_rejections` rejected fixes (the antenna "jumped" 150 m), the
//!   next fix is forced, the filter resets onto the new position and is consistent again.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use firmware::scenario::{imu_sample, start_pos, Lcg};
use firmware::{board, error, info};
use nalgebra::Vector3;
use nav_core::config::FilterConfig;
use nav_core::filter::{Filter, InitialUncertainty, STATUS_LAST_FIX_REJECTED};
use nav_core::model::{Layout, LAYOUT_KF_GINS, LAYOUT_NBK};
use nav_core::strapdown::NavState;
use nav_core::types::{FixQuality, GnssFix};

const IMU_HZ: f64 = 200.0;
const T0_S: f64 = 5000.0;
/// Metres per radian of latitude (close enough for the offsets used here).
const M_PER_RAD: f64 = 6_370_000.0;

/// A fix at the start position moved `north_m` north, with 1e-8 rad of noise.
fn fix(t_s: f64, north_m: f64, rng: &mut Lcg) -> GnssFix {
    let p = start_pos();
    GnssFix {
        t_s,
        lat_rad: p.lat_rad + north_m / M_PER_RAD + 1e-8 * rng.next(),
        lon_rad: p.lon_rad + 1e-8 * rng.next(),
        h_m: p.h_m + 0.05 * rng.next(),
        pos_std_ned_m: [0.5, 0.5, 1.0],
        vel_ned_mps: [0.0; 3],
        vel_std_ned_mps: [0.1; 3],
        has_velocity: false,
        quality: FixQuality::Single,
        num_sats: 12,
    }
}

fn new_filter<const N: usize>(
    layout: Layout,
    cfg: &FilterConfig,
) -> Result<Filter<f32, N>, &'static str> {
    let init = NavState::from_rpy(T0_S, start_pos(), Vector3::zeros(), [0.0, 0.0, 0.0]);
    let unc = InitialUncertainty {
        att_sigma_rad: [0.01, 0.01, 0.05],
        vel_sigma_mps: [0.1; 3],
        pos_sigma_m: [1.0; 3],
    };
    Filter::new(layout, cfg, init, &unc).map_err(|_| "filter construction failed")
}

/// Exact symmetry (the prediction mirrors the upper triangle; the update keeps it) and a
/// successful f32 Cholesky factorisation.
fn spd_and_symmetric<const N: usize>(f: &Filter<f32, N>) -> Result<(), &'static str> {
    let p = f.covariance();
    for i in 0..N {
        for j in 0..i {
            if p[i][j].to_bits() != p[j][i].to_bits() {
                return Err("covariance not exactly symmetric");
            }
        }
        if !(p[i][i] > 0.0) {
            return Err("covariance diagonal not positive");
        }
    }
    if !f.covariance_is_positive_definite() {
        return Err("covariance not positive definite (f32 Cholesky failed)");
    }
    Ok(())
}

fn north_error_m<const N: usize>(f: &Filter<f32, N>, north_m: f64) -> f64 {
    (f.nav_state().pos.lat_rad - start_pos().lat_rad) * M_PER_RAD - north_m
}

/// 21 states, 180 s at 200 Hz (36,000 epochs, 1,800 predictions), 1 Hz fixes except a 60 s
/// outage; symmetry and SPD checked every second and after every update; the position sigma
/// must grow in the outage and come back after it.
fn covariance_stays_spd_over_a_long_run_21_states_f32() -> Result<(), &'static str> {
    let cfg = FilterConfig::source_nbk_model();
    let mut f = new_filter::<{ LAYOUT_KF_GINS.dim() }>(LAYOUT_KF_GINS, &cfg)?;
    let mut rng = Lcg(11);
    let (mut sigma_before, mut sigma_end_outage) = (0.0f64, 0.0f64);
    for k in 1..=36_000u32 {
        let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
        f.propagate(&s).map_err(|_| "propagate failed")?;
        if k % 200 == 0 {
            let sec = k / 200;
            let in_outage = (60..120).contains(&sec);
            if sec == 59 {
                sigma_before = f.solution().pos_std_ned_m[0];
            }
            if sec == 119 {
                f.predict_covariance().map_err(|_| "prediction failed")?;
                sigma_end_outage = f.solution().pos_std_ned_m[0];
            }
            if !in_outage {
                let o = f
                    .update_gnss(&fix(s.t_s, 0.0, &mut rng))
                    .map_err(|_| "update failed")?;
                if !o.accepted {
                    return Err("a good fix was rejected");
                }
            }
            spd_and_symmetric(&f)?;
        }
    }
    let sigma_end = f.solution().pos_std_ned_m[0];
    info!(
        "  north sigma: {} m before the outage, {} m at its end, {} m at the end",
        sigma_before, sigma_end_outage, sigma_end
    );
    if !(sigma_end_outage > 2.0 * sigma_before && sigma_end < 0.5 * sigma_end_outage) {
        return Err("position sigma did not grow in the outage and shrink after it");
    }
    if f.counters().numerical_failures != 0 {
        return Err("numerical failures counted");
    }
    Ok(())
}

/// 18 states: converge 20 s, then a fix 30 m off is rejected (state and covariance
/// untouched, status bit set, counter +1) and the next good fix is accepted.
fn gate_rejects_an_outlier_and_accepts_the_next_fix() -> Result<(), &'static str> {
    let cfg = FilterConfig::source_nbk_model();
    let mut f = new_filter::<{ LAYOUT_NBK.dim() }>(LAYOUT_NBK, &cfg)?;
    let mut rng = Lcg(12);
    let mut k = 0u32;
    let mut t = T0_S;
    for _ in 0..20 {
        for _ in 0..200 {
            k += 1;
            let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
            t = s.t_s;
            f.propagate(&s).map_err(|_| "propagate failed")?;
        }
        let o = f
            .update_gnss(&fix(t, 0.0, &mut rng))
            .map_err(|_| "update failed")?;
        if !o.accepted {
            return Err("a good fix was rejected while converging");
        }
    }
    for _ in 0..200 {
        k += 1;
        let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
        t = s.t_s;
        f.propagate(&s).map_err(|_| "propagate failed")?;
    }
    f.predict_covariance().map_err(|_| "prediction failed")?;
    let before = *f.nav_state();
    let p_before = *f.covariance();
    let rejected_before = f.counters().gnss_rejected;
    let o = f
        .update_gnss(&fix(t, 30.0, &mut rng))
        .map_err(|_| "update failed")?;
    info!(
        "  outlier 30 m: NIS {} (threshold {})",
        o.nis, o.nis_threshold
    );
    if o.accepted || o.forced || !(o.nis > o.nis_threshold) {
        return Err("the 30 m outlier passed the gate");
    }
    if f.counters().gnss_rejected != rejected_before + 1
        || f.status() & STATUS_LAST_FIX_REJECTED == 0
    {
        return Err("rejection not counted or not in the status");
    }
    if f.nav_state().pos.lat_rad.to_bits() != before.pos.lat_rad.to_bits()
        || f.covariance() != &p_before
    {
        return Err("a rejected fix changed the state or the covariance");
    }
    for _ in 0..200 {
        k += 1;
        let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
        t = s.t_s;
        f.propagate(&s).map_err(|_| "propagate failed")?;
    }
    let o = f
        .update_gnss(&fix(t, 0.0, &mut rng))
        .map_err(|_| "update failed")?;
    if !o.accepted || o.forced || f.status() & STATUS_LAST_FIX_REJECTED != 0 {
        return Err("the good fix after the outlier was not accepted cleanly");
    }
    spd_and_symmetric(&f)
}

/// 18 states: converge, then every fix is 150 m north (the antenna's true position changed):
/// the gate rejects `max_consecutive_rejections` of them, the next is forced (reset onto the
/// new position: north error under 3 m), and the following fixes pass the gate again.
fn forced_update_resets_the_filter_after_consecutive_rejections() -> Result<(), &'static str> {
    let cfg = FilterConfig::source_nbk_model();
    let max_rej = cfg.gating.max_consecutive_rejections;
    if max_rej == 0 {
        return Err("the default gating never forces");
    }
    let mut f = new_filter::<{ LAYOUT_NBK.dim() }>(LAYOUT_NBK, &cfg)?;
    let mut rng = Lcg(13);
    let mut k = 0u32;
    let mut forced_at = None;
    let mut rejected = 0u32;
    for sec in 1..=(20 + max_rej + 10) {
        let mut t = T0_S;
        for _ in 0..200 {
            k += 1;
            let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
            t = s.t_s;
            f.propagate(&s).map_err(|_| "propagate failed")?;
        }
        let north = if sec > 20 { 150.0 } else { 0.0 };
        let o = f
            .update_gnss(&fix(t, north, &mut rng))
            .map_err(|_| "update failed")?;
        if sec > 20 && forced_at.is_none() {
            if o.forced {
                forced_at = Some(sec);
                let e = north_error_m(&f, 150.0);
                info!(
                    "  forced after {} rejections: north error {} m",
                    rejected, e
                );
                if !(libm::fabs(e) < 3.0) {
                    return Err("the forced update did not reset onto the new position");
                }
            } else if o.accepted {
                return Err("a 150 m jump passed the gate");
            } else {
                rejected += 1;
            }
        } else if forced_at.is_some() && (!o.accepted || o.forced) {
            return Err("fixes after the reset did not pass the gate");
        }
        spd_and_symmetric(&f)?;
    }
    if rejected != max_rej || forced_at.is_none() {
        return Err("not exactly max_consecutive_rejections rejections before the forced fix");
    }
    if f.counters().gnss_forced != 1 {
        return Err("forced updates miscounted");
    }
    let e = north_error_m(&f, 150.0);
    if !(libm::fabs(e) < 1.0) {
        return Err("the filter did not settle on the new position");
    }
    Ok(())
}

/// The tests, in order.
const TESTS: &[(&str, fn() -> Result<(), &'static str>)] = &[
    (
        "covariance_stays_spd_over_a_long_run_21_states_f32",
        covariance_stays_spd_over_a_long_run_21_states_f32,
    ),
    (
        "gate_rejects_an_outlier_and_accepts_the_next_fix",
        gate_rejects_an_outlier_and_accepts_the_next_fix,
    ),
    (
        "forced_update_resets_the_filter_after_consecutive_rejections",
        forced_update_resets_the_filter_after_consecutive_rejections,
    ),
];

#[entry]
fn main() -> ! {
    let _b = board::init();
    let mut passed = 0usize;
    for (name, t) in TESTS {
        match t() {
            Ok(()) => {
                info!("test {} ... ok", name);
                passed += 1;
            }
            Err(why) => error!("test {} ... FAILED: {}", name, why),
        }
    }
    info!("on-target tests: {} of {} passed", passed, TESTS.len());
    board::exit(passed == TESTS.len())
}
