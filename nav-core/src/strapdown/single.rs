//! The single-precision step of [`Strapdown`]: every increment of the step in `f32`, only the
//! sums of the nominal state (time, position, velocity, attitude quaternion) in `f64`. The
//! error budget of this split is in `docs/precision.md`.

use super::*;

/// What one single-precision mechanization step saw: the [`StepInfo`] quantities in `f32`
/// (what the `f32` error-state model uses directly).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StepInfo32 {
    /// Length of the interval, s.
    pub dt_s: f64,
    /// Mean specific force over the interval in body axes, m/s^2 (dv / dt).
    pub f_body_mps2: [f32; 3],
    /// Mean angular rate (inertial) over the interval in body axes, rad/s (dtheta / dt).
    pub omega_ib_body_radps: [f32; 3],
    /// Mean specific force over the interval in NED, m/s^2.
    pub f_ned_mps2: [f32; 3],
}

impl StepInfo32 {
    /// The same quantities in `f64` (exact conversions).
    pub fn to_f64(&self) -> StepInfo {
        StepInfo {
            dt_s: self.dt_s,
            f_body_mps2: to64(self.f_body_mps2),
            omega_ib_body_radps: to64(self.omega_ib_body_radps),
            f_ned_mps2: to64(self.f_ned_mps2),
        }
    }
}

/// Earth quantities at an offset from the reference, single precision.
#[derive(Debug, Clone, Copy)]
struct Local32 {
    /// Earth rate times cos(lat) and sin(lat), rad/s.
    w_cos: f32,
    w_sin: f32,
    /// cos(lat), sin(lat).
    cos: f32,
    sin: f32,
    /// 1 / (R_M + h), 1 / (R_N + h), 1/m.
    inv_m: f32,
    inv_n: f32,
    /// tan(lat).
    tan: f32,
    /// Normal gravity, m/s^2.
    g: f32,
}

impl EarthRef {
    /// [`EarthRef::at`] in single precision: the same series, added to the `f32` reference
    /// values.
    fn at32(&self, d_rad: f32, e_m: f32) -> Local32 {
        let w = earth::OMEGA_IE_RADPS as f32;
        let (s, c) = (self.sin32, self.cos32);
        let hd2 = 0.5 * d_rad * d_rad;
        let sin = s + (c * d_rad - s * hd2);
        let cos = c + (-s * d_rad - c * hd2);
        let dg = d_rad * (self.g_l + 0.5 * self.g_ll * d_rad + self.g_lh * e_m)
            + e_m * (self.g_h + 0.5 * self.g_hh * e_m);
        let n_rel = self.n_l * d_rad - self.inv_n32 * e_m;
        let m_rel = self.m_l * d_rad - self.inv_m32 * e_m;
        Local32 {
            w_cos: w * cos,
            w_sin: w * sin,
            cos,
            sin,
            inv_m: self.inv_m32 * (1.0 + m_rel),
            inv_n: self.inv_n32 * (1.0 + n_rel),
            tan: self.tan32 + (1.0 + self.tan32 * self.tan32) * d_rad,
            g: self.g32 + dg,
        }
    }

    /// 1 / (R_M + h) at latitude offset `d_rad` and height offset `e_m`, single precision, 1/m.
    fn inv_meridian32(&self, d_rad: f32, e_m: f32) -> f32 {
        let ie = self.inv_m32 * e_m;
        let y = d_rad * (self.m_l + 0.5 * self.m_ll * d_rad) - ie + 0.5 * ie * ie;
        self.inv_m32 + self.inv_m32 * expm1_2(y)
    }

    /// 1 / ((R_N + h) cos(lat)) at latitude offset `d_rad` and height offset `e_m`, single
    /// precision, 1/m.
    fn lon_factor32(&self, d_rad: f32, e_m: f32) -> f32 {
        let ie = self.inv_n32 * e_m;
        let y = d_rad * (self.f_l + 0.5 * self.f_ll * d_rad) - ie + 0.5 * ie * ie;
        self.lon_f32 + self.lon_f32 * expm1_2(y)
    }
}

/// Quaternion `[w, x, y, z]` in single precision.
type Q32 = [f32; 4];

/// The quaternion product `a b`.
fn qmul32(a: Q32, b: Q32) -> Q32 {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    [
        aw * bw - (ax * bx + ay * by + az * bz),
        aw * bx + ax * bw + (ay * bz - az * by),
        aw * by + ay * bw + (az * bx - ax * bz),
        aw * bz + az * bw + (ax * by - ay * bx),
    ]
}

