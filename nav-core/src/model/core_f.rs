//! The core 9x9 block of the continuous error dynamics F for the phi-angle error model in NED
//! (Groves 2013 ch. 14.2 / Shin 2001 / KF-GINS), with dx = estimate - truth:
//!
//! ```text
//! phi' = -w_in x phi + dw_in(dv, dr)          - C_b^n dw_ib
//! dv'  =  f_n x phi  - (2 w_ie + w_en) x dv - (2 dw_ie + dw_en) x v + dg + C_b^n df_b
//! dr'  =  dv + F_rr dr
//! ```
//!
//! where `dw_ie = W_ie_r dr`, `dw_en = W_en_v dv + W_en_r dr`, `dg` the height and latitude
//! slopes of normal gravity. The derivation of every entry is in
//! `docs/derivations/error_state.md`.
//!
//! Computed in the covariance scalar type `T` (the entries only need a few significant
//! digits; on the MCU this keeps the earth model's trigonometry in hardware `f32`). The
//! `[f_n x]` coupling is left out (zero): the filter adds the interval's integral of it.

use crate::earth;
use crate::scalar::Scalar;

type M3<T> = [[T; 3]; 3];

fn c<T: Scalar>(x: f64) -> T {
    T::of_f64(x)
}

fn mul3<T: Scalar>(a: &M3<T>, b: &M3<T>) -> M3<T> {
    let mut out = [[T::ZERO; 3]; 3];
    for (orow, arow) in out.iter_mut().zip(a) {
        for (j, o) in orow.iter_mut().enumerate() {
            let mut acc = T::ZERO;
            for (aik, brow) in arow.iter().zip(b) {
                acc += *aik * brow.get(j).copied().unwrap_or(T::ZERO);
            }
            *o = acc;
        }
    }
    out
}

fn add3m<T: Scalar>(a: &M3<T>, b: &M3<T>) -> M3<T> {
    let mut out = *a;
    for (orow, brow) in out.iter_mut().zip(b) {
        for (o, x) in orow.iter_mut().zip(brow) {
            *o += *x;
        }
    }
    out
}

fn skew_t<T: Scalar>(v: &[T; 3]) -> M3<T> {
    let [x, y, z] = *v;
    let o = T::ZERO;
    [[o, -z, y], [z, o, -x], [-y, x, o]]
}

