//! Support for the emulated build (`qemu` feature, QEMU machine `netduinoplus2`).
//!
//! A run passes when the control task has ticked [`PASS_TICKS`] times: it prints
//! [`PASS_LINE`] on QEMU's stderr and ends QEMU with status 0. A HardFault (a panic
//! ends in one through panic-probe's `udf`) ends QEMU with status 1. defmt frames go to
//! QEMU's stdout (decode with `defmt-print -e ELF`).

use cortex_m_rt::{exception, ExceptionFrame};

/// Control ticks after which the emulated run passes.
pub const PASS_TICKS: u32 = 100;

/// The line printed when the run passes.
pub const PASS_LINE: &str = "dca-firmware: 100 ticks ok";

/// Prints [`PASS_LINE`] over semihosting and ends QEMU with success.
pub fn pass() -> ! {
    semihosting::eprintln!("{}", PASS_LINE);
    semihosting::process::exit(0)
}

/// Ends QEMU with failure on any hard fault, so that a crash is a non-zero status.
#[allow(unsafe_code)] // cortex-m-rt requires the HardFault handler to be `unsafe fn`.
#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    semihosting::process::exit(1)
}
