//! Why a run stopped in the middle of the data: the typed cause of [`super::RunError::Fault`].

use nav_core::filter::FilterError;

/// Why a run stopped in the middle of the data ([`super::RunError::Fault`]); the nav-core error
/// where there is one (its message is the nav-core error's own).
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum FaultCause {
    /// The IMU guard refused a sample (time not increasing, gap too long).
    #[error(transparent)]
    Guard(nav_core::imu_guard::GuardError),
    /// The filter refused a sample or a fix, or failed numerically.
    #[error(transparent)]
    Filter(FilterError),
    /// Another navigator error (e.g. its fix queue overflowed).
    #[error(transparent)]
    Navigator(nav_core::navigator::NavigatorError),
    /// An implausible IMU sample with `stop_on_implausible` set.
    #[error("implausible IMU sample: {0}")]
    Implausible(nav_core::imu_guard::Implausible),
}

impl From<nav_core::navigator::NavigatorError> for FaultCause {
    fn from(e: nav_core::navigator::NavigatorError) -> Self {
        use nav_core::navigator::NavigatorError as N;
        match e {
            N::Guard(g) => Self::Guard(g),
            N::Filter(f) => Self::Filter(f),
            other => Self::Navigator(other),
        }
    }
}
