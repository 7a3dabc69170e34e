//! The [`super::Navigator`]'s error.

use crate::align::AlignError;
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

/// The inner filter or guard error is part of the message, so `source()` is `None`: a chain
/// printer (`anyhow`'s `{:#}`) would otherwise print it twice. Match on the variant for it.
impl core::error::Error for NavigatorError {}

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

/// A static window that did not align ([`super::ImuEvent::AlignFailed`]); a new window starts.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum AlignFailure {
    /// The static test or the levelling failed.
    Align(AlignError),
    /// No valid GNSS fix in the window (no position).
    NoFix,
    /// The filter refused the initial state.
    Filter(FilterError),
}

impl core::fmt::Display for AlignFailure {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Self::Align(e) => write!(f, "static window not aligned: {e}"),
            Self::NoFix => f.write_str("static window not aligned: no valid GNSS fix in it"),
            Self::Filter(e) => {
                write!(
                    f,
                    "static window not aligned: the filter refused the initial state: {e}"
                )
            }
        }
    }
}

/// As [`NavigatorError`]: the inner error is in the message, `source()` is `None`.
impl core::error::Error for AlignFailure {}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    #[test]
    fn align_failure_messages_name_the_cause_once() {
        let e = AlignFailure::Align(AlignError::NonFinite { index: 3 });
        let m = e.to_string();
        assert!(m.starts_with("static window not aligned: "), "{m}");
        assert!(
            m.ends_with(&AlignError::NonFinite { index: 3 }.to_string()),
            "{m}"
        );
        assert_eq!(
            AlignFailure::NoFix.to_string(),
            "static window not aligned: no valid GNSS fix in it"
        );
        let f = AlignFailure::Filter(FilterError::InitialState);
        assert!(f
            .to_string()
            .contains(&FilterError::InitialState.to_string()));
        let as_error: &dyn core::error::Error = &f;
        assert!(as_error.source().is_none());
    }
}