fn qadd32(a: Q32, b: Q32) -> Q32 {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    [aw + bw, ax + bx, ay + by, az + bz]
}

fn qdot32(a: Q32, b: Q32) -> f32 {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    aw * bw + ax * bx + ay * by + az * bz
}

/// `d` with `(1 + d)` the quaternion of the body rotation vector `phi` (rad): `(0, k phi)` with
/// `k = tan(|phi|/2)/|phi|` for small angles (the unnormalised `(1, t)` form, normalised with
/// the attitude), the exact `(cos(a/2) - 1, sin(a/2)/a phi)` otherwise.
fn body_delta32(phi: V32) -> Q32 {
    let [px, py, pz] = phi;
    let a2 = px * px + py * py + pz * pz;
    if a2 < SMALL_ROT2_RAD2 {
        // tan(a/2)/a = 1/2 + a^2/24 + a^4/240 + ... (next term below 1e-10 relative here)
        let k = 0.5 + a2 * (1.0 / 24.0 + a2 * (1.0 / 240.0));
        [0.0, px * k, py * k, pz * k]
    } else {
        let a = libm::sqrtf(a2);
        let s4 = libm::sinf(0.25 * a);
        let k = libm::sinf(0.5 * a) / a;
        [-2.0 * s4 * s4, px * k, py * k, pz * k]
    }
}

