//! Read access to a [`Filter`] and its sensor-error estimates: the solution, the nominal
//! state, the covariance and standard deviations, block estimates (and setting them from a
//! calibration), the IMU correction, counters and status.

use super::*;

impl<T: Scalar, const N: usize> Filter<T, N> {
    /// The IMU error correction from the current sensor-error estimates.
    pub fn imu_correction(&self) -> ImuCorrection {
        let mut c = ImuCorrection {
            temperature_ref_c: self.temperature_ref_c,
            ..ImuCorrection::default()
        };
        for (off, b) in self.layout.iter() {
            if let Some(e) = self.est.get(off..off + b.dim()) {
                b.add_correction(e, &mut c);
            }
        }
        c
    }

    /// The GNSS antenna lever arm in use, body FRD, m: the configured one plus the
    /// [`crate::model::Block::LeverArm`] estimate when the layout has it.
    pub fn lever_arm_body_m(&self) -> [f64; 3] {
        let mut l = self.cfg.lever_arm_body_m;
        if let Some(e) = self.block_estimate(BlockKind::LeverArm) {
            for (a, b) in l.iter_mut().zip(e) {
                *a += *b;
            }
        }
        l
    }

    /// The estimated IMU-GNSS time offset at the filter's current time, s
    /// ([`crate::model::Block::TimeOffset`] or [`crate::model::Block::ImuClockDrift`]; 0
    /// without either).
    pub fn time_offset_s(&self) -> f64 {
        self.time_offset_at_s(self.mech.state().t_s)
    }

    /// The estimated IMU-GNSS time offset at time `t_s` (s): the `time_offset` estimate, or
    /// `dt_0 + r (t_s - t_0)` with the `imu_clock_drift` block (`t_0`: the filter's start,
    /// [`Self::clock_ref_s`]); 0 without either block.
    pub fn time_offset_at_s(&self, t_s: f64) -> f64 {
        match self.block_estimate(BlockKind::TimeOffset) {
            Some([dt0, rate]) => dt0 + rate * (t_s - self.clock_ref_s),
            Some([dt0, ..]) => *dt0,
            _ => 0.0,
        }
    }

    /// The reference time `t_0` of the [`crate::model::Block::ImuClockDrift`] offset (the
    /// filter's initial state's time), s.
    pub fn clock_ref_s(&self) -> f64 {
        self.clock_ref_s
    }

    /// The estimated time-correlated GNSS antenna-position error, NED, m
    /// ([`crate::model::Block::GnssPositionGm`]; None without the block).
    pub fn gnss_position_error_ned_m(&self) -> Option<[f64; 3]> {
        match self.block_estimate(BlockKind::GnssPositionGm) {
            Some([n, e, d]) => Some([*n, *e, *d]),
            _ => None,
        }
    }

    /// The reference temperature of the temperature blocks, degC (NaN until the first sample
    /// with a temperature when none is configured).
    pub fn temperature_ref_c(&self) -> f64 {
        self.temperature_ref_c
    }

    /// Estimate and 1-sigma of every state of a block (SI units of the block, see
    /// [`crate::model::Block`]), or None when the layout has no such block.
    pub fn block_value(&self, kind: BlockKind) -> Option<BlockValue> {
        let (off, b) = self.layout.find(kind)?;
        let mut v = BlockValue {
            block: b,
            dim: b.dim(),
            estimate: [0.0; MAX_BLOCK_DIM],
            sigma: [0.0; MAX_BLOCK_DIM],
        };
        for (k, (e, sg)) in v.estimate.iter_mut().zip(v.sigma.iter_mut()).enumerate() {
            if k >= b.dim() {
                break;
            }
            *e = self.est.get(off + k).copied().unwrap_or(0.0);
            *sg = libm::sqrt(get2(&self.p, off + k, off + k).to_f64().max(0.0));
        }
        Some(v)
    }

    /// The nominal navigation state (IMU reference point).
    pub fn nav_state(&self) -> &NavState {
        self.mech.state()
    }

    /// The last mechanisation step (corrected specific force and rate).
    pub fn last_step(&self) -> &StepInfo {
        &self.last_step
    }

    /// The error covariance (row-major; units of the states: rad, m/s, m, sensor units).
    pub fn covariance(&self) -> &Cov<T, N> {
        &self.p
    }

    /// 1-sigma of every error state (sqrt of the covariance diagonal).
    pub fn state_std(&self) -> [f64; N] {
        let mut out = [0.0; N];
        for (i, (o, row)) in out.iter_mut().zip(self.p.iter()).enumerate() {
            *o = libm::sqrt(row.get(i).copied().unwrap_or(T::ZERO).to_f64());
        }
        out
    }

