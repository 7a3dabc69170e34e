//! Chi-square statistics: the regularized lower incomplete gamma function, the chi-square CDF
//! and quantiles, the standard normal quantile, and the NEES consistency band. One definition
//! for the whole workspace: the Allan confidence intervals ([`crate::edf::interval`]), the
//! study's NEES bands (R runs x d dimensions degrees of freedom, far beyond the fixed tables in
//! `nav_core::config::chi2`) and the filter-consistency tests use these.

/// Regularized lower incomplete gamma function P(a, x) (series for x < a + 1, modified Lentz
/// continued fraction for Q = 1 - P otherwise; Numerical Recipes 6.2). Relative accuracy ~1e-14
/// for the a, x of chi-square quantiles up to 10^6 degrees of freedom. NaN for `a <= 0` or a NaN
/// argument, 0 for `x <= 0`.
pub fn gamma_p(a: f64, x: f64) -> f64 {
    if a.is_nan() || a <= 0.0 || x.is_nan() {
        return f64::NAN;
    }
    if x <= 0.0 {
        return 0.0;
    }
    let ln_pre = -x + a * x.ln() - libm::lgamma(a);
    if x < a + 1.0 {
        // Series.
        let mut ap = a;
        let mut del = 1.0 / a;
        let mut sum = del;
        for _ in 0..1_000_000 {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if del.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (sum.ln() + ln_pre).exp().min(1.0)
    } else {
        // Continued fraction for Q (modified Lentz).
        let tiny = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / tiny;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..1_000_000 {
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
        (1.0 - (ln_pre + h.ln()).exp()).max(0.0)
    }
}

/// Chi-square CDF with `dof` degrees of freedom at `x`: `P(dof / 2, x / 2)`.
pub fn chi2_cdf(dof: f64, x: f64) -> f64 {
    gamma_p(0.5 * dof, 0.5 * x)
}

/// Standard normal quantile (Acklam's rational approximation refined by one Halley step with
/// `erfc`; ~1e-15 relative).
pub fn norm_inv(p: f64) -> f64 {
    if p <= 0.0 {
        return f64::NEG_INFINITY;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    const A: [f64; 6] = [
        -3.969_683_028_665_376e1,
        2.209_460_984_245_205e2,
        -2.759_285_104_469_687e2,
        1.383_577_518_672_69e2,
        -3.066_479_806_614_716e1,
        2.506_628_277_459_239,
    ];
    const B: [f64; 5] = [
        -5.447_609_879_822_406e1,
        1.615_858_368_580_409e2,
        -1.556_989_798_598_866e2,
        6.680_131_188_771_972e1,
        -1.328_068_155_288_572e1,
    ];
    const C: [f64; 6] = [
        -7.784_894_002_430_293e-3,
        -3.223_964_580_411_365e-1,
        -2.400_758_277_161_838,
        -2.549_732_539_343_734,
        4.374_664_141_464_968,
        2.938_163_982_698_783,
    ];
    const D: [f64; 4] = [
        7.784_695_709_041_462e-3,
        3.224_671_290_700_398e-1,
        2.445_134_137_142_996,
        3.754_408_661_907_416,
    ];
    let pl = 0.02425;
    let x = if p < pl {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else if p <= 1.0 - pl {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        let q = (-2.0 * (1.0 - p).ln()).sqrt();
        -(((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    // Halley refinement.
    let e = 0.5 * libm::erfc(-x / std::f64::consts::SQRT_2) - p;
    let u = e * (2.0 * std::f64::consts::PI).sqrt() * (x * x / 2.0).exp();
    x - u / (1.0 + x * u / 2.0)
}

/// Chi-square quantile: the `x` with `P(chi2_nu <= x) = p` (Wilson-Hilferty start, Newton
/// steps safeguarded by bisection, relative accuracy ~1e-14). 0 for `p <= 0` or NaN, infinity
/// for `p >= 1`.
pub fn chi2_inv(p: f64, nu: f64) -> f64 {
    if p.is_nan() || p <= 0.0 {
        return 0.0;
    }
    if p >= 1.0 {
        return f64::INFINITY;
    }
    // Wilson-Hilferty start.
    let z = norm_inv(p);
    let h = 2.0 / (9.0 * nu);
    let mut x = nu * (1.0 - h + z * h.sqrt()).powi(3);
    if x.is_nan() || x <= 0.0 {
        x = nu * 0.5;
    }
    let a = 0.5 * nu;
    let (mut lo, mut hi) = (0.0f64, f64::INFINITY);
    for _ in 0..100 {
        let f = gamma_p(a, 0.5 * x) - p;
        if f < 0.0 {
            lo = lo.max(x);
        } else {
            hi = hi.min(x);
        }
        // pdf of chi2_nu at x.
        let ln_pdf =
            (a - 1.0) * (0.5 * x).ln() - 0.5 * x - libm::lgamma(a) - std::f64::consts::LN_2;
        let pdf = ln_pdf.exp();
        let mut xn = if pdf > 0.0 { x - f / pdf } else { f64::NAN };
        if xn.is_nan() || xn <= lo || xn >= hi {
            xn = if hi.is_finite() {
                0.5 * (lo + hi)
            } else {
                2.0 * x.max(lo)
            };
        }
        if (xn - x).abs() <= 1e-14 * x {
            return xn;
        }
        x = xn;
    }
    x
}

/// Two-sided 95 % band of the average NEES of `runs` independent runs of dimension `dim`:
/// `[q(0.025), q(0.975)] / runs` of chi-square with `runs * dim` degrees of freedom.
pub fn nees_band_95(runs: usize, dim: usize) -> (f64, f64) {
    let r = runs.max(1) as f64;
    let dof = r * dim as f64;
    (chi2_inv(0.025, dof) / r, chi2_inv(0.975, dof) / r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chi2_quantiles_match_tables() {
        // Values from standard chi-square tables (scipy.stats.chi2.ppf).
        let cases = [
            (0.5, 1.0, 0.454_936_423_119_572_8),
            (0.95, 10.0, 18.307_038_053_275_146),
            (0.025, 5.0, 0.831_211_613_486_662_5),
            (0.158_655_253_931_457, 100.0, 85.905_326_348_287_82),
        ];
        for (p, nu, want) in cases {
            let got = chi2_inv(p, nu);
            assert!(
                (got / want - 1.0).abs() < 1e-9,
                "chi2({p},{nu}) = {got}, want {want}"
            );
        }
        // Large dof: consistent with the normal limit.
        let x = chi2_inv(0.841_344_746_068_543, 1e6);
        assert!((x - (1e6 + (2e6f64).sqrt())).abs() < 3.0, "{x}");
    }

    #[test]
    fn norm_inv_is_accurate() {
        assert!((norm_inv(0.975) - 1.959_963_984_540_054).abs() < 1e-13);
        assert!((norm_inv(1e-10) + 6.361_340_902_404_056).abs() < 1e-10);
    }

    #[test]
    fn quantiles_match_tables_and_closed_forms() {
        // nav-core's closed-form-checked constants (3 and 6 dof)
        let c = nav_core::config::chi2::DIM3_P95;
        assert!((chi2_inv(0.95, 3.0) - c).abs() < 1e-7);
        let c = nav_core::config::chi2::DIM6_P9999;
        assert!((chi2_inv(0.9999, 6.0) - c).abs() < 1e-6);
        // 2 dof: cdf = 1 - exp(-x/2)
        for x in [0.1, 1.0, 5.0, 30.0] {
            assert!((chi2_cdf(2.0, x) - (1.0 - (-x / 2.0f64).exp())).abs() < 1e-13);
        }
        // published table values (Abramowitz & Stegun 26.8): dof 60, p 0.025 / 0.975
        assert!((chi2_inv(0.025, 60.0) - 40.4817).abs() < 1e-3);
        assert!((chi2_inv(0.975, 60.0) - 83.2977).abs() < 1e-3);
        // dof 100
        assert!((chi2_inv(0.025, 100.0) - 74.2219).abs() < 1e-3);
        assert!((chi2_inv(0.975, 100.0) - 129.561).abs() < 1e-2);
        let (lo, hi) = nees_band_95(20, 3);
        assert!((lo - 40.4817 / 20.0).abs() < 1e-4 && (hi - 83.2977 / 20.0).abs() < 1e-4);
    }

    #[test]
    fn gamma_p_domain_and_limits() {
        assert!(gamma_p(0.0, 1.0).is_nan() && gamma_p(1.0, f64::NAN).is_nan());
        assert_eq!(gamma_p(2.0, 0.0), 0.0);
        // a = 1: P = 1 - e^-x on both branches (x < a + 1 and x >= a + 1)
        for x in [0.5, 1.9, 2.1, 40.0] {
            assert!((gamma_p(1.0, x) - (1.0 - (-x).exp())).abs() < 1e-14, "{x}");
        }
        assert!(gamma_p(3.0, 1e4) == 1.0);
    }
}
