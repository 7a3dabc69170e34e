//! The core 9x9 block of the continuous error dynamics F for the phi-angle error model in NED
//! (Groves 2013 ch. 14.2 / Shin 2001 / KF-GINS), with dx = estimate - truth:
//!
//! ```text
//! phi' = -w_in x phi + dw_in(dv, dr)          - C_b^n dw_ib
//! dv'  =  f_n x phi  - (2 w_ie + w_en) x dv - (2 dw_ie + dw_en) x v + dg + C_b^n df_b
//! dr'  =  dv + F_rr dr
//! ```
//!
//! where `dw_ie = W_ie_r dr`, `dw_en = W_en_v dv + W_en_r dr`, `dg = (0, 0, 2 g / (R + h)) dr_D`.
//! The derivation of every entry is in `docs/derivations/error_state.md`. All f64.

use crate::earth::{self, Llh};
use nalgebra::{Matrix3, Vector3};

/// The nine 3x3 blocks of the core F, row-major as [[phi,v,r] rows][phi,v,r cols].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoreF {
    /// `F[row block][col block]`, blocks ordered (phi, v, r).
    pub blocks: [[Matrix3<f64>; 3]; 3],
}

impl CoreF {
    /// The 9x9 matrix, row-major.
    pub fn to_rows(&self) -> [[f64; 9]; 9] {
        let mut out = [[0.0; 9]; 9];
        for (bi, brow) in self.blocks.iter().enumerate() {
            for (bj, m) in brow.iter().enumerate() {
                let rows: [[f64; 3]; 3] = m.transpose().into();
                super::set3(&mut out, 3 * bi, 3 * bj, &rows);
            }
        }
        out
    }
}

/// F's core block at position `pos`, NED velocity `v_ned_mps` and NED specific force
/// `f_ned_mps2` (the phi-v coupling `[f_n x]`; pass zero to add it separately).
pub fn core_f(pos: &Llh, v_ned_mps: &Vector3<f64>, f_ned_mps2: &Vector3<f64>) -> CoreF {
    let lat = pos.lat_rad;
    let h = pos.h_m;
    let r = earth::radii(lat);
    let rm = r.meridian_m + h;
    let rn = r.transverse_m + h;
    let (sl, cl) = (libm::sin(lat), libm::cos(lat));
    let tl = sl / cl;
    let (vn, ve, vd) = (v_ned_mps.x, v_ned_mps.y, v_ned_mps.z);
    let w = earth::OMEGA_IE_RADPS;
    let w_ie = earth::earth_rate_ned_radps(lat);
    let w_en = earth::transport_rate_ned_radps(lat, h, v_ned_mps);
    let w_in = w_ie + w_en;

    // d(w_ie)/d(dr): only through latitude, dL = dr_N / (R_M + h)
    let w_ie_r = Matrix3::new(
        -w * sl / rm,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        -w * cl / rm,
        0.0,
        0.0,
    );
    // d(w_en)/d(dv)
    let w_en_v = Matrix3::new(0.0, 1.0 / rn, 0.0, -1.0 / rm, 0.0, 0.0, 0.0, -tl / rn, 0.0);
    // d(w_en)/d(dr): latitude (dr_N / R_M) and height (dh = -dr_D), curvature radii held
    let w_en_r = Matrix3::new(
        0.0,
        0.0,
        ve / (rn * rn),
        0.0,
        0.0,
        -vn / (rm * rm),
        -ve / (rm * rn * cl * cl),
        0.0,
        -ve * tl / (rn * rn),
    );
    let v_x = v_ned_mps.cross_matrix();
    let g = earth::gravity_mps2(lat, h);
    let r_geo = libm::sqrt(r.meridian_m * r.transverse_m) + h;

    let f_pp = -w_in.cross_matrix();
    let f_pv = w_en_v;
    let f_pr = w_ie_r + w_en_r;

    let f_vp = f_ned_mps2.cross_matrix();
    let f_vv = -(2.0 * w_ie + w_en).cross_matrix() + v_x * w_en_v;
    let mut f_vr = v_x * (2.0 * w_ie_r + w_en_r);
    // gravity error: height (dh = -dr_D, dg/dh = -2 g / R) and latitude (Somigliana slope)
    f_vr.m33 += 2.0 * g / r_geo;
    f_vr.m31 += somigliana_dg_dlat(sl, cl) / rm;

    let f_rp = Matrix3::zeros();
    let f_rv = Matrix3::identity();
    let f_rr = Matrix3::new(
        -vd / rm,
        0.0,
        vn / rm,
        ve * tl / rm,
        -(vd / rn + vn * tl / rm),
        ve / rn,
        0.0,
        0.0,
        0.0,
    );
    CoreF {
        blocks: [[f_pp, f_pv, f_pr], [f_vp, f_vv, f_vr], [f_rp, f_rv, f_rr]],
    }
}

/// d(normal gravity)/d(latitude) of the Somigliana formula at sea level, m/s^2/rad
/// (about 0.052 at 45 deg; the height correction's latitude dependence is neglected).
fn somigliana_dg_dlat(sin_lat: f64, cos_lat: f64) -> f64 {
    let s2 = sin_lat * sin_lat;
    let d = 1.0 - earth::E2 * s2;
    let sd = libm::sqrt(d);
    let sc = sin_lat * cos_lat;
    earth::GAMMA_E_MPS2
        * (2.0 * earth::SOMIGLIANA_K * sc / sd
            + (1.0 + earth::SOMIGLIANA_K * s2) * earth::E2 * sc / (d * sd))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nalgebra_array_conversion_is_column_major_and_transpose_gives_rows() {
        let m = Matrix3::new(1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0);
        let rows: [[f64; 3]; 3] = m.transpose().into();
        assert_eq!(rows, [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]);
    }

    #[test]
    fn somigliana_slope_matches_a_numerical_derivative() {
        for lat_deg in [-70.0f64, -10.0, 0.0, 30.0, 47.1, 80.0] {
            let lat = lat_deg.to_radians();
            let d = 1e-6;
            let num =
                (earth::gravity_mps2(lat + d, 0.0) - earth::gravity_mps2(lat - d, 0.0)) / (2.0 * d);
            let ana = somigliana_dg_dlat(libm::sin(lat), libm::cos(lat));
            assert!((num - ana).abs() < 1e-7, "{lat_deg}: {num} vs {ana}");
        }
    }

    #[test]
    fn static_core_f_has_the_schuler_and_gravity_terms() {
        let pos = Llh::from_deg(45.0, 10.0, 100.0);
        let g = earth::gravity_mps2(pos.lat_rad, pos.h_m);
        let f = core_f(&pos, &Vector3::zeros(), &Vector3::new(0.0, 0.0, -g)).to_rows();
        // dv_N' = f_n x phi: (f x phi)_N = f_E phi_D - f_D phi_E = g phi_E
        assert!((f[3][1] - g).abs() < 1e-12);
        assert!((f[4][0] + g).abs() < 1e-12);
        // phi_N' = dv_E / R_N, phi_E' = -dv_N / R_M
        let r = earth::radii(pos.lat_rad);
        assert!((f[0][4] - 1.0 / (r.transverse_m + 100.0)).abs() < 1e-18);
        assert!((f[1][3] + 1.0 / (r.meridian_m + 100.0)).abs() < 1e-18);
        // dr' = dv
        assert_eq!(f[6][3], 1.0);
        assert_eq!(f[8][5], 1.0);
        // vertical instability 2 g / R
        assert!((f[5][8] - 2.0 * g / 6.37e6).abs() < 2e-8);
    }
}
