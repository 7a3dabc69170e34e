//! `nav-app`: the navigation board's application, independent of any board. Wire frames
//! (`nav_core::wire`) come in over an `embedded_io` link, [`NavApp`] runs them through
//! `nav_core`'s [`Navigator`](nav_core::navigator::Navigator) (start-up on the first fix,
//! the IMU guard, nearest-epoch fix scheduling) and sends solutions and health frames back;
//! time comes from the board's [`TimeBase`].
//!
//! `#![no_std]`, no allocation. The firmware runs it on the MCU; `hw-bridge` (`stream
//! --host-filter`) and `xtask` (the HIL comparison) run the very same code on the host, so
//! their solutions are bit-exact with the board's.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod app;
pub mod time;

pub use app::{serve, AppCounters, NavApp, COURSE_MIN_SPEED_MPS};
pub use time::TimeBase;
