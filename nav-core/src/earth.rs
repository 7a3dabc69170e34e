//! WGS84 earth model: radii of curvature, normal gravity, earth and transport rates in NED,
//! and geodetic <-> ECEF conversions. The one earth model of the project: the simulator, the
//! filter and the tools all use this module.

use libm::{atan2, cos, sin, sqrt, tan};
use nalgebra::Vector3;

/// WGS84 semi-major axis, m.
pub const A_M: f64 = 6_378_137.0;
/// WGS84 flattening (dimensionless).
pub const F: f64 = 1.0 / 298.257_223_563;
/// WGS84 semi-minor axis, m.
pub const B_M: f64 = A_M * (1.0 - F);
/// WGS84 first eccentricity squared (dimensionless).
pub const E2: f64 = F * (2.0 - F);
/// Earth rotation rate, rad/s.
pub const OMEGA_IE_RADPS: f64 = 7.292_115e-5;
/// WGS84 earth gravitational constant GM, m^3/s^2.
pub const GM_M3PS2: f64 = 3.986_004_418e14;
/// Normal gravity at the equator (Somigliana), m/s^2.
pub const GAMMA_E_MPS2: f64 = 9.780_325_335_9;
/// Somigliana's constant k = (b gamma_p) / (a gamma_e) - 1 (dimensionless).
pub const SOMIGLIANA_K: f64 = 0.001_931_852_652_41;
/// m = omega^2 a^2 b / GM (dimensionless), used in the height correction of normal gravity.
pub const M_RATIO: f64 = OMEGA_IE_RADPS * OMEGA_IE_RADPS * A_M * A_M * B_M / GM_M3PS2;
/// Standard gravity, m/s^2 (unit conversions only: 1 g = 9.80665 m/s^2).
pub const G0_MPS2: f64 = 9.806_65;

/// A geodetic position on the WGS84 ellipsoid.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Llh {
    /// Geodetic latitude, rad.
    pub lat_rad: f64,
    /// Longitude, rad.
    pub lon_rad: f64,
    /// Ellipsoidal height, m.
    pub h_m: f64,
}

impl Llh {
    /// A position from latitude and longitude in degrees and ellipsoidal height in metres.
    pub fn from_deg(lat_deg: f64, lon_deg: f64, h_m: f64) -> Self {
        Self {
            lat_rad: lat_deg.to_radians(),
            lon_rad: lon_deg.to_radians(),
            h_m,
        }
    }
}

/// Meridian (north-south) and transverse (east-west, prime vertical) radii of curvature.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Radii {
    /// Meridian radius of curvature R_M (R_N in Groves), m.
    pub meridian_m: f64,
    /// Transverse radius of curvature R_N (R_E in Groves), m.
    pub transverse_m: f64,
}

/// Radii of curvature at geodetic latitude `lat_rad` (rad).
pub fn radii(lat_rad: f64) -> Radii {
    let s = sin(lat_rad);
    let d = 1.0 - E2 * s * s;
    let sd = sqrt(d);
    Radii {
        meridian_m: A_M * (1.0 - E2) / (d * sd),
        transverse_m: A_M / sd,
    }
}

/// Normal gravity magnitude (Somigliana, with the second-order height correction), m/s^2,
/// at geodetic latitude `lat_rad` and ellipsoidal height `h_m`. Points down in NED.
pub fn gravity_mps2(lat_rad: f64, h_m: f64) -> f64 {
    let s2 = sin(lat_rad) * sin(lat_rad);
    let g0 = GAMMA_E_MPS2 * (1.0 + SOMIGLIANA_K * s2) / sqrt(1.0 - E2 * s2);
    g0 * (1.0 - 2.0 / A_M * (1.0 + F + M_RATIO - 2.0 * F * s2) * h_m
        + 3.0 * h_m * h_m / (A_M * A_M))
}

/// Normal gravity vector in NED, m/s^2 (the north component of the plumb-line deflection of
/// the normal field is neglected, below 1e-5 m/s^2 at land-vehicle heights).
pub fn gravity_ned_mps2(lat_rad: f64, h_m: f64) -> Vector3<f64> {
    Vector3::new(0.0, 0.0, gravity_mps2(lat_rad, h_m))
}

/// Earth rotation rate expressed in NED, rad/s.
pub fn earth_rate_ned_radps(lat_rad: f64) -> Vector3<f64> {
    Vector3::new(
        OMEGA_IE_RADPS * cos(lat_rad),
        0.0,
        -OMEGA_IE_RADPS * sin(lat_rad),
    )
}

/// Transport rate (rotation of NED with respect to the earth) in NED, rad/s, for velocity
/// `v_ned_mps` (m/s) at geodetic latitude `lat_rad` and height `h_m`.
pub fn transport_rate_ned_radps(lat_rad: f64, h_m: f64, v_ned_mps: &Vector3<f64>) -> Vector3<f64> {
    let r = radii(lat_rad);
    let rn = r.transverse_m + h_m;
    let rm = r.meridian_m + h_m;
    Vector3::new(
        v_ned_mps.y / rn,
        -v_ned_mps.x / rm,
        -v_ned_mps.y * tan(lat_rad) / rn,
    )
}

/// Rate of change of (latitude rad/s, longitude rad/s, height m/s) for a NED velocity in m/s.
pub fn llh_rate(llh: &Llh, v_ned_mps: &Vector3<f64>) -> Vector3<f64> {
    let r = radii(llh.lat_rad);
    Vector3::new(
        v_ned_mps.x / (r.meridian_m + llh.h_m),
        v_ned_mps.y / ((r.transverse_m + llh.h_m) * cos(llh.lat_rad)),
        -v_ned_mps.z,
    )
}

