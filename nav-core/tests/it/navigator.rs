//! `nav_core::navigator`: the push-form loop gives, bit for bit, the results of the host's run
//! loop (`nav-engine/src/run/engine.rs`: guard, integrate, then every pending fix with
//! `t_f < t_k + dt_next / 2`) on the same data; the alignment modes start where they should;
//! the fix queue reports overflow.

use test_support::filter_sim::{nav_errors, test_uncertainty, Motion, Sim, SimConfig};

use nav_core::config::FilterConfig;
use nav_core::filter::observe::{CovObserver, PredictionRecord};
use nav_core::filter::{Filter, FilterError, InitialUncertainty, UpdateOutcome};
use nav_core::imu_guard::{GuardConfig, ImuGuard, Verdict};
use nav_core::model::{LAYOUT_KF_GINS, LAYOUT_NBK};
use nav_core::navigator::{
    AlignMode, FirstFixAlign, FixEvent, GnssEvent, ImuEvent, NavHooks, Navigator, NavigatorConfig,
    NavigatorError, NavigatorKfGins, NavigatorNbk, StaticAlignSettings,
};
use nav_core::strapdown::NavState;
use nav_core::types::{GnssFix, ImuSample};

const NBK: usize = LAYOUT_NBK.dim();
const DT: f64 = 0.01;

/// A 300 s drive at 100 Hz with everything the scheduling and the guard must handle:
/// fixes off the IMU epochs (including exactly half an interval after one), two fixes in
/// one interval, an outlier, an invalid fix, a fix before the start, gaps of 4 and 50
/// samples, an implausible and a non-finite sample.
struct Drive {
    imu: Vec<ImuSample>,
    gnss: Vec<GnssFix>,
    init: NavState,
    unc: InitialUncertainty,
    truth_end: NavState,
}

fn drive(seed: u64) -> Drive {
    let mut sim = Sim::new(SimConfig::nbk(100.0), seed);
    let unc = test_uncertainty();
    let mut imu = Vec::new();
    let mut gnss = Vec::new();
    let mut init = None;
    let mut truth_end = *sim.truth();
    for k in 0..30_000usize {
        let ep = sim.step();
        imu.push(ep.imu);
        if k == 99 {
            init = Some(sim.perturbed_initial(&unc));
        }
        if let Some(mut g) = ep.gnss {
            let n = gnss.len();
            g.t_s += [0.0, 0.004, 0.005, -0.005, 0.0049, -0.0031][n % 6];
            if n == 50 {
                g.lat_rad += 30.0 / 6.4e6; // 30 m north: rejected
            }
            if n == 80 {
                g.pos_std_ned_m[1] = f64::NAN; // invalid
            }
            gnss.push(g);
            if n % 7 == 3 {
                // a second fix in the same IMU interval
                gnss.push(GnssFix {
                    t_s: g.t_s + 0.001,
                    ..g
                });
            }
        }
        truth_end = *sim.truth();
    }
    // a fix before the start (t0 = 1001.0)
    gnss.insert(
        0,
        GnssFix {
            t_s: 1000.5,
            ..gnss[0]
        },
    );
    // gaps, an implausible and a non-finite sample
    imu[20_000].dv_mps[0] = 1.0e6;
    imu[25_000].dtheta_rad[2] = f64::NAN;
    imu.drain(12_000..12_050);
    imu.drain(5_000..5_004);
    gnss.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
    Drive {
        imu,
        gnss,
        init: init.expect("initial state"),
        unc,
        truth_end,
    }
}

/// Bit patterns of a state.
fn bits(s: &NavState) -> [u64; 11] {
    let q = s.q_nb.quaternion().coords;
    [
        s.t_s.to_bits(),
        s.pos.lat_rad.to_bits(),
        s.pos.lon_rad.to_bits(),
        s.pos.h_m.to_bits(),
        s.vel_ned_mps.x.to_bits(),
        s.vel_ned_mps.y.to_bits(),
        s.vel_ned_mps.z.to_bits(),
        q[0].to_bits(),
        q[1].to_bits(),
        q[2].to_bits(),
        q[3].to_bits(),
    ]
}

