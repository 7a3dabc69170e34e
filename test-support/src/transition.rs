//! The finite-difference check of the filter's linearised error model: the product of the
//! filter's discrete transition matrices along a drive against the difference of two filters'
//! nominal trajectories, one started with a small error in one state, both fed the same raw
//! increments and no GNSS. One definition for every layout test (`filter_error_model`,
//! `effects_error_model`).
use crate::filter_sim::nav_errors;
use nalgebra::{SMatrix, Vector3};
use nav_core::config::FilterConfig;
use nav_core::earth;
use nav_core::filter::{dcm_f64, Filter, InitialUncertainty};
use nav_core::model::discrete::{discretize, Accumulator};
use nav_core::model::{BlockKind, Layout, Regressors};
use nav_core::strapdown::NavState;
use nav_core::types::ImuSample;

/// Error-state coordinates of `est` relative to `reference`: phi (rad), dv (m/s), dr (NED m).
pub fn err9(est: &NavState, reference: &NavState) -> [f64; 9] {
    let (phi, dv, dr) = nav_errors(est, reference);
    [
        phi[0], phi[1], phi[2], dv[0], dv[1], dv[2], dr[0], dr[1], dr[2],
    ]
}

/// The drive, the filter configuration and the model's transition product along it.
pub struct TransitionRun<'a, const N: usize> {
    /// The layout under test.
    pub layout: Layout,
    /// The filter configuration.
    pub cfg: &'a FilterConfig,
    /// The initial uncertainty of every filter.
    pub unc: &'a InitialUncertainty,
    /// The state both filters start from.
    pub start: NavState,
    /// The raw increments both filters are fed.
    pub samples: &'a [ImuSample],
    /// The reference filter after the drive.
    pub reference: Filter<f64, N>,
    /// The product of the discrete transition matrices over the drive.
    pub phi_total: SMatrix<f64, N, N>,
}

/// How one state is perturbed at the start.
#[derive(Clone, Copy, Debug)]
pub enum Perturbation {
    /// Attitude error about NED axis 0..3 (rad).
    Attitude(usize),
    /// Velocity error along NED axis 0..3 (m/s).
    Velocity(usize),
    /// Position error along NED axis 0..3 (m).
    Position(usize),
    /// Element `index` of the estimate of a sensor-error block of dimension `dim`.
    Estimate {
        /// The block.
        kind: BlockKind,
        /// Element within the block.
        index: usize,
        /// The block's dimension.
        dim: usize,
    },
}

/// Column `j` of the model against the finite difference, core rows.
#[derive(Clone, Copy, Debug)]
pub struct ColumnCheck {
    /// Finite-difference column (core rows: attitude, velocity, position).
    pub fd: [f64; 9],
    /// The model's column.
    pub model: [f64; 9],
    /// Worst mismatch over the three row groups, relative to the group's scale (or to a small
    /// absolute floor where the column stays numerically zero).
    pub worst_rel: f64,
    /// Whether some row group moved above its floor (the state affects the solution).
    pub moves: bool,
}

impl<'a, const N: usize> TransitionRun<'a, N> {
    /// Runs the reference filter over `samples` and accumulates the model's transition product.
    /// `temperature_ref_c`: the regressors' temperature is the sample's minus this (NaN when
    /// `None`). The drive must be a whole number of covariance-prediction intervals.
    pub fn new(
        layout: Layout,
        cfg: &'a FilterConfig,
        unc: &'a InitialUncertainty,
        start: NavState,
        samples: &'a [ImuSample],
        temperature_ref_c: Option<f64>,
    ) -> Self {
        let mut reference: Filter<f64, N> = Filter::new(layout, cfg, start, unc).unwrap();
        let mut acc: Accumulator<f64, N> = Accumulator::default();
        let mut phi_total = SMatrix::<f64, N, N>::identity();
        for s in samples {
            reference.propagate(s).unwrap();
            let st = *reference.last_step();
            let nav = *reference.nav_state();
            let c = dcm_f64(&nav.q_nb);
            let reg = Regressors {
                dt: st.dt_s,
                c_nb: c.transpose().into(),
                f_b: st.f_body_mps2.into(),
                omega_b: st.omega_ib_body_radps.into(),
                temperature_c: temperature_ref_c.map_or(f64::NAN, |t| s.temperature_c - t),
            };
            acc.add(&layout, &reg, st.dt_s, &st.f_ned_mps2.into());
            if reference.pending_prediction_s() == 0.0 {
                let d = discretize(&layout, cfg, &nav, &acc);
                acc = Accumulator::default();
                let p = d.phi.to_dense();
                let m = SMatrix::<f64, N, N>::from_fn(|i, j| p[i][j]);
                phi_total = m * phi_total;
            }
        }
        assert_eq!(
            acc.epochs, 0,
            "the drive must be a whole number of prediction intervals"
        );
        Self {
            layout,
            cfg,
            unc,
            start,
            samples,
            reference,
            phi_total,
        }
    }

