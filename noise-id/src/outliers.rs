//! Outlier detection on a rate record with a Hampel filter: sample `i` is an outlier when it
//! differs from the median of the window `i - half ..= i + half` (clipped at the ends) by more
//! than `n_sigma` robust standard deviations, the robust sigma being 1.4826 times the window's
//! median absolute deviation. Heavy-tailed spikes (a sensor glitch, a bit error) inflate the
//! white-noise level of the Allan deviation; removing them by replacing each with its window
//! median keeps the record evenly sampled.
//!
//! The threshold is calibrated on Gaussian noise ([`gaussian_false_positive_rate`],
//! [`n_sigma_for_rate`]): the robust sigma of 51 samples scatters by about 16 %, so the
//! test statistic has heavier tails than a normal variable, and the default threshold is the
//! one that flags [`DEFAULT_FALSE_POSITIVE_RATE`] of the samples of spike-free Gaussian noise.

use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

/// Scale from the median absolute deviation to a Gaussian standard deviation.
pub const MAD_TO_SIGMA: f64 = 1.482_6;

/// Hampel filter settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HampelOptions {
    /// Half-width of the window, samples.
    pub half_window: usize,
    /// Threshold, robust standard deviations.
    pub n_sigma: f64,
}

/// Fraction of the samples of Gaussian noise that the default threshold flags: 1e-6 (one
/// false outlier in 1e6 samples, 2.8 h at 100 Hz).
pub const DEFAULT_FALSE_POSITIVE_RATE: f64 = 1e-6;

/// Default half-width of the window, samples (a MAD from 51 samples).
pub const DEFAULT_HALF_WINDOW: usize = 25;

impl Default for HampelOptions {
    /// 25 samples either side (a MAD from 51 samples), the threshold that flags
    /// [`DEFAULT_FALSE_POSITIVE_RATE`] of Gaussian noise (6.96 robust sigmas).
    fn default() -> Self {
        static N_SIGMA: std::sync::OnceLock<f64> = std::sync::OnceLock::new();
        Self {
            half_window: DEFAULT_HALF_WINDOW,
            n_sigma: *N_SIGMA
                .get_or_init(|| n_sigma_for_rate(DEFAULT_HALF_WINDOW, DEFAULT_FALSE_POSITIVE_RATE)),
        }
    }
}

impl HampelOptions {
    /// The window `2 half_window + 1` with the threshold that flags `rate` of the samples of
    /// Gaussian noise ([`n_sigma_for_rate`]).
    pub fn with_false_positive_rate(half_window: usize, rate: f64) -> Self {
        Self {
            half_window,
            n_sigma: n_sigma_for_rate(half_window, rate),
        }
    }

    /// The fraction of the samples of Gaussian noise these settings flag
    /// ([`gaussian_false_positive_rate`]).
    pub fn false_positive_rate(&self) -> f64 {
        gaussian_false_positive_rate(self.half_window, self.n_sigma)
    }
}

/// Simulated windows of the Gaussian calibration.
const CALIBRATION_WINDOWS: usize = 20_000;

/// Upper tail of the standard normal distribution, `P(Z > x)`.
fn normal_tail(x: f64) -> f64 {
    0.5 * libm::erfc(x / std::f64::consts::SQRT_2)
}

/// For each simulated window of `2 half_window` standard normal neighbours: (median, robust
/// sigma) of the window with the centre sample above all neighbours, and the same with it
/// below all of them (an outlier is beyond every neighbour, so only its side matters).
fn calibration_windows(half_window: usize) -> Vec<[(f64, f64); 2]> {
    let h = half_window.max(1);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x4861_6d70_656c);
    let mut x = vec![0.0f64; 2 * h];
    let mut dev = vec![0.0f64; 2 * h];
    (0..CALIBRATION_WINDOWS)
        .map(|_| {
            for v in x.iter_mut() {
                *v = StandardNormal.sample(&mut rng);
            }
            x.sort_by(f64::total_cmp);
            // 2h + 1 samples: with the centre highest the median is the neighbours' x[h],
            // with it lowest x[h - 1]; the centre's deviation is then the largest, so the
            // MAD is the (h + 1)-th smallest neighbour deviation
            let side = |med: f64, dev: &mut Vec<f64>| {
                for (d, v) in dev.iter_mut().zip(&x) {
                    *d = (v - med).abs();
                }
                let (_, m, _) = dev.select_nth_unstable_by(h, f64::total_cmp);
                (med, MAD_TO_SIGMA * *m)
            };
            [side(x[h], &mut dev), side(x[h - 1], &mut dev)]
        })
        .collect()
}

