//! Equivalent degrees of freedom, noise identification and chi-square confidence intervals.
//!
//! - EDF: C. A. Greenhall and W. J. Riley, "Uncertainty of stability variances based on finite
//!   differences", Proc. 35th PTTI (2003), the algorithm also given in NIST SP1065 sec. 5.2.
//!   It covers the overlapping/non-overlapping Allan and Hadamard variances and the modified
//!   Allan variance for power-law noise `S_y(f) ~ f^alpha`, alpha = 2 ... -4.
//! - Noise identification: W. J. Riley and C. A. Greenhall, "Power law noise identification
//!   using the lag 1 autocorrelation" (2004), applied to the block means at each averaging
//!   factor (frequency data, linear trend removed).
//! - Confidence interval: `sigma^2 edf / chi2(1 - p/2, edf) <= sigma_true^2 <= sigma^2 edf /
//!   chi2(p/2, edf)` (SP1065 eq. 45), chi-square quantiles from the regularized incomplete
//!   gamma function solved by Newton's method (relative accuracy ~1e-12).
use super::{Deviation, Phase};
use crate::stats::chi2_inv;

/// Probability of a 1-sigma interval, erf(1/sqrt 2).
pub const ONE_SIGMA: f64 = 0.682_689_492_137_085_9;

/// Greenhall's `sw(t, alpha)` (eq. 7).
fn sw(t: f64, alpha: i32) -> f64 {
    let a = t.abs();
    let lnt = |p: i32| if t == 0.0 { 0.0 } else { t.powi(p) * a.ln() };
    match alpha {
        2 => -a,
        1 => lnt(2),
        0 => a * a * a,
        -1 => lnt(4),
        -2 => a.powi(5),
        -3 => lnt(6),
        _ => a.powi(7),
    }
}

/// `sx(t, F, alpha)` (eq. 8); `F = inf` gives `sw(t, alpha + 2)`.
fn sx(t: f64, f: f64, alpha: i32) -> f64 {
    if f.is_infinite() {
        sw(t, alpha + 2)
    } else {
        f * f * (2.0 * sw(t, alpha) - sw(t - 1.0 / f, alpha) - sw(t + 1.0 / f, alpha))
    }
}

/// `sz(t, F, alpha, d)` (eq. 9): the binomial d-th difference of `sx`.
fn sz(t: f64, f: f64, alpha: i32, d: usize) -> f64 {
    let w: &[f64] = match d {
        1 => &[2.0, -1.0],
        2 => &[6.0, -4.0, 1.0],
        _ => &[20.0, -15.0, 6.0, -1.0],
    };
    let mut s = w[0] * sx(t, f, alpha);
    for (k, wk) in w.iter().enumerate().skip(1) {
        let kf = k as f64;
        s += wk * (sx(t - kf, f, alpha) + sx(t + kf, f, alpha));
    }
    s
}

/// Basic sum (eq. 10).
fn basic_sum(j: f64, m_big: f64, s: f64, f: f64, alpha: i32, d: usize) -> f64 {
    let mut sum = sz(0.0, f, alpha, d).powi(2);
    sum += (1.0 - j / m_big) * sz(j / s, f, alpha, d).powi(2);
    let ji = j as usize;
    for jj in 1..ji {
        let jf = jj as f64;
        sum += 2.0 * (1.0 - jf / m_big) * sz(jf / s, f, alpha, d).powi(2);
    }
    sum
}

fn table_row(alpha: i32) -> usize {
    (2 - alpha).clamp(0, 6) as usize
}

/// Greenhall table 1 (modified variances): (a0, a1) per alpha (rows 2..-4) and d (cols 1..3).
const TABLE1: [[(f64, f64); 3]; 7] = [
    [
        (2.0 / 3.0, 1.0 / 3.0),
        (7.0 / 9.0, 0.5),
        (22.0 / 25.0, 2.0 / 3.0),
    ],
    [(0.840, 0.345), (0.997, 0.616), (1.141, 0.843)],
    [(1.079, 0.368), (1.033, 0.607), (1.184, 0.848)],
    [(f64::NAN, f64::NAN), (1.048, 0.534), (1.180, 0.816)],
    [(f64::NAN, f64::NAN), (1.302, 0.535), (1.175, 0.777)],
    [(f64::NAN, f64::NAN), (f64::NAN, f64::NAN), (1.194, 0.703)],
    [(f64::NAN, f64::NAN), (f64::NAN, f64::NAN), (1.489, 0.702)],
];
/// Greenhall table 2 (unmodified variances).
const TABLE2: [[(f64, f64); 3]; 7] = [
    [(1.5, 0.5), (35.0 / 18.0, 1.0), (231.0 / 100.0, 1.5)],
    [(78.6, 25.2), (790.0, 410.0), (9950.0, 6520.0)],
    [
        (2.0 / 3.0, 1.0 / 6.0),
        (2.0 / 3.0, 1.0 / 3.0),
        (7.0 / 9.0, 0.5),
    ],
    [(f64::NAN, f64::NAN), (0.852, 0.375), (0.997, 0.617)],
    [(f64::NAN, f64::NAN), (1.079, 0.368), (1.033, 0.607)],
    [(f64::NAN, f64::NAN), (f64::NAN, f64::NAN), (1.053, 0.553)],
    [(f64::NAN, f64::NAN), (f64::NAN, f64::NAN), (1.302, 0.535)],
];
/// Greenhall table 3 (alpha = 1, unmodified): (b0, b1) per d.
const TABLE3: [(f64, f64); 3] = [(6.0, 4.0), (15.23, 12.0), (47.8, 40.0)];

