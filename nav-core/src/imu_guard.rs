//! IMU sample conditioning before the strapdown: time gaps and physical plausibility.
//!
//! The mechanisation integrates gravity, Coriolis and transport rate over the true interval
//! since the previous sample (`t_k - t_{k-1}`). When samples are missing that interval is
//! longer than the nominal one, and what the increment of the next sample covers depends on
//! the source:
//!
//! - [`GapIncrements::Span`]: the increment covers the whole interval since the previous
//!   sample (a sensor that keeps accumulating, or rates converted to increments over the true
//!   interval, as `host-sim`'s CSV reader does). The sample is used as it is, over the gap.
//! - [`GapIncrements::Sample`]: the increment covers one nominal interval ending at its time
//!   stamp; the increments of the missing samples are lost (lines deleted from an increment
//!   file, a frame lost on the link). The lost part of the gap is filled with synthetic
//!   samples at about the nominal interval whose rates are interpolated linearly between the
//!   previous sample's mean rates and this one's, then the sample itself is used over its
//!   own nominal interval.
//! - [`GapIncrements::Auto`] (default): decided per gap from the specific force, which on
//!   any vehicle is dominated by gravity: the hypothesis whose mean specific force
//!   `|dv| / interval` is closer (in ratio) to the previous sample's is taken. The two
//!   hypotheses differ by the factor `gap / nominal >= 1.5`, far more than the specific
//!   force changes from one sample to the next on a land vehicle or a boat.
//!
//! A sample whose mean angular rate or specific force exceeds the configured physical range
//! on any axis ([`ImuLimits`], e.g. from the sensor class with [`ImuLimits::for_class`]), that
//! is not finite, or whose six increments are all exactly zero, is *rejected*: it is not integrated and the interval it covered is
//! bridged as a gap by the next sample. A gap longer than [`GuardConfig::max_gap_s`] is a
//! fault ([`GuardError::GapTooLong`]): the caller stops there.
//!
//! Allocation-free and panic-free: [`ImuGuard::check`] returns a [`Conditioned`] holding the
//! fill (an iterator of synthetic samples) and the sample to integrate after it.

use crate::strapdown::MAX_DT_S;
use crate::types::ImuSample;

/// What the increment of the first sample after a time gap covers (see the module notes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GapIncrements {
    /// Decide per gap from the specific force.
    #[default]
    Auto,
    /// The increment covers the whole interval since the previous sample.
    Span,
    /// The increment covers one nominal interval; the missing samples' increments are lost.
    Sample,
}

/// Sensor classes with typical full-scale ranges (used for [`ImuLimits::for_class`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ImuClass {
    /// Consumer / automotive MEMS (e.g. ICM-4xxxx, BMI, LSM6): up to 4000 deg/s, 32 g.
    #[default]
    ConsumerMems,
    /// Industrial MEMS (e.g. ADIS164xx): 2000 deg/s, 40 g.
    Industrial,
    /// Tactical grade (FOG / high-end MEMS): 1000 deg/s, 40 g.
    Tactical,
    /// Navigation grade (RLG / FOG): 500 deg/s, 30 g.
    Navigation,
}

/// Physical plausibility limits of an IMU sample: per-axis magnitude of the mean angular rate
/// (`|dtheta| / interval`) and of the mean specific force (`|dv| / interval`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuLimits {
    /// Largest plausible angular rate on any axis, rad/s.
    pub max_rate_radps: f64,
    /// Largest plausible specific force on any axis, m/s^2.
    pub max_accel_mps2: f64,
}

impl ImuLimits {
    /// The full-scale range of a sensor class (module [`ImuClass`]) plus a 10 % margin for
    /// calibration and the increment's integration.
    pub fn for_class(c: ImuClass) -> Self {
        const DEG: f64 = core::f64::consts::PI / 180.0;
        const G: f64 = 9.806_65;
        let (rate_deg, accel_g) = match c {
            ImuClass::ConsumerMems => (4000.0, 32.0),
            ImuClass::Industrial => (2000.0, 40.0),
            ImuClass::Tactical => (1000.0, 40.0),
            ImuClass::Navigation => (500.0, 30.0),
        };
        Self {
            max_rate_radps: 1.1 * rate_deg * DEG,
            max_accel_mps2: 1.1 * accel_g * G,
        }
    }

