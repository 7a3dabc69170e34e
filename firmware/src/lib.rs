//! Navigation board firmware, embassy-style: a board-independent application ([`app`], crate
//! `nav-app`,
//! generic over `embedded-io` / `embedded-hal` 1.0 traits and a [`time::TimeBase`]) and one
//! folder per board under [`boards`] supplying the UART, the time base and the sensors.
//! The board is chosen by cargo feature (`board-mps2-an386`, the default, or
//! `board-stm32f407`), the filter model by `model-n` / `model-nbk` / `model-kf-gins`.
//!
//! Binaries: `firmware` (the cross-platform self-test), `bench` (instruction, RAM and stack
//! budgets), `uart-echo` (UART loopback), `nav` (the application).
#![no_std]

#[macro_use]
pub mod fmt;

pub mod boards;
pub mod icm42688;
pub mod model;
pub mod scenario;
pub mod stack;

pub use boards::board;
/// The board-independent application (crate `nav-app`).
pub use nav_app::app;
/// The time base a board supplies (crate `nav-app`).
pub use nav_app::time;
