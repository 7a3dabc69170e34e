//! The nominal navigation state and the strapdown mechanization on IMU increments (NED,
//! quaternion attitude). The state is `f64`; small correction terms of the step are computed in
//! `f32` (see [`Strapdown`] for why that is exact enough and what it saves on an MCU whose FPU
//! is single precision).
//!
//! The interface is fixed (the filter and the tools use it); the integration algorithm inside
//! [`Strapdown::update`] is free to improve.

use crate::attitude;
use crate::earth::{self, Llh};
use crate::types::{ImuSample, NavSolution};
use libm::{cos, sin, sqrt};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// Nominal navigation state at the IMU reference point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavState {
    /// GPS seconds of week of this state, s.
    pub t_s: f64,
    /// Geodetic position.
    pub pos: Llh,
    /// Velocity relative to the earth in NED, m/s.
    pub vel_ned_mps: Vector3<f64>,
    /// Attitude: rotates body (FRD) vectors into NED, `v_ned = q_nb * v_body` (C_b^n).
    pub q_nb: UnitQuaternion<f64>,
}

impl NavState {
    /// Roll, pitch, yaw (ZYX Euler angles of the body relative to NED), rad; roll and yaw in
    /// (-pi, pi], pitch in [-pi/2, pi/2] (see [`attitude::euler_zyx_from_quat`] for gimbal lock).
    pub fn rpy_rad(&self) -> [f64; 3] {
        attitude::euler_zyx_from_quat(&self.q_nb)
    }

    /// A state from position, NED velocity and roll/pitch/yaw in radians.
    pub fn from_rpy(t_s: f64, pos: Llh, vel_ned_mps: Vector3<f64>, rpy_rad: [f64; 3]) -> Self {
        Self {
            t_s,
            pos,
            vel_ned_mps,
            q_nb: attitude::quat_from_euler_zyx(rpy_rad),
        }
    }
}

impl NavState {
    /// A nav-format record as a state (attitude from its ZYX Euler angles; the standard
    /// deviations, week and status are dropped).
    pub fn from_solution(s: &NavSolution) -> Self {
        Self::from_rpy(
            s.t_s,
            Llh {
                lat_rad: s.lat_rad,
                lon_rad: s.lon_rad,
                h_m: s.h_m,
            },
            Vector3::from(s.vel_ned_mps),
            s.rpy_rad,
        )
    }

    /// The state as a nav-format record: week 0 (unknown here), standard deviations NaN
    /// (unknown), status 0. [`crate::filter::Filter::solution`] gives one with the filter's
    /// standard deviations and status.
    pub fn to_solution(&self) -> NavSolution {
        NavSolution {
            week: 0,
            t_s: self.t_s,
            lat_rad: self.pos.lat_rad,
            lon_rad: self.pos.lon_rad,
            h_m: self.pos.h_m,
            vel_ned_mps: self.vel_ned_mps.into(),
            rpy_rad: self.rpy_rad(),
            pos_std_ned_m: [f64::NAN; 3],
            vel_std_ned_mps: [f64::NAN; 3],
            att_std_rad: [f64::NAN; 3],
            status: 0,
        }
    }
}

impl From<&NavSolution> for NavState {
    fn from(s: &NavSolution) -> Self {
        Self::from_solution(s)
    }
}

impl From<&NavState> for NavSolution {
    fn from(s: &NavState) -> Self {
        s.to_solution()
    }
}

/// Errors of the mechanization (the state is left unchanged when one is returned).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum MechError {
    /// An increment or the time is NaN or infinite.
    NonFinite,
    /// The sample's time is not after the current state's time, or the step is longer than
    /// [`MAX_DT_S`].
    BadTimeStep,
}

impl core::fmt::Display for MechError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::NonFinite => f.write_str("IMU sample has a non-finite time or increment"),
            Self::BadTimeStep => {
                f.write_str("IMU sample time is not increasing or the gap is too long")
            }
        }
    }
}

impl core::error::Error for MechError {}

/// Longest IMU interval the mechanization accepts, s.
pub const MAX_DT_S: f64 = 1.0;

/// What one mechanization step saw, for the error-state model (F and G matrices) and for
/// regressors of effect blocks. The rates and specific forces are computed in single precision
/// (relative rounding below 2e-7), which is what the error-state model needs.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepInfo {
    /// Length of the interval, s.
    pub dt_s: f64,
    /// Mean specific force over the interval in body axes, m/s^2 (dv / dt).
    pub f_body_mps2: Vector3<f64>,
    /// Mean angular rate (inertial) over the interval in body axes, rad/s (dtheta / dt).
    pub omega_ib_body_radps: Vector3<f64>,
    /// Mean specific force over the interval in NED, m/s^2.
    pub f_ned_mps2: Vector3<f64>,
}

