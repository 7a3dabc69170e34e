//! Discretisation of the error model over a covariance-prediction interval and the covariance
//! prediction itself.
//!
//! # What is integrated
//!
//! Over an interval of k IMU epochs (length `T = sum dt`), the filter accumulates per epoch the
//! time-varying parts of F times dt (the NED specific force of the phi-v coupling, C_b^n, and
//! each block's coupling `F[core, block] dt` from the epoch's regressors) into an
//! [`Accumulator`]. At the prediction, with `A = integral of F dt` (the core's slowly varying
//! earth/transport terms evaluated at the end of the interval):
//!
//! * `Phi = I + A + A^2 / 2` (second order; the first Magnus term, the commutator term of a
//!   time-varying F is of order T^2 |dF/dt| and negligible at T <= 0.1 s), except that the
//!   diagonal self-transition of every Gauss-Markov state is the exact `e^(-T/T_B)`;
//! * the system noise by the trapezoidal rule,
//!   `Q = (Phi G S G^T Phi^T + G S G^T) T / 2`, applied as
//!   `P <- Phi (P + Q_a) Phi^T + Q_b` with `Q_a = Q_b = G S G^T T / 2` for the white sensor
//!   noise on the core (gyro S_N T on phi, accelerometer S_N T on the velocity, mapped by the
//!   mean C_b^n), and for each sensor-error state `Q_a = Q_b = q / (1 + Phi_ii^2)` with q its
//!   exact discrete variance (`(S_B T_B / 2)(1 - Phi^2)`, `S_K T`): the diagonal then receives
//!   exactly q, and the noise's coupling into the core is trapezoidal. This is the source's
//!   `Q = T G S G^T T^T dt` with its transition T taken half at each end of the interval.
//!
//! # Sparsity
//!
//! Phi has 9 core rows (9 x N) and is diagonal below (the sensor-error states are
//! Gauss-Markov or random walks: their transition is a vector). The core rows are block
//! sparse: the position rows do not see the gyro errors, the attitude rows couple to the
//! accelerometer errors only through the second-order term, and so on; the prediction visits
//! each core row only over its non-zero entries. `Phi P Phi^T` then costs about
//! `nnz(Phi_top) N + 45 nnz(Phi_top) / 9 + (N - 9)^2` multiply-adds instead of `2 N^3`: for
//! N = 21 (KF-GINS), about 4.6 k instead of 18.5 k. Forming Phi costs up to `9 * 9 * N` (the
//! square of the top rows, zero entries skipped).

use super::{core_f::core_f, Layout, Regressors, CORE_DIM, IDX_ATT, IDX_VEL};
use crate::config::FilterConfig;
use crate::scalar::Scalar;
use crate::strapdown::NavState;

/// A covariance matrix, row-major.
pub type Cov<T, const N: usize> = [[T; N]; N];

/// The time-varying parts of F integrated over the epochs since the last prediction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accumulator<T, const N: usize> {
    /// Accumulated time, s.
    pub dt_s: f64,
    /// Number of IMU epochs accumulated.
    pub epochs: u32,
    /// Sum of f_ned dt, m/s.
    pub f_ned_dt: [T; 3],
    /// Sum of C_b^n dt, s (row-major).
    pub c_dt: [[T; 3]; 3],
    /// Sum of `F[core, :] dt` contributed by the blocks' couplings (core columns unused; the
    /// bias blocks' columns stay zero: their coupling is `+-c_dt`, added by [`discretize`]).
    pub f_top: [[T; N]; CORE_DIM],
}

impl<T: Scalar, const N: usize> Default for Accumulator<T, N> {
    fn default() -> Self {
        Self {
            dt_s: 0.0,
            epochs: 0,
            f_ned_dt: [T::ZERO; 3],
            c_dt: [[T::ZERO; 3]; 3],
            f_top: [[T::ZERO; N]; CORE_DIM],
        }
    }
}

impl<T: Scalar, const N: usize> Accumulator<T, N> {
    /// Adds one IMU epoch: `dt_s` seconds with regressors `reg` and NED specific force.
    pub fn add(&mut self, layout: &Layout, reg: &Regressors<T>, dt_s: f64, f_ned_mps2: &[T; 3]) {
        self.dt_s += dt_s;
        self.epochs = self.epochs.saturating_add(1);
        for (a, f) in self.f_ned_dt.iter_mut().zip(f_ned_mps2) {
            *a += *f * reg.dt;
        }
        for (arow, crow) in self.c_dt.iter_mut().zip(&reg.c_nb) {
            for (a, c) in arow.iter_mut().zip(crow) {
                *a += *c * reg.dt;
            }
        }
        // the host forms C_b^n dt once for every block; the MCU per block (its flash budget,
        // see Block::accumulate_f_scaled)
        #[cfg(not(target_os = "none"))]
        {
            let [[a, b, c], [d, e, f], [g, h, i]] = reg.c_nb;
            let s = reg.dt;
            let c_dt = [
                [a * s, b * s, c * s],
                [d * s, e * s, f * s],
                [g * s, h * s, i * s],
            ];
            for (off, b) in layout.iter() {
                b.accumulate_f_scaled(off, reg, &c_dt, &mut self.f_top);
            }
        }
        #[cfg(target_os = "none")]
        for (off, b) in layout.iter() {
            b.accumulate_f(off, reg, &mut self.f_top);
        }
    }
}

