//! Support for the emulated build (`qemu` feature, QEMU machine `netduinoplus2`).
//!
//! * [`SimSensors`] stands in for the ADC and the encoder in the local source:
//!   Xi integrates the drive command and Xo follows Xi (no hydraulics), the
//!   pressures sit at the accumulator precharge and the force at 0. It lets the
//!   console's motion commands be exercised; closed-loop runs with a plant go
//!   through HIL frames.
//! * The console command `quit` ends QEMU with status 0 ([`exit`]); a HardFault
//!   (a panic ends in one through panic-probe's `udf`) ends it with status 1.
//! * defmt frames go to QEMU's stdout over semihosting (decode with
//!   `defmt-print -e ELF`).

use cortex_m_rt::{exception, ExceptionFrame};
use dca_core::controller::Sample;

/// The simulated sensors of the local source.
#[derive(Clone, Copy, Debug, Default)]
pub struct SimSensors {
    xi_m: f32,
}

impl SimSensors {
    /// The sample now.
    pub fn sample(&self) -> Sample {
        Sample {
            xo_m: self.xi_m,
            xi_m: self.xi_m,
            p1_pa: 1.0e6,
            p2_pa: 1.0e6,
            ft_n: 0.0,
        }
    }

    /// Move by the command over one period.
    pub fn advance(&mut self, v_cmd_mps: f32, dt_s: f32) {
        self.xi_m += v_cmd_mps * dt_s;
    }
}

/// End QEMU with `status` (semihosting).
pub fn exit(status: i32) -> ! {
    semihosting::process::exit(status)
}

/// Ends QEMU with failure on any hard fault, so that a crash is a non-zero status.
#[allow(unsafe_code)] // cortex-m-rt requires the HardFault handler to be `unsafe fn`.
#[exception]
unsafe fn HardFault(_frame: &ExceptionFrame) -> ! {
    semihosting::process::exit(1)
}
