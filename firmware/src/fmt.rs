//! Logging shim: `info!`, `warn!`, `error!` go to `defmt` (transport defmt-semihosting) with
//! the `defmt` feature, to semihosting `hprintln` on the emulated board otherwise, and nowhere
//! on a real board without `defmt` (semihosting halts a board with no debugger attached).
//! Use only `{}` placeholders and plain values (integers, floats, `&str`) so every backend
//! accepts the same call.

#[doc(hidden)]
#[cfg(all(not(feature = "defmt"), feature = "board-mps2-an386"))]
pub use cortex_m_semihosting::hprintln as __hprintln;

/// Logs at info level (see the module docs for where it goes).
#[cfg(feature = "defmt")]
#[macro_export]
macro_rules! info { ($($t:tt)*) => { ::defmt::info!($($t)*) } }
/// Logs at warning level.
#[cfg(feature = "defmt")]
#[macro_export]
macro_rules! warn { ($($t:tt)*) => { ::defmt::warn!($($t)*) } }
/// Logs at error level.
#[cfg(feature = "defmt")]
#[macro_export]
macro_rules! error { ($($t:tt)*) => { ::defmt::error!($($t)*) } }

/// Logs at info level (see the module docs for where it goes).
#[cfg(all(not(feature = "defmt"), feature = "board-mps2-an386"))]
#[macro_export]
macro_rules! info { ($($t:tt)*) => { $crate::fmt::__hprintln!($($t)*) } }
/// Logs at warning level.
#[cfg(all(not(feature = "defmt"), feature = "board-mps2-an386"))]
#[macro_export]
macro_rules! warn { ($fmt:literal $($t:tt)*) => { $crate::fmt::__hprintln!(concat!("WARN ", $fmt) $($t)*) } }
/// Logs at error level.
#[cfg(all(not(feature = "defmt"), feature = "board-mps2-an386"))]
#[macro_export]
macro_rules! error { ($fmt:literal $($t:tt)*) => { $crate::fmt::__hprintln!(concat!("ERROR ", $fmt) $($t)*) } }

/// Logs at info level (see the module docs for where it goes).
#[cfg(all(not(feature = "defmt"), not(feature = "board-mps2-an386")))]
#[macro_export]
macro_rules! info { ($($t:tt)*) => { { let _ = core::format_args!($($t)*); } } }
/// Logs at warning level.
#[cfg(all(not(feature = "defmt"), not(feature = "board-mps2-an386")))]
#[macro_export]
macro_rules! warn { ($($t:tt)*) => { { let _ = core::format_args!($($t)*); } } }
/// Logs at error level.
#[cfg(all(not(feature = "defmt"), not(feature = "board-mps2-an386")))]
#[macro_export]
macro_rules! error { ($($t:tt)*) => { { let _ = core::format_args!($($t)*); } } }