/// A transition matrix with dense core rows and a diagonal below:
/// `Phi = [[top (9 x N)], [0 | diag(d[9..N])]]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition<T, const N: usize> {
    /// The first 9 rows of Phi.
    pub top: [[T; N]; CORE_DIM],
    /// The diagonal of Phi; entries 0..9 are unused (the core rows are in `top`).
    pub diag: [T; N],
}

impl<T: Scalar, const N: usize> Transition<T, N> {
    /// The full N x N matrix (tests and diagnostics).
    pub fn to_dense(&self) -> Cov<T, N> {
        let mut out = [[T::ZERO; N]; N];
        for (i, row) in out.iter_mut().enumerate() {
            if i < CORE_DIM {
                if let Some(t) = self.top.get(i) {
                    *row = *t;
                }
            } else if let (Some(x), Some(d)) = (row.get_mut(i), self.diag.get(i)) {
                *x = *d;
            }
        }
        out
    }
}

/// Discretised model over one prediction interval: the transition and the noise halves.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Discrete<T, const N: usize> {
    /// Transition matrix.
    pub phi: Transition<T, N>,
    /// White noise on phi over the interval, rad^2 (`C S_g C^T T`, full 3x3).
    pub q_att: [[T; 3]; 3],
    /// White noise on the velocity over the interval, m^2/s^2 (`C S_a C^T T`).
    pub q_vel: [[T; 3]; 3],
    /// Exact discrete noise variance of each sensor-error state (entries 0..9 unused).
    pub q_diag: [T; N],
    /// The self-transition of every state over the interval (1 for the core): the
    /// deterministic prediction of the sensor-error estimates (a Gauss-Markov estimate decays
    /// like its mean, `b_hat <- e^(-T/T_B) b_hat`).
    pub est_decay: [T; N],
}

/// Builds Phi and Q for the interval accumulated in `acc`, with the core's earth and transport
/// terms evaluated at the nominal state `nav` (the end of the interval).
pub fn discretize<T: Scalar, const N: usize>(
    layout: &Layout,
    cfg: &FilterConfig,
    nav: &NavState,
    acc: &Accumulator<T, N>,
) -> Discrete<T, N> {
    let dt = acc.dt_s;
    let t = T::of_f64(dt);
    // A = integral of F dt: core from the state (phi-v coupling from the accumulated f_n dt)
    let cf = core_f::<T>(nav.pos.lat_rad, nav.pos.h_m, &nav.vel_ned_mps.into());
    let mut a_top = acc.f_top;
    for (off, b) in layout.iter() {
        b.add_bias_f(off, &acc.c_dt, &mut a_top);
    }
    for (arow, crow) in a_top.iter_mut().zip(cf.iter()) {
        for (a, c) in arow.iter_mut().zip(crow) {
            *a = *c * t;
        }
    }
    let [fx, fy, fz] = acc.f_ned_dt;
    let z = T::ZERO;
    let f_x = [[z, -fz, fy], [fz, z, -fx], [-fy, fx, z]];
    super::add3(&mut a_top, IDX_VEL, IDX_ATT, &f_x);

    // self-dynamics of the blocks
    let mut f_dt = [T::ZERO; N];
    let mut phi_d = [T::ONE; N];
    let mut q_d = [T::ZERO; N];
    for (off, b) in layout.iter() {
        let (Some(fs), Some(ps), Some(qs)) = (
            f_dt.get_mut(off..),
            phi_d.get_mut(off..),
            q_d.get_mut(off..),
        ) else {
            continue;
        };
        b.discretize(cfg, t, fs, ps, qs);
    }
    let a_diag: [T; N] = f_dt;

    // Phi_top = I + A + A^2/2; (A^2)_top = A_top[:, core] A_top + A_top[:, j] a_diag[j] (j >= 9)
    let mut top = a_top;
    for (i, (row, arow)) in top.iter_mut().zip(a_top.iter()).enumerate() {
        // A_top[i, :9] . A_top[:9, :]
        for (k, aik) in arow.iter().take(CORE_DIM).enumerate() {
            if *aik == T::ZERO {
                continue;
            }
            let h = *aik * T::HALF;
            if let Some(akrow) = a_top.get(k) {
                axpy(row, h, akrow);
            }
        }
        for ((r, aij), dj) in row.iter_mut().zip(arow).zip(a_diag.iter()).skip(CORE_DIM) {
            *r += T::HALF * *aij * *dj;
        }
        if let Some(d) = row.get_mut(i) {
            *d += T::ONE;
        }
    }
    let diag: [T; N] = phi_d;

    // white sensor noise through the mean C_b^n: C diag(S) C^T T
    let inv_t = if dt > 0.0 { T::ONE / t } else { T::ZERO };
    let c_mean = acc.c_dt.map(|r| r.map(|v| v * inv_t));
    let q_att = rotate_diag(&c_mean, &cfg.gyro.s_n, t);
    let q_vel = rotate_diag(&c_mean, &cfg.accel.s_n, t);
    Discrete {
        phi: Transition { top, diag },
        q_att,
        q_vel,
        q_diag: q_d,
        est_decay: phi_d,
    }
}