/// ECEF position, m, of a geodetic position.
pub fn geodetic_to_ecef_m(llh: &Llh) -> Vector3<f64> {
    let r = radii(llh.lat_rad);
    let (sl, cl) = (sin(llh.lat_rad), cos(llh.lat_rad));
    let (so, co) = (sin(llh.lon_rad), cos(llh.lon_rad));
    Vector3::new(
        (r.transverse_m + llh.h_m) * cl * co,
        (r.transverse_m + llh.h_m) * cl * so,
        (r.transverse_m * (1.0 - E2) + llh.h_m) * sl,
    )
}

/// Geodetic position of an ECEF point (m), by Bowring's method refined by fixed-point
/// iteration (sub-millimetre for any terrestrial point).
pub fn ecef_to_geodetic(p_m: &Vector3<f64>) -> Llh {
    let lon = atan2(p_m.y, p_m.x);
    let p = sqrt(p_m.x * p_m.x + p_m.y * p_m.y);
    let ep2 = E2 / (1.0 - E2);
    let theta = atan2(p_m.z * A_M, p * B_M);
    let (st, ct) = (sin(theta), cos(theta));
    let mut lat = atan2(
        p_m.z + ep2 * B_M * st * st * st,
        p - E2 * A_M * ct * ct * ct,
    );
    let mut h = 0.0;
    for _ in 0..4 {
        let rn = radii(lat).transverse_m;
        let cl = cos(lat);
        h = if cl.abs() > 1e-10 {
            p / cl - rn
        } else {
            p_m.z.abs() - B_M
        };
        lat = atan2(p_m.z, p * (1.0 - E2 * rn / (rn + h)));
    }
    Llh {
        lat_rad: lat,
        lon_rad: lon,
        h_m: h,
    }
}

/// Rotation matrix from ECEF to the local NED frame at `llh` (C_e^n).
pub fn ecef_to_ned_dcm(llh: &Llh) -> nalgebra::Matrix3<f64> {
    let (sl, cl) = (sin(llh.lat_rad), cos(llh.lat_rad));
    let (so, co) = (sin(llh.lon_rad), cos(llh.lon_rad));
    nalgebra::Matrix3::new(
        -sl * co,
        -sl * so,
        cl,
        -so,
        co,
        0.0,
        -cl * co,
        -cl * so,
        -sl,
    )
}

/// North-east-down offset in metres of `to` relative to `from`, exact (through ECEF, expressed
/// in the NED frame at `from`).
pub fn ned_offset_m(from: &Llh, to: &Llh) -> Vector3<f64> {
    let d = geodetic_to_ecef_m(to) - geodetic_to_ecef_m(from);
    ecef_to_ned_dcm(from) * d
}

/// The position displaced from `llh` by a small NED offset `d_ned_m` (m), using the local
/// radii of curvature (the first-order curvilinear map the filter's position error uses).
pub fn displace(llh: &Llh, d_ned_m: &Vector3<f64>) -> Llh {
    let r = radii(llh.lat_rad);
    Llh {
        lat_rad: llh.lat_rad + d_ned_m.x / (r.meridian_m + llh.h_m),
        lon_rad: llh.lon_rad + d_ned_m.y / ((r.transverse_m + llh.h_m) * cos(llh.lat_rad)),
        h_m: llh.h_m - d_ned_m.z,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gravity_matches_somigliana_reference_values() {
        // WGS84 normal gravity at the equator and the pole on the ellipsoid (NIMA TR8350.2).
        assert!((gravity_mps2(0.0, 0.0) - 9.780_325_335_9).abs() < 1e-9);
        let pole = gravity_mps2(core::f64::consts::FRAC_PI_2, 0.0);
        assert!((pole - 9.832_184_937_8).abs() < 1e-8, "{pole}");
        // Free-air gradient about -3.086e-6 s^-2 at mid latitudes.
        let lat = 45f64.to_radians();
        let grad = (gravity_mps2(lat, 1000.0) - gravity_mps2(lat, 0.0)) / 1000.0;
        assert!((grad + 3.086e-6).abs() < 0.01e-6, "{grad}");
    }

    #[test]
    fn ecef_round_trip_is_sub_millimetre() {
        for &(lat, lon, h) in &[
            (40.097, -105.147, 1601.0),
            (-33.9, 151.2, -30.0),
            (89.9, 10.0, 5000.0),
            (0.0, 0.0, 0.0),
        ] {
            let p = Llh::from_deg(lat, lon, h);
            let q = ecef_to_geodetic(&geodetic_to_ecef_m(&p));
            assert!((q.lat_rad - p.lat_rad).abs() * A_M < 1e-4);
            assert!((q.lon_rad - p.lon_rad).abs() * A_M < 1e-4);
            assert!((q.h_m - p.h_m).abs() < 1e-4);
        }
    }

    #[test]
    fn displace_agrees_with_exact_offset_for_small_steps() {
        let p = Llh::from_deg(48.2, 16.37, 200.0);
        let d = Vector3::new(100.0, -50.0, 3.0);
        let q = displace(&p, &d);
        let back = ned_offset_m(&p, &q);
        assert!((back - d).norm() < 2e-3, "{back:?}");
    }

    #[test]
    fn radii_at_equator() {
        let r = radii(0.0);
        assert!((r.transverse_m - A_M).abs() < 1e-6);
        assert!((r.meridian_m - A_M * (1.0 - E2)).abs() < 1e-6);
    }
}
