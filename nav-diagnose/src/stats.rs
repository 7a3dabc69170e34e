//! Residual statistics of a run: NIS against its chi-square band, whiteness (autocorrelation,
//! Ljung-Box) per innovation component, the innovation log-likelihood, and the correlation of
//! the normalised innovations with each candidate effect's regressor.
use nav_core::model::Block;
use nav_core::types::{ImuSample, NavSolution};
use serde::Serialize;

use nav_engine::run::{FixUse, InnovationRecord, RunOutput};

/// Number of autocorrelation lags of the whiteness test.
pub const LAGS: usize = 10;
/// 95 % point of chi-square with [`LAGS`] degrees of freedom.
pub const LJUNG_BOX_Q95: f64 = 18.307;

/// Whiteness statistics of one innovation component.
#[derive(Debug, Clone, Serialize)]
pub struct Whiteness {
    /// Component index (0-2 position N/E/D, 3-5 velocity N/E/D).
    pub component: usize,
    /// Number of normalised innovations.
    pub n: usize,
    /// Mean of the normalised innovations (0 when unbiased).
    pub mean: f64,
    /// Autocorrelation of the normalised innovations at lags 1..=LAGS (fix epochs).
    pub autocorr: Vec<f64>,
    /// Ljung-Box Q over lags 1..=LAGS (chi-square with LAGS degrees of freedom when white).
    pub ljung_box_q: f64,
    /// 95 % point of chi-square(LAGS).
    pub ljung_box_q95: f64,
    /// Allan variance of the normalised innovations over clusters of m consecutive fixes,
    /// times m, for m = 1, 2, 4, ... (at least 8 clusters): `[m, m AVAR(m)]`. White
    /// innovations give about 1 at every m; a value growing with m is a slowly varying
    /// (unmodelled, time-correlated) error.
    pub allan_ratio: Vec<[f64; 2]>,
}

/// Residual statistics of one run.
#[derive(Debug, Clone, Serialize)]
pub struct ResidualStats {
    /// Fixes in the statistics (used, forced or gate-rejected: every fix with an innovation
    /// covariance; withheld fixes are not innovations of the filter).
    pub updates: usize,
    /// Mean NIS.
    pub nis_mean: f64,
    /// Mean measurement dimension (the NIS mean's expectation).
    pub nis_expected: f64,
    /// Two-sided 95 % band of the NIS mean (normal approximation of chi-square / n).
    pub nis_band: [f64; 2],
    /// Whether the NIS mean is inside its band.
    pub nis_in_band: bool,
    /// Per-component whiteness.
    pub whiteness: Vec<Whiteness>,
    /// Innovation log-likelihood, nats: `-1/2 sum (NIS + sum ln(2 pi S_ii))` (the diagonal's
    /// log-determinant bounds the full one from above).
    pub log_likelihood: f64,
    /// Number of scalar measurements in the log-likelihood.
    pub scalar_measurements: usize,
}

/// Whether a record enters the statistics.
pub fn in_stats(r: &InnovationRecord) -> bool {
    matches!(r.used, FixUse::Accepted | FixUse::Forced | FixUse::Rejected)
        && r.nis.is_finite()
        && r.dim > 0
        && r.innovation_var
            .iter()
            .take(r.dim)
            .all(|s| s.is_finite() && *s > 0.0)
}

