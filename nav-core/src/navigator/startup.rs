//! Start-up helpers of the [`super::Navigator`]: the levelling mean, the static window's fix
//! mean and the configuration probe.

use crate::config::FilterConfig;
use crate::earth::{self, Llh};
use crate::filter::{Filter, FilterError, InitialUncertainty};
use crate::model::Layout;
use crate::scalar::Scalar;
use crate::strapdown::{NavState, MAX_DT_S};
use crate::types::{GnssFix, ImuSample};
use nalgebra::Vector3;

/// Running mean of the specific force before a first-fix start (levelling).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(super) struct Leveller {
    sum_dv_mps: [f64; 3],
    sum_dt_s: f64,
    intervals: u32,
}

impl Leveller {
    pub(super) fn add(&mut self, s: &ImuSample, last_t_s: Option<f64>) {
        if let Some(t0) = last_t_s {
            let dt = s.t_s - t0;
            if dt > 0.0 && dt <= MAX_DT_S {
                for (a, d) in self.sum_dv_mps.iter_mut().zip(s.dv_mps) {
                    *a += d;
                }
                self.sum_dt_s += dt;
                self.intervals = self.intervals.saturating_add(1);
            }
        }
    }

    /// Roll and pitch, rad, from the mean specific force (at rest f = -C_n^b g).
    pub(super) fn roll_pitch_rad(&self) -> [f64; 2] {
        if self.sum_dt_s <= 0.0 {
            return [0.0, 0.0];
        }
        let [fx, fy, fz] = self.sum_dv_mps.map(|v| v / self.sum_dt_s);
        let roll = libm::atan2(-fy, -fz);
        let pitch = libm::atan2(fx, libm::sqrt(fy * fy + fz * fz));
        [roll, pitch]
    }

    /// Mean interval, s.
    pub(super) fn mean_dt_s(&self) -> Option<f64> {
        (self.intervals > 0).then(|| self.sum_dt_s / f64::from(self.intervals))
    }
}

/// Mean antenna position of the fixes of a static window.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(super) struct FixMean {
    ref0: Option<Llh>,
    sum_off_m: [f64; 3],
    sum_std_m: [f64; 3],
    n: u32,
}

impl FixMean {
    pub(super) fn add(&mut self, g: &GnssFix) {
        let p = Llh {
            lat_rad: g.lat_rad,
            lon_rad: g.lon_rad,
            h_m: g.h_m,
        };
        let r = *self.ref0.get_or_insert(p);
        let d = earth::ned_offset_m(&r, &p);
        for (s, v) in self.sum_off_m.iter_mut().zip(d.iter()) {
            *s += v;
        }
        for (s, v) in self.sum_std_m.iter_mut().zip(g.pos_std_ned_m) {
            *s += v;
        }
        self.n = self.n.saturating_add(1);
    }

    /// Mean position and mean NED 1-sigma.
    pub(super) fn mean(&self) -> Option<(Llh, [f64; 3])> {
        let r = self.ref0?;
        let n = f64::from(self.n);
        let off = Vector3::from(self.sum_off_m) / n;
        Some((earth::displace(&r, &off), self.sum_std_m.map(|s| s / n)))
    }
}

/// Whether a filter accepts `layout` and `cfg` (its checks at a neutral state, no filter is
/// built).
#[inline(never)]
pub(super) fn check_config<T: Scalar, const N: usize>(
    layout: Layout,
    cfg: &FilterConfig,
) -> Result<(), FilterError> {
    let probe = NavState::from_rpy(
        0.0,
        Llh {
            lat_rad: 0.0,
            lon_rad: 0.0,
            h_m: 0.0,
        },
        Vector3::zeros(),
        [0.0; 3],
    );
    let unc = InitialUncertainty {
        att_sigma_rad: [1.0; 3],
        vel_sigma_mps: [1.0; 3],
        pos_sigma_m: [1.0; 3],
    };
    Filter::<T, N>::check_new(&layout, cfg, &probe, &unc)
}
