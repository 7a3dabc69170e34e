//! The [`super::Navigator`]'s error.

use crate::filter::FilterError;
use crate::imu_guard::GuardError;

/// Errors of the navigator. The navigator stays usable after every one.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum NavigatorError {
    /// The filter refused its configuration or initial state, or failed on a sample.
    Filter(FilterError),
    /// The IMU guard's fault (time not increasing, gap too long): the sample was not used.
    Guard(GuardError),
    /// The fix queue is full (more than `Q` fixes ahead of the IMU): the fix was dropped.
    FixQueueFull {
        /// Time of the dropped fix, s.
        t_s: f64,
    },
}

impl core::fmt::Display for NavigatorError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Filter(e) => write!(f, "navigator: {e}"),
            Self::Guard(e) => write!(f, "navigator: {e}"),
            Self::FixQueueFull { t_s } => write!(
                f,
                "navigator: GNSS fix at {t_s:.3} s dropped: fix queue full (fixes ahead of the IMU)"
            ),
        }
    }
}

impl core::error::Error for NavigatorError {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            Self::Guard(e) => Some(e),
            _ => None,
        }
    }
}

impl From<FilterError> for NavigatorError {
    fn from(e: FilterError) -> Self {
        Self::Filter(e)
    }
}

impl From<GuardError> for NavigatorError {
    fn from(e: GuardError) -> Self {
        Self::Guard(e)
    }
}