    /// The perturbation of state `j` in this layout (core states by index, sensor states as
    /// block estimates).
    pub fn perturbation(&self, j: usize) -> Perturbation {
        match j {
            0..=2 => Perturbation::Attitude(j),
            3..=5 => Perturbation::Velocity(j - 3),
            6..=8 => Perturbation::Position(j - 6),
            _ => {
                let (off, b) = self
                    .layout
                    .iter()
                    .find(|(o, b)| j >= *o && j < o + b.dim())
                    .unwrap();
                Perturbation::Estimate {
                    kind: b.kind(),
                    index: j - off,
                    dim: b.dim(),
                }
            }
        }
    }

    /// Compares column `j` of the transition product with the finite difference for a
    /// perturbation of size `eps`. For a sensor-error state it also asserts that the estimate's
    /// own decay matches the diagonal entry to 1e-9 (`name` labels the failure).
    pub fn check_column(&self, j: usize, eps: f64, name: &str) -> ColumnCheck {
        let mut init = self.start;
        let pert = self.perturbation(j);
        match pert {
            Perturbation::Attitude(k) => {
                let mut phi = Vector3::zeros();
                phi[k] = eps;
                init.q_nb = nav_core::attitude::quat_from_rotvec(&(-phi)) * init.q_nb;
            }
            Perturbation::Velocity(k) => init.vel_ned_mps[k] += eps,
            Perturbation::Position(k) => {
                let mut d = Vector3::zeros();
                d[k] = eps;
                init.pos = earth::displace(&init.pos, &d);
            }
            Perturbation::Estimate { .. } => {}
        }
        let mut f: Filter<f64, N> = Filter::new(self.layout, self.cfg, init, self.unc).unwrap();
        if let Perturbation::Estimate { kind, index, dim } = pert {
            let mut v = vec![0.0; dim];
            v[index] = eps;
            f.set_block_estimate(kind, &v).unwrap();
        }
        for s in self.samples {
            f.propagate(s).unwrap();
        }
        let e = err9(f.nav_state(), self.reference.nav_state());
        let mut fd = [0.0; 9];
        let mut model = [0.0; 9];
        for i in 0..9 {
            fd[i] = e[i] / eps;
            model[i] = self.phi_total[(i, j)];
        }
        if let Perturbation::Estimate { kind, index, .. } = pert {
            let decay_fd = f.block_estimate(kind).unwrap()[index] / eps;
            let decay_m = self.phi_total[(j, j)];
            assert!(
                (decay_fd - decay_m).abs() < 1e-9,
                "{name}: state {j} estimate decay {decay_fd} vs model {decay_m}"
            );
        }
        // normalise by the column's scale per row group (attitude, velocity, position);
        // groups that stay (numerically) zero are compared absolutely
        let mut worst_rel = 0.0f64;
        let mut moves = false;
        for g in 0..3 {
            let r = 3 * g..3 * g + 3;
            let scale = r.clone().map(|i| fd[i].abs()).fold(0.0, f64::max);
            let diff = r.map(|i| (fd[i] - model[i]).abs()).fold(0.0, f64::max);
            let tiny = [1e-9, 1e-7, 1e-6][g];
            let rel = if scale > tiny {
                moves = true;
                diff / scale
            } else {
                diff / tiny
            };
            worst_rel = worst_rel.max(rel);
        }
        println!(
            "{name} state {j:2}: fd [{}]\n              model [{}]  worst rel {worst_rel:.2e}",
            fd.iter()
                .map(|v| format!("{v:10.3e}"))
                .collect::<Vec<_>>()
                .join(" "),
            model
                .iter()
                .map(|v| format!("{v:10.3e}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
        ColumnCheck {
            fd,
            model,
            worst_rel,
            moves,
        }
    }
}