    /// No limit (only non-finite samples are rejected).
    pub fn none() -> Self {
        Self {
            max_rate_radps: f64::INFINITY,
            max_accel_mps2: f64::INFINITY,
        }
    }
}

impl Default for ImuLimits {
    /// [`ImuLimits::for_class`] of [`ImuClass::ConsumerMems`] (the widest class).
    fn default() -> Self {
        Self::for_class(ImuClass::ConsumerMems)
    }
}

/// Configuration of an [`ImuGuard`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GuardConfig {
    /// Nominal sample interval, s (e.g. the median interval of the record).
    pub nominal_dt_s: f64,
    /// An interval longer than `gap_factor * nominal_dt_s` is a gap (default 1.5).
    pub gap_factor: f64,
    /// Longest gap that is bridged, s; longer is a fault (default and at most
    /// [`MAX_DT_S`] when the increment spans the gap).
    pub max_gap_s: f64,
    /// What the increment after a gap covers.
    pub increments: GapIncrements,
    /// Physical range.
    pub limits: ImuLimits,
    /// Fill lost increments with the quadratic through both ends whose start slope is
    /// fitted to the samples before the gap (see [`GapFill`]; default); false: linear
    /// interpolation of the rates between both ends. On a simulated car drive (100 Hz,
    /// 50 samples lost at 230 places) the quadratic halves the RMS attitude and velocity
    /// error of the fill (4.8e-4 rad, 6.0e-3 m/s vs 1.0e-3 rad, 1.2e-2 m/s) and cuts the
    /// worst case 2.6x (2.5e-3 rad) and 3.9x (2.7e-2 m/s).
    pub fill_slope: bool,
}

impl GuardConfig {
    /// Defaults for a nominal interval: gaps beyond 1.5 intervals, bridged up to 1 s, auto
    /// increments, consumer-MEMS limits.
    pub fn new(nominal_dt_s: f64) -> Self {
        Self {
            nominal_dt_s,
            gap_factor: 1.5,
            max_gap_s: MAX_DT_S,
            increments: GapIncrements::Auto,
            limits: ImuLimits::default(),
            fill_slope: true,
        }
    }
}

/// Why a sample was rejected.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Implausible {
    /// Time or an increment is NaN or infinite.
    NonFinite,
    /// All six increments are exactly zero: no sensor reads that (gravity alone gives about
    /// 9.8 m/s^2, noise the rest); a logger that wrote an empty record.
    AllZero,
    /// Mean angular rate beyond the limit on an axis (rad/s).
    Rate {
        /// Axis (0 = x, 1 = y, 2 = z).
        axis: u8,
        /// The rate, rad/s.
        value_radps: f64,
    },
    /// Mean specific force beyond the limit on an axis (m/s^2).
    Accel {
        /// Axis (0 = x, 1 = y, 2 = z).
        axis: u8,
        /// The specific force, m/s^2.
        value_mps2: f64,
    },
}

impl core::fmt::Display for Implausible {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        const AX: [&str; 3] = ["x", "y", "z"];
        match *self {
            Self::NonFinite => f.write_str("non-finite time or increment"),
            Self::AllZero => f.write_str(
                "all six increments exactly zero (an empty record: no sensor reads zero \
                 specific force and zero rate)",
            ),
            Self::Rate { axis, value_radps } => write!(
                f,
                "angular rate {:.4e} deg/s on {} beyond the physical range",
                value_radps.to_degrees(),
                AX.get(usize::from(axis)).copied().unwrap_or("?")
            ),
            Self::Accel { axis, value_mps2 } => write!(
                f,
                "specific force {:.4e} m/s^2 on {} beyond the physical range",
                value_mps2,
                AX.get(usize::from(axis)).copied().unwrap_or("?")
            ),
        }
    }
}

