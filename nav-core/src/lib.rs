//! `nav-core`: the INS/GNSS navigation core, identical on a Cortex-M4F and on the host.
//!
//! `#![no_std]`, no `alloc`: every size is fixed at compile time (const generics), nothing in
//! the filter path allocates, panics or indexes unchecked. The nominal navigation state is
//! `f64`; the covariance scalar is a type parameter (`f32` on the MCU, `f64` on the host).
//!
//! Conventions (see `docs/DESIGN.md`): navigation frame NED, body frame FRD, WGS84 earth,
//! GPS seconds of week for time, SI units inside.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::unreachable,
        clippy::todo,
        clippy::unimplemented
    )
)]

pub mod align;
pub mod allan;
pub mod attitude;
pub mod config;
pub mod earth;
pub mod filter;
pub mod imu_guard;
pub mod model;
pub mod nav;
pub mod navigator;
pub mod scalar;
pub mod selftest;
pub mod types;
pub mod wire;
