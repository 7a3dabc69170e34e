//! The GNSS measurement model (antenna position and velocity residuals and their Jacobians at
//! the current state) and the update of a fix whose velocity has its own gate
//! ([`crate::config::Gating::velocity`]): the position first (3 dimensions, the GNSS gate with
//! its robust monitor and resets), then the velocity (3 dimensions, its own gate and counters),
//! its residual and Jacobian taken again at the state the position update left.
//!
//! Without gates the two sequential updates equal the joint 6-dimensional update (block
//! diagonal R) to first order in the position correction (test
//! `nav-core/tests/it/gnss_velocity_gate.rs`).

use super::gated::Gate;
use super::{dcm_f64, Filter, FilterError, UpdateOutcome};
use crate::config::VelocityGating;
use crate::earth;
use crate::model::{BlockKind, Layout, MeasContext, Rows3};
use crate::scalar::Scalar;
use crate::strapdown::{NavState, StepInfo};
use crate::types::GnssFix;
use nalgebra::Vector3;

/// The GNSS measurement model at the filter's current state for one fix.
pub(super) struct GnssModel<T: Scalar, const N: usize> {
    /// Predicted minus measured antenna position at the fix time, NED m.
    pub zp: [f64; 3],
    /// Predicted minus measured antenna velocity, NED m/s (meaningless without a velocity).
    pub zv: [f64; 3],
    /// Jacobian of the position residual.
    pub h_pos: [[T; N]; 3],
    /// Jacobian of the velocity residual.
    pub h_vel: [[T; N]; 3],
}

impl<T: Scalar, const N: usize> Filter<T, N> {
    /// The residuals and Jacobians of `fix` (`dt_fix` = fix time - filter time, s).
    pub(super) fn gnss_model(&self, fix: &GnssFix, dt_fix: f64) -> GnssModel<T, N> {
        let g = gnss_geometry(
            &GeometryInput {
                nav: *self.mech.state(),
                step: self.last_step,
                lever_arm_body_m: self.lever_arm_body_m(),
                time_offset: self.layout.contains(BlockKind::TimeOffset),
                time_offset_s: self.time_offset_at_s(fix.t_s),
                clock_span_s: fix.t_s - self.clock_ref_s(),
                gnss_error_ned_m: self.gnss_position_error_ned_m(),
                temperature_offset_c: self.last_temperature_c - self.temperature_ref_c,
            },
            fix,
            dt_fix,
        );
        let mut h_pos = [[T::ZERO; N]; 3];
        let mut h_vel = [[T::ZERO; N]; 3];
        gnss_jacobians(
            &self.layout,
            &g.ctx,
            Rows3::new(&mut h_pos),
            Rows3::new(&mut h_vel),
        );
        GnssModel {
            zp: g.zp,
            zv: g.zv,
            h_pos,
            h_vel,
        }
    }

    /// A fix with velocity under [`crate::config::Gating::velocity`]: the position update (the
    /// GNSS gate, its counters, monitor and resets; the returned outcome is its, `dim` 3),
    /// then, unless the position forced a reset (which takes the velocity too), the velocity
    /// update with its own gate, counted in `gnss_vel_*`.
    pub(super) fn update_gnss_separate(
        &mut self,
        fix: &GnssFix,
        dt_fix: f64,
        m: &GnssModel<T, N>,
        rp: &[f64; 3],
        force: bool,
        vg: VelocityGating,
    ) -> Result<UpdateOutcome, FilterError> {
        let rv = fix.vel_std_ned_mps.map(|s| s * s);
        let out = self.kalman_update::<3>(&m.zp, &m.h_pos, rp, force, fix.t_s)?;
        let out = self.after_update(out, &m.zp, rp, out.forced.then_some((m.zv, rv)));
        if out.forced {
            return Ok(out);
        }
        // the velocity residual and Jacobian at the state the position update left
        let mv = self.gnss_model(fix, dt_fix);
        let g = self.gated_update(
            &mv.zv,
            &mv.h_vel,
            &rv,
            Gate {
                downweight: vg.downweight_nis,
                reject: vg.reject_nis,
            },
            None,
        )?;
        let c = &mut self.counters;
        if g.accepted {
            c.gnss_vel_accepted = c.gnss_vel_accepted.saturating_add(1);
            if g.weight < 1.0 {
                c.gnss_vel_downweighted = c.gnss_vel_downweighted.saturating_add(1);
            }
        } else {
            c.gnss_vel_rejected = c.gnss_vel_rejected.saturating_add(1);
        }
        Ok(out)
    }
}

/// The GNSS Jacobians' columns of every block of `layout` (rows zero on entry). Not generic
/// over the state dimension (the rows' column count is a runtime value): one instance per
/// scalar type whatever the filter sizes a binary carries (flash).
#[inline(never)]
fn gnss_jacobians<T: Scalar>(
    layout: &Layout,
    ctx: &MeasContext,
    mut h_pos: Rows3<'_, T>,
    mut h_vel: Rows3<'_, T>,
) {
    for (off, b) in layout.iter() {
        b.gnss_jacobian(off, ctx, &mut h_pos, &mut h_vel);
    }
}