/// Faults that end a run.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GuardError {
    /// The sample's time is not after the previous accepted sample's.
    NotIncreasing {
        /// Interval, s.
        dt_s: f64,
    },
    /// The gap before the sample is longer than [`GuardConfig::max_gap_s`].
    GapTooLong {
        /// Gap, s.
        dt_s: f64,
        /// The limit, s.
        max_s: f64,
    },
    /// The configuration is unusable (nominal interval not positive and finite).
    Config,
}

impl core::fmt::Display for GuardError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::NotIncreasing { dt_s } => {
                write!(f, "IMU time not increasing (interval {dt_s:.6} s)")
            }
            Self::GapTooLong { dt_s, max_s } => write!(
                f,
                "IMU gap of {dt_s:.3} s exceeds the longest bridged gap ({max_s:.3} s)"
            ),
            Self::Config => f.write_str("IMU guard: nominal interval must be positive"),
        }
    }
}

impl core::error::Error for GuardError {}

/// Counters of an [`ImuGuard`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GuardCounters {
    /// Samples passed on unchanged.
    pub passed: u64,
    /// Gaps seen (intervals beyond `gap_factor` nominal intervals before an accepted sample).
    pub gaps: u64,
    /// Of those, gaps whose increment was taken as spanning the gap.
    pub gaps_spanned: u64,
    /// Of those, gaps whose missing increments were filled.
    pub gaps_filled: u64,
    /// Missing samples (nominal intervals missing, summed over gaps).
    pub missing_samples: u64,
    /// Synthetic samples produced by fills.
    pub synthetic_samples: u64,
    /// Samples rejected as implausible.
    pub rejected: u64,
}

/// The fill of a gap: synthetic samples over the lost part of the gap (empty when none).
///
/// Each of the six mean rates (angular rate, specific force) follows the quadratic
/// `q(tau) = r_a + s_a tau + c tau^2`, `tau = t - t_a`, through the previous sample's rate
/// `r_a` at the middle of its interval `t_a`, with the slope `s_a` fitted (least squares) to
/// the samples of the last [`SLOPE_WINDOW_S`] before the gap, and through the next sample's
/// rate at the middle of its interval; each synthetic increment is its exact integral over
/// the synthetic interval. Without a usable slope (fewer than 3 samples before the gap) the
/// rate is interpolated linearly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GapFill {
    t_start_s: f64,
    step_s: f64,
    n: u32,
    i: u32,
    t_a: f64,
    r_a: [f64; 6],
    s_a: [f64; 6],
    c: [f64; 6],
    temperature_c: f64,
    unc: FillUncertainty,
}

/// What a fill cannot know: 1-sigma of the error of the synthetic increments summed over the
/// lost span, per body axis ([`GapFill::uncertainty`]; the filter widens its covariance by it,
/// `Filter::widen_for_fill`).
///
/// Two fills fit the rates at both ends of the gap: the quadratic whose start slope follows the
/// samples before the gap ([`GuardConfig::fill_slope`]) and the straight line. Where the rate
/// ramps steadily they agree; where it bends (a turn that starts or ends inside the gap) they
/// part, and by about as much as either is off: their difference, integrated over the lost
/// span, is the 1-sigma per axis. Without a slope (fewer than 3 samples before the gap) the
/// rate is taken to move anywhere within the band between its two end values (a Brownian
/// bridge whose intensity is set by the change across the gap): `dr L / sqrt(12)` for a change
/// `dr` over the span `L`. For the velocity, the specific force times the attitude sigma over
/// half the span is added (root sum square): the tilt the fill's attitude error builds up during
/// the gap.
///
/// Measured on the 4-minute tactical drive of `host-sim/tests/it/run_faults.rs` (50 samples lost
/// in the turn): roll error of the fill 1.54e-3 rad; the band rule gives 3.6e-3 rad there but
/// also 1.3e-2 rad in yaw (error 1.5e-4) and 0.14 m/s in the lateral velocity (error 1e-4),
/// and that over-widening cost 1.5x the gapless run's maximum error after the gap.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FillUncertainty {
    /// Lost span the fill covers, s (0: no fill).
    pub span_s: f64,
    /// Attitude increment summed over the span, rad (body x, y, z).
    pub dtheta_rad: [f64; 3],
    /// Velocity increment summed over the span, m/s (body x, y, z).
    pub dv_mps: [f64; 3],
}