/// Residual statistics of a run's innovations.
pub fn residual_stats(innov: &[InnovationRecord]) -> ResidualStats {
    let recs: Vec<&InnovationRecord> = innov.iter().filter(|r| in_stats(r)).collect();
    let n = recs.len();
    let nis_mean = recs.iter().map(|r| r.nis).sum::<f64>() / n.max(1) as f64;
    let dim_mean = recs.iter().map(|r| r.dim as f64).sum::<f64>() / n.max(1) as f64;
    let half = 1.96 * (2.0 * dim_mean / n.max(1) as f64).sqrt();
    let mut ll = 0.0;
    let mut m = 0;
    for r in &recs {
        ll -= 0.5 * r.nis;
        for &s in r.innovation_var.iter().take(r.dim) {
            ll -= 0.5 * (2.0 * std::f64::consts::PI * s).ln();
            m += 1;
        }
    }
    let max_dim = recs.iter().map(|r| r.dim.min(6)).max().unwrap_or(0);
    let whiteness = (0..max_dim)
        .map(|c| {
            let z: Vec<f64> = recs
                .iter()
                .filter(|r| r.dim > c)
                .map(|r| r.innovation[c] / r.innovation_var[c].sqrt())
                .collect();
            whiteness(c, &z)
        })
        .collect();
    let band = [dim_mean - half, dim_mean + half];
    ResidualStats {
        updates: n,
        nis_mean,
        nis_expected: dim_mean,
        nis_band: band,
        nis_in_band: nis_mean >= band[0] && nis_mean <= band[1],
        whiteness,
        log_likelihood: ll,
        scalar_measurements: m,
    }
}

fn whiteness(component: usize, z: &[f64]) -> Whiteness {
    let n = z.len();
    let mean = z.iter().sum::<f64>() / n.max(1) as f64;
    let c0: f64 = z.iter().map(|v| (v - mean).powi(2)).sum();
    let mut autocorr = Vec::with_capacity(LAGS);
    let mut q = 0.0;
    for k in 1..=LAGS {
        let ck: f64 = z
            .iter()
            .zip(z.iter().skip(k))
            .map(|(a, b)| (a - mean) * (b - mean))
            .sum();
        let r = if c0 > 0.0 { ck / c0 } else { 0.0 };
        autocorr.push(r);
        if n > k {
            q += r * r / (n - k) as f64;
        }
    }
    Whiteness {
        component,
        n,
        mean,
        autocorr,
        ljung_box_q: n as f64 * (n as f64 + 2.0) * q,
        ljung_box_q95: LJUNG_BOX_Q95,
        allan_ratio: allan_ratio(z),
    }
}

/// `[m, m AVAR(m)]` of a sequence for m = 1, 2, 4, ... with at least 8 clusters
/// (non-overlapping cluster means).
pub fn allan_ratio(z: &[f64]) -> Vec<[f64; 2]> {
    let mut out = Vec::new();
    let mut m = 1;
    while z.len() / m >= 8 {
        let means: Vec<f64> = z
            .chunks_exact(m)
            .map(|c| c.iter().sum::<f64>() / m as f64)
            .collect();
        let k = means.len() - 1;
        let avar = means
            .windows(2)
            .map(|w| 0.5 * (w[1] - w[0]).powi(2))
            .sum::<f64>()
            / k as f64;
        out.push([m as f64, m as f64 * avar]);
        m *= 2;
    }
    out
}

/// Pearson correlation.
fn corr(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len().min(y.len());
    if n < 3 {
        return 0.0;
    }
    let mx = x.iter().take(n).sum::<f64>() / n as f64;
    let my = y.iter().take(n).sum::<f64>() / n as f64;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y.iter()).take(n) {
        sxy += (a - mx) * (b - my);
        sxx += (a - mx).powi(2);
        syy += (b - my).powi(2);
    }
    if sxx > 0.0 && syy > 0.0 {
        sxy / (sxx * syy).sqrt()
    } else {
        0.0
    }
}

