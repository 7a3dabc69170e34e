//! The scalar type of the filter's covariance, gains and error-state matrices: `f32` on the
//! MCU, `f64` on the host. The nominal navigation state is always `f64` (see [`crate::strapdown`]).
//!
//! Every operation the filter needs beyond `+ - * /` goes through this trait and is computed
//! with `libm` (or is correctly rounded by IEEE 754), so the host and the MCU builds of the same
//! code produce bit-identical results (checked by the firmware self-test).

use core::fmt::{Debug, Display};

/// A real scalar for covariance arithmetic.
///
/// `nalgebra::RealField` is a supertrait so users can move filter matrices into nalgebra
/// algorithms; the filter itself only uses the arithmetic operators and the methods below
/// (never `RealField`'s transcendental functions, whose implementation depends on whether
/// nalgebra was built with `std`).
pub trait Scalar: nalgebra::RealField + Copy + Default + Debug + Display + 'static {
    /// Zero.
    const ZERO: Self;
    /// One.
    const ONE: Self;
    /// One half.
    const HALF: Self;
    /// Whether a filter with this covariance scalar runs the single-precision mechanization
    /// ([`crate::strapdown::Strapdown::update_single`], the increments in `f32`, the nominal
    /// state's sums in `f64`) instead of the mixed-precision one
    /// ([`crate::strapdown::Strapdown::update`]): true for `f32` (the MCU build, and the
    /// host's `f32` mode, which must match it bit for bit), false for `f64`.
    const SINGLE_PRECISION_MECHANIZATION: bool;
    /// Rounds an `f64` to this type (round-to-nearest for `f32`).
    fn of_f64(x: f64) -> Self;
    /// An `f32` as this type (exact).
    fn of_f32(x: f32) -> Self;
    /// The value as `f64` (exact).
    fn to_f64(self) -> f64;
    /// Square root (`libm`, correctly rounded); NaN for negative input.
    fn sqrt_libm(self) -> Self;
    /// True when the value is neither NaN nor infinite.
    fn finite(self) -> bool;
    /// Absolute value.
    fn abs_val(self) -> Self;
    /// Sine (`libm`), rad.
    fn sin_libm(self) -> Self;
    /// Cosine (`libm`), rad.
    fn cos_libm(self) -> Self;
    /// `e^x` (`libm`).
    fn exp_libm(self) -> Self;
    /// `e^x - 1` without cancellation (`libm`).
    fn expm1_libm(self) -> Self;
}

impl Scalar for f32 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const HALF: Self = 0.5;
    const SINGLE_PRECISION_MECHANIZATION: bool = true;
    #[inline]
    fn of_f64(x: f64) -> Self {
        x as f32
    }
    #[inline]
    fn of_f32(x: f32) -> Self {
        x
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self as f64
    }
    #[inline]
    fn sqrt_libm(self) -> Self {
        libm::sqrtf(self)
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline]
    fn abs_val(self) -> Self {
        libm::fabsf(self)
    }
    #[inline]
    fn sin_libm(self) -> Self {
        libm::sinf(self)
    }
    #[inline]
    fn cos_libm(self) -> Self {
        libm::cosf(self)
    }
    #[inline]
    fn exp_libm(self) -> Self {
        libm::expf(self)
    }
    #[inline]
    fn expm1_libm(self) -> Self {
        libm::expm1f(self)
    }
}

impl Scalar for f64 {
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    const HALF: Self = 0.5;
    const SINGLE_PRECISION_MECHANIZATION: bool = false;
    #[inline]
    fn of_f64(x: f64) -> Self {
        x
    }
    #[inline]
    fn of_f32(x: f32) -> Self {
        f64::from(x)
    }
    #[inline]
    fn to_f64(self) -> f64 {
        self
    }
    #[inline]
    fn sqrt_libm(self) -> Self {
        libm::sqrt(self)
    }
    #[inline]
    fn finite(self) -> bool {
        self.is_finite()
    }
    #[inline]
    fn abs_val(self) -> Self {
        libm::fabs(self)
    }
    #[inline]
    fn sin_libm(self) -> Self {
        libm::sin(self)
    }
    #[inline]
    fn cos_libm(self) -> Self {
        libm::cos(self)
    }
    #[inline]
    fn exp_libm(self) -> Self {
        libm::exp(self)
    }
    #[inline]
    fn expm1_libm(self) -> Self {
        libm::expm1(self)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_round_trip_and_sqrt_match_ieee() {
        let x = <f32 as Scalar>::of_f64(0.1);
        assert_eq!(x, 0.1f32);
        assert_eq!(x.to_f64(), 0.1f32 as f64);
        assert_eq!(<f32 as Scalar>::sqrt_libm(2.0), core::f32::consts::SQRT_2);
        assert_eq!(<f64 as Scalar>::sqrt_libm(2.0), core::f64::consts::SQRT_2);
        assert!(!<f32 as Scalar>::finite(f32::NAN));
        assert!(!<f64 as Scalar>::finite(f64::INFINITY));
        assert_eq!(<f64 as Scalar>::abs_val(-3.5), 3.5);
    }
}
