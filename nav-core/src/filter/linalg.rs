//! Small dense linear algebra on row-major fixed-size arrays: Cholesky factorisation and
//! solves. No allocation, no panics, no unchecked indexing.

use crate::scalar::Scalar;

/// Dot product of the first `n` entries of `a` and `b`.
#[inline]
pub fn dot_n<T: Scalar>(a: &[T], b: &[T], n: usize) -> T {
    let mut acc = T::ZERO;
    for (x, y) in a.iter().zip(b).take(n) {
        acc += *x * *y;
    }
    acc
}

/// Dot product of two slices (the shorter length).
#[inline]
pub fn dot<T: Scalar>(a: &[T], b: &[T]) -> T {
    dot_n(a, b, usize::MAX)
}

/// In-place Cholesky factorisation `A = L L^T` of a symmetric matrix (only the lower triangle
/// is read); on success the lower triangle holds L and the strict upper triangle is zeroed.
/// Returns false (A partly overwritten) when A is not positive definite or not finite.
pub fn cholesky_in_place<T: Scalar, const M: usize>(a: &mut [[T; M]; M]) -> bool {
    for i in 0..M {
        let Some((done, rest)) = a.split_at_mut_checked(i) else {
            return false;
        };
        let Some(row_i) = rest.first_mut() else {
            return false;
        };
        for j in 0..i {
            let Some(row_j) = done.get(j) else {
                return false;
            };
            let s = dot_n(row_i, row_j, j);
            let (Some(ljj), Some(aij)) = (row_j.get(j).copied(), row_i.get(j).copied()) else {
                return false;
            };
            if let Some(x) = row_i.get_mut(j) {
                *x = (aij - s) / ljj;
            }
        }
        let s = dot_n(row_i, row_i, i);
        let Some(aii) = row_i.get(i).copied() else {
            return false;
        };
        let d = aii - s;
        if d <= T::ZERO || !d.finite() {
            return false;
        }
        if let Some(x) = row_i.get_mut(i) {
            *x = d.sqrt_libm();
        }
        for x in row_i.iter_mut().skip(i + 1) {
            *x = T::ZERO;
        }
    }
    true
}

/// Solves `L y = b` (forward substitution) for lower-triangular L.
pub fn forward_solve<T: Scalar, const M: usize>(l: &[[T; M]; M], b: &[T; M]) -> [T; M] {
    let mut y = [T::ZERO; M];
    for i in 0..M {
        let (Some(row), Some(bi)) = (l.get(i), b.get(i)) else {
            break;
        };
        let s = dot_n(row, &y, i);
        let lii = row.get(i).copied().unwrap_or(T::ONE);
        if let Some(yi) = y.get_mut(i) {
            *yi = (*bi - s) / lii;
        }
    }
    y
}

/// Solves `L^T x = y` (back substitution) for lower-triangular L.
pub fn back_solve<T: Scalar, const M: usize>(l: &[[T; M]; M], y: &[T; M]) -> [T; M] {
    let mut x = [T::ZERO; M];
    for i in (0..M).rev() {
        let mut s = T::ZERO;
        for k in i + 1..M {
            let lki = l.get(k).and_then(|r| r.get(i)).copied().unwrap_or(T::ZERO);
            s += lki * x.get(k).copied().unwrap_or(T::ZERO);
        }
        let lii = l.get(i).and_then(|r| r.get(i)).copied().unwrap_or(T::ONE);
        let yi = y.get(i).copied().unwrap_or(T::ZERO);
        if let Some(xi) = x.get_mut(i) {
            *xi = (yi - s) / lii;
        }
    }
    x
}

/// Solves `(L L^T) x = b`.
pub fn cholesky_solve<T: Scalar, const M: usize>(l: &[[T; M]; M], b: &[T; M]) -> [T; M] {
    back_solve(l, &forward_solve(l, b))
}

/// Whether every entry is finite.
pub fn all_finite<T: Scalar, const R: usize, const C: usize>(a: &[[T; C]; R]) -> bool {
    a.iter().all(|r| r.iter().all(|v| v.finite()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cholesky_reconstructs_and_solves() {
        let a = [[4.0, 2.0, 0.4], [2.0, 5.0, 1.0], [0.4, 1.0, 3.0]];
        let mut l = a;
        assert!(cholesky_in_place(&mut l));
        for i in 0..3 {
            for j in 0..3 {
                let v: f64 = (0..3).map(|k| l[i][k] * l[j][k]).sum();
                assert!((v - a[i][j]).abs() < 1e-14);
            }
        }
        let b = [1.0, -2.0, 0.5];
        let x = cholesky_solve(&l, &b);
        for i in 0..3 {
            let v: f64 = (0..3).map(|k| a[i][k] * x[k]).sum();
            assert!((v - b[i]).abs() < 1e-14);
        }
        let mut bad = [[1.0, 2.0], [2.0, 1.0]];
        assert!(!cholesky_in_place(&mut bad));
        let mut nan = [[f32::NAN]];
        assert!(!cholesky_in_place(&mut nan));
    }
}
