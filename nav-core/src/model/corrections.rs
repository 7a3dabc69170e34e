//! The IMU correction applied before mechanisation ([`ImuCorrection`], the inverse of the
//! sensor model in the [module notes](super)) and its reciprocal scales.

use super::*;

/// The IMU error estimates applied to a raw sample before mechanisation (the inverse of the
/// sensor model in the module docs), per sample with `dT = T - T_ref` (0 without a
/// temperature):
///
/// ```text
/// f = (I + diag(s_a) + M_a)^-1 (f_meas - b_a - k_a dT)
/// w = (I + diag(s_g) + M_g)^-1 (w_meas - b_g - k_g dT - diag(g_s) f)
/// ```
///
/// applied to the increments (`f dt = dv`, `w dt = dtheta`). With no misalignment,
/// temperature coefficient or g-sensitivity (all zero) it reduces to the per-axis
/// `(x_meas - b)/(1 + s)`, computed exactly as before these were added.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ImuCorrection {
    /// Accelerometer bias, m/s^2.
    pub accel_bias_mps2: [f64; 3],
    /// Gyro bias, rad/s.
    pub gyro_bias_radps: [f64; 3],
    /// Accelerometer scale-factor error (dimensionless).
    pub accel_scale: [f64; 3],
    /// Gyro scale-factor error (dimensionless).
    pub gyro_scale: [f64; 3],
    /// Accelerometer misalignment `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`, rad.
    pub accel_misalignment_rad: [f64; 6],
    /// Gyro misalignment `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`, rad.
    pub gyro_misalignment_rad: [f64; 6],
    /// Accelerometer bias temperature coefficient, m/s^2/degC.
    pub accel_temp_coeff_mps2_per_c: [f64; 3],
    /// Gyro bias temperature coefficient, rad/s/degC.
    pub gyro_temp_coeff_radps_per_c: [f64; 3],
    /// Reference temperature of the coefficients, degC (NaN: none yet, zero regressor).
    pub temperature_ref_c: f64,
    /// Diagonal gyro g-sensitivity, rad/s per m/s^2.
    pub gyro_g_sensitivity_radps_per_mps2: [f64; 3],
}

impl ImuCorrection {
    /// Corrects increments over `dt_s` seconds in place, without a temperature (the
    /// temperature terms are zero; use [`Self::apply_with_temperature`] for samples that carry
    /// one).
    pub fn apply(&self, dtheta_rad: &mut [f64; 3], dv_mps: &mut [f64; 3], dt_s: f64) {
        self.apply_with(&self.inverse_scales(), dtheta_rad, dv_mps, dt_s, f64::NAN);
    }

    /// Corrects increments over `dt_s` seconds of a sample taken at `temperature_c` degC (NaN:
    /// none) in place.
    pub fn apply_with_temperature(
        &self,
        dtheta_rad: &mut [f64; 3],
        dv_mps: &mut [f64; 3],
        dt_s: f64,
        temperature_c: f64,
    ) {
        self.apply_with(
            &self.inverse_scales(),
            dtheta_rad,
            dv_mps,
            dt_s,
            temperature_c,
        );
    }

    /// Whether any misalignment, temperature coefficient or g-sensitivity is non-zero (then
    /// the general correction is needed).
    pub fn is_general(&self) -> bool {
        let nz = |a: &[f64]| a.iter().any(|v| *v != 0.0);
        nz(&self.accel_misalignment_rad)
            || nz(&self.gyro_misalignment_rad)
            || nz(&self.accel_temp_coeff_mps2_per_c)
            || nz(&self.gyro_temp_coeff_radps_per_c)
            || nz(&self.gyro_g_sensitivity_radps_per_mps2)
    }