impl Strapdown {
    /// Integrates one IMU sample given in single precision: increments `dtheta_rad` (rad) and
    /// `dv_mps` (m/s) over (state.t_s, `t_s`], already corrected for the estimated sensor
    /// errors. The same algorithm as [`Strapdown::update`] (the algorithm notes there), with
    /// every term of the step computed in `f32` and only the nominal state's sums in `f64`:
    /// `t`, `lat += dlat`, `lon += dlon`, `h += dh`, `v += dv_n` and `q += dq` (the attitude
    /// increment `dq`, including the normalisation, in `f32`). On a single-precision FPU this
    /// costs about 13 software `f64` additions per step instead of ~170 `f64` operations; the
    /// accuracy cost is stated in `docs/precision.md`. On error the state is unchanged.
    ///
    /// The quaternion is kept at unit norm to about 1e-7 (the `f32` rounding of the norm
    /// computed from the rounded quaternion; a norm error scales, it does not rotate).
    pub fn update_single(
        &mut self,
        t_s: f64,
        dtheta_rad: [f32; 3],
        dv_mps: [f32; 3],
    ) -> Result<StepInfo32, MechError> {
        if !(t_s.is_finite() && dtheta_rad.iter().chain(&dv_mps).all(|x| x.is_finite())) {
            return Err(MechError::NonFinite);
        }
        let dt = t_s - self.state.t_s;
        if !(dt > 0.0 && dt <= MAX_DT_S) {
            return Err(MechError::BadTimeStep);
        }
        let dt32 = dt as f32;
        let hdt32 = 0.5 * dt32;

        // 1. Body frame: coning, rotation compensation and sculling (the terms of `update`).
        let (dth32, dv32) = (dtheta_rad, dv_mps);
        let BodyTerms { dv_corr, phi32, .. } = self.body_terms(dth32, dv32, dt32);
        let dv_b = add32(dv32, dv_corr);

        let s = self.state;
        let q = *s.q_nb.quaternion();
        let q32: Q32 = [q.w as f32, q.i as f32, q.j as f32, q.k as f32];
        let v0 = to32(&s.vel_ned_mps);

        // 2. Body increment in n(t_{k-1}), mid-interval extrapolation, earth quantities there.
        let dv_n0 = rotate32(q32, dv_b);
        let mut d0 = (s.pos.lat_rad - self.earth.lat_rad) as f32;
        let mut e0 = (s.pos.h_m - self.earth.h_m) as f32;
        if !(d0.abs() <= self.earth.lat_tol_rad && e0.abs() <= EARTH_REF_H_TOL_M) {
            self.earth = EarthRef::new(s.pos.lat_rad, s.pos.h_m);
            d0 = 0.0;
            e0 = 0.0;
        }
        let er = self.earth;
        let half_dv = scale32(add32(dv_n0, scale32(self.accel_ng_mps2, dt32)), 0.5);
        let v_mid = add32(v0, half_dv);
        let d_mid = d0 + hdt32 * v_mid[0] * er.inv_m32;
        let e_mid = e0 - hdt32 * v_mid[2];
        let e = er.at32(d_mid, e_mid);
        let w_en = transport_rate32(&e, v_mid);

        // 3. Velocity: navigation-frame rotation, gravity and Coriolis at mid-interval.
        let zeta = scale32(add32([e.w_cos, 0.0, -e.w_sin], w_en), dt32);
        let dv_n = add32(dv_n0, scale32(cross32(zeta, dv_n0), -0.5));
        let w2 = [2.0 * e.w_cos + w_en[0], w_en[1], -2.0 * e.w_sin + w_en[2]];
        let [cx, cy, cz] = cross32(w2, v_mid);
        let a_ng = [-cx, -cy, e.g - cz];
        let dvel = add32(dv_n, scale32(a_ng, dt32));
        let v1 = plus32(&s.vel_ned_mps.into(), dvel);

        // 4. Position: height, then latitude, then longitude (trapezoid velocity).
        let [yn, ye, yd] = scale32(add32(v0, scale32(dvel, 0.5)), dt32);
        let h1 = s.pos.h_m - f64::from(yd);
        let e_bar = e0 - 0.5 * yd;
        let dlat = yn * er.inv_meridian32(d_mid, e_bar);
        let lat1 = s.pos.lat_rad + f64::from(dlat);
        let d_bar = d0 + 0.5 * dlat;
        let dlon = ye * er.lon_factor32(d_bar, e_bar);
        let lon1 = s.pos.lon_rad + f64::from(dlon);

        // 5. Attitude: q1 = (1 + n) q (1 + d), n = (0, -zeta'/2) the navigation frame's
        //    rotation (earth rate and the transport rate of v_bar, from the position
        //    increments), d the body rotation; the increment q1 - q in f32, normalised.
        let wh = (earth::OMEGA_IE_RADPS as f32) * hdt32 + 0.5 * dlon;
        let n = [0.0, -(e.cos * wh), 0.5 * dlat, e.sin * wh];
        let d1 = qmul32(q32, body_delta32(phi32));
        let dq = qadd32(d1, qadd32(qmul32(n, q32), qmul32(n, d1)));
        // |q + dq|^2 - 1, and the increment of the normalisation (q + dq)(f - 1)
        let x = (qdot32(q32, q32) - 1.0) + (2.0 * qdot32(q32, dq) + qdot32(dq, dq));
        let f1 = if x.abs() < SMALL_NORM_ERR as f32 {
            // (1 + x)^(-1/2) - 1 = -x/2 + 3x^2/8 - 5x^3/16
            x * (-0.5 + x * (0.375 - 0.3125 * x))
        } else {
            1.0 / libm::sqrtf(1.0 + x) - 1.0
        };
        let [a, b, c, d] = qadd32(dq, scale_q32(qadd32(q32, dq), f1));
        let q1 = Quaternion::new(
            q.w + f64::from(a),
            q.i + f64::from(b),
            q.j + f64::from(c),
            q.k + f64::from(d),
        );

        self.state = NavState {
            t_s,
            pos: Llh {
                lat_rad: lat1,
                lon_rad: lon1,
                h_m: h1,
            },
            vel_ned_mps: v1,
            q_nb: UnitQuaternion::new_unchecked(q1),
        };
        self.prev_dtheta_rad = dth32;
        self.prev_dv_mps = dv32;
        self.prev_dt_s = dt32;
        self.have_prev = true;
        self.accel_ng_mps2 = a_ng;
        let inv_dt = 1.0 / dt32;
        Ok(StepInfo32 {
            dt_s: dt,
            f_body_mps2: scale32(dv32, inv_dt),
            omega_ib_body_radps: scale32(dth32, inv_dt),
            f_ned_mps2: scale32(dv_n, inv_dt),
        })
    }
}

fn scale_q32(q: Q32, k: f32) -> Q32 {
    q.map(|v| v * k)
}

/// Transport rate omega_en^n (rad/s) for NED velocity `v` (m/s), single precision.
fn transport_rate32(e: &Local32, v: V32) -> V32 {
    let [vn, ve, _] = v;
    let a = ve * e.inv_n;
    [a, -vn * e.inv_m, -a * e.tan]
}