/// Greenhall's EDF for noise exponent `alpha`, difference order `d` (2 Allan, 3 Hadamard),
/// averaging factor `m`, `n_phase` phase points (rate samples + 1), overlapping or not,
/// modified or not. `alpha` is clamped to the valid range `alpha + 2d > 1`.
pub fn edf_greenhall(
    alpha: i32,
    d: usize,
    m: usize,
    n_phase: usize,
    overlapping: bool,
    modified: bool,
) -> f64 {
    let d = d.clamp(1, 3);
    let alpha = alpha.clamp(2 - 2 * d as i32, 2);
    let mf = m as f64;
    let nf = n_phase as f64;
    let df = d as f64;
    let f = if modified { 1.0 } else { mf };
    let s = if overlapping { mf } else { 1.0 };
    let l = mf / f + mf * df;
    if nf < l {
        return f64::NAN;
    }
    let m_big = 1.0 + (s * (nf - l) / mf).floor();
    let j = m_big.min((df + 1.0) * s);
    const J_MAX: f64 = 100.0;
    let r = m_big / s;
    let row = table_row(alpha);
    let col = d - 1;
    let inv = if modified {
        if j <= J_MAX {
            basic_sum(j, m_big, s, 1.0, alpha, d) / (sz(0.0, 1.0, alpha, d).powi(2) * m_big)
        } else if r > df + 1.0 {
            let (a0, a1) = TABLE1[row][col];
            (a0 - a1 / r) / r
        } else {
            let mp = J_MAX / r;
            basic_sum(J_MAX, J_MAX, mp, 1.0, alpha, d) / (sz(0.0, 1.0, alpha, d).powi(2) * J_MAX)
        }
    } else if alpha <= 0 {
        if j <= J_MAX {
            let mp = if mf * (df + 1.0) <= J_MAX {
                mf
            } else {
                f64::INFINITY
            };
            basic_sum(j, m_big, s, mp, alpha, d) / (sz(0.0, mp, alpha, d).powi(2) * m_big)
        } else if r > df + 1.0 {
            let (a0, a1) = TABLE2[row][col];
            (a0 - a1 / r) / r
        } else {
            let mp = J_MAX / r;
            basic_sum(J_MAX, J_MAX, mp, f64::INFINITY, alpha, d)
                / (sz(0.0, f64::INFINITY, alpha, d).powi(2) * J_MAX)
        }
    } else if alpha == 1 {
        let (b0, b1) = TABLE3[col];
        if j <= J_MAX {
            basic_sum(j, m_big, s, mf, 1, d) / (sz(0.0, mf, 1, d).powi(2) * m_big)
        } else if r > df + 1.0 {
            let (a0, a1) = TABLE2[row][col];
            (a0 - a1 / r) / ((b0 + b1 * mf.ln()).powi(2) * r)
        } else {
            let mp = J_MAX / r;
            basic_sum(J_MAX, J_MAX, mp, mp, 1, d) / ((b0 + b1 * mf.ln()).powi(2) * J_MAX)
        }
    } else {
        // alpha = 2, unmodified.
        let k = r.ceil();
        if k <= df {
            // Few terms: the exact basic sum (J = M here).
            basic_sum(j, m_big, s, mf, 2, d) / (sz(0.0, mf, 2, d).powi(2) * m_big)
        } else {
            let a0 = binom(4 * d, 2 * d) / binom(2 * d, d).powi(2);
            let a1 = df / 2.0;
            (a0 - a1 / r) / m_big
        }
    };
    1.0 / inv
}

fn binom(n: usize, k: usize) -> f64 {
    (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64)
}

/// EDF of deviation `dev` at averaging factor `m` for `n_phase` phase points.
pub fn edf_for(dev: Deviation, alpha: i32, m: usize, n_phase: usize) -> f64 {
    match dev {
        Deviation::Adev => edf_greenhall(alpha, 2, m, n_phase, false, false),
        Deviation::Oadev => edf_greenhall(alpha, 2, m, n_phase, true, false),
        Deviation::Mdev => edf_greenhall(alpha, 2, m, n_phase, true, true),
        Deviation::Hdev => edf_greenhall(alpha, 3, m, n_phase, false, false),
        Deviation::Ohdev => edf_greenhall(alpha, 3, m, n_phase, true, false),
    }
}