fn rate_of(windows: &[[(f64, f64); 2]], n_sigma: f64) -> f64 {
    let sum: f64 = windows
        .iter()
        .map(|[(mh, sh), (ml, sl)]| normal_tail(mh + n_sigma * sh) + normal_tail(n_sigma * sl - ml))
        .sum();
    sum / windows.len().max(1) as f64
}

/// Fraction of the samples of white Gaussian noise (away from the record's ends) that the
/// Hampel filter with window `2 half_window + 1` and threshold `n_sigma` flags: the
/// probability, averaged over 20,000 simulated windows of normal neighbours (fixed seed),
/// that the centre sample lies beyond the threshold given its neighbours (exact normal
/// tail for the centre, so rates down to 1e-12 are resolved).
pub fn gaussian_false_positive_rate(half_window: usize, n_sigma: f64) -> f64 {
    rate_of(&calibration_windows(half_window), n_sigma)
}

/// The threshold (robust sigmas) that flags the fraction `rate` of the samples of white
/// Gaussian noise with window `2 half_window + 1` ([`gaussian_false_positive_rate`] solved
/// by bisection; `rate` is clamped to 1e-15 - 0.5).
pub fn n_sigma_for_rate(half_window: usize, rate: f64) -> f64 {
    let w = calibration_windows(half_window);
    let target = rate.clamp(1e-15, 0.5).ln();
    let (mut lo, mut hi) = (0.5f64, 100.0f64);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if rate_of(&w, mid).ln() > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

/// The outliers of one record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Outliers {
    /// Settings used.
    pub options: HampelOptions,
    /// 0-based indices of the outliers, increasing.
    pub indices: Vec<usize>,
    /// The window median of each outlier (its replacement), rate units.
    pub medians: Vec<f64>,
    /// Size of each outlier in robust sigmas (signed).
    pub sizes_sigma: Vec<f64>,
    /// Samples in the record.
    pub samples: usize,
}

impl Outliers {
    /// Fraction of the samples that are outliers.
    pub fn fraction(&self) -> f64 {
        if self.samples == 0 {
            0.0
        } else {
            self.indices.len() as f64 / self.samples as f64
        }
    }

    /// The record with every outlier replaced by its window median.
    pub fn replaced(&self, y: &[f64]) -> Vec<f64> {
        let mut out = y.to_vec();
        for (&i, &m) in self.indices.iter().zip(&self.medians) {
            if let Some(v) = out.get_mut(i) {
                *v = m;
            }
        }
        out
    }
}

fn median(buf: &mut [f64]) -> f64 {
    let n = buf.len();
    if n == 0 {
        return f64::NAN;
    }
    let mid = n / 2;
    let (_, m, _) = buf.select_nth_unstable_by(mid, f64::total_cmp);
    let hi = *m;
    if n % 2 == 1 {
        hi
    } else {
        let lo = buf[..mid].iter().copied().fold(f64::NEG_INFINITY, f64::max);
        0.5 * (lo + hi)
    }
}

/// Finds the outliers of `y` (see the module notes). Non-finite samples are outliers too.
pub fn hampel(y: &[f64], opt: &HampelOptions) -> Outliers {
    let n = y.len();
    let h = opt.half_window.max(1);
    let mut buf = Vec::with_capacity(2 * h + 1);
    let mut out = Outliers {
        options: *opt,
        indices: Vec::new(),
        medians: Vec::new(),
        sizes_sigma: Vec::new(),
        samples: n,
    };
    for i in 0..n {
        let (a, b) = (i.saturating_sub(h), (i + h + 1).min(n));
        buf.clear();
        buf.extend(y[a..b].iter().copied().filter(|v| v.is_finite()));
        let med = median(&mut buf);
        for v in buf.iter_mut() {
            *v = (*v - med).abs();
        }
        let sigma = MAD_TO_SIGMA * median(&mut buf);
        let yi = y[i];
        // a window of identical (quantized) values has no spread to judge by: not flagged
        let size = if sigma > 0.0 { (yi - med) / sigma } else { 0.0 };
        if !yi.is_finite() || size.abs() > opt.n_sigma {
            out.indices.push(i);
            out.medians.push(med);
            out.sizes_sigma.push(size);
        }
    }
    out
}
