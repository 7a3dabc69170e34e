//! The covariance prediction `discrete::predict_covariance` (block-sparse: the known-zero
//! blocks of Phi's core rows skipped, the sensor-error diagonal as a vector) against the dense
//! product `Phi (P + Q/2) Phi^T + Q/2` computed in f64, for the 15-, 18- and 21-state layouts
//! and the largest layout (every block), in f64 and f32: equal within the rounding bound of
//! the products (`4 N eps` times the sum of the absolute terms), exactly symmetric, and on
//! random states, epochs and covariances (proptest); the accumulation of the coupling and
//! both forms of `Phi_top P` (the host's and the MCU's) against plain entry-by-entry
//! references, bit for bit.
// the reference is written with matrix indices, as the formula reads
#![allow(clippy::needless_range_loop)]

use nalgebra::{UnitQuaternion, Vector3};
use nav_core::config::FilterConfig;
use nav_core::earth::Llh;
use nav_core::model::discrete::{self, Accumulator, Cov, Discrete};
use nav_core::model::{
    Block, Layout, Regressors, CORE_DIM, IDX_ATT, IDX_VEL, LAYOUT_KF_GINS, LAYOUT_N, LAYOUT_NBK,
};
use nav_core::scalar::Scalar;
use nav_core::strapdown::NavState;
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Every block (the largest layout).
const LAYOUT_ALL: Layout = LAYOUT_NBK
    .with(Block::GyroScaleFactor)
    .with(Block::AccelScaleFactor)
    .with(Block::AccelMisalignment)
    .with(Block::GyroMisalignment)
    .with(Block::LeverArm)
    .with(Block::TimeOffset)
    .with(Block::AccelTemperatureBias)
    .with(Block::GyroTemperatureBias)
    .with(Block::GyroGSensitivity)
    .with(Block::GnssPositionGm)
    .with(Block::OdometerScale);

/// A discretised model over 20 epochs of a moving, turning vehicle (every coupling block
/// non-zero) and a random covariance (`A A^T` plus a diagonal, SPD).
fn case<T: Scalar, const N: usize>(layout: &Layout, seed: u64) -> (Cov<T, N>, Discrete<T, N>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let cfg = FilterConfig::source_nbk_model();
    let mut acc = Accumulator::<T, N>::default();
    let dt = 0.005;
    let yaw: f64 = rng.random_range(-3.0..3.0);
    for k in 0..20 {
        let y = yaw + 0.01 * f64::from(k);
        let (s, c) = y.sin_cos();
        let c_nb = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]].map(|r| r.map(T::of_f64));
        let mut f_b = [0.0; 3].map(|_: f64| T::of_f64(rng.random_range(-3.0..3.0)));
        f_b[2] = T::of_f64(-9.8 + rng.random_range(-0.5..0.5));
        let omega_b = [0.0; 3].map(|_: f64| T::of_f64(rng.random_range(-0.5..0.5)));
        let reg = Regressors {
            dt: T::of_f64(dt),
            c_nb,
            f_b,
            omega_b,
            temperature_c: T::of_f64(rng.random_range(-10.0..10.0)),
        };
        let f_ned = [
            rng.random_range(-3.0..3.0),
            rng.random_range(-3.0..3.0),
            -9.8,
        ]
        .map(T::of_f64);
        acc.add(layout, &reg, dt, &f_ned);
    }
    let nav = NavState {
        t_s: 1000.0,
        pos: Llh::from_deg(rng.random_range(-60.0..60.0), 11.0, 300.0),
        vel_ned_mps: Vector3::new(
            rng.random_range(-30.0..30.0),
            rng.random_range(-30.0..30.0),
            rng.random_range(-1.0..1.0),
        ),
        q_nb: UnitQuaternion::identity(),
    };
    let d = discrete::discretize(layout, &cfg, &nav, &acc);
    let scale: [f64; N] = core::array::from_fn(|i| match i {
        0..3 => 1e-2,
        3..6 => 0.3,
        6..9 => 3.0,
        _ => 1e-3 * rng.random_range(0.5..2.0),
    });
    let a: [[f64; N]; N] =
        core::array::from_fn(|i| core::array::from_fn(|_| scale[i] * rng.random_range(-1.0..1.0)));
    let p: Cov<T, N> = core::array::from_fn(|i| {
        core::array::from_fn(|j| {
            let s: f64 = (0..N).map(|k| a[i][k] * a[j][k]).sum();
            T::of_f64(s + if i == j { scale[i] * scale[i] } else { 0.0 })
        })
    });
    (p, d)
}

