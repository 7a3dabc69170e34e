//! The navigation application: the board supplies the frame link, the time base and (on a
//! real board) the IMU; [`firmware::app::NavApp`] runs the filter of the compile-time model.
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
    let mut app: NavApp<{ model::N }> =
        NavApp::new(model::LAYOUT, model::config(), NAV_DIVIDER, HEALTH_EVERY);
    board::run_nav(&mut app)
}
