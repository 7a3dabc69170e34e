//! Stationarity detector on the IMU (measurement check of the zero-velocity and zero-rate
//! updates): a window of the corrected specific force and angular rate, tested on
//!
//! * the spread of the specific force (root of the summed per-axis variances, m/s^2): a
//!   moving vehicle vibrates and accelerates;
//! * the magnitude of the mean specific force against normal gravity (m/s^2);
//! * the magnitude of the mean angular rate (rad/s, bias-corrected by the filter) and its
//!   spread (rad/s);
//! * the GNSS speed when a recent one is given (m/s).
//!
//! The window is a ring buffer of `W` samples (const generic, no allocation); the window used
//! is `StationarityConfig::window_s` long, at most `W` samples.
//!
//! A vehicle standing with its engine idling vibrates: its specific-force and rate spreads
//! can lie above the fixed thresholds. [`RestLevel`] learns that signature while a recent GNSS
//! velocity says the vehicle stands (an exponential average of the two spreads over windows
//! that pass every other test) and raises the two spread thresholds to
//! `learn_margin` times the learned spreads, never above the bounds `learn_accel_std_max_mps2`
//! and `learn_gyro_std_max_radps` (driving shakes more than that) and only while the filter's
//! own speed is at most `learn_filter_speed_max_mps` (slow driving on a smooth road can vibrate
//! like a stop: the filter's speed tells them apart when the GNSS is missing).

use crate::scalar::Scalar;

/// Thresholds of the stationarity detector (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct StationarityConfig {
    /// Length of the test window, s (capped at the detector's `W` samples).
    pub window_s: f64,
    /// Largest spread of the specific force over the window, m/s^2 (root of the summed
    /// per-axis variances).
    pub accel_std_max_mps2: f64,
    /// Largest | |mean specific force| - normal gravity |, m/s^2 (allow for the accelerometer
    /// bias and scale error).
    pub accel_mag_tol_mps2: f64,
    /// Largest magnitude of the mean angular rate, rad/s.
    pub gyro_mean_max_radps: f64,
    /// Largest spread of the angular rate, rad/s (root of the summed per-axis variances).
    pub gyro_std_max_radps: f64,
    /// Largest GNSS speed, m/s (applies when a GNSS velocity at most `gnss_max_age_s` old is
    /// given).
    pub gnss_speed_max_mps: f64,
    /// Oldest GNSS velocity used by the test, s.
    pub gnss_max_age_s: f64,
    /// Largest speed of the filter's own estimate, m/s: without GNSS a straight drive at
    /// constant speed on a smooth road looks still to the IMU; the filter knows it moves.
    pub filter_speed_max_mps: f64,
    /// Whether the spread thresholds adapt to the vibration learned at GNSS-confirmed stops
    /// ([`RestLevel`]).
    pub learn: bool,
    /// Learned thresholds: this factor times the learned spreads (dimensionless, >= 1).
    pub learn_margin: f64,
    /// Time constant of the learning (exponential average over the stops' windows), s.
    pub learn_tau_s: f64,
    /// Upper bound of the learned specific-force spread threshold, m/s^2 (windows above it
    /// are not learned).
    pub learn_accel_std_max_mps2: f64,
    /// Upper bound of the learned rate spread threshold, rad/s (windows above it are not
    /// learned).
    pub learn_gyro_std_max_radps: f64,
    /// Largest speed of the filter's estimate at which the learned thresholds apply, m/s
    /// (above it the fixed thresholds do).
    pub learn_filter_speed_max_mps: f64,
}

impl StationarityConfig {
    /// Defaults for a car with a consumer MEMS IMU: 0.5 s window, 0.1 m/s^2 specific-force
    /// spread, 0.3 m/s^2 gravity tolerance, 1 deg/s mean rate, 0.5 deg/s rate spread, 0.15 m/s
    /// GNSS speed no older than 1 s; learning of the idling vibration on, thresholds 1.5 times
    /// the learned spreads over 5 s, at most 0.2 m/s^2 and 2 deg/s, at filter speeds up to
    /// 0.5 m/s.
    pub const DEFAULT: Self = Self {
        window_s: 0.5,
        accel_std_max_mps2: 0.1,
        accel_mag_tol_mps2: 0.3,
        gyro_mean_max_radps: 1.0 * core::f64::consts::PI / 180.0,
        gyro_std_max_radps: 0.5 * core::f64::consts::PI / 180.0,
        gnss_speed_max_mps: 0.15,
        gnss_max_age_s: 1.0,
        filter_speed_max_mps: 1.0,
        learn: true,
        learn_margin: 1.5,
        learn_tau_s: 5.0,
        learn_accel_std_max_mps2: 0.2,
        learn_gyro_std_max_radps: 2.0 * core::f64::consts::PI / 180.0,
        learn_filter_speed_max_mps: 0.5,
    };
}