/// The noise added before and after the transition, as a dense matrix (f64).
fn noise_half<T: Scalar, const N: usize>(d: &Discrete<T, N>) -> [[f64; N]; N] {
    let mut q = [[0.0; N]; N];
    let h = T::HALF;
    for r in 0..3 {
        for c in 0..3 {
            q[IDX_ATT + r][IDX_ATT + c] = (d.q_att[r][c] * h).to_f64();
            q[IDX_VEL + r][IDX_VEL + c] = (d.q_vel[r][c] * h).to_f64();
        }
    }
    for i in CORE_DIM..N {
        let phi = d.phi.diag[i];
        q[i][i] = (d.q_diag[i] / (T::ONE + phi * phi)).to_f64();
    }
    q
}

/// Checks the structured prediction against the dense product: returns the largest error
/// relative to its rounding bound and how many entries of Phi's core rows are exactly zero.
fn check<T: Scalar, const N: usize>(layout: &Layout, seed: u64) -> (f64, usize) {
    assert_eq!(layout.dim(), N);
    let (p0, d) = case::<T, N>(layout, seed);
    let phi = d.phi.to_dense().map(|r| r.map(|v| v.to_f64()));
    let qh = noise_half(&d);
    // inputs as the structured code sees them, after the first half of the noise
    let pa: [[f64; N]; N] = core::array::from_fn(|i| {
        core::array::from_fn(|j| (p0[i][j] + T::of_f64(qh[i][j])).to_f64())
    });
    let mut got = p0;
    discrete::predict_covariance(&mut got, &d);
    let eps = if core::mem::size_of::<T>() == 4 {
        f64::from(f32::EPSILON)
    } else {
        f64::EPSILON
    };
    let mut worst: f64 = 0.0;
    for i in 0..N {
        for j in 0..N {
            let (mut want, mut bound) = (qh[i][j], qh[i][j].abs());
            for k in 0..N {
                for l in 0..N {
                    let t = phi[i][k] * pa[k][l] * phi[j][l];
                    want += t;
                    bound += t.abs();
                }
            }
            let g = got[i][j].to_f64();
            assert!(g.is_finite(), "{i},{j}");
            assert!(got[i][j] == got[j][i], "not symmetric at {i},{j}");
            let tol = 4.0 * N as f64 * eps * bound + f64::MIN_POSITIVE;
            let e = (g - want).abs() / tol;
            assert!(
                e <= 1.0,
                "N = {N}, seed {seed}: P[{i}][{j}] = {g:e}, dense {want:e} (bound {tol:e})"
            );
            worst = worst.max(e);
        }
    }
    let zeros = d
        .phi
        .top
        .iter()
        .map(|r| r.iter().filter(|v| **v == T::ZERO).count())
        .sum();
    (worst, zeros)
}