/// Window before a gap over which the slope of the rates is fitted, s.
pub const SLOPE_WINDOW_S: f64 = 0.2;

/// Samples kept for the slope fit (at most; those within [`SLOPE_WINDOW_S`] are used).
pub const HISTORY: usize = 64;

impl GapFill {
    fn empty() -> Self {
        Self {
            t_start_s: 0.0,
            step_s: 0.0,
            n: 0,
            i: 0,
            t_a: 0.0,
            r_a: [0.0; 6],
            s_a: [0.0; 6],
            c: [0.0; 6],
            temperature_c: f64::NAN,
            unc: FillUncertainty::default(),
        }
    }

    /// 1-sigma of the fill's error over the lost span (zero for an empty fill).
    pub fn uncertainty(&self) -> FillUncertainty {
        self.unc
    }

    /// Number of synthetic samples in the fill.
    pub fn len(&self) -> u32 {
        self.n
    }

    /// Whether the fill is empty.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }
}

impl Iterator for GapFill {
    type Item = ImuSample;

    fn next(&mut self) -> Option<ImuSample> {
        if self.i >= self.n {
            return None;
        }
        let t0 = self.t_start_s + f64::from(self.i) * self.step_s;
        self.i += 1;
        let t1 = self.t_start_s + f64::from(self.i) * self.step_s;
        let (u0, u1) = (t0 - self.t_a, t1 - self.t_a);
        let mut inc = [0.0; 6];
        for (k, v) in inc.iter_mut().enumerate() {
            let r = self.r_a.get(k).copied().unwrap_or(0.0);
            let sl = self.s_a.get(k).copied().unwrap_or(0.0);
            let c = self.c.get(k).copied().unwrap_or(0.0);
            *v = r * (u1 - u0)
                + sl * 0.5 * (u1 * u1 - u0 * u0)
                + c * (u1 * u1 * u1 - u0 * u0 * u0) / 3.0;
        }
        let [a, b, c, d, e, f] = inc;
        Some(ImuSample {
            t_s: t1,
            dtheta_rad: [a, b, c],
            dv_mps: [d, e, f],
            temperature_c: self.temperature_c,
        })
    }
}

/// What to integrate for one input sample: the fill (possibly empty), then `sample`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conditioned {
    /// Synthetic samples over the lost part of a gap, to integrate first.
    pub fill: GapFill,
    /// The sample to integrate after the fill (the input sample, unchanged).
    pub sample: ImuSample,
    /// Missing nominal intervals before the sample (0 when there is no gap).
    pub missing: u32,
    /// When there was a gap: whether its increment was taken as spanning it.
    pub spanned: bool,
}

/// The outcome of [`ImuGuard::check`].
#[derive(Debug, Clone, Copy, PartialEq)]
// no allocation in nav-core: the fill travels by value (about 300 bytes)
#[allow(clippy::large_enum_variant)]
pub enum Verdict {
    /// Integrate [`Conditioned::fill`] then [`Conditioned::sample`].
    Use(Conditioned),
    /// The sample is implausible: skip it (counted; its interval is bridged by the next one).
    Reject(Implausible),
}

/// Gap handling and plausibility checks in front of the strapdown (module notes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuGuard {
    cfg: GuardConfig,
    prev: Option<(ImuSample, f64)>,
    t_last_s: f64,
    counters: GuardCounters,
    // mean rates (6) at the middle of the intervals of the last accepted samples since the
    // last gap, ring buffer
    hist_t: [f64; HISTORY],
    hist_r: [[f64; 6]; HISTORY],
    hist_len: usize,
    hist_head: usize,
}

fn rates6(s: &ImuSample, dt: f64) -> [f64; 6] {
    let [a, b, c] = s.dtheta_rad;
    let [d, e, f] = s.dv_mps;
    [a, b, c, d, e, f].map(|x| x / dt)
}

fn norm(v: &[f64; 3]) -> f64 {
    libm::sqrt(v.iter().map(|x| x * x).sum::<f64>())
}