impl Default for StationarityConfig {
    fn default() -> Self {
        Self::DEFAULT
    }
}

/// Statistics of the detector's window.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct WindowStats {
    /// Samples in the window.
    pub n: usize,
    /// Mean specific force, body, m/s^2.
    pub f_mean_mps2: [f64; 3],
    /// Root of the summed per-axis variances of the specific force, m/s^2.
    pub f_std_mps2: f64,
    /// Mean angular rate, body, rad/s.
    pub w_mean_radps: [f64; 3],
    /// Root of the summed per-axis variances of the angular rate, rad/s.
    pub w_std_radps: f64,
}

/// The detector: a ring buffer of the last `W` corrected IMU samples.
#[derive(Debug, Clone)]
pub struct StationarityDetector<T: Scalar, const W: usize> {
    f: [[T; 3]; W],
    w: [[T; 3]; W],
    head: usize,
    len: usize,
}

impl<T: Scalar, const W: usize> Default for StationarityDetector<T, W> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Scalar, const W: usize> StationarityDetector<T, W> {
    /// An empty detector.
    pub const fn new() -> Self {
        Self {
            f: [[T::ZERO; 3]; W],
            w: [[T::ZERO; 3]; W],
            head: 0,
            len: 0,
        }
    }

    /// Adds one sample: specific force (m/s^2) and angular rate (rad/s), body axes. Non-finite
    /// samples empty the window (the next decisions wait for a full window again).
    pub fn push(&mut self, f_mps2: &[f64; 3], w_radps: &[f64; 3]) {
        if !(f_mps2.iter().chain(w_radps).all(|v| v.is_finite())) {
            self.clear();
            return;
        }
        if W == 0 {
            return;
        }
        if let Some(x) = self.f.get_mut(self.head) {
            *x = f_mps2.map(T::of_f64);
        }
        if let Some(x) = self.w.get_mut(self.head) {
            *x = w_radps.map(T::of_f64);
        }
        self.head = (self.head + 1) % W;
        self.len = (self.len + 1).min(W);
    }

    /// Empties the window.
    pub fn clear(&mut self) {
        self.len = 0;
        self.head = 0;
    }

    /// Samples held.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no sample is held.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Statistics of the last `n` samples (n >= 2), or None when fewer are held.
    pub fn stats(&self, n: usize) -> Option<WindowStats> {
        if n < 2 || n > self.len || W == 0 {
            return None;
        }
        let (fm, fs) = mean_spread(&self.f, self.head, n);
        let (wm, ws) = mean_spread(&self.w, self.head, n);
        Some(WindowStats {
            n,
            f_mean_mps2: fm,
            f_std_mps2: fs,
            w_mean_radps: wm,
            w_std_radps: ws,
        })
    }
}

/// Mean and root of summed per-axis (sample) variances of the last `n` entries before `head`,
/// two-pass in the scalar type (f32 on the MCU: no soft-float f64 in the loop).
fn mean_spread<T: Scalar, const W: usize>(
    buf: &[[T; 3]; W],
    head: usize,
    n: usize,
) -> ([f64; 3], f64) {
    let mut mean = [T::ZERO; 3];
    let mut k = 0usize;
    for i in 0..n {
        let idx = (head + W - 1 - i) % W;
        if let Some(s) = buf.get(idx) {
            for (m, v) in mean.iter_mut().zip(s) {
                *m += *v;
            }
            k += 1;
        }
    }
    if k < 2 {
        return ([f64::NAN; 3], f64::NAN);
    }
    let kf = T::of_f64(k as f64);
    for m in mean.iter_mut() {
        *m /= kf;
    }
    let mut ss = T::ZERO;
    for i in 0..n {
        let idx = (head + W - 1 - i) % W;
        if let Some(s) = buf.get(idx) {
            for (m, v) in mean.iter().zip(s) {
                let d = *v - *m;
                ss += d * d;
            }
        }
    }
    let var = ss / (kf - T::ONE);
    (mean.map(|m| m.to_f64()), var.sqrt_libm().to_f64())
}