/// What the N-independent part of the GNSS model needs of the filter.
struct GeometryInput {
    nav: NavState,
    step: StepInfo,
    lever_arm_body_m: [f64; 3],
    time_offset: bool,
    time_offset_s: f64,
    clock_span_s: f64,
    gnss_error_ned_m: Option<[f64; 3]>,
    temperature_offset_c: f64,
}

/// The N-independent part of the GNSS model: the residuals and the measurement context.
struct Geometry {
    ctx: MeasContext,
    zp: [f64; 3],
    zv: [f64; 3],
}

/// The residuals and the Jacobians' context of `fix` at the filter's state `inp` (`dt_fix` =
/// fix time - filter time, s). Not generic over the state dimension: one instance whatever
/// the filter sizes a binary carries (flash).
#[inline(never)]
fn gnss_geometry(inp: &GeometryInput, fix: &GnssFix, dt_fix: f64) -> Geometry {
    let nav = &inp.nav;
    let c = dcm_f64(&nav.q_nb);
    let l = Vector3::from(inp.lever_arm_body_m);
    let w = inp.step.omega_ib_body_radps;
    let c_l = c * l;
    let c_w_x_l = c * w.cross(&l);
    let c_lx = c * l.cross_matrix();
    // time offset: the fix is the antenna at IMU time t_fix + dt_hat, tau after this epoch
    let time_offset = inp.time_offset;
    let tau = dt_fix + inp.time_offset_s;
    let lat = nav.pos.lat_rad;
    let v_ant0 = nav.vel_ned_mps + c_w_x_l;
    let acc_n = if time_offset {
        inp.step.f_ned_mps2 + earth::gravity_ned_mps2(lat, nav.pos.h_m)
    } else {
        Vector3::zeros()
    };
    // local curvilinear map (that of `earth::displace` and of the position error; it
    // differs from the exact ECEF offset by d^2/R, 4e-6 m at 5 m) with one sin/cos/sqrt
    let (sl, cl) = (libm::sin(lat), libm::cos(lat));
    let d = 1.0 - earth::E2 * sl * sl;
    let sd = libm::sqrt(d);
    let rn = earth::A_M / sd + nav.pos.h_m;
    let rm = earth::A_M * (1.0 - earth::E2) / (d * sd) + nav.pos.h_m;
    let w_in = {
        let v = &nav.vel_ned_mps;
        let w = earth::OMEGA_IE_RADPS;
        Vector3::new(w * cl + v.y / rn, -v.x / rm, -w * sl - v.y * sl / (cl * rn))
    };
    let ctx = MeasContext {
        c_l: c_l.into(),
        c_w_x_l: c_w_x_l.into(),
        c_lx: c_lx.transpose().into(),
        omega_b_radps: w.into(),
        c_nb: c.transpose().into(),
        f_b_mps2: inp.step.f_body_mps2.into(),
        temperature_offset_c: inp.temperature_offset_c,
        // d/d(dt) of the predicted antenna position v_ant tau + a tau^2 / 2
        v_ant_ned_mps: (v_ant0 + acc_n * tau).into(),
        acc_ned_mps2: acc_n.into(),
        bridge_s: tau,
        lever_bridge_s: if time_offset { tau } else { 0.0 },
        w_in_ned_radps: w_in.into(),
        f_ned_mps2: inp.step.f_ned_mps2.into(),
        clock_span_s: inp.clock_span_s,
    };
    // predicted antenna position at the fix time minus the measured one, NED m
    let mut dlon = fix.lon_rad - nav.pos.lon_rad;
    if dlon > core::f64::consts::PI {
        dlon -= 2.0 * core::f64::consts::PI;
    } else if dlon < -core::f64::consts::PI {
        dlon += 2.0 * core::f64::consts::PI;
    }
    let meas_off = Vector3::new(
        (fix.lat_rad - lat) * rm,
        dlon * rn * cl,
        nav.pos.h_m - fix.h_m,
    );
    let mut zp = if time_offset {
        // second order: 0.5 a tau^2 is 2 cm at 2 m/s^2 and 150 ms
        c_l + v_ant0 * tau + acc_n * (0.5 * tau * tau) - meas_off
    } else {
        c_l + nav.vel_ned_mps * dt_fix - meas_off
    };
    // the predicted measurement carries the estimated GNSS position error (measured = true + e)
    if let Some(e) = inp.gnss_error_ned_m {
        zp += Vector3::from(e);
    }
    let mut v_ant = nav.vel_ned_mps + c_w_x_l - w_in.cross(&c_l);
    if time_offset {
        v_ant += acc_n * tau;
    }
    let zv = v_ant - Vector3::from(fix.vel_ned_mps);
    Geometry {
        ctx,
        zp: [zp.x, zp.y, zp.z],
        zv: [zv.x, zv.y, zv.z],
    }
}
