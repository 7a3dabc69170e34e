//! Budgets measured on the emulated Cortex-M4F: instructions per call (SysTick ticks under
//! `qemu -icount shift=5`; `cargo xtask fw bench` converts ticks to instructions), the filter
//! structs' sizes and the peak stack of each case (painted before it, high-water mark after).
//!
//! Output lines for `cargo xtask fw bench` (ticks are raw SysTick ticks, overhead removed):
//!
//! - `BENCH calib loop_instructions=<n> ticks=<t>`: a loop of exactly n instructions;
//! - `BENCH row case=<case> what=<what> calls=<k> ticks_total=<t> ticks_max=<m>`;
//! - `BENCH size what=<what> bytes=<b>`;
//! - `BENCH stack case=<case> bytes=<b>`;
//! - `BENCH done`.
//!
//! Adding a case is one line in [`CASES`].
//!
//! With the cargo feature `bench-aiding` the binary is a variant that runs only the
//! land-vehicle aiding cases (`nav_core::aiding`, 18 states f32): the default bench binary's
//! flash stays within its budget, and `cargo xtask fw bench` keeps measuring it.
#![no_std]
#![no_main]
#![cfg_attr(feature = "bench-aiding", allow(dead_code))]

use cortex_m_rt::entry;
use firmware::scenario::{imu_sample, start_pos, Lcg};
use firmware::{board, error, info, stack, time::TimeBase};
use nalgebra::Vector3;
use nav_core::config::FilterConfig;
use nav_core::filter::{Filter, InitialUncertainty};
use nav_core::model::{Layout, LAYOUT_NBK};
#[cfg(not(feature = "bench-aiding"))]
use nav_core::model::{LAYOUT_KF_GINS, LAYOUT_N};
use nav_core::strapdown::{NavState, Strapdown};
use nav_core::types::{FixQuality, GnssFix};

/// IMU rate of the scenario, Hz.
const IMU_HZ: f64 = 200.0;
/// IMU epochs per case (10 s at 200 Hz, 10 GNSS updates at 1 Hz).
const EPOCHS: u32 = 2000;
/// IMU epochs per GNSS fix (1 Hz).
const GNSS_EVERY: u32 = 200;

type Clock = board::SysTickClock;

/// Times calls and accumulates per-metric totals.
struct Meter<'a> {
    clock: &'a mut Clock,
    overhead: u64,
}

impl Meter<'_> {
    /// Runs `f`, returns its result and its duration in ticks (measurement overhead removed).
    fn time<R>(&mut self, f: impl FnOnce() -> R) -> (R, u64) {
        let t0 = self.clock.now_ticks();
        let r = f();
        let t1 = self.clock.now_ticks();
        (r, (t1 - t0).saturating_sub(self.overhead))
    }
}

/// Accumulated timing of one metric.
#[derive(Default, Clone, Copy)]
struct Acc {
    calls: u32,
    total: u64,
    max: u64,
}

impl Acc {
    fn add(&mut self, ticks: u64) {
        self.calls += 1;
        self.total += ticks;
        self.max = self.max.max(ticks);
    }
    fn print(&self, case: &str, what: &str) {
        info!(
            "BENCH row case={} what={} calls={} ticks_total={} ticks_max={}",
            case, what, self.calls, self.total, self.max
        );
    }
}