/// The detector's decision on window statistics with the fixed thresholds: whether every test
/// passes. `gravity_mps2` is normal gravity at the vehicle; `gnss_speed_mps` a recent GNSS
/// speed, if any; `filter_speed_mps` the filter's estimated speed.
pub fn is_stationary(
    cfg: &StationarityConfig,
    s: &WindowStats,
    gravity_mps2: f64,
    gnss_speed_mps: Option<f64>,
    filter_speed_mps: f64,
) -> bool {
    let thr = Thresholds {
        accel_std_mps2: cfg.accel_std_max_mps2,
        gyro_std_radps: cfg.gyro_std_max_radps,
    };
    passes(cfg, &thr, s, gravity_mps2, gnss_speed_mps, filter_speed_mps)
}

/// Spread thresholds of one decision (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Thresholds {
    /// Largest specific-force spread, m/s^2.
    pub accel_std_mps2: f64,
    /// Largest rate spread, rad/s.
    pub gyro_std_radps: f64,
}

fn norm3(v: &[f64; 3]) -> f64 {
    libm::sqrt(v.iter().map(|x| x * x).sum::<f64>())
}

/// The tests other than the two spreads: gravity magnitude and mean rate.
fn still_apart_from_spread(cfg: &StationarityConfig, s: &WindowStats, gravity_mps2: f64) -> bool {
    (norm3(&s.f_mean_mps2) - gravity_mps2).abs() <= cfg.accel_mag_tol_mps2
        && norm3(&s.w_mean_radps) <= cfg.gyro_mean_max_radps
}

fn passes(
    cfg: &StationarityConfig,
    thr: &Thresholds,
    s: &WindowStats,
    gravity_mps2: f64,
    gnss_speed_mps: Option<f64>,
    filter_speed_mps: f64,
) -> bool {
    let imu_still = s.f_std_mps2 <= thr.accel_std_mps2
        && s.w_std_radps <= thr.gyro_std_radps
        && still_apart_from_spread(cfg, s, gravity_mps2);
    let gnss_still = gnss_speed_mps.is_none_or(|v| v <= cfg.gnss_speed_max_mps);
    imu_still && gnss_still && filter_speed_mps <= cfg.filter_speed_max_mps
}

/// The vibration signature learned at stops: exponential averages of the specific-force and
/// rate spreads of windows taken while a recent GNSS velocity says the vehicle stands
/// ([`StationarityConfig::learn`]). Scalar type `T` like the detector's window (f32 on the
/// MCU); no allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RestLevel<T: Scalar> {
    accel_std: T,
    gyro_std: T,
    learned: bool,
}

impl<T: Scalar> Default for RestLevel<T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<T: Scalar> RestLevel<T> {
    /// Nothing learned yet (the fixed thresholds apply).
    pub const fn new() -> Self {
        Self {
            accel_std: T::ZERO,
            gyro_std: T::ZERO,
            learned: false,
        }
    }

    /// The learned spreads `[specific force m/s^2, rate rad/s]`, once a stop was seen.
    pub fn level(&self) -> Option<[f64; 2]> {
        self.learned
            .then(|| [self.accel_std.to_f64(), self.gyro_std.to_f64()])
    }

    /// Learns from a window `dt_s` after the previous decision when the GNSS speed (recent,
    /// as for the decision) is at most `gnss_speed_max_mps`, the filter's speed at most
    /// `learn_filter_speed_max_mps`, the gravity and mean-rate tests pass and both spreads lie
    /// within the learning bounds. Returns whether the window was learned.
    pub fn learn(
        &mut self,
        cfg: &StationarityConfig,
        s: &WindowStats,
        gravity_mps2: f64,
        gnss_speed_mps: Option<f64>,
        filter_speed_mps: f64,
        dt_s: f64,
    ) -> bool {
        let standing = gnss_speed_mps.is_some_and(|v| v <= cfg.gnss_speed_max_mps)
            && filter_speed_mps <= cfg.learn_filter_speed_max_mps;
        let usable = s.f_std_mps2.is_finite()
            && s.w_std_radps.is_finite()
            && s.f_std_mps2 <= cfg.learn_accel_std_max_mps2
            && s.w_std_radps <= cfg.learn_gyro_std_max_radps
            && still_apart_from_spread(cfg, s, gravity_mps2);
        if !(cfg.learn && standing && usable) {
            return false;
        }
        let (a, g) = (T::of_f64(s.f_std_mps2), T::of_f64(s.w_std_radps));
        if self.learned {
            let k = if cfg.learn_tau_s > 0.0 && dt_s.is_finite() {
                (dt_s / cfg.learn_tau_s).clamp(0.0, 1.0)
            } else {
                1.0
            };
            let k = T::of_f64(k);
            self.accel_std += (a - self.accel_std) * k;
            self.gyro_std += (g - self.gyro_std) * k;
        } else {
            (self.accel_std, self.gyro_std, self.learned) = (a, g, true);
        }
        true
    }

