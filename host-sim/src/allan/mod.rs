//! Allan statistics (overlapping/non-overlapping Allan, modified Allan, Hadamard and
//! overlapping Hadamard deviations) with confidence intervals, and the noise-model fit of the
//! source document.
//!
//! Input is a **rate** series `y_i` (frequency data in time-and-frequency language: m/s^2 for
//! an accelerometer, rad/s for a gyro) with sample time `tau0_s`. The mean is removed and the
//! series is integrated once into a "phase" buffer `x_k = sum_{i<k} (y_i - mean)` (N + 1
//! values, the only extra buffer of size N), and every statistic is a sum of squared
//! differences of `x`, so each tau costs O(N) and a large constant offset (9.81 m/s^2) costs no
//! precision. Formulas: NIST SP1065 (W. Riley, Handbook of Frequency Stability Analysis, 2008),
//! eqs. (8) ADEV, (11) OADEV, (14) MDEV, (17)/(18) HDEV/OHDEV, with `N'` = N + 1 phase points:
//!
//! - OAVAR(m) = sum_{i=0}^{N'-2m-1} (x_{i+2m} - 2x_{i+m} + x_i)^2 / (2 m^2 (N'-2m))
//! - AVAR(m): the same sum with stride m (non-overlapping averages)
//! - MVAR(m) = sum_{j=0}^{N'-3m} (sum_{i=j}^{j+m-1} (x_{i+2m} - 2x_{i+m} + x_i))^2 / (2 m^4 (N'-3m+1))
//! - OHVAR(m) = sum_{i=0}^{N'-3m-1} (x_{i+3m} - 3x_{i+2m} + 3x_{i+m} - x_i)^2 / (6 m^2 (N'-3m)),
//!   HVAR(m) the same with stride m.
//!
//! Confidence intervals: equivalent degrees of freedom by Greenhall's algorithm
//! ([`edf::edf_greenhall`]) for the noise type identified at each tau by the lag-1
//! autocorrelation method ([`edf::noise_id_lag1`]), and chi-square bounds
//! ([`edf::chi2_inv`]).
pub mod cli;
pub mod edf;
pub mod fit;
pub mod plot;
pub mod reader;

use serde::{Deserialize, Serialize};

/// Which deviation to compute.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum)]
pub enum Deviation {
    /// Non-overlapping Allan deviation.
    Adev,
    /// Overlapping Allan deviation (the default).
    Oadev,
    /// Modified Allan deviation.
    Mdev,
    /// Non-overlapping Hadamard deviation.
    Hdev,
    /// Overlapping Hadamard deviation.
    Ohdev,
}

impl Deviation {
    /// Order of the difference (2 for Allan types, 3 for Hadamard types).
    pub fn d(self) -> usize {
        match self {
            Deviation::Adev | Deviation::Oadev | Deviation::Mdev => 2,
            Deviation::Hdev | Deviation::Ohdev => 3,
        }
    }
    /// Largest averaging factor with at least one term for `n_rate` rate samples.
    pub fn max_m(self, n_rate: usize) -> usize {
        match self {
            Deviation::Adev | Deviation::Oadev => n_rate / 2,
            Deviation::Mdev | Deviation::Hdev | Deviation::Ohdev => n_rate / 3,
        }
    }
    /// Short lower-case name.
    pub fn name(self) -> &'static str {
        match self {
            Deviation::Adev => "adev",
            Deviation::Oadev => "oadev",
            Deviation::Mdev => "mdev",
            Deviation::Hdev => "hdev",
            Deviation::Ohdev => "ohdev",
        }
    }
}

/// Which averaging factors `m` (tau = m tau0) to evaluate.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Taus {
    /// m = 1, 2, 4, 8, ... (powers of two).
    Octave,
    /// m = 1, 2, 4, 10, 20, 40, 100, ... (Stable32's decade set).
    Decade,
    /// Every m = 1, 2, 3, ...
    All,
    /// The given averaging factors.
    List(Vec<usize>),
}

impl Taus {
    /// The averaging factors for `n_rate` samples and deviation `dev` (each with >= 1 term).
    pub fn factors(&self, n_rate: usize, dev: Deviation) -> Vec<usize> {
        let max_m = dev.max_m(n_rate);
        let mut v: Vec<usize> = match self {
            Taus::Octave => (0..64)
                .map(|k| 1usize.checked_shl(k).unwrap_or(usize::MAX))
                .take_while(|&m| m <= max_m)
                .collect(),
            Taus::Decade => {
                let mut v = Vec::new();
                let mut dec = 1usize;
                'outer: loop {
                    for f in [1usize, 2, 4] {
                        let m = dec.saturating_mul(f);
                        if m > max_m {
                            break 'outer;
                        }
                        v.push(m);
                    }
                    dec = dec.saturating_mul(10);
                }
                v
            }
            Taus::All => (1..=max_m).collect(),
            Taus::List(l) => l
                .iter()
                .copied()
                .filter(|&m| m >= 1 && m <= max_m)
                .collect(),
        };
        v.sort_unstable();
        v.dedup();
        v
    }
}