/// A benchmark case: a name (no spaces) and the function that runs and reports it.
struct Case {
    name: &'static str,
    run: fn(&mut Meter, &'static str) -> bool,
}

/// The cases, in order. One line each.
#[cfg(not(feature = "bench-aiding"))]
const CASES: &[Case] = &[
    Case {
        name: "strapdown",
        run: |m, n| strapdown(m, n),
    },
    Case {
        name: "strapdown_single",
        run: |m, n| strapdown_single(m, n),
    },
    Case {
        name: "wire_decode",
        run: |m, n| wire_decode(m, n),
    },
    Case {
        name: "allan_stream",
        run: |m, n| allan_stream(m, n),
    },
    Case {
        name: "filter15_N_f32",
        run: |m, n| filter::<{ LAYOUT_N.dim() }>(m, n, LAYOUT_N, FilterConfig::source_n_model()),
    },
    Case {
        name: "filter18_NBK_f32",
        run: |m, n| {
            filter::<{ LAYOUT_NBK.dim() }>(m, n, LAYOUT_NBK, FilterConfig::source_nbk_model())
        },
    },
    Case {
        name: "filter21_KFGINS_f32",
        run: |m, n| {
            filter::<{ LAYOUT_KF_GINS.dim() }>(
                m,
                n,
                LAYOUT_KF_GINS,
                FilterConfig::source_nbk_model(),
            )
        },
    },
];

/// The aiding variant's cases: the aiding of an 18-state f32 filter at 200 Hz; moving (the
/// filter told it moves at 10 m/s: never still, the NHC runs) or still (ZUPT or ZARU alone).
#[cfg(feature = "bench-aiding")]
const CASES: &[Case] = &[
    Case {
        name: "aiding18_nhc",
        run: |m, n| aiding_case(m, n, 10.0, land_only(true, false, false)),
    },
    Case {
        name: "aiding18_zupt",
        run: |m, n| aiding_case(m, n, 0.0, land_only(false, true, false)),
    },
    Case {
        name: "aiding18_zaru",
        run: |m, n| aiding_case(m, n, 0.0, land_only(false, false, true)),
    },
    Case {
        name: "aiding18_land_still",
        run: |m, n| aiding_case(m, n, 0.0, nav_core::aiding::AidingConfig::LAND),
    },
];

/// `AidingConfig::LAND` with only the chosen sources on.
#[cfg(feature = "bench-aiding")]
fn land_only(nhc: bool, zupt: bool, zaru: bool) -> nav_core::aiding::AidingConfig {
    let mut c = nav_core::aiding::AidingConfig::LAND;
    c.nhc.enabled = nhc;
    c.zupt.enabled = zupt;
    c.zaru.enabled = zaru;
    c
}

/// Times `Aiding::on_imu` after every propagation of an NBK-18 f32 filter (200 Hz, 1 Hz fixes
/// without velocity), `speed_mps` the filter's initial northward speed; rows: every epoch
/// (`on_imu_per_epoch`), epochs that only feed the detector (`detector_push`), decision epochs
/// without an update (`decision_only`) and decision epochs with the enabled updates
/// (`decision_with_updates`, 10 Hz), and the whole epoch: propagation, aiding and the 1 Hz
/// GNSS update (`epoch_incl_aiding_1Hz_gnss`, to compare with `filter18_NBK_f32`'s
/// `epoch_incl_1Hz_gnss`: an aiding update predicts the covariance first, which the next
/// propagation then need not do).
#[cfg(feature = "bench-aiding")]
fn aiding_case(
    m: &mut Meter,
    case: &'static str,
    speed_mps: f64,
    cfg: nav_core::aiding::AidingConfig,
) -> bool {
    use nav_core::aiding::Aiding;
    let unc = InitialUncertainty {
        att_sigma_rad: [0.01, 0.01, 0.05],
        vel_sigma_mps: [0.1; 3],
        pos_sigma_m: [1.0; 3],
    };
    let mut init = init_state();
    init.vel_ned_mps = Vector3::new(speed_mps, 0.0, 0.0);
    let mut f = match Filter::<f32, { LAYOUT_NBK.dim() }>::new(
        LAYOUT_NBK,
        &FilterConfig::source_nbk_model(),
        init,
        &unc,
    ) {
        Ok(f) => f,
        Err(_) => {
            error!("bench {}: filter construction failed", case);
            return false;
        }
    };
    let Ok(mut aid) = Aiding::<f32, { firmware::app::AID_WINDOW }>::new(&cfg) else {
        error!("bench {}: aiding configuration refused", case);
        return false;
    };
    let mut rng = Lcg(5);
    let (mut all, mut push, mut decide, mut update, mut epoch) = (
        Acc::default(),
        Acc::default(),
        Acc::default(),
        Acc::default(),
        Acc::default(),
    );
    for k in 1..=EPOCHS {
        let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
        let (r, t_prop) = m.time(|| f.propagate(&s));
        if r.is_err() {
            error!("bench {}: propagate failed at epoch {}", case, k);
            return false;
        }
        let mut t_epoch = t_prop;
        let before = *aid.counters();
        let ((), t) = m.time(|| aid.on_imu(&mut f, None));
        all.add(t);
        t_epoch += t;
        let after = aid.counters();
        let updates = |c: &nav_core::aiding::AidingCounters| {
            c.nhc.used
                + c.nhc.rejected
                + c.zupt.used
                + c.zupt.rejected
                + c.zaru.used
                + c.zaru.rejected
        };
        if after.epochs == before.epochs {
            push.add(t);
        } else if updates(after) == updates(&before) {
            decide.add(t);
        } else {
            update.add(t);
        }
        if k % GNSS_EVERY == 0 {
            let p0 = start_pos();
            let fix = GnssFix {
                t_s: s.t_s,
                lat_rad: p0.lat_rad,
                lon_rad: p0.lon_rad,
                h_m: p0.h_m,
                pos_std_ned_m: [0.5, 0.5, 1.0],
                vel_ned_mps: [0.0; 3],
                vel_std_ned_mps: [0.1; 3],
                has_velocity: false,
                quality: FixQuality::Single,
                num_sats: 12,
            };
            let (_, t) = m.time(|| f.update_gnss(&fix));
            t_epoch += t;
        }
        epoch.add(t_epoch);
    }
    all.print(case, "on_imu_per_epoch");
    push.print(case, "detector_push");
    decide.print(case, "decision_only");
    update.print(case, "decision_with_updates");
    epoch.print(case, "epoch_incl_aiding_1Hz_gnss");
    let c = aid.counters();
    info!(
        "BENCH counts case={} epochs={} stationary={} nhc={} zupt={} zaru={} failed={}",
        case,
        c.epochs,
        c.stationary_epochs,
        c.nhc.used,
        c.zupt.used,
        c.zaru.used,
        c.nhc.failed + c.zupt.failed + c.zaru.failed
    );
    info!(
        "BENCH size what=Aiding<f32,{}> bytes={}",
        firmware::app::AID_WINDOW,
        core::mem::size_of::<Aiding<f32, { firmware::app::AID_WINDOW }>>()
    );
    update.calls > 0 && f.covariance_is_positive_definite()
}

const T0_S: f64 = 1000.0;

fn init_state() -> NavState {
    NavState::from_rpy(T0_S, start_pos(), Vector3::zeros(), [0.0, 0.0, 0.0])
}

fn strapdown(m: &mut Meter, case: &'static str) -> bool {
    let mut mech = Strapdown::new(init_state());
    let mut rng = Lcg(1);
    let mut acc = Acc::default();
    for k in 1..=EPOCHS {
        let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
        let (r, t) = m.time(|| mech.update(&s));
        if r.is_err() {
            error!("bench {}: mechanization failed at epoch {}", case, k);
            return false;
        }
        acc.add(t);
    }
    acc.print(case, "update_per_epoch");
    info!(
        "BENCH size what=Strapdown bytes={}",
        core::mem::size_of::<Strapdown>()
    );
    true
}

/// [`Strapdown::update_single`] (the `f32` filter's mechanization) on the same samples,
/// the increments rounded to `f32` outside the timed call.
fn strapdown_single(m: &mut Meter, case: &'static str) -> bool {
    let mut mech = Strapdown::new(init_state());
    let mut rng = Lcg(1);
    let mut acc = Acc::default();
    for k in 1..=EPOCHS {
        let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
        let (dth, dv) = (s.dtheta_rad.map(|x| x as f32), s.dv_mps.map(|x| x as f32));
        let (r, t) = m.time(|| mech.update_single(s.t_s, dth, dv));
        if r.is_err() {
            error!("bench {}: mechanization failed at epoch {}", case, k);
            return false;
        }
        acc.add(t);
    }
    acc.print(case, "update_per_epoch");
    true
}

/// Frames of the decoder case: IMU frames with a GNSS fix every 10th (a 200 Hz link carrying
/// 20 Hz of fixes is busier than the real 1 Hz; the mix barely changes the per-byte cost).
const DECODE_FRAMES: u32 = 40;
/// Rounds of decoding the same bytes.
const DECODE_ROUNDS: u32 = 10;

fn wire_decode(m: &mut Meter, case: &'static str) -> bool {
    use nav_core::wire::{Encoder, FrameDecoder, ImuFrame, Payload, MAX_FRAME_LEN};
    let mut buf = [0u8; 4096];
    let mut len = 0usize;
    let mut enc = Encoder::new();
    let mut rng = Lcg(3);
    let mut frames = 0u32;
    for k in 1..=DECODE_FRAMES {
        let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
        let mut one = [0u8; MAX_FRAME_LEN];
        let mut put = |p: &Payload, len: &mut usize| -> bool {
            let Ok(n) = enc.encode(p, &mut one) else {
                return false;
            };
            match (buf.get_mut(*len..*len + n), one.get(..n)) {
                (Some(dst), Some(src)) => {
                    dst.copy_from_slice(src);
                    *len += n;
                    true
                }
                _ => false,
            }
        };
        if !put(
            &Payload::Imu(ImuFrame {
                sample: s,
                status: 0,
            }),
            &mut len,
        ) {
            error!("bench {}: encode buffer full", case);
            return false;
        }
        frames += 1;
        if k % 10 == 0 {
            let p0 = start_pos();
            let fix = GnssFix {
                t_s: s.t_s,
                lat_rad: p0.lat_rad,
                lon_rad: p0.lon_rad,
                h_m: p0.h_m,
                pos_std_ned_m: [0.5, 0.5, 1.0],
                vel_ned_mps: [0.0; 3],
                vel_std_ned_mps: [0.1; 3],
                has_velocity: true,
                quality: FixQuality::Single,
                num_sats: 12,
            };
            if !put(&Payload::Gnss(fix), &mut len) {
                error!("bench {}: encode buffer full", case);
                return false;
            }
            frames += 1;
        }
    }
    let bytes = buf.get(..len).unwrap_or(&[]);
    let mut per_round = Acc::default();
    let mut ok_total = 0u32;
    for _ in 0..DECODE_ROUNDS {
        let mut dec = FrameDecoder::new();
        let (n_ok, t) = m.time(|| dec.feed(bytes).filter(|r| r.is_ok()).count() as u32);
        per_round.add(t);
        ok_total += n_ok;
    }
    if ok_total != frames * DECODE_ROUNDS {
        error!(
            "bench {}: decoded {} frames of {}",
            case,
            ok_total,
            frames * DECODE_ROUNDS
        );
        return false;
    }
    // per byte: the rounds' total over all bytes decoded (max: a round's ticks per byte)
    info!(
        "BENCH row case={} what=decode_per_byte calls={} ticks_total={} ticks_max={}",
        case,
        len as u64 * u64::from(DECODE_ROUNDS),
        per_round.total,
        per_round.max / (len as u64).max(1)
    );
    info!(
        "BENCH row case={} what=decode_per_frame calls={} ticks_total={} ticks_max={}",
        case,
        u64::from(frames) * u64::from(DECODE_ROUNDS),
        per_round.total,
        per_round.max / u64::from(frames.max(1))
    );
    info!(
        "BENCH size what=FrameDecoder bytes={}",
        core::mem::size_of::<FrameDecoder>()
    );
    true
}

/// Levels of the streaming Allan variance: octaves 2^0 .. 2^19 sample times (0.005 s to
/// 44 min at 200 Hz).
const ALLAN_LEVELS: usize = 20;
/// Samples pushed (2^14: every level below 14 closes blocks).
const ALLAN_SAMPLES: u32 = 1 << 14;

fn allan_stream(m: &mut Meter, case: &'static str) -> bool {
    use nav_core::allan::StreamingAllan;
    let mut a = StreamingAllan::<ALLAN_LEVELS>::new();
    let mut rng = Lcg(4);
    let mut acc = Acc::default();
    for _ in 0..ALLAN_SAMPLES {
        let x = 1e-3 * rng.next();
        let (ok, t) = m.time(|| a.push(x));
        if !ok {
            error!("bench {}: sample refused", case);
            return false;
        }
        acc.add(t);
    }
    acc.print(case, "push_per_sample_one_channel");
    info!(
        "BENCH size what=StreamingAllan<{}> bytes={}",
        ALLAN_LEVELS,
        core::mem::size_of::<StreamingAllan<ALLAN_LEVELS>>()
    );
    // white noise uniform in [-1e-3, 1e-3]: AVAR at tau0 = variance = 1e-6 / 3
    let v0 = a.avar(0).unwrap_or(0.0);
    if !(v0 > 0.9e-6 / 3.0 && v0 < 1.1e-6 / 3.0) {
        error!("bench {}: AVAR(tau0) implausible", case);
        return false;
    }
    true
}

fn filter<const N: usize>(
    m: &mut Meter,
    case: &'static str,
    layout: Layout,
    cfg: FilterConfig,
) -> bool {
    let unc = InitialUncertainty {
        att_sigma_rad: [0.01, 0.01, 0.05],
        vel_sigma_mps: [0.1; 3],
        pos_sigma_m: [1.0; 3],
    };
    let mut f = match Filter::<f32, N>::new(layout, &cfg, init_state(), &unc) {
        Ok(f) => f,
        Err(_) => {
            error!("bench {}: filter construction failed", case);
            return false;
        }
    };
    let mut rng = Lcg(2);
    let (mut prop, mut prop_plain, mut prop_pred, mut gnss, mut epoch) = (
        Acc::default(),
        Acc::default(),
        Acc::default(),
        Acc::default(),
        Acc::default(),
    );
    let p0 = start_pos();
    let mut accepted = 0u32;
    for k in 1..=EPOCHS {
        let s = imu_sample(k, T0_S, IMU_HZ, &mut rng);
        let preds = f.counters().cov_predictions;
        let (r, t) = m.time(|| f.propagate(&s));
        if r.is_err() {
            error!("bench {}: propagate failed at epoch {}", case, k);
            return false;
        }
        prop.add(t);
        if f.counters().cov_predictions != preds {
            prop_pred.add(t);
        } else {
            prop_plain.add(t);
        }
        let mut t_epoch = t;
        if k % GNSS_EVERY == 0 {
            let fix = GnssFix {
                t_s: s.t_s,
                lat_rad: p0.lat_rad + 1e-8 * rng.next(),
                lon_rad: p0.lon_rad + 1e-8 * rng.next(),
                h_m: p0.h_m + 0.1 * rng.next(),
                pos_std_ned_m: [0.5, 0.5, 1.0],
                vel_ned_mps: [0.0; 3],
                vel_std_ned_mps: [0.1; 3],
                has_velocity: false,
                quality: FixQuality::Single,
                num_sats: 12,
            };
            let (r, t) = m.time(|| f.update_gnss(&fix));
            match r {
                Ok(o) if o.accepted => accepted += 1,
                _ => {
                    error!(
                        "bench {}: GNSS update {} not accepted",
                        case,
                        k / GNSS_EVERY
                    );
                    return false;
                }
            }
            gnss.add(t);
            t_epoch += t;
        }
        epoch.add(t_epoch);
    }
    prop.print(case, "propagate_per_epoch");
    prop_plain.print(case, "propagate_without_cov_prediction");
    prop_pred.print(case, "propagate_with_cov_prediction");
    gnss.print(case, "gnss_update");
    epoch.print(case, "epoch_incl_1Hz_gnss");
    info!(
        "BENCH size what=Filter<f32,{}> bytes={}",
        N,
        core::mem::size_of::<Filter<f32, N>>()
    );
    if !f.covariance_is_positive_definite() || accepted != EPOCHS / GNSS_EVERY {
        error!("bench {}: covariance not SPD or fixes rejected", case);
        return false;
    }
    true
}

/// A loop of exactly `2 * n` instructions (`subs` + `bne` per iteration).
#[inline(always)]
fn known_loop(n: u32) {
    // SAFETY: register-only arithmetic loop.
    unsafe {
        core::arch::asm!("1:", "subs {0}, {0}, #1", "bne 1b", inout(reg) n => _, options(nomem, nostack));
    }
}

#[entry]
fn main() -> ! {
    stack::paint();
    let mut b = board::init();
    let clock = &mut b.clock;
    // measurement overhead: two back-to-back reads
    let mut overhead = u64::MAX;
    for _ in 0..8 {
        let t0 = clock.now_ticks();
        let t1 = clock.now_ticks();
        overhead = overhead.min(t1 - t0);
    }
    let mut m = Meter { clock, overhead };
    info!("BENCH overhead ticks={}", overhead);
    for n in [10_000u32, 1_000_000] {
        let ((), t) = m.time(|| known_loop(n));
        info!("BENCH calib loop_instructions={} ticks={}", 2 * n, t);
    }
    let mut ok = true;
    for c in CASES {
        stack::paint();
        let pass = (c.run)(&mut m, c.name);
        info!("BENCH stack case={} bytes={}", c.name, stack::peak_bytes());
        ok &= pass;
    }
    info!("BENCH done");
    board::exit(ok)
}