#[test]
fn structured_prediction_equals_the_dense_product_for_every_layout_f64_and_f32() {
    for seed in 0..3 {
        let r = [
            check::<f64, { LAYOUT_N.dim() }>(&LAYOUT_N, seed),
            check::<f64, { LAYOUT_NBK.dim() }>(&LAYOUT_NBK, seed),
            check::<f64, { LAYOUT_KF_GINS.dim() }>(&LAYOUT_KF_GINS, seed),
            check::<f64, { LAYOUT_ALL.dim() }>(&LAYOUT_ALL, seed),
            check::<f32, { LAYOUT_N.dim() }>(&LAYOUT_N, seed),
            check::<f32, { LAYOUT_NBK.dim() }>(&LAYOUT_NBK, seed),
            check::<f32, { LAYOUT_KF_GINS.dim() }>(&LAYOUT_KF_GINS, seed),
            check::<f32, { LAYOUT_ALL.dim() }>(&LAYOUT_ALL, seed),
        ];
        // the known-zero blocks exist (the position rows do not see the gyro errors, ...)
        for (worst, zeros) in r {
            assert!(worst <= 1.0);
            assert!(zeros >= 9, "{zeros} zero entries in Phi's core rows");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]
    #[test]
    fn structured_prediction_equals_the_dense_product_on_random_cases(seed in any::<u64>()) {
        check::<f64, { LAYOUT_KF_GINS.dim() }>(&LAYOUT_KF_GINS, seed);
        check::<f32, { LAYOUT_KF_GINS.dim() }>(&LAYOUT_KF_GINS, seed);
        check::<f32, { LAYOUT_ALL.dim() }>(&LAYOUT_ALL, seed);
    }
}

/// One IMU epoch's coupling of the sensor-error blocks into the core rows (`F[core, block]
/// dt`), written out entry by entry from the error model of [`Block::accumulate_f`]'s docs in
/// `T`, each term `(C_ij dt) v_j` rounded as written and negated where the model has a minus
/// (the bias blocks come in at the discretisation; the measurement-only blocks have none).
fn plain_coupling<T: Scalar, const N: usize>(
    layout: &Layout,
    reg: &Regressors<T>,
    f_top: &mut [[T; N]; CORE_DIM],
) {
    let c_dt = |i: usize, j: usize| reg.c_nb[i][j] * reg.dt;
    let d_t = if reg.temperature_c.finite() {
        reg.temperature_c
    } else {
        T::ZERO
    };
    // the columns of J(v) (misalignment order): (column of C, component of v)
    const MIS: [(usize, usize); 6] = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)];
    for (off, b) in layout.iter() {
        for i in 0..3 {
            let (att, vel) = (IDX_ATT + i, IDX_VEL + i);
            match b {
                Block::GyroScaleFactor => {
                    for j in 0..3 {
                        f_top[att][off + j] += c_dt(i, j) * reg.omega_b[j];
                    }
                }
                Block::AccelScaleFactor => {
                    for j in 0..3 {
                        f_top[vel][off + j] += -(c_dt(i, j) * reg.f_b[j]);
                    }
                }
                Block::GyroMisalignment => {
                    for (k, (j, l)) in MIS.into_iter().enumerate() {
                        f_top[att][off + k] += c_dt(i, j) * reg.omega_b[l];
                    }
                }
                Block::AccelMisalignment => {
                    for (k, (j, l)) in MIS.into_iter().enumerate() {
                        f_top[vel][off + k] += -(c_dt(i, j) * reg.f_b[l]);
                    }
                }
                Block::GyroTemperatureBias if d_t != T::ZERO => {
                    for j in 0..3 {
                        f_top[att][off + j] += c_dt(i, j) * d_t;
                    }
                }
                Block::AccelTemperatureBias if d_t != T::ZERO => {
                    for j in 0..3 {
                        f_top[vel][off + j] += -(c_dt(i, j) * d_t);
                    }
                }
                Block::GyroGSensitivity => {
                    for j in 0..3 {
                        f_top[att][off + j] += c_dt(i, j) * reg.f_b[j];
                    }
                }
                _ => {}
            }
        }
    }
}

/// `Accumulator::add` (the host's form: `C_b^n dt` formed once per epoch for every block) and
/// the per-block form `Block::accumulate_f` (the MCU's) against [`plain_coupling`] over 50
/// random epochs of the largest layout (every seventh without a temperature): the same sums,
/// bit for bit, in f64 and f32.
fn accumulation_is_the_plain_coupling<T: Scalar, const N: usize>(seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut acc = Accumulator::<T, N>::default();
    let mut plain = [[T::ZERO; N]; CORE_DIM];
    let mut per_block = [[T::ZERO; N]; CORE_DIM];
    let mut r = |a: f64, b: f64| T::of_f64(rng.random_range(a..b));
    for k in 0..50 {
        let temperature_c = r(-10.0, 10.0);
        let reg = Regressors {
            dt: r(0.001, 0.02),
            c_nb: [[0.0f64; 3]; 3].map(|row| row.map(|_| r(-1.0, 1.0))),
            f_b: [r(-3.0, 3.0), r(-3.0, 3.0), r(-10.5, -9.0)],
            omega_b: [0.0f64; 3].map(|_| r(-0.5, 0.5)),
            temperature_c: if k % 7 == 3 {
                T::of_f64(f64::NAN)
            } else {
                temperature_c
            },
        };
        acc.add(&LAYOUT_ALL, &reg, 0.005, &[T::ZERO; 3]);
        for (off, b) in LAYOUT_ALL.iter() {
            b.accumulate_f(off, &reg, &mut per_block);
        }
        plain_coupling(&LAYOUT_ALL, &reg, &mut plain);
    }
    let bits = |m: &[[T; N]; CORE_DIM]| -> Vec<u64> {
        m.iter().flatten().map(|v| v.to_f64().to_bits()).collect()
    };
    assert_eq!(bits(&acc.f_top), bits(&plain));
    assert_eq!(bits(&per_block), bits(&plain));
    assert!(plain.iter().flatten().filter(|v| v.to_f64() != 0.0).count() > 50);
}

