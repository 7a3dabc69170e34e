//! Chi-square distribution: CDF from the regularized lower incomplete gamma function and
//! quantiles by bisection, for the NEES consistency bands (R runs x d dimensions degrees of
//! freedom, far beyond the fixed tables in `nav_core::config::chi2`).

/// Regularized lower incomplete gamma function P(a, x) (series for x < a + 1, Lentz continued
/// fraction otherwise; Numerical Recipes 6.2). Accurate to ~1e-14 for the a, x used here.
pub fn gamma_p(a: f64, x: f64) -> f64 {
    if a.is_nan() || a <= 0.0 || x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 0.0;
    }
    let ln_pre = a * x.ln() - x - libm::lgamma(a);
    if x < a + 1.0 {
        let mut ap = a;
        let mut del = 1.0 / a;
        let mut sum = del;
        for _ in 0..10_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (sum.ln() + ln_pre).exp().min(1.0)
    } else {
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < tiny {
                d = tiny;
            }
            c = b + an / c;
            if c.abs() < tiny {
                c = tiny;
            }
            d = 1.0 / d;
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (1.0 - (ln_pre.exp() * h)).max(0.0)
    }
}

/// Chi-square CDF with `dof` degrees of freedom at `x`.
pub fn cdf(dof: f64, x: f64) -> f64 {
    gamma_p(0.5 * dof, 0.5 * x)
}

/// Chi-square quantile: the x with `cdf(dof, x) = p` (bisection to 1e-12 relative).
pub fn quantile(dof: f64, p: f64) -> f64 {
    if !(dof > 0.0 && p > 0.0 && p < 1.0) {
        return f64::NAN;
    }
    let (mut lo, mut hi) = (0.0, dof.max(1.0));
    while cdf(dof, hi) < p {
        hi *= 2.0;
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf(dof, mid) < p {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-12 * hi {
            break;
        }
    }
    0.5 * (lo + hi)
}

/// Two-sided 95 % band of the average NEES of `runs` independent runs of dimension `dim`:
/// `[q(0.025), q(0.975)] / runs` of chi-square with `runs * dim` degrees of freedom.
pub fn nees_band_95(runs: usize, dim: usize) -> (f64, f64) {
    let r = runs.max(1) as f64;
    let dof = r * dim as f64;
    (quantile(dof, 0.025) / r, quantile(dof, 0.975) / r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_tables_and_closed_forms() {
        // nav-core's closed-form-checked constants (3 and 6 dof)
        let c = nav_core::config::chi2::DIM3_P95;
        assert!((quantile(3.0, 0.95) - c).abs() < 1e-7);
        let c = nav_core::config::chi2::DIM6_P9999;
        assert!((quantile(6.0, 0.9999) - c).abs() < 1e-6);
        // 2 dof: cdf = 1 - exp(-x/2)
        for x in [0.1, 1.0, 5.0, 30.0] {
            assert!((cdf(2.0, x) - (1.0 - (-x / 2.0f64).exp())).abs() < 1e-13);
        }
        // published table values (Abramowitz & Stegun 26.8): dof 60, p 0.025 / 0.975
        assert!((quantile(60.0, 0.025) - 40.4817).abs() < 1e-3);
        assert!((quantile(60.0, 0.975) - 83.2977).abs() < 1e-3);
        // dof 100
        assert!((quantile(100.0, 0.025) - 74.2219).abs() < 1e-3);
        assert!((quantile(100.0, 0.975) - 129.561).abs() < 1e-2);
        let (lo, hi) = nees_band_95(20, 3);
        assert!((lo - 40.4817 / 20.0).abs() < 1e-4 && (hi - 83.2977 / 20.0).abs() < 1e-4);
    }
}