/// Maximum number of block means used for noise identification (the lag-1 autocorrelation
/// of 2^20 points is known to ~1e-3; more only costs time and memory).
pub const NOISE_ID_MAX_POINTS: usize = 1 << 20;

/// Lag-1 autocorrelation noise identification at averaging factor `m` (Riley & Greenhall
/// 2004) on the block means `(x_{(k+1)m} - x_{km}) / m` (at most [`NOISE_ID_MAX_POINTS`]):
/// linear trend removed, differenced until `rho = r1 / (1 + r1) < 0.25` or `d = dmax`;
/// `alpha = -round(2 rho) - 2 d`, clamped to the range the EDF accepts for difference order
/// `dmax` (`alpha + 2 dmax > 1`). `None` when fewer than 30 block means exist.
pub fn noise_id_lag1(phase: &Phase, m: usize, dmax: usize) -> Option<i32> {
    let x = phase.as_slice();
    if m == 0 {
        return None;
    }
    let n = (phase.n_rate() / m).min(NOISE_ID_MAX_POINTS);
    if n < 30 {
        return None;
    }
    let mut z: Vec<f64> = (0..n).map(|k| x[(k + 1) * m] - x[k * m]).collect();
    detrend_linear(&mut z);
    let mut d = 0usize;
    loop {
        let r1 = lag1_acf(&z).clamp(-0.999_999, 0.999_999);
        let rho = r1 / (1.0 + r1);
        if rho < 0.25 || d >= dmax {
            let a = -(2.0 * rho).round() as i32 - 2 * d as i32;
            let lo = 2 - 2 * dmax as i32;
            return Some(a.clamp(lo, 2));
        }
        for i in 0..z.len() - 1 {
            z[i] = z[i + 1] - z[i];
        }
        z.pop();
        d += 1;
        if z.len() < 3 {
            return None;
        }
    }
}

fn detrend_linear(z: &mut [f64]) {
    let n = z.len() as f64;
    let tm = (n - 1.0) / 2.0;
    let zm = z.iter().sum::<f64>() / n;
    let (mut stz, mut stt) = (0.0, 0.0);
    for (i, v) in z.iter().enumerate() {
        let t = i as f64 - tm;
        stz += t * (v - zm);
        stt += t * t;
    }
    let b = if stt > 0.0 { stz / stt } else { 0.0 };
    for (i, v) in z.iter_mut().enumerate() {
        *v -= zm + b * (i as f64 - tm);
    }
}

fn lag1_acf(z: &[f64]) -> f64 {
    let n = z.len() as f64;
    let mu = z.iter().sum::<f64>() / n;
    let den: f64 = z.iter().map(|v| (v - mu) * (v - mu)).sum();
    let num: f64 = z.windows(2).map(|w| (w[0] - mu) * (w[1] - mu)).sum();
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

/// Confidence interval `(lo, hi)` of a deviation `dev` with `edf` degrees of freedom at
/// two-sided confidence level `p` (e.g. [`ONE_SIGMA`]). NaN/`<= 0` EDF gives `(dev, dev)`.
pub fn interval(dev: f64, edf: f64, p: f64) -> (f64, f64) {
    if !edf.is_finite() || edf <= 0.0 {
        return (dev, dev);
    }
    let tail = 0.5 * (1.0 - p);
    let c_lo = chi2_inv(tail, edf);
    let c_hi = chi2_inv(1.0 - tail, edf);
    (dev * (edf / c_hi).sqrt(), dev * (edf / c_lo).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn greenhall_edf_white_fm_matches_published_values() {
        // Values of the reference implementation of Greenhall's algorithm (allantools
        // ci.edf_greenhall) for alpha = 0, N = 1001 phase points.
        let cases = [
            (Deviation::Adev, 1, 782.030_299_072_743_8),
            (Deviation::Adev, 128, 4.235_294_117_647_059),
            (Deviation::Oadev, 2, 540.681_194_116_047_2),
            (Deviation::Oadev, 128, 9.550_953_331_497_8),
            (Deviation::Hdev, 8, 64.275_463_102_626_12),
            (Deviation::Ohdev, 64, 17.123_049_418_604_65),
            (Deviation::Mdev, 2, 478.996_152_279_208_7),
            (Deviation::Mdev, 128, 5.321_547_874_256_73),
        ];
        for (dev, m, want) in cases {
            let got = edf_for(dev, 0, m, 1001);
            assert!(
                (got / want - 1.0).abs() < 1e-9,
                "{dev:?} m={m}: {got} vs {want}"
            );
        }
    }
}