#[test]
fn accumulation_equals_the_plain_coupling_bit_for_bit() {
    for seed in 0..4 {
        accumulation_is_the_plain_coupling::<f64, { LAYOUT_ALL.dim() }>(seed);
        accumulation_is_the_plain_coupling::<f32, { LAYOUT_ALL.dim() }>(seed);
    }
}

/// The bits of `v`, or one value for every NaN: the sign and payload of a NaN are not fixed by
/// Rust's float semantics (the compiler may swap the operands of an addition, and the x86 FPU
/// keeps the first operand's NaN), and no output shows them (a non-finite covariance is a
/// numerical failure; a NaN is written `NaN`).
fn bits_or_nan(v: f64) -> u64 {
    if v.is_nan() {
        u64::MAX
    } else {
        v.to_bits()
    }
}

/// `Phi_top P` as written: element `(i, j)` summed from zero over `k` ascending, the terms
/// `top[i][k] P[k][j]` of the non-zero `top[i][k]` only, each rounded as it is added.
fn plain_top_times<T: Scalar, const N: usize>(
    top: &[[T; N]; CORE_DIM],
    p: &Cov<T, N>,
) -> [[T; N]; CORE_DIM] {
    let mut m = [[T::ZERO; N]; CORE_DIM];
    for i in 0..CORE_DIM {
        for j in 0..N {
            for k in 0..N {
                if top[i][k] != T::ZERO {
                    m[i][j] += top[i][k] * p[k][j];
                }
            }
        }
    }
    m
}

/// `discrete::top_times_rows` (the host's `Phi_top P`, the first step of the prediction) and
/// `discrete::top_times` (the MCU's) against [`plain_top_times`] for one layout: the same bits (NaN at the same places) on the case
/// above, on a covariance with NaN, infinities, signed zeros, a subnormal and the largest
/// finite value planted in it, and with non-finite entries in Phi as well (they propagate the
/// same way).
fn row_product_is_the_plain_product<T: Scalar, const N: usize>(layout: &Layout, seed: u64) {
    let (mut p, d) = case::<T, N>(layout, seed);
    let bits = |m: &[[T; N]; CORE_DIM]| -> Vec<u64> {
        m.iter()
            .flatten()
            .map(|v| bits_or_nan(v.to_f64()))
            .collect()
    };
    let mut top = d.phi.top;
    let same = |top: &[[T; N]; CORE_DIM], p: &Cov<T, N>| {
        let plain = bits(&plain_top_times(top, p));
        let rows = discrete::top_times_rows(top, p);
        assert_eq!(bits(&rows), plain);
        assert_eq!(bits(&discrete::top_times(top, p)), plain);
        rows
    };
    let finite = same(&top, &p);
    assert!(finite.iter().flatten().all(|v| v.to_f64().is_finite()));
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    let specials = [
        f64::NAN,
        -f64::NAN,
        f64::INFINITY,
        f64::NEG_INFINITY,
        -0.0,
        0.0,
        f64::MIN_POSITIVE * 0.25,
        f64::MAX,
    ];
    for s in specials {
        let (i, j) = (rng.random_range(0..N), rng.random_range(0..N));
        p[i][j] = T::of_f64(s);
    }
    let planted = same(&top, &p);
    assert!(planted.iter().flatten().any(|v| v.to_f64().is_nan()));
    for s in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0] {
        let (i, k) = (rng.random_range(0..CORE_DIM), rng.random_range(0..N));
        top[i][k] = T::of_f64(s);
    }
    same(&top, &p);
}

#[test]
fn row_product_equals_the_plain_product_bit_for_bit_on_every_layout() {
    for seed in 0..3 {
        row_product_is_the_plain_product::<f64, { LAYOUT_N.dim() }>(&LAYOUT_N, seed);
        row_product_is_the_plain_product::<f64, { LAYOUT_NBK.dim() }>(&LAYOUT_NBK, seed);
        row_product_is_the_plain_product::<f64, { LAYOUT_KF_GINS.dim() }>(&LAYOUT_KF_GINS, seed);
        row_product_is_the_plain_product::<f64, { LAYOUT_ALL.dim() }>(&LAYOUT_ALL, seed);
        row_product_is_the_plain_product::<f32, { LAYOUT_N.dim() }>(&LAYOUT_N, seed);
        row_product_is_the_plain_product::<f32, { LAYOUT_NBK.dim() }>(&LAYOUT_NBK, seed);
        row_product_is_the_plain_product::<f32, { LAYOUT_KF_GINS.dim() }>(&LAYOUT_KF_GINS, seed);
        row_product_is_the_plain_product::<f32, { LAYOUT_ALL.dim() }>(&LAYOUT_ALL, seed);
    }
}