/// C_b^n of ZYX Euler angles (roll, pitch, yaw), rad.
pub fn c_bn(rpy: [f64; 3]) -> [[f64; 3]; 3] {
    let (sr, cr) = rpy[0].sin_cos();
    let (sp, cp) = rpy[1].sin_cos();
    let (sy, cy) = rpy[2].sin_cos();
    [
        [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
        [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
        [-sp, sr * cp, cr * cp],
    ]
}

/// Index of the element of `v` (sorted by `key`) whose key is nearest `t` (the later one on a
/// tie); None when `v` is empty.
pub(crate) fn nearest<T>(v: &[T], t: f64, key: impl Fn(&T) -> f64) -> Option<usize> {
    if v.is_empty() {
        return None;
    }
    let i = v.partition_point(|x| key(x) < t);
    let i = i.min(v.len() - 1);
    if i > 0 && (t - key(&v[i - 1])).abs() < (key(&v[i]) - t).abs() {
        Some(i - 1)
    } else {
        Some(i)
    }
}

/// NED regressor vectors (one per state of the block) of a candidate at one fix: the
/// direction in which one unit of the state moves the navigation error now (the innovation
/// integrates it: a correlation with the instantaneous regressor is a screening statistic, the
/// re-run decides).
fn regressors(
    b: Block,
    imu: &[ImuSample],
    i: usize,
    nav: &NavSolution,
    t_ref: f64,
) -> Vec<[f64; 3]> {
    let c = c_bn(nav.rpy_rad);
    let dt = if i > 0 {
        imu[i].t_s - imu[i - 1].t_s
    } else {
        imu.get(1).map_or(0.0, |s| s.t_s - imu[0].t_s)
    };
    let rate = |v: [f64; 3]| {
        if dt > 0.0 {
            [v[0] / dt, v[1] / dt, v[2] / dt]
        } else {
            [0.0; 3]
        }
    };
    let col = |j: usize, s: f64| [c[0][j] * s, c[1][j] * s, c[2][j] * s];
    // off-diagonal pairs (i, j) in the order [xy, xz, yx, yz, zx, zy]
    const PAIRS: [(usize, usize); 6] = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)];
    let f = rate(imu[i].dv_mps);
    let w = rate(imu[i].dtheta_rad);
    let d_t = imu[i].temperature_c - t_ref;
    let d_t = if d_t.is_finite() { d_t } else { 0.0 };
    match b {
        Block::AccelScaleFactor => (0..3).map(|j| col(j, f[j])).collect(),
        Block::GyroScaleFactor => (0..3).map(|j| col(j, w[j])).collect(),
        Block::AccelMisalignment => PAIRS.iter().map(|&(r, k)| col(r, f[k])).collect(),
        Block::GyroMisalignment => PAIRS.iter().map(|&(r, k)| col(r, w[k])).collect(),
        Block::AccelTemperatureBias | Block::GyroTemperatureBias => {
            (0..3).map(|j| col(j, d_t)).collect()
        }
        Block::GyroGSensitivity => (0..3).map(|j| col(j, f[j])).collect(),
        Block::LeverArm => (0..3).map(|j| col(j, 1.0)).collect(),
        Block::TimeOffset => vec![nav.vel_ned_mps],
        _ => Vec::new(),
    }
}

/// Largest |correlation| of the normalised position innovations with one of the candidate's
/// regressors (pooled over N/E/D), and the number of pairs.
pub fn regressor_correlation(b: Block, imu: &[ImuSample], run: &RunOutput) -> (f64, usize) {
    let mut best = (0.0f64, 0);
    let recs: Vec<&InnovationRecord> = run.innovations.iter().filter(|r| in_stats(r)).collect();
    let t_ref = imu
        .iter()
        .map(|s| s.temperature_c)
        .find(|t| t.is_finite())
        .unwrap_or(f64::NAN);
    for j in 0..b.dim() {
        let mut x = Vec::new();
        let mut y = Vec::new();
        for r in &recs {
            let (Some(ii), Some(ni)) = (
                nearest(imu, r.t_s, |s| s.t_s),
                nearest(&run.nav, r.t_s, |s| s.t_s),
            ) else {
                continue;
            };
            let reg = regressors(b, imu, ii, &run.nav[ni], t_ref);
            let Some(rv) = reg.get(j) else { continue };
            let comps = r.innovation.iter().zip(&r.innovation_var).zip(rv);
            for ((v, &s), reg) in comps.take(r.dim.min(3)) {
                x.push(v / s.sqrt());
                y.push(*reg);
            }
        }
        let c = corr(&x, &y).abs();
        if c > best.0 {
            best = (c, x.len());
        }
    }
    best
}