/// A fix outcome as comparable bits: (time, used, forced, nis, weight, innovations) or the
/// refusal.
fn outcome_bits(r: &Result<UpdateOutcome, FilterError>) -> String {
    match r {
        Ok(o) => format!(
            "{:x} {} {} {} {:x} {:x} {:?}",
            o.t_s.to_bits(),
            o.dim,
            o.accepted,
            o.forced,
            o.nis.to_bits(),
            o.weight.to_bits(),
            o.innovation.map(f64::to_bits)
        ),
        Err(e) => format!("err {e:?}"),
    }
}

fn event_bits(e: &FixEvent) -> String {
    match e {
        FixEvent::Accepted(o) | FixEvent::Downweighted(o) | FixEvent::Rejected(o) => {
            outcome_bits(&Ok(*o))
        }
        FixEvent::Reset(o) => outcome_bits(&Ok(*o)),
        FixEvent::Refused { error, .. } => outcome_bits(&Err(*error)),
    }
}

/// What both loops record: the state after every integrated sample, every fix outcome, the
/// final state and covariance diagonal.
#[derive(Debug, PartialEq)]
struct Record {
    states: Vec<[u64; 11]>,
    fixes: Vec<String>,
    final_state: [u64; 11],
    final_std: Vec<u64>,
    implausible: u64,
    refused: u64,
}

/// The host's run loop as it was before it became the navigator's with hooks (the reference
/// form of the rule, without outages and records): start at the given state, skip samples up
/// to it, guard, integrate, then apply every pending fix with `t_f < t_k + dt_next / 2`.
fn host_rule<const N: usize>(
    d: &Drive,
    layout: nav_core::model::Layout,
    cfg: &FilterConfig,
    guard_cfg: GuardConfig,
) -> Record {
    let t0 = d.init.t_s;
    let mut filter = Filter::<f32, N>::new(layout, cfg, d.init, &d.unc).unwrap();
    let first = d.imu.partition_point(|s| s.t_s <= t0);
    let last = d.imu.len();
    let prev = first
        .checked_sub(1)
        .and_then(|i| Some((d.imu.get(i)?, d.imu.get(i.checked_sub(1)?)?)))
        .filter(|(p, _)| (p.t_s - t0).abs() < 1e-9)
        .map(|(p, pp)| (*p, p.t_s - pp.t_s));
    let mut guard = ImuGuard::new(guard_cfg, t0, prev).unwrap();
    let mut gi = d.gnss.partition_point(|g| g.t_s < t0 - 1e-9);
    let mut rec = Record {
        states: Vec::new(),
        fixes: Vec::new(),
        final_state: [0; 11],
        final_std: Vec::new(),
        implausible: 0,
        refused: 0,
    };
    for k in first..last {
        let s = d.imu[k];
        let dt = s.t_s - filter.nav_state().t_s;
        let c = match guard.check(&s).unwrap() {
            Verdict::Use(c) => c,
            Verdict::Reject(_) => {
                rec.implausible += 1;
                continue;
            }
        };
        for f in c.fill {
            filter.propagate(&f).unwrap();
        }
        filter.widen_for_fill(&c.fill.uncertainty());
        match filter.propagate(&c.sample) {
            Ok(()) => {}
            Err(FilterError::NonFiniteImu) => {
                rec.refused += 1;
                continue;
            }
            Err(e) => panic!("{e}"),
        }
        rec.states.push(bits(filter.nav_state()));
        let t_k = s.t_s;
        let dt_next = d
            .imu
            .get(k + 1)
            .filter(|_| k + 1 < last)
            .map_or(dt, |n| n.t_s - t_k);
        let horizon = t_k + 0.5 * dt_next;
        while let Some(fix) = d.gnss.get(gi) {
            if fix.t_s >= horizon {
                break;
            }
            gi += 1;
            rec.fixes.push(outcome_bits(&filter.update_gnss(fix)));
        }
    }
    rec.final_state = bits(filter.nav_state());
    rec.final_std = filter.state_std().iter().map(|v| v.to_bits()).collect();
    rec
}

