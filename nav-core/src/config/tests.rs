//! Unit tests of the filter configuration.
use super::units::*;
use super::*;

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * b.abs()
}

#[test]
fn design_md_checks_of_the_source_table() {
    // N = sqrt(6.2865e-9) = 8.085 ug/sqrt(Hz)
    assert!(close(accel_ug_per_sqrt_hz_from_psd(6.2865e-9), 8.085, 2e-4));
    // K = 1.6350e-6 m/s^2.5 = 10.0 ug/sqrt(h)
    assert!(close(libm::sqrt(2.6731e-12), 1.6350e-6, 1e-4));
    assert!(close(
        accel_ug_per_sqrt_h_from_rw_psd(2.6731e-12),
        10.0,
        5e-4
    ));
    // gyro N = sqrt(5.3079e-10) rad/sqrt(s) = 0.0792 deg/sqrt(h)
    assert!(close(
        gyro_deg_per_sqrt_h_from_psd(5.3079e-10),
        0.0792,
        5e-4
    ));
    // B = 0.6572 sqrt(S_B T_B) = 2.219 ug
    assert!(close(GM_PEAK_ADEV / FLICKER_FLOOR_ADEV, 0.6572, 1e-4));
    assert!(close(
        ug_from_mps2(flicker_b_from_gm(2.4360e-11, 45.0)),
        2.219,
        5e-4
    ));
}

#[test]
fn conversions_invert() {
    for x in [0.1, 8.085, 50.0] {
        assert!(close(
            accel_ug_per_sqrt_hz_from_psd(accel_psd_from_ug_per_sqrt_hz(x)),
            x,
            1e-12
        ));
        assert!(close(
            gyro_deg_per_sqrt_h_from_psd(gyro_psd_from_deg_per_sqrt_h(x)),
            x,
            1e-12
        ));
        assert!(close(
            accel_mps_per_sqrt_h_from_psd(accel_psd_from_mps_per_sqrt_h(x)),
            x,
            1e-12
        ));
        assert!(close(
            accel_ug_per_sqrt_h_from_rw_psd(accel_rw_psd_from_ug_per_sqrt_h(x)),
            x,
            1e-12
        ));
        assert!(close(
            deg_per_h_from_radps(radps_from_deg_per_h(x)),
            x,
            1e-12
        ));
        assert!(close(ug_from_mps2(mps2_from_ug(x)), x, 1e-12));
        let s = gm_psd_from_flicker_b(x, 45.0);
        assert!(close(flicker_b_from_gm(s, 45.0), x, 1e-12));
        assert!(close(
            gm_sigma_from_psd(gm_psd_from_sigma(x, 30.0), 30.0),
            x,
            1e-12
        ));
    }
    // 1 mGal = 1e-5 m/s^2 = 1.0197 ug; 1 deg/h = 4.8481e-6 rad/s; 1 m/s/sqrt(h) = 1/60 m/s^1.5
    assert!(close(mps2_from_mgal(1.0), 1e-5, 1e-15));
    assert!(close(ug_from_mps2(mps2_from_mgal(1.0)), 1.019_716, 1e-6));
    assert!(close(radps_from_deg_per_h(1.0), 4.848_136_8e-6, 1e-7));
    assert!(close(
        accel_psd_from_mps_per_sqrt_h(1.0),
        1.0 / 3600.0,
        1e-12
    ));
    assert!(close(from_ppm(1000.0), 1e-3, 1e-15));
}

#[test]
fn gm_peak_constant_is_the_maximum_of_the_allan_curve() {
    // Brute-force search of the Gauss-Markov Allan variance shape (DESIGN.md's corrected
    // bracket, coefficient 1 on e^-2x).
    let f =
        |x: f64| (1.0 / x) * (1.0 - (3.0 - 4.0 * libm::exp(-x) + libm::exp(-2.0 * x)) / (2.0 * x));
    let mut best = (0.0, 0.0);
    let mut x = 0.01;
    while x < 20.0 {
        let v = f(x);
        if v > best.0 {
            best = (v, x);
        }
        x += 1e-4;
    }
    assert!(close(libm::sqrt(best.0), GM_PEAK_ADEV, 1e-7));
    assert!((best.1 - 1.89).abs() < 0.01);
    assert!(close(
        FLICKER_FLOOR_ADEV,
        libm::sqrt(2.0 * core::f64::consts::LN_2 / core::f64::consts::PI),
        1e-8
    ));
}

