//! Plain data types shared by every layer: IMU samples, GNSS fixes and navigation solutions.
//! They hold plain arrays (no matrices) so the wire codec, file readers and the firmware can
//! all use them unchanged.

/// One IMU sample: angle and velocity increments over the interval (t_prev, t_s], FRD body
/// axes, as in the KF-GINS IMU text format.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ImuSample {
    /// GPS seconds of week at the END of the interval, s.
    pub t_s: f64,
    /// Angle increments (x, y, z), rad.
    pub dtheta_rad: [f64; 3],
    /// Velocity increments (x, y, z), m/s.
    pub dv_mps: [f64; 3],
    /// Sensor temperature, degrees Celsius; NaN when the source has none.
    pub temperature_c: f64,
}

impl ImuSample {
    /// True when time and all six increments are finite (temperature may be NaN: absent).
    pub fn is_finite(&self) -> bool {
        self.t_s.is_finite()
            && self.dtheta_rad.iter().all(|v| v.is_finite())
            && self.dv_mps.iter().all(|v| v.is_finite())
    }

    /// Whether the sample carries a temperature.
    pub fn has_temperature(&self) -> bool {
        self.temperature_c.is_finite()
    }

    /// The sample as 8 values in a fixed order: time (s), angle increments x, y, z (rad),
    /// velocity increments x, y, z (m/s), temperature (degC, NaN when absent). The inverse of
    /// [`ImuSample::from_values`] (bit for bit).
    pub fn to_values(&self) -> [f64; 8] {
        let [a0, a1, a2] = self.dtheta_rad;
        let [v0, v1, v2] = self.dv_mps;
        [self.t_s, a0, a1, a2, v0, v1, v2, self.temperature_c]
    }

    /// The sample from the 8 values of [`ImuSample::to_values`] (same order and units).
    pub fn from_values(v: [f64; 8]) -> Self {
        let [t_s, a0, a1, a2, v0, v1, v2, temperature_c] = v;
        Self {
            t_s,
            dtheta_rad: [a0, a1, a2],
            dv_mps: [v0, v1, v2],
            temperature_c,
        }
    }
}

/// Quality of a GNSS fix (RTKLIB's Q flag order: lower is better).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FixQuality {
    /// RTK with fixed ambiguities (RTKLIB Q = 1).
    RtkFixed = 1,
    /// RTK with float ambiguities (RTKLIB Q = 2).
    RtkFloat = 2,
    /// SBAS (RTKLIB Q = 3).
    Sbas = 3,
    /// Differential GNSS (RTKLIB Q = 4).
    Dgnss = 4,
    /// Single point positioning (RTKLIB Q = 5).
    #[default]
    Single = 5,
    /// Precise point positioning (RTKLIB Q = 6).
    Ppp = 6,
    /// No fix: the record carries no usable position.
    NoFix = 0,
}

impl FixQuality {
    /// The quality from RTKLIB's Q flag (1 fix, 2 float, 3 SBAS, 4 DGPS, 5 single, 6 PPP).
    pub fn from_rtklib_q(q: u8) -> Self {
        match q {
            1 => Self::RtkFixed,
            2 => Self::RtkFloat,
            3 => Self::Sbas,
            4 => Self::Dgnss,
            5 => Self::Single,
            6 => Self::Ppp,
            _ => Self::NoFix,
        }
    }

    /// RTKLIB's Q flag for this quality (0 for no fix).
    pub fn rtklib_q(self) -> u8 {
        self as u8
    }
}

/// One GNSS fix: antenna position (and optionally velocity) with standard deviations.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GnssFix {
    /// GPS seconds of week of the fix, s.
    pub t_s: f64,
    /// Geodetic latitude of the antenna, rad.
    pub lat_rad: f64,
    /// Longitude of the antenna, rad.
    pub lon_rad: f64,
    /// Ellipsoidal height of the antenna, m.
    pub h_m: f64,
    /// Position standard deviations north, east, down, m.
    pub pos_std_ned_m: [f64; 3],
    /// NED velocity, m/s, when `has_velocity`.
    pub vel_ned_mps: [f64; 3],
    /// Velocity standard deviations north, east, down, m/s, when `has_velocity`.
    pub vel_std_ned_mps: [f64; 3],
    /// Whether `vel_ned_mps` and `vel_std_ned_mps` are valid.
    pub has_velocity: bool,
    /// Fix quality.
    pub quality: FixQuality,
    /// Number of satellites used (0 when unknown).
    pub num_sats: u8,
}

impl GnssFix {
    /// True when time, position and standard deviations are finite and the deviations positive
    /// (and, when present, velocity too).
    pub fn is_valid(&self) -> bool {
        let pos_ok = self.t_s.is_finite()
            && self.lat_rad.is_finite()
            && self.lon_rad.is_finite()
            && self.h_m.is_finite()
            && self.pos_std_ned_m.iter().all(|s| s.is_finite() && *s > 0.0);
        let vel_ok = !self.has_velocity
            || (self.vel_ned_mps.iter().all(|v| v.is_finite())
                && self
                    .vel_std_ned_mps
                    .iter()
                    .all(|s| s.is_finite() && *s > 0.0));
        pos_ok && vel_ok && self.quality != FixQuality::NoFix
    }
}

/// A navigation solution at one epoch (IMU reference point), as written in the nav format
/// `week sow lat_deg lon_deg h_m vn ve vd roll_deg pitch_deg yaw_deg`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct NavSolution {
    /// GPS week number.
    pub week: u16,
    /// GPS seconds of week, s.
    pub t_s: f64,
    /// Geodetic latitude, rad.
    pub lat_rad: f64,
    /// Longitude, rad.
    pub lon_rad: f64,
    /// Ellipsoidal height, m.
    pub h_m: f64,
    /// NED velocity, m/s.
    pub vel_ned_mps: [f64; 3],
    /// Roll, pitch, yaw (ZYX Euler angles, body FRD relative to NED), rad.
    pub rpy_rad: [f64; 3],
    /// Position standard deviations north, east, down, m (NaN when unknown).
    pub pos_std_ned_m: [f64; 3],
    /// Velocity standard deviations north, east, down, m/s (NaN when unknown).
    pub vel_std_ned_mps: [f64; 3],
    /// Attitude standard deviations roll, pitch, yaw, rad (NaN when unknown).
    pub att_std_rad: [f64; 3],
    /// Filter status bits (0 = nominal); meaning defined by the filter.
    pub status: u32,
}