/// The same data through a [`Navigator`]: samples and fixes merged in time order (a fix is
/// pushed before the first sample at or after it), then `flush`.
fn navigator_run<const N: usize>(
    d: &Drive,
    layout: nav_core::model::Layout,
    cfg: &FilterConfig,
    guard_cfg: GuardConfig,
) -> (Record, Navigator<f32, N>) {
    let mut nav = Navigator::<f32, N>::new(
        layout,
        NavigatorConfig {
            filter: *cfg,
            guard: guard_cfg,
            align: AlignMode::Given {
                state: d.init,
                unc: d.unc,
            },
        },
    )
    .unwrap();
    let mut rec = Record {
        states: Vec::new(),
        fixes: Vec::new(),
        final_state: [0; 11],
        final_std: Vec::new(),
        implausible: 0,
        refused: 0,
    };
    let mut gi = 0;
    for s in &d.imu {
        while let Some(g) = d.gnss.get(gi).filter(|g| g.t_s <= s.t_s) {
            nav.push_gnss(g).unwrap();
            gi += 1;
        }
        let step = nav.push_imu(s).unwrap();
        rec.fixes.extend(step.fixes.iter().map(event_bits));
        match step.imu {
            ImuEvent::Propagated | ImuEvent::GapBridged { .. } => {
                rec.states.push(bits(nav.state().unwrap()))
            }
            ImuEvent::Rejected(_) => rec.implausible += 1,
            ImuEvent::Refused(_) => rec.refused += 1,
            ImuEvent::BeforeStart => {}
            other => panic!("unexpected {other:?}"),
        }
    }
    for g in &d.gnss[gi..] {
        nav.push_gnss(g).unwrap();
    }
    rec.fixes.extend(nav.flush().iter().map(event_bits));
    let f = nav.filter().unwrap();
    rec.final_state = bits(f.nav_state());
    rec.final_std = f.state_std().iter().map(|v| v.to_bits()).collect();
    (rec, nav)
}

#[test]
fn navigator_is_bit_identical_to_the_host_loop() {
    let d = drive(7);
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = SimConfig::nbk(100.0).lever_arm_body_m;
    let gc = GuardConfig::new(DT);
    let host = host_rule::<NBK>(&d, LAYOUT_NBK, &cfg, gc);
    let (nav, navigator) = navigator_run::<NBK>(&d, LAYOUT_NBK, &cfg, gc);
    // the data exercise what they should
    assert_eq!(host.implausible, 2, "implausible and non-finite samples");
    assert!(host.fixes.len() > 300, "{} fixes", host.fixes.len());
    assert!(
        host.fixes.iter().any(|f| f.starts_with("err")),
        "the invalid fix"
    );
    assert!(
        host.fixes.iter().any(|f| f.contains(" false false ")),
        "the outlier"
    );
    let g = navigator.guard_counters();
    // 4 + 50 lost samples, and the intervals of the two rejected ones bridged by the next
    assert_eq!((g.gaps, g.missing_samples), (4, 56));
    assert_eq!(
        navigator.counters().gnss_dropped,
        1,
        "the fix before the start"
    );
    assert_eq!(navigator.counters().imu_before_start, 100);
    // and both loops agree bit for bit
    assert_eq!(host.states.len(), nav.states.len());
    for (i, (a, b)) in host.states.iter().zip(&nav.states).enumerate() {
        assert_eq!(a, b, "state after integrated sample {i}");
    }
    assert_eq!(host.fixes, nav.fixes);
    assert_eq!(host, nav);
    // and the run is a good one
    let (_, _, dr) = nav_errors(navigator.state().unwrap(), &d.truth_end);
    let h = dr[0].hypot(dr[1]);
    assert!(h < 0.1, "final horizontal error {h} m");
}

#[test]
fn kf_gins_alias_is_bit_identical_too() {
    let d = drive(11);
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = SimConfig::nbk(100.0).lever_arm_body_m;
    let gc = GuardConfig::new(DT);
    const K: usize = LAYOUT_KF_GINS.dim();
    let host = host_rule::<K>(&d, LAYOUT_KF_GINS, &cfg, gc);
    let (nav, _) = navigator_run::<K>(&d, LAYOUT_KF_GINS, &cfg, gc);
    assert_eq!(host, nav);
    // the alias names the same type
    let _: Option<NavigatorKfGins> = None::<Navigator<f32, K>>;
}

