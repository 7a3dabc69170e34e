use super::*;

/// The previous implementation of [`Strapdown`]'s algorithm, every term in `f64`.
#[derive(Debug, Clone, Copy)]
pub(super) struct PlainStrapdown {
    state: NavState,
    prev_dtheta_rad: Vector3<f64>,
    prev_dv_mps: Vector3<f64>,
    prev_dt_s: f64,
    have_prev: bool,
    /// Gravity minus Coriolis/centripetal acceleration in NED of the last step, m/s^2 (only for
    /// the mid-interval extrapolation).
    accel_ng_mps2: Vector3<f64>,
    /// Meridian radius of curvature of the last step, m (only for the extrapolation).
    meridian_m: f64,
}

/// Earth quantities at one latitude and height, computed from one `sin` / `cos` / `sqrt`.
#[derive(Debug, Clone, Copy)]
struct EarthAt {
    sin_lat: f64,
    cos_lat: f64,
    /// Meridian radius of curvature R_M, m.
    meridian_m: f64,
    /// Transverse radius of curvature R_N, m.
    transverse_m: f64,
    /// Normal gravity magnitude, m/s^2.
    gravity_mps2: f64,
}

impl EarthAt {
    /// The same formulas as [`earth::radii`] and [`earth::gravity_mps2`] (checked against them
    /// in the tests), sharing the trigonometry and the square root.
    fn new(lat_rad: f64, h_m: f64) -> Self {
        let sin_lat = sin(lat_rad);
        let cos_lat = cos(lat_rad);
        let s2 = sin_lat * sin_lat;
        let d = 1.0 - earth::E2 * s2;
        let sd = sqrt(d);
        let transverse_m = earth::A_M / sd;
        let meridian_m = earth::A_M * (1.0 - earth::E2) / (d * sd);
        let g0 = earth::GAMMA_E_MPS2 * (1.0 + earth::SOMIGLIANA_K * s2) / sd;
        let gravity_mps2 = g0
            * (1.0
                - 2.0 / earth::A_M * (1.0 + earth::F + earth::M_RATIO - 2.0 * earth::F * s2) * h_m
                + 3.0 * h_m * h_m / (earth::A_M * earth::A_M));
        Self {
            sin_lat,
            cos_lat,
            meridian_m,
            transverse_m,
            gravity_mps2,
        }
    }

    /// Earth rate in NED, rad/s.
    fn earth_rate(&self) -> Vector3<f64> {
        Vector3::new(
            earth::OMEGA_IE_RADPS * self.cos_lat,
            0.0,
            -earth::OMEGA_IE_RADPS * self.sin_lat,
        )
    }

    /// Transport rate in NED (rad/s) for velocity `v` (m/s) at height `h_m`.
    fn transport_rate(&self, h_m: f64, v: &Vector3<f64>) -> Vector3<f64> {
        let inv_rn = 1.0 / (self.transverse_m + h_m);
        let inv_rm = 1.0 / (self.meridian_m + h_m);
        Vector3::new(
            v.y * inv_rn,
            -v.x * inv_rm,
            -v.y * inv_rn * self.sin_lat / self.cos_lat,
        )
    }
}

/// Gravity minus Coriolis and centripetal acceleration in NED, m/s^2.
fn accel_ng(
    g_mps2: f64,
    w_ie: &Vector3<f64>,
    w_en: &Vector3<f64>,
    v: &Vector3<f64>,
) -> Vector3<f64> {
    Vector3::new(0.0, 0.0, g_mps2) - (w_ie * 2.0 + w_en).cross(v)
}

impl PlainStrapdown {
    /// Starts the mechanization from `state`.
    pub(super) fn new(state: NavState) -> Self {
        let e = EarthAt::new(state.pos.lat_rad, state.pos.h_m);
        let w_ie = e.earth_rate();
        let w_en = e.transport_rate(state.pos.h_m, &state.vel_ned_mps);
        Self {
            state,
            prev_dtheta_rad: Vector3::zeros(),
            prev_dv_mps: Vector3::zeros(),
            prev_dt_s: 0.0,
            have_prev: false,
            accel_ng_mps2: accel_ng(e.gravity_mps2, &w_ie, &w_en, &state.vel_ned_mps),
            meridian_m: e.meridian_m,
        }
    }