/// Strapdown inertial navigation on IMU increments in the local-level NED frame, quaternion
/// attitude; the state is `f64`.
///
/// # Algorithm (one [`update`](Strapdown::update), interval (t_{k-1}, t_k], length dt)
///
/// The formulation is Savage's / Groves' single-speed increment form, as in KF-GINS:
///
/// 1. **Body frame.** Rotation vector of the body over the interval with the two-sample coning
///    correction from the previous increment, `phi = dtheta + dtheta_prev x dtheta / 12`, and
///    the velocity increment in the body frame at t_{k-1} with rotation compensation (to
///    second order) and two-sample sculling: `dv_b = dv + dtheta x dv / 2 +
///    dtheta x (dtheta x dv) / 6 + (dtheta_prev x dv + dv_prev x dtheta) / 12` (see
///    [`attitude::sculled_dv`]). The two-sample terms are exact for rates and specific forces
///    varying linearly over the two intervals; the residual coning drift for a coning motion
///    of half-angle `alpha` and frequency `W` is `alpha^2 W (W dt)^4 / 60` (rad/s). The
///    previous increments are used only when the previous interval was between half and twice
///    the current one (otherwise, and on the first sample after [`new`](Strapdown::new), the
///    two-sample terms are zero).
/// 2. **Mid-interval extrapolation.** Velocity, height and latitude at t_{k-1/2} are
///    extrapolated from the start values, the body increment rotated into NED and the gravity /
///    Coriolis acceleration of the previous step (an error in that cached value, e.g. after a
///    large reset through [`state_mut`](Strapdown::state_mut), only affects one step at second
///    order). At the mid-interval position: radii of curvature, Somigliana gravity, earth rate
///    omega_ie^n and transport rate omega_en^n.
/// 3. **Velocity.** `dv_n = (I - [zeta x] / 2) C_b^n(t_{k-1}) dv_b` with
///    `zeta = (omega_ie^n + omega_en^n) dt` (rotation of the navigation frame over the
///    interval), then `v_k = v_{k-1} + dv_n + (g^n - (2 omega_ie^n + omega_en^n) x v_mid) dt`.
/// 4. **Position**, with the trapezoid velocity `v_bar = (v_{k-1} + v_k) / 2`: height first
///    (`h_k = h_{k-1} - v_bar_D dt`), then latitude with the meridian radius at the mid height,
///    then longitude with the transverse radius and `cos` of the mean latitude.
/// 5. **Attitude**: `q_nb,k = q(-zeta') * q_nb,k-1 * q(phi)` where `zeta'` uses the transport
///    rate of `v_bar`; the result is normalised every step.
///
/// # Arithmetic (why this is cheap on a single-precision FPU and still exact)
///
/// On a Cortex-M4F every `f64` operation is a software routine (80-100 instructions), an
/// `f32` one a single FPU instruction. The step therefore splits the work into large terms
/// computed in `f64` and small corrections computed in `f32` and added to them: an `f32`
/// correction of size `c` carries a rounding error of about `6e-8 c`, negligible when `c` is
/// itself tiny. In `f64`: the rotation of `dv_b` into NED, gravity times dt, the Coriolis
/// acceleration of the start velocity, the velocity and position sums, the position
/// increments, the earth and transport rates of the attitude update (the latter as
/// `(dlon cos lat, -dlat, -dlon sin lat) / dt`), and the quaternion products. In `f32`: the
/// coning, sculling and rotation-compensation terms (below 1e-4 of `dtheta` / `dv` at vehicle
/// rates), the navigation-frame rotation of `dv_n` (`zeta x dv / 2`, below 1e-6 of `dv`), the
/// Coriolis term of the half-step velocity change, the transport rate inside those, the
/// mid-interval extrapolation, and the earth-model corrections below. Measured against the
/// all-`f64` implementation over a lively 60 s run: 1e-7 m, 1.3e-8 m/s, 4e-12 rad (the test
/// `optimised_step_matches_the_plain_f64_step`); at rest for 1 h the `f32` rounding of the
/// rotation compensation (a constant 1e-13 m/s^2) adds 1.3e-5 m to the vertical drift of the
/// unstable height channel (2.4e-5 m in total).
///
/// **Earth model.** The earth quantities are evaluated at a reference point (latitude,
/// height) with `libm` in `f64` (sin and cos of latitude, gravity, 1/(R_M+h),
/// 1/((R_N+h) cos lat)) together with their first and second derivatives; each step evaluates
/// them at the mid-interval point by a Taylor series in the latitude and height offsets from
/// the reference, the series in `f32` and added to the `f64` reference values. The reference
/// moves to the current position when the latitude offset exceeds 1e-5 rad / (1 + |tan lat|)
/// (64 m at the equator, 30 m at 48 deg) or the height offset [`EARTH_REF_H_TOL_M`]; within
/// those, series truncation plus `f32` rounding stay below 1e-16 rad/s for the earth rate,
/// 3e-12 relative for the radii and 1e-11 m/s^2 for gravity (checked in the tests), and at
/// rest the offsets are zero. A car at 30 m/s moves the reference about once a second (one
/// `sin`, `cos`, `sqrt` and ~60 `f64` operations, ~13k instructions on the M4F).
///
/// **Attitude.** The body and navigation-frame rotations are applied as `(1, t)` quaternions
/// with `t = tan(|phi| / 2) / |phi| phi` (series for |phi| < 0.01 rad, exact quaternion
/// otherwise), so each product is `q + q * (0, t)` in `f64` (the first-order rotation terms
/// at full precision); the product is then scaled to unit norm by a series in `|q|^2 - 1`.
///
/// Cost per step: about 80 `f64` multiplications, 90 additions and one division, no `libm`
/// call except when the earth reference moves, no allocation. The local-level NED frame is
/// singular at the poles (|latitude| -> 90 deg): longitude rate and transport rate diverge
/// there.
#[derive(Debug, Clone, Copy)]
pub struct Strapdown {
    state: NavState,
    prev_dtheta_rad: [f32; 3],
    prev_dv_mps: [f32; 3],
    prev_dt_s: f32,
    have_prev: bool,
    /// Gravity minus Coriolis/centripetal acceleration in NED of the last step, m/s^2 (only for
    /// the mid-interval extrapolation).
    accel_ng_mps2: [f32; 3],
    /// Earth quantities at the reference point and their derivatives.
    earth: EarthRef,
}