/// Length of the bins of [`misfit_spans`], s.
pub const MISFIT_BIN_S: f64 = 60.0;

/// A stretch of the drive where the innovations do not fit the model.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MisfitSpan {
    /// Start, GPS seconds of week.
    pub start_s: f64,
    /// End, GPS seconds of week.
    pub end_s: f64,
    /// Mean NIS of its fixes.
    pub nis_mean: f64,
    /// Its expectation (mean measurement dimension).
    pub nis_expected: f64,
    /// Fixes in it.
    pub fixes: usize,
}

/// Misfit no effect of the vocabulary explains.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Unexplained {
    /// What is unexplained and where, in words.
    pub summary: String,
    /// Where the NIS is high, strongest first.
    pub spans: Vec<MisfitSpan>,
}

/// The stretches where the NIS is significantly high: bins of `bin_s` whose NIS sum exceeds
/// its chi-square expectation by more than 4 standard deviations (`sum dim + 4 sqrt(2 sum
/// dim)`), adjacent bins merged; strongest (highest mean NIS) first.
pub fn misfit_spans(innov: &[InnovationRecord], bin_s: f64) -> Vec<MisfitSpan> {
    let recs: Vec<&InnovationRecord> = innov.iter().filter(|r| in_stats(r)).collect();
    let Some(t0) = recs.first().map(|r| r.t_s) else {
        return Vec::new();
    };
    let mut bins: Vec<(f64, f64, usize)> = Vec::new(); // (sum NIS, sum dim, fixes)
    for r in &recs {
        let i = ((r.t_s - t0) / bin_s).floor().max(0.0) as usize;
        if bins.len() <= i {
            bins.resize(i + 1, (0.0, 0.0, 0));
        }
        bins[i].0 += r.nis;
        bins[i].1 += r.dim as f64;
        bins[i].2 += 1;
    }
    let high = |b: &(f64, f64, usize)| b.2 > 0 && b.0 > b.1 + 4.0 * (2.0 * b.1).sqrt();
    let mut spans: Vec<MisfitSpan> = Vec::new();
    let mut open: Option<(usize, f64, f64, usize)> = None;
    for (i, b) in bins
        .iter()
        .chain(std::iter::once(&(0.0, 0.0, 0)))
        .enumerate()
    {
        if high(b) {
            let o = open.get_or_insert((i, 0.0, 0.0, 0));
            o.1 += b.0;
            o.2 += b.1;
            o.3 += b.2;
        } else if let Some((s, nis, dim, n)) = open.take() {
            spans.push(MisfitSpan {
                start_s: t0 + s as f64 * bin_s,
                end_s: t0 + i as f64 * bin_s,
                nis_mean: nis / n as f64,
                nis_expected: dim / n as f64,
                fixes: n,
            });
        }
    }
    spans.sort_by(|a, b| b.nis_mean.total_cmp(&a.nis_mean));
    spans
}

/// One-sided significance level of the paired held-out tests (each direction).
pub const HELDOUT_ALPHA: f64 = 0.05;