/// [`FillUncertainty`] of a fill over `[u0, u0 + lost]` (s after `t_a`, the middle of the
/// previous sample's interval) of the rates `r_a` (at `t_a`) and `r_b` (at `t_a + big_t`),
/// with `slope` the start slopes fitted before the gap when there are any.
fn fill_uncertainty(
    r_a: &[f64; 6],
    r_b: &[f64; 6],
    slope: Option<[f64; 6]>,
    big_t: f64,
    u0: f64,
    lost: f64,
) -> FillUncertainty {
    // integral of tau (T - tau) / T over the span: the shape of quadratic minus linear fill
    let g = |u: f64| u * u / 2.0 - u * u * u / (3.0 * big_t);
    let shape = g(u0 + lost) - g(u0);
    let mut sig = [0.0; 6];
    for (k, o) in sig.iter_mut().enumerate() {
        let (ra, rb) = (
            r_a.get(k).copied().unwrap_or(0.0),
            r_b.get(k).copied().unwrap_or(0.0),
        );
        *o = match slope {
            Some(sa) => libm::fabs((sa.get(k).copied().unwrap_or(0.0) - (rb - ra) / big_t) * shape),
            None => libm::fabs(rb - ra) * lost / libm::sqrt(12.0),
        };
    }
    let [a, b, c, d, e, f] = sig;
    let att = [a, b, c];
    let fm = [3, 4, 5]
        .map(|k| 0.5 * (r_a.get(k).copied().unwrap_or(0.0) + r_b.get(k).copied().unwrap_or(0.0)));
    let tilt = norm(&fm) * norm(&att) * 0.5 * lost;
    let dv = [d, e, f].map(|x| libm::sqrt(x * x + tilt * tilt));
    let ok = |v: &[f64; 3]| v.iter().all(|x| x.is_finite());
    if !(lost.is_finite() && lost > 0.0 && ok(&att) && ok(&dv)) {
        return FillUncertainty::default();
    }
    FillUncertainty {
        span_s: lost,
        dtheta_rad: att,
        dv_mps: dv,
    }
}