/// Largest latitude offset from the earth reference (times 1 + |tan lat|), rad.
const EARTH_REF_LAT_TOL_RAD: f64 = 1.0e-5;
/// Largest height offset from the earth reference, m.
pub const EARTH_REF_H_TOL_M: f32 = 20.0;
/// Squared body rotation angle per step (rad^2) below which the `tan(a/2)/a` series is used
/// (truncation below 1e-17 with terms up to a^6).
const SMALL_ROT2_RAD2: f32 = 1.0e-4;
/// |q|^2 - 1 below which the normalisation uses its series (truncation below 3e-17).
const SMALL_NORM_ERR: f64 = 1.0e-4;

/// Earth quantities at a reference latitude and height (`f64`), with the derivatives (`f32`)
/// for the Taylor series around it. Derivatives `_l` are per rad of latitude, `_h` per m.
#[derive(Debug, Clone, Copy)]
struct EarthRef {
    lat_rad: f64,
    h_m: f64,
    /// Latitude offset beyond which the reference moves, rad.
    lat_tol_rad: f32,
    /// sin(lat).
    sin: f64,
    /// cos(lat).
    cos: f64,
    /// Normal gravity, m/s^2.
    g_mps2: f64,
    /// 1 / (R_M + h), 1/m.
    inv_m: f64,
    /// 1 / ((R_N + h) cos(lat)), 1/m.
    lon_f: f64,
    sin32: f32,
    cos32: f32,
    tan32: f32,
    inv_m32: f32,
    inv_n32: f32,
    /// Gravity and `lon_f` rounded to single precision (for [`Strapdown::update_single`]).
    g32: f32,
    lon_f32: f32,
    /// d ln(1/(R_M+h)) / d lat and its second derivative.
    m_l: f32,
    m_ll: f32,
    /// d ln(1/(R_N+h)) / d lat.
    n_l: f32,
    /// d ln(lon_f) / d lat and its second derivative.
    f_l: f32,
    f_ll: f32,
    /// Gravity derivatives.
    g_l: f32,
    g_h: f32,
    g_ll: f32,
    g_lh: f32,
    g_hh: f32,
}