    /// The current nominal state.
    pub(super) fn state(&self) -> &NavState {
        &self.state
    }

    /// Integrates one IMU sample (already corrected for the estimated sensor errors) over
    /// (state.t_s, imu.t_s]. On error the state is unchanged.
    pub(super) fn update(&mut self, imu: &ImuSample) -> Result<StepInfo, MechError> {
        if !imu.is_finite() {
            return Err(MechError::NonFinite);
        }
        let dt = imu.t_s - self.state.t_s;
        if !(dt > 0.0 && dt <= MAX_DT_S) {
            return Err(MechError::BadTimeStep);
        }
        let dth = Vector3::from(imu.dtheta_rad);
        let dv = Vector3::from(imu.dv_mps);

        // 1. Body frame: coning, rotation compensation and sculling (two-sample, previous
        //    interval). Without a usable previous sample the two-sample terms are dropped.
        let use_prev = self.have_prev && dt <= 2.0 * self.prev_dt_s && self.prev_dt_s <= 2.0 * dt;
        let (phi_b, dv_b) = if use_prev {
            (
                dth + attitude::coning_correction(&self.prev_dtheta_rad, &dth),
                attitude::sculled_dv(&self.prev_dtheta_rad, &self.prev_dv_mps, &dth, &dv),
            )
        } else {
            (
                dth,
                attitude::sculled_dv(&Vector3::zeros(), &Vector3::zeros(), &dth, &dv),
            )
        };

        let s = self.state;
        let (lat0, lon0, h0) = (s.pos.lat_rad, s.pos.lon_rad, s.pos.h_m);
        let v0 = s.vel_ned_mps;

        // 2. Body increment in n(t_{k-1}); mid-interval extrapolation of v, h, lat.
        let dv_n0 = s.q_nb * dv_b;
        let v_mid = v0 + (dv_n0 + self.accel_ng_mps2 * dt) * 0.5;
        let h_mid = h0 - 0.5 * v_mid.z * dt;
        let lat_mid = lat0 + 0.5 * dt * v_mid.x / (self.meridian_m + h_mid);
        let e = EarthAt::new(lat_mid, h_mid);
        let w_ie = e.earth_rate();
        let w_en = e.transport_rate(h_mid, &v_mid);

        // 3. Velocity: navigation-frame rotation over the interval, gravity, Coriolis.
        let zeta = (w_ie + w_en) * dt;
        let dv_n = dv_n0 - zeta.cross(&dv_n0) * 0.5;
        let a_ng = accel_ng(e.gravity_mps2, &w_ie, &w_en, &v_mid);
        let v1 = v0 + dv_n + a_ng * dt;

        // 4. Position: height, then latitude, then longitude (trapezoid velocity, mid radii).
        let v_bar = (v0 + v1) * 0.5;
        let h1 = h0 - v_bar.z * dt;
        let h_bar = 0.5 * (h0 + h1);
        let lat1 = lat0 + v_bar.x * dt / (e.meridian_m + h_bar);
        // cos of the true mid latitude, to first order around the extrapolated one.
        let cos_bar = e.cos_lat - e.sin_lat * (0.5 * (lat0 + lat1) - lat_mid);
        let lon1 = lon0 + v_bar.y * dt / ((e.transverse_m + h_bar) * cos_bar);

        // 5. Attitude: body rotation, then the navigation frame's rotation (with v_bar).
        let zeta_att = (w_ie + e.transport_rate(h_bar, &v_bar)) * dt;
        let q_bb = attitude::quat_from_rotvec(&phi_b);
        let q_nn = attitude::quat_from_rotvec(&(-zeta_att));
        let q = q_nn.quaternion() * s.q_nb.quaternion() * q_bb.quaternion();
        let q_nb = UnitQuaternion::new_unchecked(attitude::renormalized(q));

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
        self.prev_dtheta_rad = dth;
        self.prev_dv_mps = dv;
        self.prev_dt_s = dt;
        self.have_prev = true;
        self.accel_ng_mps2 = a_ng;
        self.meridian_m = e.meridian_m;
        Ok(StepInfo {
            dt_s: dt,
            f_body_mps2: dv / dt,
            omega_ib_body_radps: dth / dt,
            f_ned_mps2: dv_n / dt,
        })
    }
}