#[test]
fn chi2_quantiles_match_closed_form_cdfs() {
    let cdf3 = |x: f64| {
        libm::erf(libm::sqrt(x / 2.0))
            - libm::sqrt(2.0 * x / core::f64::consts::PI) * libm::exp(-x / 2.0)
    };
    let cdf6 = |x: f64| 1.0 - libm::exp(-x / 2.0) * (1.0 + x / 2.0 + x * x / 8.0);
    for (q, p) in [
        (chi2::DIM3_P95, 0.95),
        (chi2::DIM3_P99, 0.99),
        (chi2::DIM3_P999, 0.999),
        (chi2::DIM3_P9999, 0.9999),
    ] {
        assert!((cdf3(q) - p).abs() < 1e-9, "{q} {p}");
    }
    for (q, p) in [
        (chi2::DIM6_P95, 0.95),
        (chi2::DIM6_P99, 0.99),
        (chi2::DIM6_P999, 0.999),
        (chi2::DIM6_P9999, 0.9999),
    ] {
        assert!((cdf6(q) - p).abs() < 1e-9, "{q} {p}");
    }
}

#[test]
fn source_models_have_the_papers_numbers() {
    let n = FilterConfig::source_n_model();
    assert!(close(
        accel_ug_per_sqrt_hz_from_psd(n.accel.s_n[0]),
        50.0,
        1e-12
    ));
    assert!(close(
        gyro_deg_per_sqrt_h_from_psd(n.gyro.s_n[2]),
        0.15,
        1e-12
    ));
    assert_eq!(n.accel.s_b, [0.0; 3]);
    assert_eq!(n.accel.s_k, [0.0; 3]);
    assert!(n.validate().is_ok());
    let m = FilterConfig::source_nbk_model();
    assert_eq!(m.accel.s_n, [6.2865e-9; 3]);
    assert_eq!(m.accel.s_b, [2.4360e-11; 3]);
    assert_eq!(m.accel.t_b_s, 45.0);
    assert_eq!(m.accel.s_k, [2.6731e-12; 3]);
    assert_eq!(m.gyro.s_n, [5.3079e-10; 3]);
    assert!(m.validate().is_ok());
    let mut bad = m;
    bad.accel.t_b_s = 0.0;
    assert_eq!(bad.validate(), Err(ConfigError::AccelNoise));
    bad = m;
    bad.gyro.s_n[1] = f64::NAN;
    assert_eq!(bad.validate(), Err(ConfigError::GyroNoise));
}

#[test]
fn kf_gins_noise_maps_to_psds() {
    let k = KfGinsImuNoise {
        arw_deg_per_sqrt_h: [0.003; 3],
        vrw_mps_per_sqrt_h: [0.03; 3],
        gbstd_deg_per_h: [0.027; 3],
        abstd_mgal: [15.0; 3],
        gsstd_ppm: [300.0; 3],
        asstd_ppm: [300.0; 3],
        corrtime_h: 4.0,
    };
    let c = FilterConfig::from_kf_gins(&k);
    assert!(c.validate().is_ok());
    assert_eq!(c.gyro.t_b_s, 14_400.0);
    // stationary sigma recovers gbstd and abstd
    assert!(close(
        deg_per_h_from_radps(gm_sigma_from_psd(c.gyro.s_b[0], c.gyro.t_b_s)),
        0.027,
        1e-12
    ));
    assert!(close(
        gm_sigma_from_psd(c.accel.s_b[1], c.accel.t_b_s),
        15e-5,
        1e-12
    ));
    assert!(close(c.accel.s_n[2], (0.03f64 / 60.0).powi(2), 1e-12));
    assert!(close(c.gyro_scale.sigma[0], 3e-4, 1e-12));
}