/// Earth quantities at an offset from the reference.
#[derive(Debug, Clone, Copy)]
struct EarthLocal {
    /// sin(lat).
    sin: f64,
    /// cos(lat).
    cos: f64,
    /// Normal gravity, m/s^2.
    g_mps2: f64,
    /// Single-precision copies for the transport rate and the small terms.
    w_cos32: f32,
    w_sin32: f32,
    inv_m32: f32,
    inv_n32: f32,
    tan32: f32,
}

/// `1 + y + y^2 / 2 - 1`: the relative change `e^y - 1` to second order.
fn expm1_2(y: f32) -> f32 {
    y + 0.5 * y * y
}

impl EarthRef {
    /// The same formulas as [`earth::radii`] and [`earth::gravity_mps2`] (checked against them
    /// in the tests), sharing the trigonometry and the square root.
    fn new(lat_rad: f64, h_m: f64) -> Self {
        let s = sin(lat_rad);
        let c = cos(lat_rad);
        let s2 = s * s;
        let d = 1.0 - earth::E2 * s2;
        let sd = sqrt(d);
        let transverse_m = earth::A_M / sd;
        let meridian_m = earth::A_M * (1.0 - earth::E2) / (d * sd);
        let g0 = earth::GAMMA_E_MPS2 * (1.0 + earth::SOMIGLIANA_K * s2) / sd;
        let k_h = 2.0 / earth::A_M * (1.0 + earth::F + earth::M_RATIO - 2.0 * earth::F * s2);
        let hh = 1.0 - k_h * h_m + 3.0 * h_m * h_m / (earth::A_M * earth::A_M);
        let g = g0 * hh;
        let inv_m = 1.0 / (meridian_m + h_m);
        let inv_n = 1.0 / (transverse_m + h_m);
        let tan = s / c;
        // derivatives (single precision is ample: they multiply offsets of at most 1e-5 rad
        // and 20 m)
        let sc_d = s * c / d;
        let rm_l = 3.0 * earth::E2 * meridian_m * sc_d; // dR_M/dlat
        let rn_l = earth::E2 * transverse_m * sc_d; // dR_N/dlat
        let rm_ll = 3.0 * earth::E2 * meridian_m * (c * c - s * s); // leading order in e^2
        let m_l = -rm_l * inv_m;
        let m_ll = -rm_ll * inv_m + m_l * m_l;
        let n_l = -rn_l * inv_n;
        let f_l = n_l + tan;
        let f_ll = 1.0 + tan * tan;
        // gravity: g = g0(S) H(S, h) with S = sin^2(lat)
        let g1 = earth::SOMIGLIANA_K / (1.0 + earth::SOMIGLIANA_K * s2) + 0.5 * earth::E2 / d;
        let h_s = 4.0 * earth::F / earth::A_M * h_m; // dH/dS
        let h_h = -k_h + 6.0 * h_m / (earth::A_M * earth::A_M); // dH/dh
        let s_l = 2.0 * s * c; // dS/dlat
        let s_ll = 2.0 * (c * c - s * s);
        let g_s = g0 * (g1 * hh + h_s); // dg/dS
        Self {
            lat_rad,
            h_m,
            lat_tol_rad: (EARTH_REF_LAT_TOL_RAD / (1.0 + tan.abs())) as f32,
            sin: s,
            cos: c,
            g_mps2: g,
            inv_m,
            lon_f: inv_n / c,
            sin32: s as f32,
            cos32: c as f32,
            tan32: tan as f32,
            inv_m32: inv_m as f32,
            inv_n32: inv_n as f32,
            g32: g as f32,
            lon_f32: (inv_n / c) as f32,
            m_l: m_l as f32,
            m_ll: m_ll as f32,
            n_l: n_l as f32,
            f_l: f_l as f32,
            f_ll: f_ll as f32,
            g_l: (g_s * s_l) as f32,
            g_h: (g0 * h_h) as f32,
            g_ll: (g_s * s_ll) as f32,
            g_lh: (g0 * (g1 * h_h + 4.0 * earth::F / earth::A_M) * s_l) as f32,
            g_hh: (g0 * 6.0 / (earth::A_M * earth::A_M)) as f32,
        }
    }

