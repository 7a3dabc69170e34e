//! Outlier detection on a rate record with a Hampel filter: sample `i` is an outlier when it
//! differs from the median of the window `i - half ..= i + half` (clipped at the ends) by more
//! than `n_sigma` robust standard deviations, the robust sigma being 1.4826 times the window's
//! median absolute deviation. Heavy-tailed spikes (a sensor glitch, a bit error) inflate the
//! white-noise level of the Allan deviation; removing them by replacing each with its window
//! median keeps the record evenly sampled.

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

impl Default for HampelOptions {
    /// 25 samples either side (a MAD from 51 samples), 8 robust sigmas.
    fn default() -> Self {
        Self {
            half_window: 25,
            n_sigma: 8.0,
        }
    }
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
