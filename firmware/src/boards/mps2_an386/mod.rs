//! The emulated board: Arm MPS2-AN386 (Cortex-M4F, 25 MHz) as run by
//! `qemu-system-arm -machine mps2-an386`. UART0 (CMSDK APB UART, register driver in
//! [`uart`]) carries the frames, SysTick ([`systick`]) is the time base, semihosting carries
//! logs and the exit code. It has no IMU: IMU and GNSS frames arrive on the UART (HIL).

pub mod systick;
pub mod uart;

pub use systick::{SysTickClock, CLOCK_HZ};
pub use uart::{CmsdkUart, UART0_BASE};

/// The board's name as `cargo xtask fw --board` spells it.
pub const NAME: &str = "mps2-an386";

/// UART baud rate (qemu ignores it; the divider is programmed as on hardware).
pub const BAUD: u32 = 115_200;

/// What the application gets from the board.
pub struct Board {
    /// UART0: frames in and out.
    pub uart: CmsdkUart,
    /// SysTick time base, 25 MHz.
    pub clock: SysTickClock,
}

/// Takes the core peripherals and sets up UART0 and SysTick. Call once.
pub fn init() -> Board {
    let Some(cp) = cortex_m::Peripherals::take() else {
        crate::error!("board init: core peripherals already taken");
        exit(false)
    };
    // SAFETY: UART0 of this board; `Peripherals::take` above succeeds only once, so this runs once.
    let uart = unsafe { CmsdkUart::new(UART0_BASE, CLOCK_HZ, BAUD) };
    Board {
        uart,
        clock: SysTickClock::new(cp.SYST),
    }
}

/// Ends the program: qemu exits with status 0 (`ok`) or 1 through semihosting.
pub fn exit(ok: bool) -> ! {
    use cortex_m_semihosting::debug;
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    #[allow(clippy::empty_loop)]
    loop {}
}

#[cfg(feature = "defmt")]
use defmt_semihosting as _;

#[cfg(feature = "defmt")]
#[defmt::panic_handler]
fn defmt_panic() -> ! {
    exit(false)
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    #[cfg(not(feature = "defmt"))]
    cortex_m_semihosting::hprintln!("firmware panic: {}", info);
    #[cfg(feature = "defmt")]
    defmt::error!("firmware panic: {}", defmt::Display2Format(info));
    exit(false)
}

/// The navigation application on this board: IMU and GNSS frames arrive on UART0 (HIL), the
/// solutions and health frames leave on it. Never returns.
pub fn run_nav<const N: usize>(app: &mut crate::app::NavApp<N>) -> ! {
    let mut b = init();
    crate::info!("nav: {} states, serving frames on UART0", N);
    app.set_stack_probe(crate::stack::peak_bytes);
    let Ok(never) = crate::app::serve(app, &mut b.uart, &mut b.clock);
    match never {}
}