    /// The earth quantities at latitude offset `d_rad` and height offset `e_m`.
    fn at(&self, d_rad: f32, e_m: f32) -> EarthLocal {
        let w = earth::OMEGA_IE_RADPS as f32;
        let (s, c) = (self.sin32, self.cos32);
        let hd2 = 0.5 * d_rad * d_rad;
        // sin(lat + d) - sin(lat), cos(lat + d) - cos(lat), to d^2 (d^3/6 < 2e-16)
        let ds = c * d_rad - s * hd2;
        let dc = -s * d_rad - c * hd2;
        let dg = d_rad * (self.g_l + 0.5 * self.g_ll * d_rad + self.g_lh * e_m)
            + e_m * (self.g_h + 0.5 * self.g_hh * e_m);
        let n_rel = self.n_l * d_rad - self.inv_n32 * e_m;
        let m_rel = self.m_l * d_rad - self.inv_m32 * e_m;
        EarthLocal {
            sin: self.sin + f64::from(ds),
            cos: self.cos + f64::from(dc),
            g_mps2: self.g_mps2 + f64::from(dg),
            w_cos32: w * (c + dc),
            w_sin32: w * (s + ds),
            inv_m32: self.inv_m32 * (1.0 + m_rel),
            inv_n32: self.inv_n32 * (1.0 + n_rel),
            tan32: self.tan32 + (1.0 + self.tan32 * self.tan32) * d_rad,
        }
    }

    /// 1 / (R_M + h) at latitude offset `d_rad` and height offset `e_m`, 1/m.
    fn inv_meridian(&self, d_rad: f32, e_m: f32) -> f64 {
        let ie = self.inv_m32 * e_m;
        let y = d_rad * (self.m_l + 0.5 * self.m_ll * d_rad) - ie + 0.5 * ie * ie;
        self.inv_m + f64::from(self.inv_m32 * expm1_2(y))
    }

    /// 1 / ((R_N + h) cos(lat)) at latitude offset `d_rad` and height offset `e_m`, 1/m.
    fn lon_factor(&self, d_rad: f32, e_m: f32) -> f64 {
        let ie = self.inv_n32 * e_m;
        let y = d_rad * (self.f_l + 0.5 * self.f_ll * d_rad) - ie + 0.5 * ie * ie;
        self.lon_f + f64::from((self.lon_f as f32) * expm1_2(y))
    }
}

type V32 = [f32; 3];

fn cross32(a: V32, b: V32) -> V32 {
    let [ax, ay, az] = a;
    let [bx, by, bz] = b;
    [ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx]
}

fn add32(a: V32, b: V32) -> V32 {
    let [ax, ay, az] = a;
    let [bx, by, bz] = b;
    [ax + bx, ay + by, az + bz]
}

fn scale32(a: V32, k: f32) -> V32 {
    let [ax, ay, az] = a;
    [ax * k, ay * k, az * k]
}

fn to32(v: &Vector3<f64>) -> V32 {
    [v.x as f32, v.y as f32, v.z as f32]
}

fn arr32(v: &[f64; 3]) -> V32 {
    let [x, y, z] = *v;
    [x as f32, y as f32, z as f32]
}

fn to64(v: V32) -> Vector3<f64> {
    let [x, y, z] = v;
    Vector3::new(f64::from(x), f64::from(y), f64::from(z))
}

/// `v + c` with an `f32` correction `c`.
fn plus32(v: &[f64; 3], c: V32) -> Vector3<f64> {
    let [x, y, z] = *v;
    let [cx, cy, cz] = c;
    Vector3::new(x + f64::from(cx), y + f64::from(cy), z + f64::from(cz))
}

/// Gravity minus Coriolis and centripetal acceleration in NED (`f32`, for the extrapolation),
/// m/s^2.
fn accel_ng32(e: &EarthLocal, w_en: V32, v: V32) -> V32 {
    let w2 = [
        2.0 * e.w_cos32 + w_en[0],
        w_en[1],
        -2.0 * e.w_sin32 + w_en[2],
    ];
    let [cx, cy, cz] = cross32(w2, v);
    [-cx, -cy, e.g_mps2 as f32 - cz]
}

/// Transport rate omega_en^n (rad/s) for NED velocity `v` (m/s).
fn transport32(e: &EarthLocal, v: V32) -> V32 {
    let [vn, ve, _] = v;
    let a = ve * e.inv_n32;
    [a, -vn * e.inv_m32, -a * e.tan32]
}

