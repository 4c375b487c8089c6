//! dca-firmware: RTIC 2 application of the miniature double-cylinder hydraulic actuator
//! on an STM32F417VE.
//!
//! Structure after quartiq/stabilizer: [`hardware::setup`] configures the chip and
//! returns one [`hardware::Devices`] struct that `init` unpacks; the tasks below never
//! touch registers themselves.
//!
//! With the `qemu` feature the same app runs on QEMU's `netduinoplus2` (STM32F405):
//! see the `qemu` module.
#![no_std]
#![no_main]
#![deny(unsafe_code)]
#![warn(missing_docs)]

pub mod hardware;
#[cfg(feature = "qemu")]
pub mod qemu;

// The defmt transport: RTT to the probe on the board, semihosting under QEMU.
#[cfg(not(feature = "qemu"))]
use defmt_rtt as _;
#[cfg(feature = "qemu")]
use defmt_semihosting as _;
// The panic handler: the message over defmt, then `udf` (a HardFault).
use panic_probe as _;

use rtic_monotonics::systick::prelude::*;

// The monotonic of the async tasks: SysTick at 1 kHz, one tick is 1 ms. (A literal: the
// macro uses the rate both as a `u32` argument and as a `u64` const generic.)
systick_monotonic!(Mono, 1_000);

/// A duration of [`Mono`].
type Duration = <Mono as rtic_monotonics::TimerQueueBasedMonotonic>::Duration;

// defmt log lines carry the monotonic time in ms.
defmt::timestamp!("{=u32:ms}", Mono::now().as_ticks());

/// The RTIC application.
#[rtic::app(device = stm32f4xx_hal::pac, dispatchers = [DCMI, HASH_RNG])]
mod app {
    use super::{hardware, Duration, Mono};
    use dca_core::controller::{Controller, ControllerConfig, ControllerKind, Preset, Sample};
    use rtic_monotonics::systick::prelude::*;

    /// Period of the control task.
    const CONTROL_PERIOD: Duration = Duration::from_millis(1);
    /// Period of the heartbeat.
    const HEARTBEAT_PERIOD: Duration = Duration::from_secs(1);

    /// Resources shared between tasks.
    #[shared]
    struct Shared {
        /// Control ticks since boot.
        ticks: u32,
    }

    /// Resources owned by one task.
    #[local]
    struct Local {
        /// The control law (designed in `init`), owned by the control task.
        controller: Controller,
    }

    /// Runs once after reset, interrupts disabled: sets up the hardware, starts the
    /// monotonic, and spawns the tasks.
    #[init]
    fn init(cx: init::Context) -> (Shared, Local) {
        let devices = hardware::setup(cx.core, cx.device);
        Mono::start(devices.systick, devices.systick_hz);

        // Design on the board (f64, slow path): the "paper" MPC-ESO at the 1 kHz tick.
        let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso);
        cfg.base_dt_s = 1.0e-3;
        let controller = match Controller::new(&cfg) {
            Ok(c) => c,
            Err(e) => defmt::panic!("controller design refused: {=str}", e.as_str()),
        };
        let (n_h, n_c) = controller.periods();
        defmt::info!(
            "dca-firmware {=str}: core clock {=u32} Hz, {=str} ESO every {=u32} ticks, MPC every {=u32}",
            env!("CARGO_PKG_VERSION"),
            devices.systick_hz,
            controller.kind().name(),
            n_h,
            n_c
        );

        // Each task is spawned once, here: spawning cannot fail.
        control::spawn().unwrap();
        heartbeat::spawn().unwrap();

        (Shared { ticks: 0 }, Local { controller })
    }

    /// Sleeps until the next interrupt (RTIC's default idle would busy-spin).
    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// The control tick, highest priority.
    ///
    /// Period 1 ms (1 kHz), released by the SysTick monotonic for now (a hardware timer
    /// later). Deadline: 1 ms after release, i.e. before the next release.
    ///
    /// Skeleton: the sensors are not read yet; the controller steps on a resting
    /// sample so that the whole per-tick path runs on the target.
    #[task(priority = 2, shared = [ticks], local = [controller])]
    async fn control(mut cx: control::Context) {
        let mut next = Mono::now();
        loop {
            let out = cx.local.controller.step(&Sample::default(), 0.0);
            if out.flags.is_error() || !out.v_cmd_mps.is_finite() {
                defmt::panic!("controller error flags {=u8}", out.flags.0);
            }
            // Only the `qemu` build reads the count here.
            let _ticks = cx.shared.ticks.lock(|t| {
                *t = t.wrapping_add(1);
                *t
            });
            #[cfg(feature = "qemu")]
            if _ticks == crate::qemu::PASS_TICKS {
                crate::qemu::pass();
            }
            next += CONTROL_PERIOD;
            Mono::delay_until(next).await;
        }
    }

    /// The heartbeat: logs uptime and the control-tick count.
    ///
    /// Period 1 s, lowest priority; deadline: none (best effort).
    #[task(priority = 1, shared = [ticks])]
    async fn heartbeat(mut cx: heartbeat::Context) {
        let mut next = Mono::now();
        loop {
            next += HEARTBEAT_PERIOD;
            Mono::delay_until(next).await;
            let ticks = cx.shared.ticks.lock(|t| *t);
            defmt::info!("heartbeat: {=u32} control ticks", ticks);
        }
    }
}
