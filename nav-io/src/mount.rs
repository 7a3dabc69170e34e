//! IMU mounting rotation: from the IMU's sensor axes to the body (FRD) axes.
//!
//! Convention: `rpy_deg = [roll, pitch, yaw]` are ZYX Euler angles of the body-to-IMU rotation
//! `C_b^imu = Rz(yaw) Ry(pitch) Rx(roll)` (the same form as the attitude C_b^n, with the IMU
//! frame in the role of the navigation frame). Vectors measured in IMU axes map to body axes
//! with the transpose: `x_b = (C_b^imu)^T x_imu`. This is the convention of rtklibexplorer's
//! GNSS_IMU (`C_imu_misalign = Euler_to_CTM(imu_misalign)`, Groves' C_beta^alpha, applied as
//! `C_imu_misalign @ meas`).
//!
//! `then_rpy_deg` lists further rotations composed on the right:
//! `C_b^imu = R(rpy_deg) R(then[0]) R(then[1]) ...`, i.e. a coarse orientation followed by small
//! corrections expressed in the coarsely-rotated frame.
//!
//! Beware: GNSS_IMU ADDS Euler angles (`imu_misalign = [180, 0, 180] + [0, -6.79, 5.35]`),
//! which is not a composition. For that drive the sum `[180, -6.79, 185.35]` equals the
//! composition `[180, 0, 180]` then `[0, +6.79, -5.35]` (the 180 deg roll flips the y and z
//! axes of the correction). `configs/drive0708.toml` uses the sum.

use nalgebra::{Matrix3, Vector3};
use nav_core::attitude::dcm_from_euler_zyx;
use nav_core::types::ImuSample;

use super::imucsv::RawImuSample;

/// Mounting of the IMU in the body (see the module notes for the convention).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Mounting {
    /// Body-to-IMU rotation as ZYX Euler angles [roll, pitch, yaw], deg.
    pub rpy_deg: [f64; 3],
    /// Further rotations composed on the right, each [roll, pitch, yaw] deg.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub then_rpy_deg: Vec<[f64; 3]>,
}

impl Default for Mounting {
    fn default() -> Self {
        Self::identity()
    }
}

impl Mounting {
    /// No rotation: IMU axes are the body axes.
    pub fn identity() -> Self {
        Self {
            rpy_deg: [0.0; 3],
            then_rpy_deg: Vec::new(),
        }
    }

    /// A single body-to-IMU rotation.
    pub fn from_rpy_deg(rpy_deg: [f64; 3]) -> Self {
        Self {
            rpy_deg,
            then_rpy_deg: Vec::new(),
        }
    }

    /// Whether every angle is finite.
    pub fn is_finite(&self) -> bool {
        self.rpy_deg
            .iter()
            .chain(self.then_rpy_deg.iter().flatten())
            .all(|v| v.is_finite())
    }

    /// C_b^imu (body-to-IMU DCM).
    pub fn c_b_imu(&self) -> Matrix3<f64> {
        let r = |a: &[f64; 3]| {
            dcm_from_euler_zyx([a[0].to_radians(), a[1].to_radians(), a[2].to_radians()])
        };
        self.then_rpy_deg
            .iter()
            .fold(r(&self.rpy_deg), |c, a| c * r(a))
    }

    /// C_imu^b: the matrix that maps IMU-axis vectors to body axes.
    pub fn c_imu_b(&self) -> Matrix3<f64> {
        self.c_b_imu().transpose()
    }

    /// A vector in IMU axes expressed in body axes.
    pub fn to_body(&self, v_imu: [f64; 3]) -> [f64; 3] {
        let v = self.c_imu_b() * Vector3::from(v_imu);
        [v.x, v.y, v.z]
    }

    /// Rotates increments (angle and velocity) from IMU to body axes in place. Exact for a
    /// constant mounting: the increments are integrals of vectors in a fixed frame.
    pub fn rotate_increments(&self, samples: &mut [ImuSample]) {
        let c = self.c_imu_b();
        for s in samples {
            let a = c * Vector3::from(s.dtheta_rad);
            let v = c * Vector3::from(s.dv_mps);
            s.dtheta_rad = [a.x, a.y, a.z];
            s.dv_mps = [v.x, v.y, v.z];
        }
    }

    /// Rotates raw rates and specific forces from IMU to body axes in place.
    pub fn rotate_raw(&self, samples: &mut [RawImuSample]) {
        let c = self.c_imu_b();
        for s in samples {
            let w = c * Vector3::from(s.gyro_radps);
            let f = c * Vector3::from(s.accel_mps2);
            s.gyro_radps = [w.x, w.y, w.z];
            s.accel_mps2 = [f.x, f.y, f.z];
        }
    }
}