/// `q` rotating `v` (`q v q*`; `q` of unit norm).
fn rotate(q: &Quaternion<f64>, v: &Vector3<f64>) -> Vector3<f64> {
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    // c = u x v; v' = v + 2 (w c + u x c)
    let cx = y * v.z - z * v.y;
    let cy = z * v.x - x * v.z;
    let cz = x * v.y - y * v.x;
    let tx = w * cx + (y * cz - z * cy);
    let ty = w * cy + (z * cx - x * cz);
    let tz = w * cz + (x * cy - y * cx);
    Vector3::new(v.x + 2.0 * tx, v.y + 2.0 * ty, v.z + 2.0 * tz)
}

/// `q + q * (0, t)`: `q` times the unnormalised rotation quaternion `(1, t)`.
fn mul_right_1t(q: &Quaternion<f64>, t: &[f64; 3]) -> Quaternion<f64> {
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    let [a, b, c] = *t;
    Quaternion::new(
        w - (x * a + y * b + z * c),
        x + (w * a + y * c - z * b),
        y + (w * b + z * a - x * c),
        z + (w * c + x * b - y * a),
    )
}

/// `C v` for the quaternion `q = [w, x, y, z]` (unit norm) of `C`, single precision.
fn rotate32(q: [f32; 4], v: V32) -> V32 {
    let [w, x, y, z] = q;
    // c = u x v; v' = v + 2 (w c + u x c)
    let u = [x, y, z];
    let c = cross32(u, v);
    let t = add32(scale32(c, w), cross32(u, c));
    add32(v, scale32(t, 2.0))
}

/// `q + (0, t) * q`: the unnormalised rotation quaternion `(1, t)` times `q`.
fn mul_left_1t(t: &[f64; 3], q: &Quaternion<f64>) -> Quaternion<f64> {
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    let [a, b, c] = *t;
    Quaternion::new(
        w - (a * x + b * y + c * z),
        x + (a * w + b * z - c * y),
        y + (b * w + c * x - a * z),
        z + (c * w + a * y - b * x),
    )
}

impl Strapdown {
    /// Starts the mechanization from `state`.
    pub fn new(state: NavState) -> Self {
        let earth = EarthRef::new(state.pos.lat_rad, state.pos.h_m);
        let e = earth.at(0.0, 0.0);
        let v = to32(&state.vel_ned_mps);
        Self {
            state,
            prev_dtheta_rad: [0.0; 3],
            prev_dv_mps: [0.0; 3],
            prev_dt_s: 0.0,
            have_prev: false,
            accel_ng_mps2: accel_ng32(&e, transport32(&e, v), v),
            earth,
        }
    }

    /// The current nominal state.
    pub fn state(&self) -> &NavState {
        &self.state
    }

    /// Mutable access to the nominal state (closed-loop error feedback).
    pub fn state_mut(&mut self) -> &mut NavState {
        &mut self.state
    }

    /// Forgets the previous increments, so the next step uses no coning / sculling terms
    /// (call after a data gap or when the sensor-error corrections change abruptly).
    pub fn reset_history(&mut self) {
        self.have_prev = false;
    }

    /// The body-frame terms of the step over `dt32` s (step 1 of [`Strapdown::update`] and of
    /// [`Strapdown::update_single`]) from the increments `dth32` (rad) and `dv32` (m/s) in
    /// f32: the coning term (two-sample, with the previous interval's increments when it is
    /// usable, else zero), the rotation compensation plus sculling of `dv` and the body
    /// rotation vector `dtheta + coning`, rad and m/s.
    #[inline(always)]
    fn body_terms(&self, dth32: [f32; 3], dv32: [f32; 3], dt32: f32) -> BodyTerms {
        let use_prev =
            self.have_prev && dt32 <= 2.0 * self.prev_dt_s && self.prev_dt_s <= 2.0 * dt32;
        let (p_th, p_dv) = if use_prev {
            (self.prev_dtheta_rad, self.prev_dv_mps)
        } else {
            ([0.0; 3], [0.0; 3])
        };
        let coning = scale32(cross32(p_th, dth32), 1.0 / 12.0);
        let half_rot = scale32(cross32(dth32, dv32), 0.5);
        let dv_corr = add32(
            add32(half_rot, scale32(cross32(dth32, half_rot), 1.0 / 3.0)),
            scale32(add32(cross32(p_th, dv32), cross32(p_dv, dth32)), 1.0 / 12.0),
        );
        let phi32 = add32(dth32, coning);
        BodyTerms {
            dth32,
            dv32,
            coning,
            dv_corr,
            phi32,
        }
    }

