#![doc = include_str!("../README.md")]
//!
//! ## Module notes
//!
//! `noise-id`: inertial sensor noise identification. Allan statistics (overlapping/non-overlapping Allan, modified Allan, Hadamard and
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
//! ([`stats::chi2_inv`]).
#![deny(missing_docs)]
pub mod edf;
pub mod fit;
pub mod outliers;
pub mod reader;
pub mod stats;

use serde::{Deserialize, Serialize};

/// Theoretical Allan variance of the continuous first-order Gauss-Markov process (corrected
/// formula of `docs/DESIGN.md`, coefficient 1 on `e^(-2 tau/T_B)`):
/// `(S_B T_B^2 / tau) [1 - (T_B / (2 tau)) (3 - 4 e^(-tau/T_B) + e^(-2 tau/T_B))]`.
pub fn gauss_markov_avar(s_b: f64, t_b_s: f64, tau_s: f64) -> f64 {
    let r = tau_s / t_b_s;
    // For small r the bracket cancels: use the series 1 - (3 - 4e^-r + e^-2r)/(2r) =
    // r^2/3 - r^3/4 + 7 r^4/60 - r^5/24 + 31 r^6/2520 - ... (S_B tau / 3 at small tau).
    let bracket = if r < 1e-2 {
        r * r * (1.0 / 3.0 + r * (-0.25 + r * (7.0 / 60.0 + r * (-1.0 / 24.0 + r * 31.0 / 2520.0))))
    } else {
        1.0 - (3.0 - 4.0 * (-r).exp() + (-2.0 * r).exp()) / (2.0 * r)
    };
    s_b * t_b_s * t_b_s / tau_s * bracket
}