    /// `1 / (1 + s)` for the gyro and accelerometer scale-factor errors and, when
    /// [`Self::is_general`], what the general correction needs: `(I + diag(s) + M)^-1 - I`
    /// and the bias, temperature and g-sensitivity terms in `f32` (computed once per change of
    /// the estimates, so the per-epoch correction needs no division).
    pub fn inverse_scales(&self) -> InverseScales {
        let general = self.is_general();
        let delta = |s: &[f64; 3], m: &[f64; 6]| {
            if !general {
                return [[0.0f32; 3]; 3];
            }
            let a = effects::sensor_matrix(s, m);
            // the matrix is I + O(1e-3): invertible; identity only if the estimates are absurd
            let inv = effects::inv3(&a).unwrap_or(IDENTITY3);
            let mut d = [[0.0f32; 3]; 3];
            for (i, (drow, irow)) in d.iter_mut().zip(&inv).enumerate() {
                for (j, (x, v)) in drow.iter_mut().zip(irow).enumerate() {
                    *x = (*v - if i == j { 1.0 } else { 0.0 }) as f32;
                }
            }
            d
        };
        let f32s = |a: &[f64; 3]| a.map(|v| v as f32);
        let gyro = self.gyro_scale.map(|s| 1.0 / (1.0 + s));
        let accel = self.accel_scale.map(|s| 1.0 / (1.0 + s));
        InverseScales {
            gyro,
            accel,
            gyro32: f32s(&gyro),
            accel32: f32s(&accel),
            general,
            gyro_delta: delta(&self.gyro_scale, &self.gyro_misalignment_rad),
            accel_delta: delta(&self.accel_scale, &self.accel_misalignment_rad),
            gyro_bias: f32s(&self.gyro_bias_radps),
            accel_bias: f32s(&self.accel_bias_mps2),
            gyro_temp: f32s(&self.gyro_temp_coeff_radps_per_c),
            accel_temp: f32s(&self.accel_temp_coeff_mps2_per_c),
            g_sens: f32s(&self.gyro_g_sensitivity_radps_per_mps2),
        }
    }

    /// [`Self::apply`] with precomputed [`Self::inverse_scales`] and the sample's temperature,
    /// degC (NaN: none).
    ///
    /// Without misalignment, temperature or g-sensitivity estimates this is the per-axis
    /// `(x - b dt) / (1 + s)` in `f64`. The general correction adds a small `f32` correction to
    /// the `f64` increment, `x_hat = x + c` with `c = -e + D (x - e)` (`e` the bias, temperature
    /// and g-sensitivity terms over the interval, `D = (I + diag(s) + M)^-1 - I`): `c` is about
    /// 1e-3 of the increment, so its `f32` rounding (6e-8 of `c`) is below 1e-10 of the
    /// increment, while on a single-precision FPU it costs a few dozen instructions instead of
    /// the ~60 software `f64` operations of the full product.
    pub fn apply_with(
        &self,
        inv: &InverseScales,
        dtheta_rad: &mut [f64; 3],
        dv_mps: &mut [f64; 3],
        dt_s: f64,
        temperature_c: f64,
    ) {
        if !inv.general {
            for ((d, b), k) in dtheta_rad
                .iter_mut()
                .zip(self.gyro_bias_radps)
                .zip(inv.gyro)
            {
                *d = (*d - b * dt_s) * k;
            }
            for ((d, b), k) in dv_mps.iter_mut().zip(self.accel_bias_mps2).zip(inv.accel) {
                *d = (*d - b * dt_s) * k;
            }
            return;
        }
        let d_t = temperature_c - self.temperature_ref_c;
        let d_t = if d_t.is_finite() { d_t as f32 } else { 0.0 };
        let dt = dt_s as f32;
        // accelerometer: e = (b + k dT) dt
        let mut ea = [0.0f32; 3];
        for ((e, b), k) in ea.iter_mut().zip(inv.accel_bias).zip(inv.accel_temp) {
            *e = (b + k * d_t) * dt;
        }
        let mut ua = [0.0f32; 3];
        for ((u, d), e) in ua.iter_mut().zip(dv_mps.iter()).zip(ea) {
            *u = *d as f32 - e;
        }
        let ca = effects::mat_vec(&inv.accel_delta, &ua);
        let mut dv_hat32 = [0.0f32; 3];
        for (((d, c), e), h) in dv_mps.iter_mut().zip(ca).zip(ea).zip(dv_hat32.iter_mut()) {
            let corr = c - e;
            *h = *d as f32 + corr;
            *d += f64::from(corr);
        }
        // gyro: e = (b + k dT) dt + diag(g_s) dv_hat
        let mut eg = [0.0f32; 3];
        for ((((e, b), k), g), dv) in eg
            .iter_mut()
            .zip(inv.gyro_bias)
            .zip(inv.gyro_temp)
            .zip(inv.g_sens)
            .zip(dv_hat32)
        {
            *e = (b + k * d_t) * dt + g * dv;
        }
        let mut ug = [0.0f32; 3];
        for ((u, d), e) in ug.iter_mut().zip(dtheta_rad.iter()).zip(eg) {
            *u = *d as f32 - e;
        }
        let cg = effects::mat_vec(&inv.gyro_delta, &ug);
        for ((d, c), e) in dtheta_rad.iter_mut().zip(cg).zip(eg) {
            *d += f64::from(c - e);
        }
    }
}