/// Wilcoxon signed-rank test and Hodges-Lehmann estimate of paired differences `d` (zeros
/// and non-finite values dropped): `(n, W+, P(W+ >= observed), P(W+ <= observed), estimate,
/// [lower, upper])` with the interval at confidence `1 - 2 alpha` (its ends pair with the
/// two one-sided tests at `alpha`; infinite when `n` is too small for any bound). Exact null
/// distribution without ties and up to 60 pairs, else the normal approximation with the tie
/// correction.
pub fn signed_rank(d: &[f64], alpha: f64) -> SignedRank {
    let mut v: Vec<f64> = d
        .iter()
        .copied()
        .filter(|x| x.is_finite() && *x != 0.0)
        .collect();
    let n = v.len();
    v.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
    // mid-ranks of |d|
    let mut ranks = vec![0.0; n];
    let mut ties = false;
    let mut tie_term = 0.0;
    let mut i = 0;
    while i < n {
        let mut j = i;
        while j + 1 < n && v[j + 1].abs() == v[i].abs() {
            j += 1;
        }
        let r = 0.5 * ((i + 1) + (j + 1)) as f64;
        for x in ranks.iter_mut().take(j + 1).skip(i) {
            *x = r;
        }
        if j > i {
            ties = true;
            let t = (j - i + 1) as f64;
            tie_term += t * t * t - t;
        }
        i = j + 1;
    }
    let w_plus: f64 = v
        .iter()
        .zip(&ranks)
        .filter(|(x, _)| **x > 0.0)
        .map(|(_, r)| r)
        .sum();
    let total = (n * (n + 1) / 2) as f64;
    // null distribution of W+ (exact: counts of subsets of 1..n by their sum)
    let exact = (!ties && n <= 60).then(|| {
        let max = n * (n + 1) / 2;
        let mut c = vec![0.0f64; max + 1];
        c[0] = 1.0;
        for k in 1..=n {
            for s in (k..=max).rev() {
                c[s] += c[s - k];
            }
        }
        let all = 2f64.powi(n as i32);
        c.iter().map(|x| x / all).collect::<Vec<f64>>()
    });
    let cdf_le = |w: f64| -> f64 {
        match &exact {
            Some(p) => p
                .iter()
                .enumerate()
                .filter(|(s, _)| (*s as f64) <= w + 1e-9)
                .map(|(_, x)| x)
                .sum(),
            None => {
                let mean = total / 2.0;
                let var = (n * (n + 1) * (2 * n + 1)) as f64 / 24.0 - tie_term / 48.0;
                if var <= 0.0 {
                    return 1.0;
                }
                normal_cdf((w + 0.5 - mean) / var.sqrt())
            }
        }
    };
    let p_worse = if n == 0 { 1.0 } else { cdf_le(w_plus) };
    // P(W+ >= w) = P(W- <= total - w) (symmetric null)
    let p_better = if n == 0 { 1.0 } else { cdf_le(total - w_plus) };
    // Hodges-Lehmann: median of the Walsh averages; interval from the null quantile
    let mut walsh = Vec::with_capacity(n * (n + 1) / 2);
    for a in 0..n {
        for b in a..n {
            walsh.push(0.5 * (v[a] + v[b]));
        }
    }
    walsh.sort_by(f64::total_cmp);
    let estimate = median_sorted(&walsh);
    // k: the largest count with P(W+ <= k - 1) <= alpha; the interval is the k-th smallest and
    // k-th largest Walsh average
    let mut k = 0usize;
    while k < walsh.len() && cdf_le(k as f64) <= alpha {
        k += 1;
    }
    let ci = if k == 0 || walsh.is_empty() {
        [f64::NEG_INFINITY, f64::INFINITY]
    } else {
        let m = walsh.len();
        [walsh[k - 1], walsh[m - k]]
    };
    SignedRank {
        n,
        w_plus,
        p_greater: p_better,
        p_less: p_worse,
        estimate,
        ci,
    }
}

/// Result of [`signed_rank`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SignedRank {
    /// Pairs compared (non-zero, finite differences).
    pub n: usize,
    /// Sum of the ranks of the positive differences.
    pub w_plus: f64,
    /// One-sided p-value for differences centred above zero.
    pub p_greater: f64,
    /// One-sided p-value for differences centred below zero.
    pub p_less: f64,
    /// Hodges-Lehmann estimate of the centre of the differences (NaN without pairs).
    pub estimate: f64,
    /// Its interval at confidence `1 - 2 alpha`.
    pub ci: [f64; 2],
}

fn median_sorted(v: &[f64]) -> f64 {
    match v.len() {
        0 => f64::NAN,
        m if m % 2 == 1 => v[m / 2],
        m => 0.5 * (v[m / 2 - 1] + v[m / 2]),
    }
}

