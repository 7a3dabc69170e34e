//! The board-independent application: wire frames in, the navigator, solutions and health
//! out. Generic over `embedded_io` (the frame link) and [`TimeBase`]; it knows nothing of
//! registers, so the same code runs on every board and on the host.
//!
//! Frames in (`nav_core::wire`): IMU samples (one filter epoch each), GNSS fixes, a
//! configuration (answered with a health frame). Frames out: a navigation solution every
//! `nav_divider` IMU epochs once the filter runs, and a health frame every `health_every`
//! epochs and on request.
//!
//! Start-up, the IMU guard and the fix scheduling are `nav_core::navigator`'s
//! ([`AlignMode::FirstFix`]): the first valid GNSS fix starts the filter at the fix's position
//! and velocity (zero without one); roll and pitch come from levelling the mean specific force
//! of the IMU samples received before it, yaw from the GNSS course when the fix has a velocity
//! above [`COURSE_MIN_SPEED_MPS`], else 0 with a 180 deg sigma. Later fixes wait for the next
//! IMU sample and are applied at the IMU epoch nearest to them, before that sample is
//! integrated; every sample passes the IMU guard (gaps bridged, implausible samples
//! rejected), whose nominal interval is the mean interval before the first fix.
//!
//! Land-vehicle aiding (`nav_core::aiding`: non-holonomic constraint, zero-velocity and
//! zero-rate updates at stops) runs after every integrated sample when the configuration
//! frame sets [`wire::CONFIG_LAND_AIDING`] (off until then); its counts are
//! [`NavApp::aiding_counters`].

use crate::time::TimeBase;
use embedded_io::{Read, Write};
use nav_core::aiding::{Aiding, AidingConfig, AidingCounters};
use nav_core::config::FilterConfig;
use nav_core::filter::Filter;
use nav_core::model::StateModel;
use nav_core::navigator::{
    AlignMode, FirstFixAlign, FixEvent, GnssEvent, ImuEvent, Navigator, NavigatorConfig,
    NavigatorError,
};
use nav_core::types::{GnssFix, ImuSample};
use nav_core::wire::{self, Encoder, FrameDecoder, Health, Payload, MAX_FRAME_LEN};

/// Smallest GNSS speed whose course initialises the yaw, m/s.
pub const COURSE_MIN_SPEED_MPS: f64 = 2.0;

/// Largest stationarity-detector window of the land-vehicle aiding, IMU samples (0.32 s at
/// 200 Hz: the configured 0.5 s window is capped to it; 1.5 KB of f32). Static RAM plus the
/// peak stack with the aiding on are 32,252 B of 32,768 with 100 samples, hence 64.
pub const AID_WINDOW: usize = 64;

/// Counters of the application (the content of health frames).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct AppCounters {
    /// IMU epochs run through the filter.
    pub imu_epochs: u32,
    /// IMU samples not integrated once the filter runs (implausible, refused, guard faults).
    pub imu_rejected: u32,
    /// GNSS fixes used.
    pub gnss_updates: u32,
    /// GNSS fixes refused (invalid, mistimed, gated, or dropped on a full queue).
    pub gnss_rejected: u32,
    /// Longest IMU epoch (the fixes due before the sample, then its propagation), ticks.
    pub epoch_ticks_max: u32,
    /// Frames sent.
    pub tx_frames: u32,
}

/// The application state: navigator, decoder, encoder, counters.
pub struct NavApp<const N: usize> {
    nav: Navigator<f32, N>,
    /// Land-vehicle aiding, when configured.
    aid: Option<Aiding<f32, AID_WINDOW>>,
    /// `(fix time s, speed m/s)` of the latest GNSS velocity (the stationarity detector's).
    gnss_speed: Option<(f64, f64)>,
    last_imu: Option<ImuSample>,
    dec: FrameDecoder,
    enc: Encoder,
    nav_divider: u16,
    since_nav: u16,
    health_every: u32,
    since_health: u32,
    counters: AppCounters,
    stack_probe: Option<fn() -> usize>,
    time_from_gnss: bool,
    time_offset_s: f64,
    link_imu: bool,
}