/// The core block of F (row-major 9x9, states phi, dv, dr) at geodetic latitude `lat_rad`,
/// height `h_m` and NED velocity `v_ned_mps`, without the `[f_n x]` phi-v coupling.
pub fn core_f<T: Scalar>(lat_rad: f64, h_m: f64, v_ned_mps: &[f64; 3]) -> [[T; 9]; 9] {
    let lat: T = c(lat_rad);
    let h: T = c(h_m);
    let [vn, ve, vd] = v_ned_mps.map(c::<T>);
    let one = T::ONE;
    let two = one + one;
    let (sl, cl) = (lat.sin_libm(), lat.cos_libm());
    let tl = sl / cl;
    let e2: T = c(earth::E2);
    let a: T = c(earth::A_M);
    let s2 = sl * sl;
    let d = one - e2 * s2;
    let sd = d.sqrt_libm();
    let rn0 = a / sd;
    let rm0 = a * (one - e2) / (d * sd);
    let rm = rm0 + h;
    let rn = rn0 + h;
    let w: T = c(earth::OMEGA_IE_RADPS);
    let k: T = c(earth::SOMIGLIANA_K);
    let gamma_e: T = c(earth::GAMMA_E_MPS2);
    let g0 = gamma_e * (one + k * s2) / sd;
    let hc: T = c(2.0 / earth::A_M * (1.0 + earth::F + earth::M_RATIO));
    let hs: T = c(2.0 / earth::A_M * 2.0 * earth::F);
    let h2: T = c(3.0 / (earth::A_M * earth::A_M));
    let g = g0 * (one - (hc - hs * s2) * h + h2 * h * h);
    // Somigliana slope dg/dL (sea level), m/s^2/rad
    let sc = sl * cl;
    let dg_dlat = gamma_e * (two * k * sc / sd + (one + k * s2) * e2 * sc / (d * sd));

    let w_ie = [w * cl, T::ZERO, -w * sl];
    let w_en = [ve / rn, -vn / rm, -ve * tl / rn];
    let w_in = [w_ie[0] + w_en[0], w_en[1], w_ie[2] + w_en[2]];
    let w_cor = [two * w_ie[0] + w_en[0], w_en[1], two * w_ie[2] + w_en[2]];
    let o = T::ZERO;

    // d(w_ie)/d(dr): only through latitude, dL = dr_N / (R_M + h)
    let w_ie_r = [[-w * sl / rm, o, o], [o, o, o], [-w * cl / rm, o, o]];
    // d(w_en)/d(dv)
    let w_en_v = [[o, one / rn, o], [-one / rm, o, o], [o, -tl / rn, o]];
    // d(w_en)/d(dr): latitude (dr_N / R_M) and height (dh = -dr_D), curvature radii held
    let w_en_r = [
        [o, o, ve / (rn * rn)],
        [o, o, -vn / (rm * rm)],
        [-ve / (rm * rn * cl * cl), o, -ve * tl / (rn * rn)],
    ];
    let v_x = skew_t(&[vn, ve, vd]);
    let r_geo = (rm0 * rn0).sqrt_libm() + h;

    let neg = |m: M3<T>| m.map(|r| r.map(|x| -x));
    let f_pp = neg(skew_t(&w_in));
    let f_pv = w_en_v;
    let f_pr = add3m(&w_ie_r, &w_en_r);
    let f_vv = add3m(&neg(skew_t(&w_cor)), &mul3(&v_x, &w_en_v));
    let two_w_ie_r = w_ie_r.map(|r| r.map(|x| two * x));
    let mut f_vr = mul3(&v_x, &add3m(&two_w_ie_r, &w_en_r));
    // gravity error: height (dh = -dr_D, dg/dh = -2 g / R) and latitude (Somigliana slope)
    f_vr[2][2] += two * g / r_geo;
    f_vr[2][0] += dg_dlat / rm;
    let f_rv = [[one, o, o], [o, one, o], [o, o, one]];
    let f_rr = [
        [-vd / rm, o, vn / rm],
        [ve * tl / rm, -(vd / rn + vn * tl / rm), ve / rn],
        [o, o, o],
    ];
    let mut out = [[T::ZERO; 9]; 9];
    super::set3(&mut out, 0, 0, &f_pp);
    super::set3(&mut out, 0, 3, &f_pv);
    super::set3(&mut out, 0, 6, &f_pr);
    super::set3(&mut out, 3, 3, &f_vv);
    super::set3(&mut out, 3, 6, &f_vr);
    super::set3(&mut out, 6, 3, &f_rv);
    super::set3(&mut out, 6, 6, &f_rr);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::earth::Llh;

    #[test]
    fn static_core_f_has_the_schuler_and_gravity_terms() {
        let pos = Llh::from_deg(45.0, 10.0, 100.0);
        let g = earth::gravity_mps2(pos.lat_rad, pos.h_m);
        let f = core_f::<f64>(pos.lat_rad, pos.h_m, &[0.0; 3]);
        // phi_N' = dv_E / R_N, phi_E' = -dv_N / R_M
        let r = earth::radii(pos.lat_rad);
        assert!((f[0][4] - 1.0 / (r.transverse_m + 100.0)).abs() < 1e-18);
        assert!((f[1][3] + 1.0 / (r.meridian_m + 100.0)).abs() < 1e-18);
        // dr' = dv
        assert_eq!(f[6][3], 1.0);
        assert_eq!(f[8][5], 1.0);
        // vertical instability 2 g / R
        assert!((f[5][8] - 2.0 * g / 6.37e6).abs() < 2e-8);
        // latitude slope of gravity against a numerical derivative
        let d = 1e-6;
        let num = (earth::gravity_mps2(pos.lat_rad + d, 0.0)
            - earth::gravity_mps2(pos.lat_rad - d, 0.0))
            / (2.0 * d);
        assert!((f[5][6] * (r.meridian_m + 100.0) - num).abs() < 1e-7);
        // earth-rate terms
        let w = earth::OMEGA_IE_RADPS;
        assert!((f[0][1] - (-w * pos.lat_rad.sin())).abs() < 1e-18);
    }

    #[test]
    fn f32_core_f_agrees_with_f64_to_single_precision() {
        let v = [12.0, -7.0, 0.3];
        let a = core_f::<f64>(0.82, 350.0, &v);
        let b = core_f::<f32>(0.82, 350.0, &v);
        for i in 0..9 {
            for j in 0..9 {
                let tol = 2e-6 * a[i][j].abs() + 1e-12;
                assert!(
                    (a[i][j] - b[i][j] as f64).abs() <= tol,
                    "{i},{j}: {} {}",
                    a[i][j],
                    b[i][j]
                );
            }
        }
    }
}