/// The integrated, mean-removed series ("phase"): `x_0 = 0`, `x_k = sum_{i<k} (y_i - mean)`,
/// in units of rate x samples (tau0 is applied by the caller through `tau = m tau0`).
#[derive(Clone, Debug)]
pub struct Phase {
    x: Vec<f64>,
    mean: f64,
}

impl Phase {
    /// Builds the phase buffer from rate samples (mean removed, compensated summation).
    pub fn from_rate(y: &[f64]) -> Self {
        let n = y.len();
        let mean = if n == 0 {
            0.0
        } else {
            // Pairwise-ish: sum in f64 with Neumaier compensation.
            let (mut s, mut c) = (0.0f64, 0.0f64);
            for &v in y {
                let t = s + v;
                if s.abs() >= v.abs() {
                    c += (s - t) + v;
                } else {
                    c += (v - t) + s;
                }
                s = t;
            }
            (s + c) / n as f64
        };
        let mut x = Vec::with_capacity(n + 1);
        x.push(0.0);
        let (mut s, mut c) = (0.0f64, 0.0f64);
        for &v in y {
            let d = v - mean;
            let yk = d - c;
            let t = s + yk;
            c = (t - s) - yk;
            s = t;
            x.push(s);
        }
        Self { x, mean }
    }

    /// Number of rate samples (N; the buffer holds N + 1 phase points).
    pub fn n_rate(&self) -> usize {
        self.x.len().saturating_sub(1)
    }
    /// Mean of the rate samples that was removed.
    pub fn mean(&self) -> f64 {
        self.mean
    }
    /// The phase points.
    pub fn as_slice(&self) -> &[f64] {
        &self.x
    }

    /// Variance of type `dev` at averaging factor `m` (rate units squared) and its number of
    /// terms, or `None` if there are no terms.
    pub fn variance(&self, dev: Deviation, m: usize) -> Option<(f64, usize)> {
        if m == 0 {
            return None;
        }
        let x = &self.x;
        let np = x.len();
        let mf = m as f64;
        match dev {
            Deviation::Oadev => {
                let n = np.checked_sub(2 * m).filter(|&n| n > 0)?;
                let s = sum_sq_d2(&x[..n], &x[m..m + n], &x[2 * m..2 * m + n]);
                Some((s / (2.0 * mf * mf * n as f64), n))
            }
            Deviation::Adev => {
                let mut s = 0.0;
                let mut n = 0usize;
                let mut i = 0usize;
                while i + 2 * m < np {
                    let d = x[i + 2 * m] - 2.0 * x[i + m] + x[i];
                    s += d * d;
                    n += 1;
                    i += m;
                }
                (n > 0).then(|| (s / (2.0 * mf * mf * n as f64), n))
            }
            Deviation::Ohdev => {
                let n = np.checked_sub(3 * m).filter(|&n| n > 0)?;
                let s = sum_sq_d3(
                    &x[..n],
                    &x[m..m + n],
                    &x[2 * m..2 * m + n],
                    &x[3 * m..3 * m + n],
                );
                Some((s / (6.0 * mf * mf * n as f64), n))
            }
            Deviation::Hdev => {
                let mut s = 0.0;
                let mut n = 0usize;
                let mut i = 0usize;
                while i + 3 * m < np {
                    let d = x[i + 3 * m] - 3.0 * x[i + 2 * m] + 3.0 * x[i + m] - x[i];
                    s += d * d;
                    n += 1;
                    i += m;
                }
                (n > 0).then(|| (s / (6.0 * mf * mf * n as f64), n))
            }
            Deviation::Mdev => {
                let n = (np + 1).checked_sub(3 * m).filter(|&n| n > 0)?;
                let d2 = |i: usize| x[i + 2 * m] - 2.0 * x[i + m] + x[i];
                let fresh = |j: usize| (j..j + m).map(d2).sum::<f64>();
                // Running window sum of second differences, refreshed periodically so rounding
                // errors cannot accumulate.
                let refresh = (4 * m).max(1 << 16);
                let mut inner = fresh(0);
                let mut s = inner * inner;
                for j in 1..n {
                    if j % refresh == 0 {
                        inner = fresh(j);
                    } else {
                        inner += d2(j + m - 1) - d2(j - 1);
                    }
                    s += inner * inner;
                }
                Some((s / (2.0 * mf * mf * mf * mf * n as f64), n))
            }
        }
    }
}