fn first_fix(at_fix_time: bool) -> AlignMode {
    AlignMode::FirstFix(FirstFixAlign {
        course_min_speed_mps: COURSE_MIN_SPEED_MPS,
        start_at_fix_time: at_fix_time,
        ..FirstFixAlign::default()
    })
}

impl<const N: usize> NavApp<N> {
    /// An application running the filter of the compile-time model `M` (its layout; `N` must
    /// be `M::DIM`, checked when this is compiled) with `cfg`; one solution per `nav_divider`
    /// IMU epochs (0 = none), one health frame per `health_every` epochs (0 = only on
    /// request). Error: the filter refuses the configuration.
    pub fn new<M: StateModel>(
        cfg: FilterConfig,
        nav_divider: u16,
        health_every: u32,
    ) -> Result<Self, NavigatorError> {
        let nav = Navigator::for_model::<M>(NavigatorConfig::new(cfg, first_fix(false)))?;
        Ok(Self {
            nav,
            aid: None,
            gnss_speed: None,
            last_imu: None,
            dec: FrameDecoder::new(),
            enc: Encoder::new(),
            nav_divider,
            since_nav: 0,
            health_every,
            since_health: 0,
            counters: AppCounters::default(),
            stack_probe: None,
            time_from_gnss: false,
            time_offset_s: 0.0,
            link_imu: true,
        })
    }

    /// The counters so far.
    pub fn counters(&self) -> &AppCounters {
        &self.counters
    }

    /// The filter, once started.
    pub fn filter(&self) -> Option<&Filter<f32, N>> {
        self.nav.filter()
    }

    /// The navigator (its own and the IMU guard's counters).
    pub fn navigator(&self) -> &Navigator<f32, N> {
        &self.nav
    }

    /// Switches the land-vehicle aiding on (`Some`, validated) or off (`None`); a running
    /// aiding restarts (empty detector window, zero counts).
    pub fn set_aiding(
        &mut self,
        cfg: Option<&AidingConfig>,
    ) -> Result<(), nav_core::aiding::AidingConfigError> {
        self.aid = match cfg {
            Some(c) => Some(Aiding::new(c)?),
            None => None,
        };
        Ok(())
    }

    /// What the aiding did (None when off).
    pub fn aiding_counters(&self) -> Option<&AidingCounters> {
        self.aid.as_ref().map(|a| a.counters())
    }

    /// Sets the function that measures the peak stack use (bytes) for health frames (the
    /// board's stack painting; without one the field is 0).
    pub fn set_stack_probe(&mut self, probe: fn() -> usize) {
        self.stack_probe = Some(probe);
    }

    /// For a board that stamps IMU samples with its own clock: the first GNSS fix sets the
    /// offset from board time to GPS time (fix time minus the latest IMU stamp; transport
    /// latency is not corrected: a PPS input would be needed for that) and the filter starts
    /// at the fix's time. The board adds [`Self::time_offset_s`] to its stamps. Call before
    /// the first fix.
    pub fn set_time_from_gnss(&mut self, on: bool) {
        self.time_from_gnss = on;
        self.nav.set_align_mode(first_fix(on));
    }

    /// Whether IMU frames from the link are used (true by default; a board with its own IMU
    /// turns it off, so a replayed case's IMU frames are ignored and only its fixes used).
    pub fn set_link_imu(&mut self, on: bool) {
        self.link_imu = on;
    }

    /// GPS time minus board time, s (0 until set by the first fix, or when the frames carry
    /// GPS time already).
    pub fn time_offset_s(&self) -> f64 {
        self.time_offset_s
    }