/// `C diag(s) C^T * t`, exactly symmetric: the upper triangle is computed and mirrored (the
/// (i, j) and (j, i) sums round differently, and the covariance prediction must stay
/// bit-symmetric).
fn rotate_diag<T: Scalar>(c: &[[T; 3]; 3], s: &[f64; 3], t: T) -> [[T; 3]; 3] {
    let s_t = s.map(T::of_f64);
    let cs = super::mul_diag3(c, &s_t);
    let mut out = [[T::ZERO; 3]; 3];
    for (i, (orow, csrow)) in out.iter_mut().zip(&cs).enumerate() {
        for (o, crow) in orow.iter_mut().zip(c).skip(i) {
            let mut acc = T::ZERO;
            for (a, b) in csrow.iter().zip(crow) {
                acc += *a * *b;
            }
            *o = acc * t;
        }
    }
    symmetric_from_upper3(out)
}

/// The symmetric 3x3 matrix whose upper triangle is that of `m`.
pub(crate) fn symmetric_from_upper3<T: Copy>(m: [[T; 3]; 3]) -> [[T; 3]; 3] {
    let [[a00, a01, a02], [_, a11, a12], [_, _, a22]] = m;
    [[a00, a01, a02], [a01, a11, a12], [a02, a12, a22]]
}

/// `m += a x` element by element (`m_j = m_j + a x_j`, each rounded as written), four
/// elements per step: the same operations as the plain loop, with a quarter of its loop
/// control and the loads and stores grouped (the MCU's instruction count).
fn axpy<T: Scalar>(m: &mut [T], a: T, x: &[T]) {
    let (m4, m_rest) = m.as_chunks_mut::<4>();
    let (x4, x_rest) = x.as_chunks::<4>();
    for (mm, xx) in m4.iter_mut().zip(x4) {
        let [m0, m1, m2, m3] = mm;
        let [x0, x1, x2, x3] = *xx;
        *m0 += a * x0;
        *m1 += a * x1;
        *m2 += a * x2;
        *m3 += a * x3;
    }
    for (mi, xi) in m_rest.iter_mut().zip(x_rest) {
        *mi += a * *xi;
    }
}

/// `sum_k a_k b_k` accumulated from zero in ascending k (each term rounded, then added, as
/// the plain loop does), four terms per step.
fn dot<T: Scalar>(a: &[T], b: &[T]) -> T {
    let (a4, a_rest) = a.as_chunks::<4>();
    let (b4, b_rest) = b.as_chunks::<4>();
    let mut acc = T::ZERO;
    for (aa, bb) in a4.iter().zip(b4) {
        let [a0, a1, a2, a3] = *aa;
        let [b0, b1, b2, b3] = *bb;
        acc += a0 * b0;
        acc += a1 * b1;
        acc += a2 * b2;
        acc += a3 * b3;
    }
    for (x, y) in a_rest.iter().zip(b_rest) {
        acc += *x * *y;
    }
    acc
}