#[test]
fn first_fix_alignment_levels_and_takes_the_course() {
    let mut c = SimConfig::nbk(100.0);
    c.gnss_velocity = true;
    c.lever_arm_body_m = [0.0; 3];
    let mut sim = Sim::new(c, 3);
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.use_gnss_velocity = true;
    let mut nav = NavigatorNbk::new(
        LAYOUT_NBK,
        NavigatorConfig::new(cfg, AlignMode::FirstFix(FirstFixAlign::default())),
    )
    .unwrap();
    let mut aligned = None;
    let mut used = 0;
    for _ in 0..20_000 {
        let ep = sim.step();
        let step = nav.push_imu(&ep.imu).unwrap();
        used += step.fixes.iter().filter(|f| f.used()).count();
        if let Some(g) = ep.gnss {
            match nav.push_gnss(&g).unwrap() {
                GnssEvent::Aligned(a) => aligned = Some((a, *sim.truth())),
                GnssEvent::Queued => {}
                other => panic!("{other:?}"),
            }
        }
    }
    let (a, truth) = aligned.expect("aligned on the first fix");
    assert!(a.heading_known);
    // the first fix is at 1 s: the vehicle accelerates at 1 m/s^2, so levelling sees a
    // 0.1 g forward specific force (pitch ~ 5.8 deg wrong) until the filter corrects it
    let [_, _, yaw] = truth.rpy_rad();
    assert!(
        (a.rpy_rad[2] - yaw).abs() < 0.02,
        "yaw {} vs {}",
        a.rpy_rad[2],
        yaw
    );
    assert!(used > 180, "{used} fixes used");
    let (phi, _, dr) = nav_errors(nav.state().unwrap(), sim.truth());
    assert!(dr[0].hypot(dr[1]) < 0.1, "{dr:?}");
    assert!(phi[2].abs() < 0.2f64.to_radians(), "heading error {phi:?}");
}

#[test]
fn static_alignment_on_a_stream() {
    let mut c = SimConfig::nbk(100.0);
    c.motion = Motion::Static;
    let mut sim = Sim::new(c, 5);
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = c.lever_arm_body_m;
    let yaw = 30f64.to_radians();
    let sa = StaticAlignSettings::with_heading(20.0, yaw, 2f64.to_radians());
    let mut nav =
        NavigatorNbk::new(LAYOUT_NBK, NavigatorConfig::new(cfg, AlignMode::Static(sa))).unwrap();
    let mut aligned = None;
    for k in 0..6_000 {
        let ep = sim.step();
        if let Some(g) = ep.gnss {
            nav.push_gnss(&g).unwrap();
        }
        let step = nav.push_imu(&ep.imu).unwrap();
        if let Some(a) = step.aligned {
            assert!(
                k > 1999 && k < 2010,
                "window closes after 20 s, at sample {k}"
            );
            aligned = Some((a, *sim.truth()));
            assert_eq!(step.imu, ImuEvent::Propagated);
        }
    }
    let (a, _) = aligned.expect("aligned");
    // the levelling error is the accelerometer bias over g (NBK: ~1 mg -> 1e-3 rad)
    assert!(
        a.rpy_rad[0].abs() < 3e-3 && a.rpy_rad[1].abs() < 3e-3,
        "{:?}",
        a.rpy_rad
    );
    // the given heading, through the Euler -> quaternion -> Euler round trip of the start
    // state (its rounding depends on roll and pitch: 1 ulp here since the filter-test data
    // come from nav_sim's integrator, bit-equal with the earlier generator's data)
    assert!(
        (a.rpy_rad[2] - yaw).abs() <= 2.0 * f64::EPSILON * yaw,
        "{:?}",
        a.rpy_rad
    );
    let (_, dv, dr) = nav_errors(nav.state().unwrap(), sim.truth());
    assert!(dr.iter().all(|e| e.abs() < 0.1), "position error {dr:?}");
    assert!(dv.iter().all(|e| e.abs() < 0.02), "velocity error {dv:?}");
    assert!(nav.counters().gnss_used >= 38, "{:?}", nav.counters());
    // the guard's nominal interval was measured on the window
    let dt = nav.guard_config().unwrap().nominal_dt_s;
    assert!((dt - DT).abs() < 1e-9, "{dt}");
}