impl ImuCorrection {
    /// [`Self::apply_with`] on single-precision increments (the single-precision
    /// mechanization's input, [`crate::strapdown::Strapdown::update_single`]): the same
    /// corrections, every term in `f32`; `dt_s` in s, `temperature_c` in degC (NaN: none).
    pub fn apply_single(
        &self,
        inv: &InverseScales,
        dtheta_rad: &mut [f32; 3],
        dv_mps: &mut [f32; 3],
        dt_s: f32,
        temperature_c: f64,
    ) {
        if !inv.general {
            for ((d, b), k) in dtheta_rad.iter_mut().zip(inv.gyro_bias).zip(inv.gyro32) {
                *d = (*d - b * dt_s) * k;
            }
            for ((d, b), k) in dv_mps.iter_mut().zip(inv.accel_bias).zip(inv.accel32) {
                *d = (*d - b * dt_s) * k;
            }
            return;
        }
        let d_t = temperature_c - self.temperature_ref_c;
        let d_t = if d_t.is_finite() { d_t as f32 } else { 0.0 };
        // accelerometer: e = (b + k dT) dt; x_hat = x + D (x - e) - e
        let mut ea = [0.0f32; 3];
        for ((e, b), k) in ea.iter_mut().zip(inv.accel_bias).zip(inv.accel_temp) {
            *e = (b + k * d_t) * dt_s;
        }
        let mut ua = [0.0f32; 3];
        for ((u, d), e) in ua.iter_mut().zip(dv_mps.iter()).zip(ea) {
            *u = *d - e;
        }
        let ca = effects::mat_vec(&inv.accel_delta, &ua);
        for ((d, c), e) in dv_mps.iter_mut().zip(ca).zip(ea) {
            *d += c - e;
        }
        // gyro: e = (b + k dT) dt + diag(g_s) dv_hat
        let mut eg = [0.0f32; 3];
        for ((((e, b), k), g), dv) in eg
            .iter_mut()
            .zip(inv.gyro_bias)
            .zip(inv.gyro_temp)
            .zip(inv.g_sens)
            .zip(dv_mps.iter())
        {
            *e = (b + k * d_t) * dt_s + g * *dv;
        }
        let mut ug = [0.0f32; 3];
        for ((u, d), e) in ug.iter_mut().zip(dtheta_rad.iter()).zip(eg) {
            *u = *d - e;
        }
        let cg = effects::mat_vec(&inv.gyro_delta, &ug);
        for ((d, c), e) in dtheta_rad.iter_mut().zip(cg).zip(eg) {
            *d += c - e;
        }
    }
}

/// Reciprocal scale factors `1 / (1 + s)` of an [`ImuCorrection`], and what its general
/// correction needs (in `f32`, see [`ImuCorrection::apply_with`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseScales {
    /// Gyro x, y, z.
    pub gyro: [f64; 3],
    /// Accelerometer x, y, z.
    pub accel: [f64; 3],
    /// Gyro x, y, z rounded to `f32` (for [`ImuCorrection::apply_single`]).
    pub gyro32: [f32; 3],
    /// Accelerometer x, y, z rounded to `f32`.
    pub accel32: [f32; 3],
    /// Whether the general (matrix, temperature, g-sensitivity) correction applies.
    pub general: bool,
    /// `(I + diag(s_g) + M_g)^-1 - I` (row-major; zero when not `general`).
    pub gyro_delta: [[f32; 3]; 3],
    /// `(I + diag(s_a) + M_a)^-1 - I` (row-major; zero when not `general`).
    pub accel_delta: [[f32; 3]; 3],
    /// Gyro bias, rad/s.
    pub gyro_bias: [f32; 3],
    /// Accelerometer bias, m/s^2.
    pub accel_bias: [f32; 3],
    /// Gyro temperature coefficient, rad/s/degC.
    pub gyro_temp: [f32; 3],
    /// Accelerometer temperature coefficient, m/s^2/degC.
    pub accel_temp: [f32; 3],
    /// Gyro g-sensitivity, rad/s per m/s^2.
    pub g_sens: [f32; 3],
}