    /// Integrates one IMU sample (already corrected for the estimated sensor errors) over
    /// (state.t_s, imu.t_s]. On error the state is unchanged.
    pub fn update(&mut self, imu: &ImuSample) -> Result<StepInfo, MechError> {
        if !imu.is_finite() {
            return Err(MechError::NonFinite);
        }
        let dt = imu.t_s - self.state.t_s;
        if !(dt > 0.0 && dt <= MAX_DT_S) {
            return Err(MechError::BadTimeStep);
        }
        let dt32 = dt as f32;
        let hdt = 0.5 * dt;
        let hdt32 = 0.5 * dt32;

        // 1. Body frame: coning, rotation compensation and sculling (two-sample, previous
        //    interval) in f32, added to the f64 increments. Without a usable previous sample
        //    the two-sample terms are dropped.
        let BodyTerms {
            dth32,
            dv32,
            coning,
            dv_corr,
            phi32,
        } = self.body_terms(arr32(&imu.dtheta_rad), arr32(&imu.dv_mps), dt32);

        let s = self.state;
        let q = *s.q_nb.quaternion();
        let q32 = [q.w as f32, q.i as f32, q.j as f32, q.k as f32];
        let v0 = s.vel_ned_mps;

        // 2. Body increment in n(t_{k-1}): the raw dv rotated in f64, the corrections in f32
        //    (added with the other small terms below); mid-interval extrapolation (f32) and
        //    the earth quantities there.
        let dv_n_raw = rotate(&q, &Vector3::from(imu.dv_mps));
        let dv_corr_n = rotate32(q32, dv_corr);
        let mut d0 = (s.pos.lat_rad - self.earth.lat_rad) as f32;
        let mut e0 = (s.pos.h_m - self.earth.h_m) as f32;
        if !(d0.abs() <= self.earth.lat_tol_rad && e0.abs() <= EARTH_REF_H_TOL_M) {
            self.earth = EarthRef::new(s.pos.lat_rad, s.pos.h_m);
            d0 = 0.0;
            e0 = 0.0;
        }
        let er = self.earth;
        let v0_32 = to32(&v0);
        let dv_n0_32 = add32(to32(&dv_n_raw), dv_corr_n);
        // v_mid - v0
        let half_dv = scale32(add32(dv_n0_32, scale32(self.accel_ng_mps2, dt32)), 0.5);
        let v_mid = add32(v0_32, half_dv);
        let d_mid = d0 + hdt32 * v_mid[0] * er.inv_m32;
        let e_mid = e0 - hdt32 * v_mid[2];
        let e = er.at(d_mid, e_mid);
        let w_en = transport32(&e, v_mid);

        // 3. Velocity: navigation-frame rotation over the interval (f32), gravity and the
        //    Coriolis acceleration of v0 (f64) and of v_mid - v0 (f32).
        let zeta = scale32(add32([e.w_cos32, 0.0, -e.w_sin32], w_en), dt32);
        let nav_rot = scale32(cross32(zeta, dv_n0_32), -0.5);
        let w2dt = (2.0 * earth::OMEGA_IE_RADPS) * dt;
        let o2 = [
            e.cos * w2dt + f64::from(w_en[0] * dt32),
            f64::from(w_en[1] * dt32),
            f64::from(w_en[2] * dt32) - e.sin * w2dt,
        ];
        let [o2x, o2y, o2z] = o2;
        let cor = Vector3::new(
            o2y * v0.z - o2z * v0.y,
            o2z * v0.x - o2x * v0.z,
            o2x * v0.y - o2y * v0.x,
        );
        let small = {
            let [cx, cy, cz] = cross32(arr32(&o2), half_dv);
            let [nx, ny, nz] = add32(nav_rot, dv_corr_n);
            [nx - cx, ny - cy, nz - cz]
        };
        let v1 = (v0 + dv_n_raw - cor) + Vector3::new(0.0, 0.0, e.g_mps2 * dt);
        let v1 = plus32(&v1.into(), small);

        // 4. Position: height, then latitude, then longitude (trapezoid velocity).
        let y = (v0 + v1) * hdt;
        let h1 = s.pos.h_m - y.z;
        let e_bar = e0 - 0.5 * (y.z as f32);
        let dlat = y.x * er.inv_meridian(d_mid, e_bar);
        let lat1 = s.pos.lat_rad + dlat;
        let d_bar = d0 + 0.5 * (dlat as f32);
        let dlon = y.y * er.lon_factor(d_bar, e_bar);
        let lon1 = s.pos.lon_rad + dlon;

        // 5. Attitude: body rotation, then the navigation frame's rotation (with v_bar: the
        //    transport rate times dt is (dlon cos(lat), -dlat, -dlon sin(lat)), in f64 so the
        //    attitude follows small changes of velocity and height smoothly).
        let wh = earth::OMEGA_IE_RADPS * hdt + 0.5 * dlon;
        let t_n = [-(e.cos * wh), 0.5 * dlat, e.sin * wh];
        let q_nb = attitude_step(&q, &imu.dtheta_rad, coning, phi32, &t_n);

        self.state = NavState {
            t_s: imu.t_s,
            pos: Llh {
                lat_rad: lat1,
                lon_rad: lon1,
                h_m: h1,
            },
            vel_ned_mps: v1,
            q_nb,
        };
        self.prev_dtheta_rad = dth32;
        self.prev_dv_mps = dv32;
        self.prev_dt_s = dt32;
        self.have_prev = true;
        self.accel_ng_mps2 = accel_ng32(&e, w_en, v_mid);
        let inv_dt = 1.0 / dt32;
        Ok(StepInfo {
            dt_s: dt,
            f_body_mps2: to64(scale32(dv32, inv_dt)),
            omega_ib_body_radps: to64(scale32(dth32, inv_dt)),
            f_ned_mps2: to64(scale32(add32(dv_n0_32, nav_rot), inv_dt)),
        })
    }
}

