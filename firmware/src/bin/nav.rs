//! The navigation application: the board supplies the frame link, the time base and (on a
//! real board) the IMU; [`firmware::app::NavApp`] (crate `nav-app`) runs the navigator over
//! the filter of the compile-time model.
#![no_std]
#![no_main]

use cortex_m_rt::entry;
use firmware::app::NavApp;
use firmware::model;
use firmware::{board, stack};

/// One navigation solution per this many IMU epochs (10 Hz at 200 Hz).
const NAV_DIVIDER: u16 = 20;
/// One health frame per this many IMU epochs (1 Hz at 200 Hz).
const HEALTH_EVERY: u32 = 200;

type App = NavApp<{ model::N }>;

/// The application in static RAM (about 10 KiB with its navigator), built in this function's
/// own frame so `main`'s frame, live for the whole run, holds no copy of it.
#[inline(never)]
fn make_app() -> &'static mut App {
    let app = NavApp::new::<model::Model>(model::config(), NAV_DIVIDER, HEALTH_EVERY);
    let Ok(app) = app else {
        // the compile-time model's configuration is refused: a build error in practice
        panic!("nav: the filter refuses the model's configuration")
    };
    let Some(slot) = cortex_m::singleton!(: App = app) else {
        panic!("nav: the application is built once")
    };
    slot
}

#[entry]
fn main() -> ! {
    stack::paint();
    let app = make_app();
    board::run_nav(app)
}