/// `P <- Phi (P + Q_a) Phi^T + Q_b` (see the module docs), exploiting Phi's structure: the
/// sensor-error rows of Phi are a diagonal (a vector, `d_i P_ij d_j`), and of the 9 core rows
/// only the non-zero entries are visited (`M = Phi_top P` row by row, the known-zero blocks
/// such as the position rows' gyro-error columns skipped). The result equals the dense
/// product within rounding and is exactly symmetric (upper triangle computed, mirrored).
pub fn predict_covariance<T: Scalar, const N: usize>(p: &mut Cov<T, N>, d: &Discrete<T, N>) {
    add_noise_half(p, d);
    let phi = &d.phi;
    // M_top = Phi_top P  (9 x N)
    #[cfg(not(target_os = "none"))]
    let m_top = top_times_rows(&phi.top, p);
    #[cfg(target_os = "none")]
    let m_top = top_times(&phi.top, p);
    // sensor-sensor block: d_i P_ij d_j
    for (i, (prow, di)) in p.iter_mut().zip(phi.diag.iter()).enumerate().skip(CORE_DIM) {
        for (pij, dj) in prow.iter_mut().zip(phi.diag.iter()).skip(i) {
            *pij = *di * *pij * *dj;
        }
    }
    // core rows: P_ij = M_top_i . Phi_top_j (j < 9, j >= i), P_ij = M_top_ij d_j (j >= 9)
    for (i, (prow, mrow)) in p.iter_mut().zip(m_top.iter()).enumerate() {
        for (pij, phirow) in prow.iter_mut().zip(phi.top.iter()).skip(i) {
            *pij = dot(mrow, phirow);
        }
        for ((pij, mij), dj) in prow
            .iter_mut()
            .zip(mrow)
            .zip(phi.diag.iter())
            .skip(CORE_DIM)
        {
            *pij = *mij * *dj;
        }
    }
    mirror_upper(p);
    add_noise_half(p, d);
}

/// `Phi_top P` (9 x N), the first step of [`predict_covariance`]: row `i` is the sum over the
/// non-zero `top[i][k]`, in ascending `k`, of `top[i][k] P[k]`, each element accumulated from
/// zero and rounded term by term (`m_j = m_j + a P_kj`, as written). The zero entries of `top`
/// (the known-zero blocks of Phi's core rows) are skipped.
#[inline(always)]
pub fn top_times<T: Scalar, const N: usize>(
    top: &[[T; N]; CORE_DIM],
    p: &Cov<T, N>,
) -> [[T; N]; CORE_DIM] {
    let mut m_top = [[T::ZERO; N]; CORE_DIM];
    for (mrow, prow_phi) in m_top.iter_mut().zip(top.iter()) {
        for (phik, prow) in prow_phi.iter().zip(p.iter()) {
            if *phik != T::ZERO {
                axpy(mrow, *phik, prow);
            }
        }
    }
    m_top
}

/// [`top_times`] with each row summed in a local array of its own and stored once at the end,
/// so that the compiler keeps the row in registers across the terms (no load and store of the
/// partial sums per term): the same operations in the same order, the same bits (infinities
/// included; a NaN where the other has one, its sign and payload unspecified).
///
/// Host builds only, measured: on the host it takes the prediction on the 40-minute case
/// from 453.7 M to 376.7 M instructions (callgrind); on the MCU it is slower (`cargo xtask
/// fw bench`, qemu instructions per covariance prediction at 15 / 18 / 21 states: 53,171 /
/// 71,915 / 89,576 against [`top_times`]' 52,339 / 70,041 / 86,602, +1.6 / +2.7 / +3.4 %)
/// and 56 B larger in the `bench` image.
#[cfg(not(target_os = "none"))]
pub fn top_times_rows<T: Scalar, const N: usize>(
    top: &[[T; N]; CORE_DIM],
    p: &Cov<T, N>,
) -> [[T; N]; CORE_DIM] {
    let mut m_top = [[T::ZERO; N]; CORE_DIM];
    for (mrow, prow_phi) in m_top.iter_mut().zip(top.iter()) {
        let mut m = [T::ZERO; N];
        for (phik, prow) in prow_phi.iter().zip(p.iter()) {
            if *phik != T::ZERO {
                axpy(&mut m, *phik, prow);
            }
        }
        *mrow = m;
    }
    m_top
}

/// Adds half of the interval's noise (see the module docs) to P.
fn add_noise_half<T: Scalar, const N: usize>(p: &mut Cov<T, N>, d: &Discrete<T, N>) {
    let h = T::HALF;
    let qa = super::scale3(&d.q_att, h);
    let qv = super::scale3(&d.q_vel, h);
    super::add3(p, IDX_ATT, IDX_ATT, &qa);
    super::add3(p, IDX_VEL, IDX_VEL, &qv);
    for (i, ((row, q), phi)) in p
        .iter_mut()
        .zip(d.q_diag.iter())
        .zip(d.phi.diag.iter())
        .enumerate()
        .skip(CORE_DIM)
    {
        if let Some(x) = row.get_mut(i) {
            *x += *q / (T::ONE + *phi * *phi);
        }
    }
}

/// Copies the upper triangle of `p` onto the lower one.
pub fn mirror_upper<T: Scalar, const N: usize>(p: &mut Cov<T, N>) {
    for i in 1..N {
        let (upper, lower) = p.split_at_mut(i);
        let Some(row_i) = lower.first_mut() else {
            continue;
        };
        for (x, urow) in row_i.iter_mut().zip(upper.iter()) {
            if let Some(v) = urow.get(i) {
                *x = *v;
            }
        }
    }
}