/// Which deviation to compute.
#[derive(
    Clone,
    Copy,
    Debug,
    PartialEq,
    Eq,
    Serialize,
    Deserialize,
    strum::Display,
    strum::EnumString,
    strum::VariantNames,
)]
#[strum(serialize_all = "kebab-case")]
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
    /// Builds the phase buffer from rate samples: the mean (blockwise sums of 4096 samples in
    /// 8 lanes, the block sums added with Neumaier compensation, so the mean of 21.6 M values
    /// of 9.81 is exact to ~1e-17 relative) is removed and the differences are summed in order (four at a time).
    /// The rounding of the running sum is a white error of ~1e-16 |x_k| per point: its second
    /// differences are ~1e-12 of the noise at 2e7 points, and a residual constant in the mean
    /// only adds a straight line to `x`, which every statistic here cancels.
    pub fn from_rate(y: &[f64]) -> Self {
        let n = y.len();
        let mean = if n == 0 { 0.0 } else { mean_blocked(y) };
        let mut x = vec![0.0f64; n + 1];
        let mut s = 0.0f64;
        // Four at a time: the partial sums inside a group do not wait for `s`, so the serial
        // dependency is one addition per four points.
        let mut xo = x[1..].chunks_exact_mut(4);
        let mut yi = y.chunks_exact(4);
        for (o, v) in (&mut xo).zip(&mut yi) {
            let d0 = v[0] - mean;
            let p1 = d0 + (v[1] - mean);
            let p2 = p1 + (v[2] - mean);
            let p3 = p2 + (v[3] - mean);
            o[0] = s + d0;
            o[1] = s + p1;
            o[2] = s + p2;
            s += p3;
            o[3] = s;
        }
        for (o, &v) in xo.into_remainder().iter_mut().zip(yi.remainder()) {
            s += v - mean;
            *o = s;
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

    /// Overlapping Allan variances (rate units squared) and their numbers of terms at the
    /// averaging factors `ms`, computed in one cache-blocked sweep over the phase buffer
    /// (the same values as [`Phase::variance`] with [`Deviation::Oadev`], to rounding);
    /// `None` where a factor has no terms.
    pub fn oavar_many(&self, ms: &[usize]) -> Vec<Option<(f64, usize)>> {
        let np = self.x.len();
        let mut order: Vec<usize> = ms
            .iter()
            .copied()
            .filter(|&m| m > 0 && np > 2 * m)
            .collect();
        order.sort_unstable();
        order.dedup();
        let sums = oavar_sums(&self.x, &order);
        ms.iter()
            .map(|&m| {
                let k = order.binary_search(&m).ok()?;
                let n = np - 2 * m;
                let mf = m as f64;
                Some((sums[k] / (2.0 * mf * mf * n as f64), n))
            })
            .collect()
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

/// Mean of `y` (non-empty): 8-lane sums over blocks of 4096 values, block sums added with
/// Neumaier compensation.
fn mean_blocked(y: &[f64]) -> f64 {
    let (mut s, mut c) = (0.0f64, 0.0f64);
    for blk in y.chunks(4096) {
        let mut acc = [0.0f64; 8];
        let mut it = blk.chunks_exact(8);
        for v in &mut it {
            for k in 0..8 {
                acc[k] += v[k];
            }
        }
        let mut b: f64 = acc.iter().sum();
        b += it.remainder().iter().sum::<f64>();
        let t = s + b;
        if s.abs() >= b.abs() {
            c += (s - t) + b;
        } else {
            c += (b - t) + s;
        }
        s = t;
    }
    (s + c) / y.len() as f64
}

/// Number of phase points per chunk of the batched overlapping Allan sums (128 KiB per
/// region: the three regions of a tau and the next tau's fit in the 1 MiB L2 cache).
const OAVAR_CHUNK: usize = 16_384;

/// Sums `sum_i (x_{i+2m} - 2 x_{i+m} + x_i)^2` for every `m` in `ms` (each with at least one
/// term), in ONE sweep over `x`: for each chunk of start indices, every tau in ascending order.
/// The region `x[i + 2m]` of one octave tau is the region `x[i + m']` of the next (`m' = 2m`),
/// so it is read from cache, and the small taus reuse the chunk itself: main-memory traffic is
/// about (1 + number of taus with `m >` chunk) passes instead of one to three per tau. Uses
/// AVX2 when the CPU has it (the same additions in the same order: bit-identical results).
fn oavar_sums(x: &[f64], ms: &[usize]) -> Vec<f64> {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 (checked just above).
            return unsafe { oavar_sums_avx2(x, ms) };
        }
    }
    oavar_sums_generic(x, ms)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn oavar_sums_avx2(x: &[f64], ms: &[usize]) -> Vec<f64> {
    oavar_sums_generic(x, ms)
}

#[inline(always)]
fn oavar_sums_generic(x: &[f64], ms: &[usize]) -> Vec<f64> {
    let np = x.len();
    let mut out = vec![0.0f64; ms.len()];
    let mut s = 0usize;
    while s < np {
        let e = (s + OAVAR_CHUNK).min(np);
        for (o, &m) in out.iter_mut().zip(ms) {
            let n = np.saturating_sub(2 * m);
            if s >= n {
                continue;
            }
            let ee = e.min(n);
            *o += sum_sq_d2(&x[s..ee], &x[s + m..ee + m], &x[s + 2 * m..ee + 2 * m]);
        }
        s = e;
    }
    out
}

/// `sum (c - 2b + a)^2` over equal-length slices, 8 accumulators (vectorizes).
#[inline(always)]
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
    // Overlapping Allan: all taus in one sweep over the phase buffer.
    let batched = (opt.dev == Deviation::Oadev).then(|| phase.oavar_many(&ms));
    for (k, &m) in ms.iter().enumerate() {
        let v = match &batched {
            Some(b) => b[k],
            None => phase.variance(opt.dev, m),
        };
        let Some((var, n_terms)) = v else {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_markov_avar_peak_is_0437() {
        // IEEE 952: peak deviation 0.437 sqrt(S_B T_B) at tau = 1.89 T_B.
        let (mut best, mut at) = (0.0, 0.0);
        for i in 0..4000 {
            let tau = 0.5 + i as f64 * 0.001;
            let v = gauss_markov_avar(1.0, 1.0, tau).sqrt();
            if v > best {
                best = v;
                at = tau;
            }
        }
        assert!((best - 0.437).abs() < 5e-4, "{best}");
        assert!((at - 1.89).abs() < 0.01, "{at}");
        // The series branch agrees with the closed form at the switch point.
        let closed = gauss_markov_avar(1.0, 1.0, 1e-2 * (1.0 + 1e-12));
        let series = gauss_markov_avar(1.0, 1.0, 1e-2 * (1.0 - 1e-12));
        assert!((closed / series - 1.0).abs() < 1e-8, "{closed} {series}");
        // Small tau: S_B tau / 3 (the process looks like a random walk).
        let v = gauss_markov_avar(2.0, 45.0, 1e-3);
        assert!((v / (2.0 * 1e-3 / 3.0) - 1.0).abs() < 1e-4);
    }

    /// The cache-blocked sweep gives the per-tau sums (octave and non-octave factors, factors
    /// beyond the chunk length, one term at the largest) to rounding.
    #[test]
    fn batched_oavar_equals_per_tau_oavar() {
        let mut s = 0x1234_5678u64;
        let y: Vec<f64> = (0..100_003)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                9.81 + (s >> 11) as f64 / (1u64 << 53) as f64
            })
            .collect();
        let p = Phase::from_rate(&y);
        let ms = [
            1usize, 3, 2, 7, 1000, 16_384, 20_000, 40_000, 50_001, 50_002, 0,
        ];
        let b = p.oavar_many(&ms);
        for (&m, got) in ms.iter().zip(&b) {
            let want = p.variance(Deviation::Oadev, m);
            match (got, want) {
                (Some((g, gn)), Some((w, wn))) => {
                    assert_eq!(gn, &wn, "m {m}");
                    assert!((g / w - 1.0).abs() < 1e-12, "m {m}: {g} vs {w}");
                }
                (None, None) => {}
                _ => panic!("m {m}: {got:?} vs {want:?}"),
            }
        }
        assert!(b[8].is_some() && b[9].is_none());
    }
}