#[test]
fn static_alignment_restarts_when_the_window_moves() {
    // the drive accelerates in its first 10 s: no static window there
    let mut sim = Sim::new(SimConfig::nbk(100.0), 9);
    let cfg = FilterConfig::source_nbk_model();
    let sa = StaticAlignSettings::with_heading(5.0, 0.0, 0.1);
    let mut nav =
        NavigatorNbk::new(LAYOUT_NBK, NavigatorConfig::new(cfg, AlignMode::Static(sa))).unwrap();
    let mut failures = 0;
    for _ in 0..1_200 {
        let ep = sim.step();
        if let Some(g) = ep.gnss {
            nav.push_gnss(&g).unwrap();
        }
        let step = nav.push_imu(&ep.imu).unwrap();
        if let ImuEvent::AlignFailed(_) = step.imu {
            failures += 1;
        }
    }
    assert!(!nav.is_aligned());
    assert_eq!(failures, 2);
    assert_eq!(nav.counters().align_failures, 2);
}

#[test]
fn fix_queue_overflow_is_an_error_and_flush_drops_the_rest() {
    let d = drive(1);
    let cfg = FilterConfig::source_nbk_model();
    let mut nav: Navigator<f32, NBK, 2> = Navigator::new(
        LAYOUT_NBK,
        NavigatorConfig::new(
            cfg,
            AlignMode::Given {
                state: d.init,
                unc: d.unc,
            },
        ),
    )
    .unwrap();
    let later: Vec<_> = d.gnss.iter().filter(|g| g.t_s > 1010.0).take(3).collect();
    assert_eq!(nav.push_gnss(later[0]), Ok(GnssEvent::Queued));
    assert_eq!(nav.push_gnss(later[1]), Ok(GnssEvent::Queued));
    assert_eq!(
        nav.push_gnss(later[2]),
        Err(NavigatorError::FixQueueFull { t_s: later[2].t_s })
    );
    assert_eq!(nav.counters().gnss_queue_overflow, 1);
    assert_eq!(nav.pending_fixes(), 2);
    // no sample integrated: nothing is due, both are dropped
    assert!(nav.flush().is_empty());
    assert_eq!(nav.counters().gnss_dropped, 2);
    assert_eq!(nav.pending_fixes(), 0);
}

#[test]
fn a_bad_configuration_is_refused_at_construction() {
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.gyro.s_n[0] = -1.0;
    let r = NavigatorNbk::new(
        LAYOUT_NBK,
        NavigatorConfig::new(cfg, AlignMode::FirstFix(FirstFixAlign::default())),
    );
    assert!(matches!(
        r,
        Err(NavigatorError::Filter(FilterError::Config(_)))
    ));
}

/// Counts covariance predictions.
struct Count<'a>(&'a mut u64);

impl<const N: usize> CovObserver<f32, N> for Count<'_> {
    fn predicted(&mut self, _rec: &PredictionRecord<'_, f32, N>) {
        *self.0 += 1;
    }
}

/// Hooks that withhold the fixes in `[from, to)` and count every call.
#[derive(Default)]
struct Probe {
    from: f64,
    to: f64,
    /// Whether the update's predictions are wanted too ([`NavHooks::observes_covariance`]).
    observe: bool,
    withheld: usize,
    before: usize,
    fixes: usize,
    predictions: u64,
    after: usize,
    epochs: Vec<[u64; 11]>,
    /// Calls out of order (a fix's update without its `before_gnss`).
    disorder: usize,
}

impl<const N: usize> NavHooks<f32, N> for Probe {
    fn observes_covariance(&self) -> bool {
        self.observe
    }
    fn observer(&mut self) -> impl CovObserver<f32, N> + '_ {
        Count(&mut self.predictions)
    }
    fn after_sample(&mut self, _filter: &mut Filter<f32, N>) {
        self.after += 1;
    }
    fn withhold_fix(&mut self, _filter: &Filter<f32, N>, fix: &GnssFix) -> bool {
        let w = fix.t_s >= self.from && fix.t_s < self.to;
        self.withheld += usize::from(w);
        w
    }
    fn before_gnss(&mut self, _fix: &GnssFix) {
        self.before += 1;
    }
    fn on_fix(&mut self, _filter: &Filter<f32, N>, _fix: &GnssFix, _event: &FixEvent) {
        self.fixes += 1;
        if self.fixes != self.before {
            self.disorder += 1;
        }
    }
    fn on_epoch_done(&mut self, filter: &Filter<f32, N>) {
        self.epochs.push(bits(filter.nav_state()));
    }
}