/// The single-precision step ([`Strapdown::update_single`], the MCU's): the same body terms
/// ([`Strapdown::body_terms`]), every increment in `f32`, the state's sums in `f64`.
mod single;
pub use single::StepInfo32;

/// The body-frame terms of one strapdown step ([`Strapdown::body_terms`]), f32.
struct BodyTerms {
    /// The angle increment, rad.
    dth32: [f32; 3],
    /// The velocity increment, m/s.
    dv32: [f32; 3],
    /// The coning term, rad.
    coning: [f32; 3],
    /// Rotation compensation and sculling of the velocity increment, m/s.
    dv_corr: [f32; 3],
    /// The body rotation vector `dtheta + coning`, rad.
    phi32: [f32; 3],
}

/// The attitude after one step (step 5 of [`Strapdown::update`]): `q` rotated by the body
/// rotation vector `dtheta + coning` (rad; the small-angle series of `tan(a/2)/a` in f32 below
/// [`SMALL_ROT2_RAD2`], with `phi32` its f32 copy) on the right and by the navigation frame's
/// half rotation `t_n` (rad) on the left, then normalised (series below [`SMALL_NORM_ERR`]).
#[inline(always)]
fn attitude_step(
    q: &Quaternion<f64>,
    dtheta_rad: &[f64; 3],
    coning: [f32; 3],
    phi32: [f32; 3],
    t_n: &[f64; 3],
) -> UnitQuaternion<f64> {
    let phi = plus32(dtheta_rad, coning);
    let [px, py, pz] = phi32;
    let a2 = px * px + py * py + pz * pz;
    let q2 = if a2 < SMALL_ROT2_RAD2 {
        // tan(a/2)/a = 1/2 + a^2/24 + a^4/240 + 17 a^6/40320
        let k32 = a2 * (1.0 / 24.0 + a2 * (1.0 / 240.0 + a2 * (17.0 / 40320.0)));
        let k = 0.5 + f64::from(k32);
        mul_left_1t(t_n, &mul_right_1t(q, &[phi.x * k, phi.y * k, phi.z * k]))
    } else {
        mul_left_1t(t_n, &(q * attitude::quat_from_rotvec(&phi).into_inner()))
    };
    let n2 = q2.norm_squared();
    let x = n2 - 1.0;
    let f = if x.abs() < SMALL_NORM_ERR {
        // (1 + x)^(-1/2) = 1 - x/2 + 3x^2/8 - 5x^3/16
        let x32 = x as f32;
        1.0 + f64::from(x32 * (-0.5 + x32 * (0.375 - 0.3125 * x32)))
    } else {
        1.0 / sqrt(n2)
    };
    UnitQuaternion::new_unchecked(q2 * f)
}

/// The previous, straightforward `f64` implementation of the same algorithm (one `sin`, `cos`,
/// `sqrt` per step, every term in `f64`), kept as the reference the optimised step is checked
/// against.
#[cfg(test)]
mod plain;

#[cfg(test)]
mod tests;