    /// The health frame content now: link, filter, IMU guard and aiding counters.
    pub fn health<C: TimeBase>(&self, clock: &mut C) -> Health {
        let st = self.dec.stats();
        let aid = self.aiding_counters();
        Health {
            uptime_ms: clock.now_ms(),
            rx_frames_ok: st.frames_ok,
            rx_rejected: st.rejected(),
            rx_crc_errors: st.crc_errors,
            rx_lost: st.lost(),
            imu_epochs: self.counters.imu_epochs,
            gnss_updates: self.counters.gnss_updates,
            gnss_rejected: self.counters.gnss_rejected,
            epoch_ticks_max: self.counters.epoch_ticks_max,
            stack_peak_bytes: self.stack_probe.map_or(0, |p| p() as u32),
            filter_status: self.nav.status(),
            imu_implausible: sat_u32(self.nav.counters().imu_implausible),
            imu_gaps: sat_u32(self.nav.guard_counters().gaps),
            nhc_updates: aid.map_or(0, |a| a.nhc.used),
            zupt_updates: aid.map_or(0, |a| a.zupt.used),
            zaru_updates: aid.map_or(0, |a| a.zaru.used),
        }
    }

    /// Feeds received bytes; handles every completed frame, writing replies to `out`.
    pub fn feed<W: Write, C: TimeBase>(
        &mut self,
        bytes: &[u8],
        out: &mut W,
        clock: &mut C,
    ) -> Result<(), W::Error> {
        for &b in bytes {
            if let Some(Ok(frame)) = self.dec.push_byte(b) {
                self.handle(&frame.payload, out, clock)?;
            }
        }
        Ok(())
    }

    /// Handles one decoded payload.
    pub fn handle<W: Write, C: TimeBase>(
        &mut self,
        payload: &Payload,
        out: &mut W,
        clock: &mut C,
    ) -> Result<(), W::Error> {
        match payload {
            Payload::Imu(f) if self.link_imu => self.on_imu(&f.sample, out, clock),
            Payload::Imu(_) => Ok(()),
            Payload::Gnss(fix) => {
                self.on_gnss(fix, clock);
                Ok(())
            }
            Payload::Config(c) => self.on_config(c, out, clock),
            Payload::Nav(_) | Payload::Health(_) => self.send_health(out, clock),
        }
    }

    fn count_fix(&mut self, e: &FixEvent) {
        if e.used() {
            self.counters.gnss_updates = self.counters.gnss_updates.wrapping_add(1);
        } else {
            self.counters.gnss_rejected = self.counters.gnss_rejected.wrapping_add(1);
        }
    }

    /// One IMU epoch: levelling before the first fix; after it the fixes due, then the
    /// sample through the guard and the filter; sends the solution and health frames due.
    pub fn on_imu<W: Write, C: TimeBase>(
        &mut self,
        s: &ImuSample,
        out: &mut W,
        clock: &mut C,
    ) -> Result<(), W::Error> {
        self.last_imu = Some(*s);
        if !self.nav.is_aligned() {
            // levelling; the result is `Aligning`
            let _ = self.nav.push_imu(s);
            return Ok(());
        }
        let t0 = clock.now_ticks();
        let r = self.nav.push_imu(s);
        if let Ok(step) = &r {
            if matches!(step.imu, ImuEvent::Propagated | ImuEvent::GapBridged { .. }) {
                self.run_aiding();
            }
        }
        let dt = clock.now_ticks().wrapping_sub(t0);
        self.counters.epoch_ticks_max = self.counters.epoch_ticks_max.max(dt as u32);
        match r {
            Ok(step) => {
                for e in &step.fixes {
                    self.count_fix(e);
                }
                match step.imu {
                    ImuEvent::Propagated | ImuEvent::GapBridged { .. } => {
                        self.counters.imu_epochs = self.counters.imu_epochs.wrapping_add(1)
                    }
                    _ => self.counters.imu_rejected = self.counters.imu_rejected.wrapping_add(1),
                }
            }
            Err(_) => self.counters.imu_rejected = self.counters.imu_rejected.wrapping_add(1),
        }
        self.since_nav = self.since_nav.saturating_add(1);
        if self.nav_divider > 0 && self.since_nav >= self.nav_divider {
            self.since_nav = 0;
            self.send_solution(out)?;
        }
        self.since_health = self.since_health.saturating_add(1);
        if self.health_every > 0 && self.since_health >= self.health_every {
            self.send_health(out, clock)?;
        }
        Ok(())
    }