    /// The current estimate of a block's states (sensor errors in SI units; the core's entries
    /// are always zero: its errors are fed back), or None when the layout has no such block.
    pub fn block_estimate(&self, kind: BlockKind) -> Option<&[f64]> {
        let (off, b) = self.layout.find(kind)?;
        self.est.get(off..off + b.dim())
    }

    /// Sets a block's sensor-error estimate (e.g. biases saved from a previous run or a
    /// calibration), SI units, `values.len()` must equal the block's dimension. The covariance
    /// is unchanged. Errors: no such block, wrong length, or non-finite values.
    pub fn set_block_estimate(
        &mut self,
        kind: BlockKind,
        values: &[f64],
    ) -> Result<(), FilterError> {
        let (off, b) = self.layout.find(kind).ok_or(FilterError::NoSuchBlock)?;
        if kind == BlockKind::Core
            || values.len() != b.dim()
            || !values.iter().all(|v| v.is_finite())
        {
            return Err(FilterError::NoSuchBlock);
        }
        let dst = self
            .est
            .get_mut(off..off + b.dim())
            .ok_or(FilterError::NoSuchBlock)?;
        dst.copy_from_slice(values);
        self.refresh_correction();
        Ok(())
    }

    /// Total estimate and 1-sigma per axis of an IMU error quantity (the sum over the block's
    /// 3-state groups, e.g. b_GM + b_RW, with their cross-covariance), or None when absent.
    pub fn imu_error(&self, kind: BlockKind) -> Option<([f64; 3], [f64; 3])> {
        let (off, b) = self.layout.find(kind)?;
        b.quantity()?;
        let groups = b.dim() / 3;
        let mut val = [0.0; 3];
        let mut std = [0.0; 3];
        for axis in 0..3 {
            let mut v = 0.0;
            let mut var = 0.0;
            for g in 0..groups {
                let i = off + 3 * g + axis;
                v += self.est.get(i).copied().unwrap_or(0.0);
                for h in 0..groups {
                    var += get2(&self.p, i, off + 3 * h + axis).to_f64();
                }
            }
            if let Some(x) = val.get_mut(axis) {
                *x = v;
            }
            if let Some(x) = std.get_mut(axis) {
                *x = libm::sqrt(var);
            }
        }
        Some((val, std))
    }

    /// The navigation solution with standard deviations (GPS week unknown to the filter: 0).
    pub fn solution(&self) -> NavSolution {
        let s = self.mech.state();
        // the 1-sigma of the six position and velocity states only (as `state_std` gives them)
        let sd = |i: usize| {
            let d = |k: usize| libm::sqrt(get2(&self.p, k, k).to_f64());
            [d(i), d(i + 1), d(i + 2)]
        };
        let rpy = attitude::euler_zyx_from_quat(&s.q_nb);
        let att_std = euler_std(&rpy, &self.p);
        NavSolution {
            week: 0,
            t_s: s.t_s,
            lat_rad: s.pos.lat_rad,
            lon_rad: s.pos.lon_rad,
            h_m: s.pos.h_m,
            vel_ned_mps: s.vel_ned_mps.into(),
            rpy_rad: rpy,
            pos_std_ned_m: sd(IDX_POS),
            vel_std_ned_mps: sd(IDX_VEL),
            att_std_rad: att_std,
            status: self.status,
        }
    }

    /// Event counters.
    pub fn counters(&self) -> &Counters {
        &self.counters
    }

    /// What the robust gating and its NIS monitor did, and their current state (all zero /
    /// one with the hard gate, except `resets`).
    pub fn robust_stats(&self) -> &RobustStats {
        &self.gate.stats
    }

    /// Status bits (`STATUS_*`).
    pub fn status(&self) -> u32 {
        self.status
    }

    /// The state layout.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The configuration.
    pub fn config(&self) -> &FilterConfig {
        &self.cfg
    }

    /// IMU time accumulated since the last covariance prediction, s.
    pub fn pending_prediction_s(&self) -> f64 {
        self.acc.dt_s
    }

    /// Whether the covariance is symmetric positive definite, checked by a Cholesky
    /// factorisation in the filter's own scalar type (N^3/6 multiply-adds).
    pub fn covariance_is_positive_definite(&self) -> bool {
        let sym = self.p.iter().enumerate().all(|(i, row)| {
            row.iter()
                .enumerate()
                .all(|(j, v)| *v == get2(&self.p, j, i))
        });
        let mut a = self.p;
        sym && cholesky_in_place(&mut a)
    }

    /// The error-state correction fed back since the last covariance prediction (summed over
    /// the updates; estimate minus truth, state units): what a smoother's last node needs
    /// after the run ([`super::observe`]).
    pub fn pending_correction(&self) -> &[T; N] {
        &self.fed_back
    }
}
