//! Small fixed-size helpers of the effect blocks (misalignment Jacobian, sensor matrix and its
//! inverse, temperature regressor). Derivations: `docs/derivations/error_state.md`, section 5.
//!
//! Misalignment: a triad's sensor matrix is `I + diag(s) + M` with
//! `M = [[0, m_xy, m_xz], [m_yx, 0, m_yz], [m_zx, m_zy, 0]]`, state order
//! `[m_xy, m_xz, m_yx, m_yz, m_zx, m_zy]`. For an input vector v (body rate or specific force)
//! `M v = J(v) m` with
//!
//! ```text
//! J(v) = [[v_y, v_z, 0,   0,   0,   0  ],
//!         [0,   0,   v_x, v_z, 0,   0  ],
//!         [0,   0,   0,   0,   v_x, v_y]]
//! ```

use crate::scalar::Scalar;
use core::ops::{Add, Mul};

/// `J(v)` (3 x 6): `M v = J(v) m` for the misalignment state order of the module docs (the
/// definition [`c_mis`] is checked against; the filter uses `c_mis` only).
#[cfg(test)]
pub fn misalignment_jacobian<T: Copy + Default>(v: &[T; 3]) -> [[T; 6]; 3] {
    let [x, y, z] = *v;
    let o = T::default();
    [[y, z, o, o, o, o], [o, o, x, z, o, o], [o, o, o, o, x, y]]
}

/// `A J(v)` (3 x 6) for a 3x3 `a` (row-major): column j of J has a single non-zero entry, so
/// column j of the product is a column of `a` times one component of v.
pub fn c_mis<T: Copy + Mul<Output = T>>(a: &[[T; 3]; 3], v: &[T; 3]) -> [[T; 6]; 3] {
    let [x, y, z] = *v;
    a.map(|r| {
        let [a0, a1, a2] = r;
        [a0 * y, a0 * z, a1 * x, a1 * z, a2 * x, a2 * y]
    })
}

/// Adds the 3 x K `m` into `dst` at (row0, col0); entries outside `dst` are ignored.
pub fn add_block<T: Scalar, const R: usize, const C: usize, const K: usize>(
    dst: &mut [[T; C]; R],
    row0: usize,
    col0: usize,
    m: &[[T; K]; 3],
) {
    for (d_row, m_row) in dst.iter_mut().skip(row0).zip(m) {
        for (d, v) in d_row.iter_mut().skip(col0).zip(m_row) {
            *d += *v;
        }
    }
}

/// The temperature regressor `T - T_ref` (degC), zero when it is not finite (no temperature
/// in the sample, or no reference yet).
pub fn temperature_regressor<T: Scalar>(d_t: T) -> T {
    if d_t.finite() {
        d_t
    } else {
        T::ZERO
    }
}

/// The sensor matrix `I + diag(s) + M(m)` (row-major) of a triad.
pub fn sensor_matrix(s: &[f64; 3], m: &[f64; 6]) -> [[f64; 3]; 3] {
    let [sx, sy, sz] = *s;
    let [m_xy, m_xz, m_yx, m_yz, m_zx, m_zy] = *m;
    [
        [1.0 + sx, m_xy, m_xz],
        [m_yx, 1.0 + sy, m_yz],
        [m_zx, m_zy, 1.0 + sz],
    ]
}

/// Inverse of a 3x3 matrix by cofactors; None when (nearly) singular.
pub fn inv3(a: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let [[a00, a01, a02], [a10, a11, a12], [a20, a21, a22]] = *a;
    let c00 = a11 * a22 - a12 * a21;
    let c01 = a12 * a20 - a10 * a22;
    let c02 = a10 * a21 - a11 * a20;
    let det = a00 * c00 + a01 * c01 + a02 * c02;
    if !(det.is_finite() && det.abs() > 1e-12) {
        return None;
    }
    let k = 1.0 / det;
    Some([
        [
            c00 * k,
            (a02 * a21 - a01 * a22) * k,
            (a01 * a12 - a02 * a11) * k,
        ],
        [
            c01 * k,
            (a00 * a22 - a02 * a20) * k,
            (a02 * a10 - a00 * a12) * k,
        ],
        [
            c02 * k,
            (a01 * a20 - a00 * a21) * k,
            (a00 * a11 - a01 * a10) * k,
        ],
    ])
}

/// `a v`.
pub fn mat_vec<T: Copy + Mul<Output = T> + Add<Output = T>>(a: &[[T; 3]; 3], v: &[T; 3]) -> [T; 3] {
    let [x, y, z] = *v;
    a.map(|[a0, a1, a2]| a0 * x + a1 * y + a2 * z)
}

/// `a b` for 3x3 f64 matrices.
pub fn mul3(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut out = [[0.0; 3]; 3];
    for (orow, arow) in out.iter_mut().zip(a) {
        for (j, o) in orow.iter_mut().enumerate() {
            *o = arow
                .iter()
                .zip(b)
                .map(|(x, brow)| x * brow.get(j).copied().unwrap_or(0.0))
                .sum();
        }
    }
    out
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    #[test]
    fn misalignment_jacobian_reproduces_the_matrix_product() {
        let m = [1e-3, -2e-3, 3e-4, 4e-4, -5e-4, 6e-4];
        let v = [0.3, -1.2, 9.7];
        let a = sensor_matrix(&[0.0; 3], &m);
        let mv = mat_vec(&a, &v);
        let j = misalignment_jacobian(&v);
        for i in 0..3 {
            let jm: f64 = (0..6).map(|k| j[i][k] * m[k]).sum();
            assert!((mv[i] - v[i] - jm).abs() < 1e-15);
        }
        let c = [[0.1, 0.2, 0.3], [-0.4, 0.5, 0.6], [0.7, -0.8, 0.9]];
        let cj = c_mis(&c, &v);
        for i in 0..3 {
            for k in 0..6 {
                let want: f64 = (0..3).map(|l| c[i][l] * j[l][k]).sum();
                assert!((cj[i][k] - want).abs() < 1e-15);
            }
        }
    }

    #[test]
    fn inv3_inverts() {
        let a = sensor_matrix(
            &[1e-3, -5e-4, 2e-3],
            &[1e-3, -2e-3, 3e-4, 4e-4, -5e-4, 6e-4],
        );
        let ai = inv3(&a).unwrap();
        let p = mul3(&a, &ai);
        for i in 0..3 {
            for j in 0..3 {
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((p[i][j] - e).abs() < 1e-15);
            }
        }
        assert!(inv3(&[[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]).is_none());
    }
}