impl ImuGuard {
    /// A guard whose last accepted sample is at `t_start_s` (the filter's initial epoch),
    /// with `prev` the sample ending there and its interval (s) when known (for the rates
    /// the first fill interpolates from).
    pub fn new(
        cfg: GuardConfig,
        t_start_s: f64,
        prev: Option<(ImuSample, f64)>,
    ) -> Result<Self, GuardError> {
        if !(cfg.nominal_dt_s.is_finite() && cfg.nominal_dt_s > 0.0) {
            return Err(GuardError::Config);
        }
        Ok(Self {
            cfg,
            prev: prev.filter(|(s, dt)| s.is_finite() && dt.is_finite() && *dt > 0.0),
            t_last_s: t_start_s,
            counters: GuardCounters::default(),
            hist_t: [0.0; HISTORY],
            hist_r: [[0.0; 6]; HISTORY],
            hist_len: 0,
            hist_head: 0,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &GuardConfig {
        &self.cfg
    }

    /// The counters.
    pub fn counters(&self) -> &GuardCounters {
        &self.counters
    }

    fn plausible(&self, s: &ImuSample, dt: f64) -> Result<(), Implausible> {
        if !s.is_finite() {
            return Err(Implausible::NonFinite);
        }
        if s.dtheta_rad
            .iter()
            .chain(s.dv_mps.iter())
            .all(|x| *x == 0.0)
        {
            return Err(Implausible::AllZero);
        }
        let l = &self.cfg.limits;
        for (axis, x) in (0u8..).zip(s.dtheta_rad.iter()) {
            let r = x / dt;
            if r.is_nan() || r.abs() > l.max_rate_radps {
                return Err(Implausible::Rate {
                    axis,
                    value_radps: r,
                });
            }
        }
        for (axis, x) in (0u8..).zip(s.dv_mps.iter()) {
            let a = x / dt;
            if a.is_nan() || a.abs() > l.max_accel_mps2 {
                return Err(Implausible::Accel {
                    axis,
                    value_mps2: a,
                });
            }
        }
        Ok(())
    }

    /// Checks one sample (in time order). `Ok(Verdict::Use)` gives what to integrate;
    /// `Ok(Verdict::Reject)` an implausible sample to skip; `Err` a fault (time not
    /// increasing, a gap longer than [`GuardConfig::max_gap_s`]).
    pub fn check(&mut self, s: &ImuSample) -> Result<Verdict, GuardError> {
        if !s.t_s.is_finite() {
            self.counters.rejected = self.counters.rejected.saturating_add(1);
            return Ok(Verdict::Reject(Implausible::NonFinite));
        }
        let dt = s.t_s - self.t_last_s;
        if dt.is_nan() || dt <= 0.0 {
            return Err(GuardError::NotIncreasing { dt_s: dt });
        }
        let dt0 = self.cfg.nominal_dt_s;
        let is_gap = dt > self.cfg.gap_factor * dt0;
        if !is_gap {
            if let Err(e) = self.plausible(s, dt) {
                self.counters.rejected = self.counters.rejected.saturating_add(1);
                return Ok(Verdict::Reject(e));
            }
            self.accept(s, dt);
            self.counters.passed = self.counters.passed.saturating_add(1);
            return Ok(Verdict::Use(Conditioned {
                fill: GapFill::empty(),
                sample: *s,
                missing: 0,
                spanned: false,
            }));
        }
        let spanned = self.spans_the_gap(s, dt, dt0);
        let max = if spanned {
            self.cfg.max_gap_s.min(MAX_DT_S)
        } else {
            self.cfg.max_gap_s
        };
        if dt.is_nan() || dt > max {
            return Err(GuardError::GapTooLong {
                dt_s: dt,
                max_s: max,
            });
        }
        let own = if spanned { dt } else { dt0.min(dt) };
        if let Err(e) = self.plausible(s, own) {
            self.counters.rejected = self.counters.rejected.saturating_add(1);
            return Ok(Verdict::Reject(e));
        }
        let missing = (libm::round(dt / dt0) - 1.0).clamp(1.0, f64::from(u32::MAX)) as u32;
        self.counters.gaps = self.counters.gaps.saturating_add(1);
        self.counters.missing_samples = self
            .counters
            .missing_samples
            .saturating_add(u64::from(missing));
        let fill = if spanned {
            self.counters.gaps_spanned = self.counters.gaps_spanned.saturating_add(1);
            GapFill::empty()
        } else {
            self.counters.gaps_filled = self.counters.gaps_filled.saturating_add(1);
            let fill = self.fill_lost(s, dt, own, dt0);
            self.counters.synthetic_samples = self
                .counters
                .synthetic_samples
                .saturating_add(u64::from(fill.n));
            fill
        };
        self.hist_len = 0;
        self.accept(s, own);
        Ok(Verdict::Use(Conditioned {
            fill,
            sample: *s,
            missing,
            spanned,
        }))
    }

    /// Whether the increment of the sample `s` ending a gap of `dt` s covers the whole gap
    /// (true) or one nominal interval `dt0` (false): the configured [`GapIncrements`], `Auto`
    /// deciding by the specific force closer in ratio to the previous sample's.
    #[inline(always)]
    fn spans_the_gap(&self, s: &ImuSample, dt: f64, dt0: f64) -> bool {
        match self.cfg.increments {
            GapIncrements::Span => true,
            GapIncrements::Sample => false,
            GapIncrements::Auto => match self.prev {
                Some((p, pdt)) => {
                    let f_ref = norm(&p.dv_mps) / pdt;
                    let f_span = norm(&s.dv_mps) / dt;
                    let f_sample = norm(&s.dv_mps) / dt0;
                    if f_ref > 0.0 && f_span > 0.0 && f_sample > 0.0 {
                        libm::fabs(libm::log(f_span / f_ref))
                            <= libm::fabs(libm::log(f_sample / f_ref))
                    } else {
                        true
                    }
                }
                None => true,
            },
        }
    }

    /// The synthetic samples over the lost part `dt - own` s of a gap ended by `s` (which
    /// covers its own `own` s): the quadratic in the six rates through the previous sample's
    /// mean rates and `s`'s, its start slope fitted to the history before the gap (or the
    /// linear interpolation, [`GuardConfig::fill_slope`]), about `dt0` s per sample.
    #[inline(always)]
    fn fill_lost(&self, s: &ImuSample, dt: f64, own: f64, dt0: f64) -> GapFill {
        let lost = dt - own;
        let n = libm::round(lost / dt0).clamp(1.0, f64::from(u32::MAX)) as u32;
        let r_b = rates6(s, own);
        let t_b = s.t_s - 0.5 * own;
        let (t_a, r_a) = match self.prev {
            Some((p, pdt)) => (self.t_last_s - 0.5 * pdt, rates6(&p, pdt)),
            None => (self.t_last_s, r_b),
        };
        let big_t = t_b - t_a;
        let mut s_a = [0.0; 6];
        let mut c = [0.0; 6];
        let fitted = self.history_slope(t_a);
        let slope = if self.cfg.fill_slope { fitted } else { None };
        for k in 0..6 {
            let (ra, rb) = (
                r_a.get(k).copied().unwrap_or(0.0),
                r_b.get(k).copied().unwrap_or(0.0),
            );
            let lin = (rb - ra) / big_t;
            let sa = slope.map_or(lin, |v| v.get(k).copied().unwrap_or(lin));
            if let Some(x) = s_a.get_mut(k) {
                *x = sa;
            }
            if let Some(x) = c.get_mut(k) {
                *x = (rb - ra - sa * big_t) / (big_t * big_t);
            }
        }
        let unc = fill_uncertainty(&r_a, &r_b, fitted, big_t, self.t_last_s - t_a, lost);
        GapFill {
            t_start_s: self.t_last_s,
            step_s: lost / f64::from(n),
            n,
            i: 0,
            t_a,
            r_a,
            s_a,
            c,
            temperature_c: s.temperature_c,
            unc,
        }
    }

    fn accept(&mut self, s: &ImuSample, covered_s: f64) {
        self.prev = Some((*s, covered_s));
        self.t_last_s = s.t_s;
        if let (Some(t), Some(r)) = (
            self.hist_t.get_mut(self.hist_head),
            self.hist_r.get_mut(self.hist_head),
        ) {
            *t = s.t_s - 0.5 * covered_s;
            *r = rates6(s, covered_s);
        }
        self.hist_head = (self.hist_head + 1) % HISTORY;
        self.hist_len = (self.hist_len + 1).min(HISTORY);
    }

    /// Least-squares slope of the six rates over the history within [`SLOPE_WINDOW_S`] of
    /// `t_a`; None with fewer than 3 samples.
    fn history_slope(&self, t_a: f64) -> Option<[f64; 6]> {
        let idx = |j: usize| (self.hist_head + HISTORY - 1 - j) % HISTORY;
        let mut n = 0usize;
        let (mut st, mut sr) = (0.0, [0.0; 6]);
        for j in 0..self.hist_len {
            let (Some(&t), Some(r)) = (self.hist_t.get(idx(j)), self.hist_r.get(idx(j))) else {
                break;
            };
            if t < t_a - SLOPE_WINDOW_S {
                break;
            }
            n += 1;
            st += t;
            for (a, b) in sr.iter_mut().zip(r.iter()) {
                *a += b;
            }
        }
        if n < 3 {
            return None;
        }
        let nf = n as f64;
        let mt = st / nf;
        let mr = sr.map(|x| x / nf);
        let (mut stt, mut str_) = (0.0, [0.0; 6]);
        for j in 0..n {
            let (Some(&t), Some(r)) = (self.hist_t.get(idx(j)), self.hist_r.get(idx(j))) else {
                break;
            };
            let dt = t - mt;
            stt += dt * dt;
            for ((a, b), m) in str_.iter_mut().zip(r.iter()).zip(mr.iter()) {
                *a += dt * (b - m);
            }
        }
        if stt <= 0.0 {
            return None;
        }
        Some(str_.map(|x| x / stt))
    }
}
