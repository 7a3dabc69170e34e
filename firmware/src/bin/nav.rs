//! The navigation application: the board supplies the frame link, the time base and (on a
//! real board) the IMU; [`firmware::app::NavApp`] (crate `nav-app`) runs the filter of the compile-time model.
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

#[entry]
fn main() -> ! {
    stack::paint();
    let Ok(mut app) =
        NavApp::<{ model::N }>::new(model::LAYOUT, model::config(), NAV_DIVIDER, HEALTH_EVERY)
    else {
        // the compile-time model's configuration is refused: a build error in practice
        panic!("nav: the filter refuses the model's configuration")
    };
    board::run_nav(&mut app)
}
