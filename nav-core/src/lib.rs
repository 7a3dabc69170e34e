//! `nav-core`: the INS/GNSS navigation core, identical on a Cortex-M4F and on the host.
//!
//! `#![no_std]`, no `alloc`: every size is fixed at compile time (const generics), nothing in
//! the filter path allocates, panics or indexes unchecked. The nominal navigation state is
//! `f64`; the covariance scalar is a type parameter (`f32` on the MCU, `f64` on the host).
//!
//! Conventions (see `docs/DESIGN.md`): navigation frame NED, body frame FRD, WGS84 earth,
//! GPS seconds of week for time, SI units inside.
//!
//! # The loop
//!
//! [`navigator::Navigator`] is what a user drives: push IMU samples and GNSS fixes as they
//! come, read the solution. It owns the start-up (here: on the first fix, levelling the
//! samples before it), the IMU guard (gaps, implausible samples) and the fix scheduling (a
//! fix is applied at the IMU epoch nearest to it); every call says what happened.
//! `cargo run -p nav-core --example own_stream` runs it on a generated drive or on your
//! files.
//!
//! ```
//! use nav_core::{
//!     AlignMode, FilterConfig, FirstFixAlign, FixQuality, GnssFix, ImuSample, NavigatorConfig,
//!     NavigatorNbk, LAYOUT_NBK,
//! };
//!
//! let cfg = NavigatorConfig::new(
//!     FilterConfig::source_nbk_model(),
//!     AlignMode::FirstFix(FirstFixAlign::default()),
//! );
//! let mut nav = NavigatorNbk::new(LAYOUT_NBK, cfg)?;
//! let (lat, lon, h) = (0.82, 0.27, 350.0); // rad, rad, m
//! let g = nav_core::earth::gravity_mps2(lat, h);
//! let mut used = 0;
//! // 20 s at 100 Hz of a level IMU at rest (gyros see nothing here), a fix every second
//! for k in 1..=2000 {
//!     let t_s = 1000.0 + f64::from(k) * 0.01;
//!     let imu = ImuSample {
//!         t_s,
//!         dtheta_rad: [0.0; 3],
//!         dv_mps: [0.0, 0.0, -g * 0.01],
//!         temperature_c: f64::NAN,
//!     };
//!     let step = nav.push_imu(&imu)?;
//!     used += step.fixes.iter().filter(|f| f.used()).count();
//!     if k % 100 == 0 {
//!         let fix = GnssFix {
//!             t_s,
//!             lat_rad: lat,
//!             lon_rad: lon,
//!             h_m: h,
//!             pos_std_ned_m: [0.5, 0.5, 1.0],
//!             quality: FixQuality::Single,
//!             ..GnssFix::default()
//!         };
//!         nav.push_gnss(&fix)?; // the first starts the filter, the others wait for their epoch
//!     }
//! }
//! used += nav.flush().iter().filter(|f| f.used()).count(); // the fix due at the last epoch
//! let sol = nav.solution().expect("started on the first fix");
//! assert_eq!(used, 19); // every fix but the first, which started the filter
//! assert!((sol.h_m - h).abs() < 0.5 && sol.vel_ned_mps.iter().all(|v| v.abs() < 0.05));
//! # Ok::<(), nav_core::NavigatorError>(())
//! ```
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

pub mod aiding;
pub mod align;
pub mod allan;
pub mod attitude;
pub mod config;
pub mod earth;
pub mod filter;
pub mod imu_guard;
pub mod model;
pub mod navigator;
pub mod scalar;
pub mod selftest;
pub mod strapdown;
pub mod types;
pub mod wire;

// The user API at the crate root: the navigator and its configuration, the samples, fixes and
// solutions it takes and gives, the state layouts and the errors. The modules hold the rest.
pub use config::{ConfigError, FilterConfig};
pub use filter::FilterError;
pub use imu_guard::{GuardConfig, GuardError};
pub use model::{Block, Layout, LAYOUT_KF_GINS, LAYOUT_N, LAYOUT_NBK, LAYOUT_NBK_SINGLE};
pub use navigator::{
    AlignMode, FirstFixAlign, FixEvent, ImuStep, Navigator, NavigatorConfig, NavigatorError,
    NavigatorKfGins, NavigatorN, NavigatorNbk, NavigatorNbkSingle,
};
pub use scalar::Scalar;
pub use types::{FixQuality, GnssFix, ImuSample, NavSolution};
