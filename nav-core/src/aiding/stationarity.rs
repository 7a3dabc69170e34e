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
}

impl StationarityConfig {
    /// Defaults for a car with a consumer MEMS IMU: 0.5 s window, 0.1 m/s^2 specific-force
    /// spread, 0.3 m/s^2 gravity tolerance, 1 deg/s mean rate, 0.5 deg/s rate spread, 0.15 m/s
    /// GNSS speed no older than 1 s.
    pub const DEFAULT: Self = Self {
        window_s: 0.5,
        accel_std_max_mps2: 0.1,
        accel_mag_tol_mps2: 0.3,
        gyro_mean_max_radps: 1.0 * core::f64::consts::PI / 180.0,
        gyro_std_max_radps: 0.5 * core::f64::consts::PI / 180.0,
        gnss_speed_max_mps: 0.15,
        gnss_max_age_s: 1.0,
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

/// Mean and root of summed per-axis (sample) variances of the last `n` entries before `head`.
fn mean_spread<T: Scalar, const W: usize>(
    buf: &[[T; 3]; W],
    head: usize,
    n: usize,
) -> ([f64; 3], f64) {
    let mut mean = [0.0f64; 3];
    let mut k = 0usize;
    for i in 0..n {
        let idx = (head + W - 1 - i) % W;
        if let Some(s) = buf.get(idx) {
            for (m, v) in mean.iter_mut().zip(s) {
                *m += v.to_f64();
            }
            k += 1;
        }
    }
    if k < 2 {
        return ([f64::NAN; 3], f64::NAN);
    }
    let kf = k as f64;
    for m in mean.iter_mut() {
        *m /= kf;
    }
    let mut ss = 0.0f64;
    for i in 0..n {
        let idx = (head + W - 1 - i) % W;
        if let Some(s) = buf.get(idx) {
            for (m, v) in mean.iter().zip(s) {
                let d = v.to_f64() - m;
                ss += d * d;
            }
        }
    }
    (mean, libm::sqrt(ss / (kf - 1.0)))
}

/// The detector's decision on window statistics: whether every test passes. `gravity_mps2` is
/// normal gravity at the vehicle; `gnss_speed_mps` a recent GNSS speed, if any.
pub fn is_stationary(
    cfg: &StationarityConfig,
    s: &WindowStats,
    gravity_mps2: f64,
    gnss_speed_mps: Option<f64>,
) -> bool {
    let norm = |v: &[f64; 3]| libm::sqrt(v.iter().map(|x| x * x).sum::<f64>());
    let imu_still = s.f_std_mps2 <= cfg.accel_std_max_mps2
        && (norm(&s.f_mean_mps2) - gravity_mps2).abs() <= cfg.accel_mag_tol_mps2
        && norm(&s.w_mean_radps) <= cfg.gyro_mean_max_radps
        && s.w_std_radps <= cfg.gyro_std_max_radps;
    let gnss_still = gnss_speed_mps.is_none_or(|v| v <= cfg.gnss_speed_max_mps);
    imu_still && gnss_still
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
        assert!(is_stationary(&cfg, &s, 9.80, None));
        assert!(is_stationary(&cfg, &s, 9.80, Some(0.05)));
        // the GNSS says it moves
        assert!(!is_stationary(&cfg, &s, 9.80, Some(1.0)));
        // turning at 3 deg/s
        for _ in 0..64 {
            d.push(&[0.0, 0.0, -9.80], &[0.0, 0.0, 0.05]);
        }
        let s = d.stats(50).expect("full window");
        assert!(!is_stationary(&cfg, &s, 9.80, None));
        // vibrating / accelerating
        for k in 0..64 {
            let a = if k % 2 == 0 { 0.5 } else { -0.5 };
            d.push(&[a, 0.0, -9.80], &[0.0; 3]);
        }
        let s = d.stats(50).expect("full window");
        assert!(s.f_std_mps2 > 0.4);
        assert!(!is_stationary(&cfg, &s, 9.80, None));
        // a NaN empties the window
        d.push(&[f64::NAN, 0.0, 0.0], &[0.0; 3]);
        assert!(d.is_empty());
    }
}
