//! Hardware setup: the only module that configures peripherals.
//!
//! [`setup`] takes the core and device peripherals from RTIC's `init`, brings up the
//! clock tree and returns everything the tasks need in one [`Devices`] struct.

use stm32f4xx_hal::{
    pac,
    rcc::{Clocks, RccExt as _},
};

#[cfg(not(feature = "qemu"))]
use stm32f4xx_hal::{rcc::Config, time::Hertz};

/// HSE crystal on the board, Hz.
#[cfg(not(feature = "qemu"))]
pub const HSE_HZ: u32 = 8_000_000;

/// Core clock (SYSCLK = HCLK), Hz: 168 MHz from the HSE through the main PLL on the
/// board; QEMU's fixed core clock in the `qemu` build.
pub const SYSCLK_HZ: u32 = 168_000_000;

/// The devices of the board, set up and ready for the tasks.
pub struct Devices {
    /// The SysTick timer, the time base of the monotonic.
    pub systick: cortex_m::peripheral::SYST,
    /// The frozen clock tree. In the `qemu` build these are the reset values (HSI
    /// 16 MHz), not QEMU's clocks: nothing is configured there.
    pub clocks: Clocks,
    /// Frequency of the SysTick clock source (the core clock), Hz: the frozen SYSCLK
    /// on the board, [`SYSCLK_HZ`] under QEMU.
    pub systick_hz: u32,
}

/// Sets up the clocks and returns the devices.
///
/// Board: HSE 8 MHz -> PLL -> 168 MHz SYSCLK, APB1 42 MHz, APB2 84 MHz (the HAL picks
/// the largest legal bus clocks and the flash wait states).
///
/// `qemu` build: QEMU does not emulate the RCC (`freeze` would wait for HSERDY
/// forever), so the RCC is only constrained, which touches no register.
pub fn setup(core: cortex_m::Peripherals, device: pac::Peripherals) -> Devices {
    #[cfg(not(feature = "qemu"))]
    let (rcc, systick_hz) = {
        let rcc = device
            .RCC
            .freeze(Config::hse(Hertz::from_raw(HSE_HZ)).sysclk(Hertz::from_raw(SYSCLK_HZ)));
        let sysclk = rcc.clocks.sysclk().raw();
        (rcc, sysclk)
    };
    #[cfg(feature = "qemu")]
    let (rcc, systick_hz) = (device.RCC.constrain(), SYSCLK_HZ);

    Devices {
        systick: core.SYST,
        clocks: rcc.clocks,
        systick_hz,
    }
}