    /// The spread thresholds at a filter speed (m/s): the fixed ones, raised to
    /// `learn_margin` times the learned spreads (at most the learning bounds) when learning is
    /// on, a stop was learned and the speed is at most `learn_filter_speed_max_mps`.
    pub fn thresholds(&self, cfg: &StationarityConfig, filter_speed_mps: f64) -> Thresholds {
        let fixed = Thresholds {
            accel_std_mps2: cfg.accel_std_max_mps2,
            gyro_std_radps: cfg.gyro_std_max_radps,
        };
        match self.level() {
            Some([a, g]) if cfg.learn && filter_speed_mps <= cfg.learn_filter_speed_max_mps => {
                let raise = |fixed: f64, level: f64, bound: f64| {
                    fixed.max((cfg.learn_margin * level).min(bound))
                };
                Thresholds {
                    accel_std_mps2: raise(fixed.accel_std_mps2, a, cfg.learn_accel_std_max_mps2),
                    gyro_std_radps: raise(fixed.gyro_std_radps, g, cfg.learn_gyro_std_max_radps),
                }
            }
            _ => fixed,
        }
    }

    /// The decision with these thresholds ([`is_stationary`]'s tests).
    pub fn is_stationary(
        &self,
        cfg: &StationarityConfig,
        s: &WindowStats,
        gravity_mps2: f64,
        gnss_speed_mps: Option<f64>,
        filter_speed_mps: f64,
    ) -> bool {
        let thr = self.thresholds(cfg, filter_speed_mps);
        passes(cfg, &thr, s, gravity_mps2, gnss_speed_mps, filter_speed_mps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn still_window_passes_and_moving_or_turning_fails() {
        let cfg = StationarityConfig::DEFAULT;
        let mut d = StationarityDetector::<f64, 64>::new();
        assert!(d.stats(50).is_none());
        for k in 0..64 {
            let n = if k % 2 == 0 { 0.02 } else { -0.02 };
            d.push(&[n, -n, -9.80 + n], &[1e-4, -1e-4, 2e-4]);
        }
        let s = d.stats(50).expect("full window");
        assert_eq!(s.n, 50);
        assert!((s.f_mean_mps2[2] + 9.80).abs() < 1e-3);
        assert!(is_stationary(&cfg, &s, 9.80, None, 0.0));
        assert!(is_stationary(&cfg, &s, 9.80, Some(0.05), 0.0));
        // the GNSS says it moves
        assert!(!is_stationary(&cfg, &s, 9.80, Some(1.0), 0.0));
        // the filter says it moves (a smooth straight drive without GNSS)
        assert!(!is_stationary(&cfg, &s, 9.80, None, 10.0));
        // turning at 3 deg/s
        for _ in 0..64 {
            d.push(&[0.0, 0.0, -9.80], &[0.0, 0.0, 0.05]);
        }
        let s = d.stats(50).expect("full window");
        assert!(!is_stationary(&cfg, &s, 9.80, None, 0.0));
        // vibrating / accelerating
        for k in 0..64 {
            let a = if k % 2 == 0 { 0.5 } else { -0.5 };
            d.push(&[a, 0.0, -9.80], &[0.0; 3]);
        }
        let s = d.stats(50).expect("full window");
        assert!(s.f_std_mps2 > 0.4);
        assert!(!is_stationary(&cfg, &s, 9.80, None, 0.0));
        // a NaN empties the window
        d.push(&[f64::NAN, 0.0, 0.0], &[0.0; 3]);
        assert!(d.is_empty());
    }

    /// A window with alternating specific-force and rate (amplitudes `a` m/s^2, `w` rad/s).
    fn vibrating<T: Scalar>(a: f64, w: f64) -> WindowStats {
        let mut d = StationarityDetector::<T, 64>::new();
        for k in 0..64 {
            let s = if k % 2 == 0 { 1.0 } else { -1.0 };
            d.push(&[s * a, 0.0, -9.80 + s * a], &[s * w, -s * w, 0.0]);
        }
        d.stats(50).expect("full window")
    }

    fn learns_idling_and_refuses_driving<T: Scalar>() {
        let cfg = StationarityConfig::DEFAULT;
        // idling: 0.11 m/s^2 and 1.2 deg/s spread, above the fixed 0.1 / 0.5
        let idle = vibrating::<T>(0.08, 0.015);
        assert!(idle.f_std_mps2 > 0.11 && idle.w_std_radps > 1.1f64.to_radians());
        assert!(!is_stationary(&cfg, &idle, 9.80, Some(0.0), 0.0));
        let mut rest = RestLevel::<T>::new();
        assert_eq!(rest.level(), None);
        assert!(!rest.is_stationary(&cfg, &idle, 9.80, None, 0.0));
        // not learned: the GNSS is missing, says it moves, the filter moves, it shakes like a
        // drive, learning is off
        assert!(!rest.learn(&cfg, &idle, 9.80, None, 0.0, 0.1));
        assert!(!rest.learn(&cfg, &idle, 9.80, Some(0.5), 0.0, 0.1));
        assert!(!rest.learn(&cfg, &idle, 9.80, Some(0.0), 0.8, 0.1));
        let drive = vibrating::<T>(0.4, 0.03);
        assert!(!rest.learn(&cfg, &drive, 9.80, Some(0.0), 0.0, 0.1));
        let off = StationarityConfig {
            learn: false,
            ..cfg
        };
        assert!(!rest.learn(&off, &idle, 9.80, Some(0.0), 0.0, 0.1));
        assert_eq!(rest.level(), None);
        // learned at a GNSS-confirmed stop
        for _ in 0..50 {
            assert!(rest.learn(&cfg, &idle, 9.80, Some(0.02), 0.01, 0.1));
        }
        let [a, g] = rest.level().expect("learned");
        assert!((a - idle.f_std_mps2).abs() < 1e-4, "{a}");
        assert!((g - idle.w_std_radps).abs() < 1e-5, "{g}");
        let thr = rest.thresholds(&cfg, 0.0);
        assert!((thr.accel_std_mps2 - 1.5 * a).abs() < 1e-6);
        assert!((thr.gyro_std_radps - 1.5 * g).abs() < 1e-6);
        // the idling vibration is now still without the GNSS...
        assert!(rest.is_stationary(&cfg, &idle, 9.80, None, 0.0));
        // ...but not when the filter moves at 0.8 m/s (slow driving), nor when the GNSS moves
        assert!(!rest.is_stationary(&cfg, &idle, 9.80, None, 0.8));
        assert_eq!(
            rest.thresholds(&cfg, 0.8).accel_std_mps2,
            cfg.accel_std_max_mps2
        );
        assert!(!rest.is_stationary(&cfg, &idle, 9.80, Some(0.3), 0.0));
        // driving vibration and turning stay moving
        assert!(!rest.is_stationary(&cfg, &drive, 9.80, None, 0.0));
        let mut turn = idle;
        turn.w_mean_radps = [0.0, 0.0, 0.05];
        assert!(!rest.is_stationary(&cfg, &turn, 9.80, None, 0.0));
        // a quiet stop: the learned level follows it down over learn_tau_s, the thresholds
        // never below the fixed ones
        let quiet = vibrating::<T>(0.01, 0.001);
        for _ in 0..200 {
            rest.learn(&cfg, &quiet, 9.80, Some(0.0), 0.0, 0.1);
        }
        let thr = rest.thresholds(&cfg, 0.0);
        assert_eq!(thr.accel_std_mps2, cfg.accel_std_max_mps2);
        assert_eq!(thr.gyro_std_radps, cfg.gyro_std_max_radps);
        // the bounds cap the learned thresholds
        let mut loud = RestLevel::<T>::new();
        let near_bound = vibrating::<T>(0.13, 0.022);
        assert!(loud.learn(&cfg, &near_bound, 9.80, Some(0.0), 0.0, 0.1));
        let thr = loud.thresholds(&cfg, 0.0);
        assert_eq!(thr.accel_std_mps2, cfg.learn_accel_std_max_mps2);
        assert_eq!(thr.gyro_std_radps, cfg.learn_gyro_std_max_radps);
    }

    #[test]
    fn rest_level_learns_the_idling_vibration_in_f64_and_f32() {
        learns_idling_and_refuses_driving::<f64>();
        learns_idling_and_refuses_driving::<f32>();
    }
}
