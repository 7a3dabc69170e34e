//! Board support, one folder per board; [`board`] is the one selected by cargo feature.

#[cfg(all(feature = "board-mps2-an386", feature = "board-stm32f407"))]
compile_error!("choose one board feature (board-stm32f407 needs --no-default-features)");

#[cfg(feature = "board-mps2-an386")]
pub mod mps2_an386;
#[cfg(feature = "board-mps2-an386")]
pub use mps2_an386 as board;

#[cfg(feature = "board-stm32f407")]
pub mod stm32f407;
#[cfg(feature = "board-stm32f407")]
pub use stm32f407 as board;