    /// The land-vehicle aiding after an integrated sample (when on and the filter runs).
    // out of line, like the other calls below that are not on every epoch's path: their
    // locals stay out of the frame that calls the navigator (MCU stack)
    #[inline(never)]
    fn run_aiding(&mut self) {
        if let (Some(a), Some(f)) = (self.aid.as_mut(), self.nav.filter_mut()) {
            a.on_imu(f, self.gnss_speed);
        }
    }

    /// Sends the navigation solution now (none before the filter runs).
    #[inline(never)]
    fn send_solution<W: Write>(&mut self, out: &mut W) -> Result<(), W::Error> {
        match self.nav.solution() {
            Some(sol) => self.send(&Payload::Nav(sol), out),
            None => Ok(()),
        }
    }

    /// Applies a configuration frame (for the start to come; a running filter keeps its
    /// configuration) and answers it with a health frame.
    #[inline(never)]
    fn on_config<W: Write, C: TimeBase>(
        &mut self,
        c: &wire::Config,
        out: &mut W,
        clock: &mut C,
    ) -> Result<(), W::Error> {
        let mut cfg = self.nav.config().filter;
        cfg.use_gnss_velocity = c.flags & wire::CONFIG_USE_GNSS_VELOCITY != 0;
        cfg.lever_arm_body_m = c.lever_arm_frd_m;
        self.nav.set_filter_config(cfg);
        let land = c.flags & wire::CONFIG_LAND_AIDING != 0;
        if land != self.aid.is_some() {
            // LAND is valid by construction: a refusal leaves the aiding off
            let _ = self.set_aiding(land.then_some(&AidingConfig::LAND));
        }
        self.nav_divider = c.nav_divider;
        self.send_health(out, clock)
    }

    /// One GNSS fix: starts the filter (first valid fix) or waits for the nearest IMU epoch.
    #[inline(never)]
    pub fn on_gnss<C: TimeBase>(&mut self, fix: &GnssFix, _clock: &mut C) {
        if fix.has_velocity && fix.vel_ned_mps.iter().all(|v| v.is_finite()) {
            let [n, e, d] = fix.vel_ned_mps;
            self.gnss_speed = Some((fix.t_s, libm::sqrt(n * n + e * e + d * d)));
        }
        match self.nav.push_gnss(fix) {
            Ok(GnssEvent::Aligned(_)) => {
                if self.time_from_gnss {
                    if let Some(last) = self.last_imu {
                        self.time_offset_s = fix.t_s - last.t_s;
                    }
                }
            }
            Ok(GnssEvent::Queued) | Ok(GnssEvent::ForAlignment) => {}
            Ok(GnssEvent::Dropped) | Err(_) => {
                self.counters.gnss_rejected = self.counters.gnss_rejected.wrapping_add(1)
            }
        }
    }

    /// Sends a health frame now.
    #[inline(never)]
    pub fn send_health<W: Write, C: TimeBase>(
        &mut self,
        out: &mut W,
        clock: &mut C,
    ) -> Result<(), W::Error> {
        self.since_health = 0;
        let h = self.health(clock);
        self.send(&Payload::Health(h), out)
    }

    fn send<W: Write>(&mut self, p: &Payload, out: &mut W) -> Result<(), W::Error> {
        let mut buf = [0u8; MAX_FRAME_LEN];
        if let Ok(n) = self.enc.encode(p, &mut buf) {
            out.write_all(buf.get(..n).unwrap_or(&[]))?;
            self.counters.tx_frames = self.counters.tx_frames.wrapping_add(1);
        }
        Ok(())
    }
}

/// `v` as u32, saturated (a health counter).
fn sat_u32(v: u64) -> u32 {
    u32::try_from(v).unwrap_or(u32::MAX)
}

/// Serves the frame link forever: reads what the link has, feeds it to the app. The
/// emulated board's HIL loop; a board with its own IMU polls instead (see the board's `run`).
pub fn serve<const N: usize, U: Read + Write, C: TimeBase>(
    app: &mut NavApp<N>,
    link: &mut U,
    clock: &mut C,
) -> Result<core::convert::Infallible, U::Error> {
    let mut buf = [0u8; 64];
    loop {
        let n = link.read(&mut buf)?;
        app.feed(buf.get(..n).unwrap_or(&[]), link, clock)?;
    }
}