/// `sum (c - 2b + a)^2` over equal-length slices, 8 accumulators (vectorizes).
fn sum_sq_d2(a: &[f64], b: &[f64], c: &[f64]) -> f64 {
    let n = a.len().min(b.len()).min(c.len());
    let (a, b, c) = (&a[..n], &b[..n], &c[..n]);
    let mut acc = [0.0f64; 8];
    let mut ca = a.chunks_exact(8);
    let mut cb = b.chunks_exact(8);
    let mut cc = c.chunks_exact(8);
    for ((xa, xb), xc) in (&mut ca).zip(&mut cb).zip(&mut cc) {
        for k in 0..8 {
            let d = xc[k] - 2.0 * xb[k] + xa[k];
            acc[k] += d * d;
        }
    }
    let mut s: f64 = acc.iter().sum();
    for ((xa, xb), xc) in ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .zip(cc.remainder())
    {
        let d = xc - 2.0 * xb + xa;
        s += d * d;
    }
    s
}

/// `sum (d - 3c + 3b - a)^2` over equal-length slices.
fn sum_sq_d3(a: &[f64], b: &[f64], c: &[f64], d: &[f64]) -> f64 {
    let n = a.len().min(b.len()).min(c.len()).min(d.len());
    let mut acc = [0.0f64; 4];
    let mut i = 0;
    while i + 4 <= n {
        for k in 0..4 {
            let v = d[i + k] - 3.0 * c[i + k] + 3.0 * b[i + k] - a[i + k];
            acc[k] += v * v;
        }
        i += 4;
    }
    let mut s: f64 = acc.iter().sum();
    while i < n {
        let v = d[i] - 3.0 * c[i] + 3.0 * b[i] - a[i];
        s += v * v;
        i += 1;
    }
    s
}

/// One point of a deviation curve.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct DevPoint {
    /// Averaging factor m.
    pub m: usize,
    /// Averaging time tau = m tau0 (s).
    pub tau_s: f64,
    /// The deviation (rate units).
    pub dev: f64,
    /// Number of terms in the sum.
    pub n_terms: usize,
    /// Identified power-law noise exponent alpha (S_y ~ f^alpha) used for the EDF.
    pub alpha: i32,
    /// Equivalent degrees of freedom.
    pub edf: f64,
    /// Lower bound of the confidence interval (rate units).
    pub lo: f64,
    /// Upper bound of the confidence interval (rate units).
    pub hi: f64,
}

/// Options for [`deviation_curve`].
#[derive(Clone, Debug)]
pub struct CurveOptions {
    /// Deviation type.
    pub dev: Deviation,
    /// Averaging factors.
    pub taus: Taus,
    /// Confidence level of the interval (0.6827 for 1 sigma); `None` skips noise
    /// identification and EDF (lo = hi = dev, edf = NaN).
    pub confidence: Option<f64>,
    /// Fixed noise exponent alpha for the EDF instead of identifying it.
    pub fixed_alpha: Option<i32>,
}

impl Default for CurveOptions {
    fn default() -> Self {
        Self {
            dev: Deviation::Oadev,
            taus: Taus::Octave,
            confidence: Some(edf::ONE_SIGMA),
            fixed_alpha: None,
        }
    }
}

/// Computes a deviation curve of the rate series `y` with sample time `tau0_s`.
pub fn deviation_curve(y: &[f64], tau0_s: f64, opt: &CurveOptions) -> Vec<DevPoint> {
    let phase = Phase::from_rate(y);
    deviation_curve_phase(&phase, tau0_s, opt, |_, _| {})
}

/// [`deviation_curve`] on a prepared [`Phase`]; `progress(done, total)` is called after each
/// tau.
pub fn deviation_curve_phase(
    phase: &Phase,
    tau0_s: f64,
    opt: &CurveOptions,
    mut progress: impl FnMut(usize, usize),
) -> Vec<DevPoint> {
    let n = phase.n_rate();
    let ms = opt.taus.factors(n, opt.dev);
    let total = ms.len();
    let mut out = Vec::with_capacity(total);
    let mut last_alpha = 0i32;
    for (k, &m) in ms.iter().enumerate() {
        let Some((var, n_terms)) = phase.variance(opt.dev, m) else {
            continue;
        };
        let dev = var.max(0.0).sqrt();
        let (alpha, edf, lo, hi) = match opt.confidence {
            None => (0, f64::NAN, dev, dev),
            Some(p) => {
                let alpha = opt.fixed_alpha.unwrap_or_else(|| {
                    let a = edf::noise_id_lag1(phase, m, opt.dev.d()).unwrap_or(last_alpha);
                    last_alpha = a;
                    a
                });
                let e = edf::edf_for(opt.dev, alpha, m, n + 1);
                let (lo, hi) = edf::interval(dev, e, p);
                (alpha, e, lo, hi)
            }
        };
        out.push(DevPoint {
            m,
            tau_s: m as f64 * tau0_s,
            dev,
            n_terms,
            alpha,
            edf,
            lo,
            hi,
        });
        progress(k + 1, total);
    }
    out
}