/// Drive 5 through a navigator with `probe`: the states after every integrated sample, the
/// filter at the end.
fn probe_run(probe: &mut Probe, cfg: &FilterConfig) -> (Vec<[u64; 11]>, Navigator<f32, NBK>) {
    let d = drive(5);
    let mut nav = Navigator::<f32, NBK>::new(
        LAYOUT_NBK,
        NavigatorConfig {
            filter: *cfg,
            guard: GuardConfig::new(DT),
            align: AlignMode::Given {
                state: d.init,
                unc: d.unc,
            },
        },
    )
    .unwrap();
    let mut states = Vec::new();
    let mut gi = 0;
    for s in &d.imu {
        while let Some(g) = d.gnss.get(gi).filter(|g| g.t_s <= s.t_s) {
            nav.push_gnss(g).unwrap();
            gi += 1;
        }
        let step = nav.push_imu_with(s, probe).unwrap();
        if matches!(step.imu, ImuEvent::Propagated | ImuEvent::GapBridged { .. }) {
            states.push(bits(nav.state().unwrap()));
        }
    }
    for g in &d.gnss[gi..] {
        nav.push_gnss(g).unwrap();
    }
    nav.flush_with(probe);
    (states, nav)
}

#[test]
fn hooks_withhold_fixes_observe_every_prediction_and_close_every_epoch() {
    let mut cfg = FilterConfig::source_nbk_model();
    cfg.lever_arm_body_m = SimConfig::nbk(100.0).lever_arm_body_m;
    let (from, to) = (1100.0, 1130.0);
    // the reference: the same drive without the fixes of the window, no hooks
    let mut cut = drive(5);
    let n_all = cut.gnss.len();
    cut.gnss.retain(|g| !(g.t_s >= from && g.t_s < to));
    let n_window = n_all - cut.gnss.len();
    assert!(n_window > 30, "{n_window} fixes in the window");
    let (reference, _) = navigator_run::<NBK>(&cut, LAYOUT_NBK, &cfg, GuardConfig::new(DT));

    let mut probe = Probe {
        from,
        to,
        ..Probe::default()
    };
    let (states, nav) = probe_run(&mut probe, &cfg);
    let f = nav.filter().unwrap();
    // withheld fixes are as if they were not there, bit for bit
    assert_eq!(probe.withheld, n_window);
    assert_eq!(states, reference.states);
    assert_eq!(bits(f.nav_state()), reference.final_state);
    let std: Vec<u64> = f.state_std().iter().map(|v| v.to_bits()).collect();
    assert_eq!(std, reference.final_std);
    // every other fix: before_gnss then on_fix, once
    assert_eq!(probe.disorder, 0);
    assert_eq!(probe.fixes, reference.fixes.len());
    assert_eq!(probe.before, probe.fixes);
    // every integrated sample: one after_sample and one completed epoch at its time
    assert_eq!(probe.after, states.len());
    assert_eq!(probe.epochs.len(), states.len());
    for (e, s) in probe.epochs.iter().zip(&states) {
        assert_eq!(e[0], s[0], "epoch time");
    }
    // the propagation's predictions are seen, the updates' not (not asked for)
    let all = u64::from(f.counters().cov_predictions);
    assert!(
        probe.predictions > 2_000,
        "{} predictions",
        probe.predictions
    );
    assert!(probe.predictions < all, "{} of {all}", probe.predictions);

    // asking for them: every prediction is seen. (The navigator then predicts before each
    // update, also before a fix the update refuses, e.g. the invalid one, which the update
    // alone would not: the run differs from the one without, as the host's smoother run
    // always did.)
    let mut probe = Probe {
        from,
        to,
        observe: true,
        ..Probe::default()
    };
    let (states_obs, nav) = probe_run(&mut probe, &cfg);
    let f = nav.filter().unwrap();
    assert_eq!(probe.predictions, u64::from(f.counters().cov_predictions));
    assert_eq!(probe.disorder, 0);
    assert_eq!(probe.fixes, reference.fixes.len());
    assert_eq!(states_obs.len(), states.len());
}