/// Standard normal CDF (Abramowitz-Stegun 7.1.26 erf, |error| < 1.5e-7).
pub fn normal_cdf(z: f64) -> f64 {
    let x = z.abs() / std::f64::consts::SQRT_2;
    let t = 1.0 / (1.0 + 0.327_591_1 * x);
    let y = 1.0
        - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736) * t
            + 0.254_829_592)
            * t
            * (-x * x).exp();
    if z >= 0.0 {
        0.5 * (1.0 + y)
    } else {
        0.5 * (1.0 - y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    #[test]
    fn allan_ratio_is_one_for_white_noise_and_grows_for_a_random_walk() {
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let w: Vec<f64> = (0..4096).map(|_| StandardNormal.sample(&mut r)).collect();
        // k clusters: relative standard deviation of the estimate about sqrt(2 / k)
        for [m, a] in allan_ratio(&w) {
            let k = 4096.0 / m - 1.0;
            assert!((a - 1.0).abs() < 4.0 * (2.0 / k).sqrt(), "m {m}: {a}");
        }
        let wh = whiteness(0, &w);
        assert!(wh.ljung_box_q < 2.0 * LJUNG_BOX_Q95, "{}", wh.ljung_box_q);
        // white + a random walk of 0.1 per step: m AVAR(m) = 1 + 0.01 m^2 / 3 (approx.)
        let mut acc = 0.0;
        let rw: Vec<f64> = w
            .iter()
            .map(|x| {
                acc += 0.1 * x;
                acc + x
            })
            .collect();
        let a = allan_ratio(&rw);
        let at = |m: f64| a.iter().find(|p| p[0] == m).map_or(f64::NAN, |p| p[1]);
        assert!(at(64.0) > 5.0 * at(1.0), "{a:?}");
        assert!(whiteness(0, &rw).ljung_box_q > 10.0 * LJUNG_BOX_Q95);
    }

    #[test]
    fn signed_rank_matches_the_tables() {
        // n = 10, all positive: P(W+ >= 55) = 2^-10
        let d: Vec<f64> = (1..=10).map(f64::from).collect();
        let r = signed_rank(&d, HELDOUT_ALPHA);
        assert_eq!(r.n, 10);
        assert!((r.p_greater - 1.0 / 1024.0).abs() < 1e-12, "{r:?}");
        assert!((r.p_less - 1.0).abs() < 1e-12);
        // Hodges-Lehmann of 1..10 is 5.5; the 90 % interval of n = 10 uses the 11th Walsh
        // average from each end (one-sided 5 % critical value T = 10)
        assert!((r.estimate - 5.5).abs() < 1e-12);
        assert!(r.ci[0] > 1.0 && r.ci[0] < 5.5 && r.ci[1] > 5.5 && r.ci[1] < 10.0);
        // table: n = 12, one-sided 0.05 critical W- = 17 -> P(W+ >= 61) <= 0.05 < P(W+ >= 60)
        let mut d: Vec<f64> = (1..=12).map(f64::from).collect();
        for x in d.iter_mut().take(5) {
            *x = -*x; // W- = 1+2+3+4+5 = 15
        }
        assert!(signed_rank(&d, 0.05).p_greater < 0.05);
        d[5] = -6.0; // W- = 21
        let r = signed_rank(&d, 0.05);
        assert!(r.p_greater > 0.05 && r.p_greater < 0.2, "{r:?}");
        // n = 3: no bound at 5 %
        let r = signed_rank(&[1.0, 2.0, 3.0], 0.05);
        assert!((r.p_greater - 0.125).abs() < 1e-12);
        assert!(r.ci[0].is_infinite() && r.ci[1].is_infinite());
        // ties: normal approximation, symmetric data give about 0.5
        let r = signed_rank(&[1.0, -1.0, 2.0, -2.0, 1.0, -1.0], 0.05);
        assert!(r.p_greater > 0.4 && r.p_less > 0.4, "{r:?}");
        assert!((normal_cdf(1.644_853_6) - 0.95).abs() < 1e-6);
    }
}
