//! dca-firmware: RTIC 2 application of the miniature double-cylinder hydraulic actuator
//! on an STM32F417VE.
//!
//! Structure after quartiq/stabilizer: [`hardware::setup`] configures the chip and
//! returns one [`hardware::Devices`] struct that `init` unpacks; the tasks never touch
//! registers themselves. All control logic is dca-core's, called unchanged:
//! [`dca_app::supervisor::ControlLoop`] (supervisor, reference, controller) per tick,
//! [`dca_app::console::Console`] for the serial console,
//! [`dca_app::settings::Settings`] for the settings and their flash image, and
//! [`dca_app::frame`] for the HIL link.
//!
//! Tasks, by priority:
//!
//! | task | priority | released by | period / deadline |
//! |---|---|---|---|
//! | `control` | 4 | ADC scan done (board), SysTick (QEMU), a HIL frame | 1 ms / [`DEADLINE_US`] |
//! | `adc_done` | 3 | DMA2 stream 0 transfer complete | 1 ms / before the next scan |
//! | `tick` | 3 | SysTick | 1 ms / 1 ms |
//! | `hil_rx` | 3 | USART2 byte received | per byte / one byte time |
//! | `console_rx` | 2 | USART1 byte received | per byte / one byte time |
//! | `console` | 1 | bytes and telemetry rows | none (best effort) |
//! | idle | 0 | - | `wfi` |
//!
//! `control` sits above every task that releases it, so a release is always
//! taken before the next one can be made: two releases in a row without a tick
//! between them (an `overrun`) mean the tick itself was late, never that an
//! equally urgent handler happened to be served first.
//!
//! With the `qemu` feature the same app runs on QEMU's `netduinoplus2`
//! (STM32F405): see the `qemu` module.
#![no_std]
#![no_main]

pub mod hardware;
pub mod machine;
#[cfg(feature = "qemu")]
pub mod qemu;

// The defmt transport: RTT to the probe on the board, semihosting under QEMU.
#[cfg(not(feature = "qemu"))]
use defmt_rtt as _;
#[cfg(feature = "qemu")]
use defmt_semihosting as _;
/// The panic handler: the location over defmt, then `udf` (a HardFault; under QEMU
/// the HardFault handler ends QEMU with status 1). Only the location is printed: the
/// message would pull in `core::fmt`'s formatting machinery (several KiB of flash).
#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    match info.location() {
        Some(l) => defmt::error!("panic at {=str}:{=u32}", l.file(), l.line()),
        None => defmt::error!("panic"),
    }
    cortex_m::asm::udf()
}

use core::sync::atomic::{AtomicU32, Ordering};
use dca_app::console::LogRow;
use dca_app::frame::MAX_FRAME_LEN;
use dca_core::controller::Sample;

use machine::RunConfig;

/// Control timer periods since start-up (1 ms each): the log timestamp.
static UPTIME_MS: AtomicU32 = AtomicU32::new(0);

// defmt log lines carry the uptime in ms.
defmt::timestamp!("{=u32:ms}", UPTIME_MS.load(Ordering::Relaxed));

/// Deadline of the control task, us after its release (the interrupt that made
/// the sample available). Checked at the end of every tick; a miss trips the
/// `overrun` fault and zeroes the drive at once.
pub const DEADLINE_US: u32 = 500;

/// Capacity of the telemetry queue from the control task to the console task,
/// rows (plus one slot heapless's single-producer queue keeps free). At the
/// fastest stream (a row every 10 ms) it covers 0.48 s of a busy console: the
/// longest reply (`get`, about 0.15 s at 115 200 baud) with a wide margin. A
/// row that does not fit is counted and missing from the stream (its time
/// stamp shows the gap).
pub const TELEMETRY_ROWS: usize = 48;

/// A telemetry row of stream `generation` (rows of an older stream are not
/// printed).
pub type RowEvent = (u8, LogRow);

/// The console's receive path: [`dca_app::console::Receiver`] sized by
/// [`dca_app::console::RX_QUEUE_BYTES`].
pub type ConsoleInput = dca_app::console::Receiver<{ dca_app::console::RX_QUEUE_BYTES }>;

/// One encoded HIL frame for the transmitter.
#[derive(Clone, Copy, Debug)]
pub struct FrameBytes {
    /// The bytes, delimiter included.
    pub buf: [u8; MAX_FRAME_LEN],
    /// How many are used.
    pub len: u8,
}

/// The console transmitter as a text sink: one out-of-line `write_str`, so that the
/// console's many small writes do not each inline the USART loop.
pub struct ConsoleOut<'a>(pub &'a mut hardware::ConsoleTx);

impl core::fmt::Write for ConsoleOut<'_> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        dca_app::console::Output::write_bytes(self, s.as_bytes());
        Ok(())
    }
}

impl dca_app::console::Output for ConsoleOut<'_> {
    #[inline(never)]
    fn write_bytes(&mut self, bytes: &[u8]) {
        use embedded_hal_nb::serial::Write as _;
        for &b in bytes {
            // The HAL's USART write cannot fail other than by `WouldBlock`.
            let _ = nb::block!(self.0.write(b));
        }
    }
}

/// Rows of the record's block in main SRAM (96 KiB).
pub const RECORD_SRAM_ROWS: usize = 6144;
/// Rows of the record's block in the CCM RAM (64 KiB, all of it).
pub const RECORD_CCM_ROWS: usize = 4096;

/// The board's local sensor source: ADC scan and encoder.
#[cfg(not(feature = "qemu"))]
pub type Sensors = hardware::SensorFrontEnd;
/// The emulated build's local sensor source.
#[cfg(feature = "qemu")]
pub type Sensors = qemu::SimSensors;

/// The local sensor source as the control task sees it.
pub trait SensorSource {
    /// The calibrated sample of this tick.
    fn sample(&mut self, run: &RunConfig) -> Sample;
    /// The command applied over the next period, m/s.
    fn applied(&mut self, _v_mps: f32, _dt_s: f32) {}
    /// The scan's DMA transfer completed; false if it was lost.
    fn scan_done(&mut self) -> bool {
        false
    }
}

#[cfg(not(feature = "qemu"))]
impl SensorSource for hardware::SensorFrontEnd {
    fn sample(&mut self, run: &RunConfig) -> Sample {
        run.calibrate(&self.read())
    }
    fn scan_done(&mut self) -> bool {
        self.on_transfer_complete()
    }
}

#[cfg(feature = "qemu")]
impl SensorSource for qemu::SimSensors {
    fn sample(&mut self, _run: &RunConfig) -> Sample {
        qemu::SimSensors::sample(self)
    }
    fn applied(&mut self, v_mps: f32, dt_s: f32) {
        self.advance(v_mps, dt_s);
    }
}

/// The RTIC application.
#[rtic::app(device = stm32f4xx_hal::pac, dispatchers = [DCMI, HASH_RNG])]
mod app {
    use super::{
        hardware, machine, ConsoleInput, ConsoleOut, FrameBytes, RowEvent, SensorSource as _,
        Sensors, DEADLINE_US, RECORD_CCM_ROWS, RECORD_SRAM_ROWS, TELEMETRY_ROWS, UPTIME_MS,
    };
    use core::fmt::Write as _;
    use dca_app::console::{
        write_log_header, write_log_row, Console, Received, ECHO_BYTES, MAX_LINE,
    };
    use dca_app::frame::{self, CommandFrame, FrameReader, ReadEvent, MAX_FRAME_LEN};
    use dca_app::record::{PackedRow, Recorder, ROW_BYTES};
    use dca_app::settings::{Settings, BOARD_DT_S, IMAGE_LEN};
    use dca_app::supervisor::Faults;
    use dca_app::supervisor::State;
    use dca_app::text::Buf;
    use embedded_hal_nb::serial::{Read as _, Write as _};
    use hardware::{
        ConsoleRx, ConsoleTx, HilRx, HilTx, SettingsStore, TickTimer, UsClock, Watchdog,
    };
    use heapless::spsc::{Consumer, Producer, Queue};
    use machine::{trip, ConsoleState, Ctl, Machine, Release, Source};
    use rtic_sync::signal::{SignalReader, SignalWriter};
    use stm32f4xx_hal::pac::Interrupt;

    /// Wakes the console task: rings after every received byte batch and
    /// every queued telemetry row (a "latest only" flag, so a ring while the
    /// console is busy is never lost).
    type Doorbell = SignalWriter<'static, ()>;

    /// Resources shared between tasks.
    #[shared]
    struct Shared {
        /// Supervisor, controller, reference, link and telemetry state.
        ctl: Ctl,
        /// The control timer.
        tick: TickTimer,
        /// The watchdog.
        wdg: Watchdog,
        /// The microsecond clock.
        clock: UsClock,
        /// The local sensor source.
        sensors: Sensors,
        /// The console's receive path (line editor and line queue), between
        /// `console_rx` and `console`.
        input: ConsoleInput,
    }

    /// Resources owned by one task.
    #[local]
    struct Local {
        drive: hardware::Drive,
        rows_in: Producer<'static, RowEvent>,
        rows_out: Consumer<'static, RowEvent>,
        control_bell: Doorbell,
        console_rx: ConsoleRx,
        rx_bell: Doorbell,
        console_tx: ConsoleTx,
        hil_rx: HilRx,
        hil_tx: HilTx,
        store: SettingsStore,
        console: Console,
    }

    /// Runs once after reset, interrupts disabled: sets up the hardware, reads
    /// the stored settings (a missing or corrupt store falls back to the
    /// defaults and says so on the console), designs the controller on the
    /// board, and starts the control timer.
    #[init(local = [
        buf_a: [u16; 4] = [0; 4],
        buf_b: [u16; 4] = [0; 4],
        rows: Queue<RowEvent, { TELEMETRY_ROWS + 1 }> = Queue::new(),
        // The record's blocks, placed by memory.x (NOLOAD sections, which the
        // start-up code leaves alone: `init` zeroes them, 0.2 ms once). The
        // placement is the only reason for the `unsafe_code` allowances.
        #[allow(unsafe_code)]
        #[link_section = ".record_sram"]
        record_sram: [PackedRow; RECORD_SRAM_ROWS] = [[0; ROW_BYTES]; RECORD_SRAM_ROWS],
        #[allow(unsafe_code)]
        #[link_section = ".record_ccm"]
        record_ccm: [PackedRow; RECORD_CCM_ROWS] = [[0; ROW_BYTES]; RECORD_CCM_ROWS],
    ])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let mut devices = hardware::setup(cx.core, cx.device, (cx.local.buf_a, cx.local.buf_b));

        let mut img = [0u8; IMAGE_LEN];
        let stored = if devices.store.read(&mut img) {
            Settings::from_image(&img).map_err(|e| e.as_str())
        } else {
            Err("no settings stored")
        };
        let (settings, controller, note) = match stored {
            Ok((s, c)) => (s, c, None),
            Err(why) => {
                let s = Settings::default();
                match s.validate() {
                    Ok(c) => (s, c, Some(why)),
                    Err(e) => defmt::panic!("default settings refused: {=str}", e.as_str()),
                }
            }
        };
        if let Some(why) = note {
            defmt::warn!("{=str}: factory settings in use", why);
        }
        let (n_h, n_c) = controller.periods();
        defmt::info!(
            "dca-firmware {=str}: core clock {=u32} Hz, {=str} ESO every {=u32} ticks, MPC every {=u32}",
            env!("CARGO_PKG_VERSION"),
            devices.sysclk_hz,
            controller.kind().name(),
            n_h,
            n_c
        );

        cx.local.record_sram.fill([0; ROW_BYTES]);
        cx.local.record_ccm.fill([0; ROW_BYTES]);
        let record = Recorder::new(cx.local.record_sram, cx.local.record_ccm);
        let mut ctl = Ctl::new(controller, &settings, BOARD_DT_S, record);
        if devices.watchdog_reset {
            trip(&mut ctl, Faults::WATCHDOG);
        }
        let (rows_in, rows_out) = cx.local.rows.split();
        let (bell, bell_rx) = rtic_sync::make_signal!(());
        // Spawned once, here: cannot fail.
        console::spawn(bell_rx, note).ok();
        devices.tick.start();
        devices.ticker.start();

        #[cfg(not(feature = "qemu"))]
        let sensors = devices.sensors;
        #[cfg(feature = "qemu")]
        let sensors = crate::qemu::SimSensors::default();
        (
            Shared {
                ctl,
                tick: devices.tick,
                wdg: devices.watchdog,
                clock: devices.clock,
                sensors,
                input: ConsoleInput::new(),
            },
            Local {
                drive: devices.drive,
                rows_in,
                rows_out,
                control_bell: bell.clone(),
                console_rx: devices.console.1,
                rx_bell: bell,
                console_tx: devices.console.0,
                hil_rx: devices.hil.1,
                hil_tx: devices.hil.0,
                store: devices.store,
                console: Console::new(settings),
            },
        )
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
    /// Released once per sample: on the board by `adc_done` when the DMA has
    /// moved the ADC scan that TIM3's update (1 kHz) triggered; under QEMU by
    /// `tick` (SysTick); in HIL mode by `hil_rx` when a complete sample
    /// frame arrived. Period 1 ms (HIL: one tick per frame).
    ///
    /// Deadline: [`DEADLINE_US`] = 500 us after the release, measured on TIM2
    /// at the end of the tick (the drive output and the HIL reply are written
    /// before that). A miss trips the `overrun` fault and zeroes the drive at
    /// once; a release while the previous one is still pending trips it too.
    ///
    /// Per tick: the calibrated sample (or the frame's), dca-core's
    /// `ControlLoop::tick` (checks, reference, controller step, gating), the
    /// drive output (disabled unless armed or running with the local source),
    /// the HIL reply frame (written here, blocking: at most 18 bytes, about
    /// 0.20 ms at 921600 baud on the board, within the deadline; a separate
    /// sender task could still be finishing the previous frame when the host's
    /// next one arrives), the on-board record's row (`Recorder::push`, at
    /// most 149 instructions), a telemetry row every `decimation` ticks.
    #[task(binds = EXTI0, priority = 4, shared = [ctl, clock, sensors], local = [drive, rows_in, control_bell, hil_tx])]
    fn control(cx: control::Context) {
        let drive = cx.local.drive;
        let hil_tx = cx.local.hil_tx;
        let rows = cx.local.rows_in;
        let bell = cx.local.control_bell;
        (cx.shared.ctl, cx.shared.clock, cx.shared.sensors).lock(|c, clock, sensors| {
            let Some(release) = c.pending.take() else {
                return;
            };
            let dt_s = c.lp.dt_s() as f32;
            let (out, sample, reply) = match (release, c.source) {
                (Release::Local, Source::Local) => {
                    let s = sensors.sample(&c.run);
                    (Some(c.lp.tick(&s, None)), s, None)
                }
                (Release::Frame(f), Source::Hil) => {
                    let s = f.sample();
                    (Some(c.lp.tick(&s, Some(f.ref_m))), s, Some(f.seq))
                }
                (Release::LinkError(e), Source::Hil) => {
                    defmt::warn!("HIL link: {=str}", e.as_str());
                    trip(c, Faults::HIL_LINK);
                    (None, *c.lp.last_sample(), Some(c.link.expected()))
                }
                // A release of the other source (a mode change raced it).
                _ => return,
            };
            let (v, flags) = out.map_or((0.0, 0), |o| (o.v_cmd_mps, o.flags.0));
            let enabled = c.lp.supervisor().drive_enabled() && c.source == Source::Local;
            let (duty, extend) = c.run.drive.duty(v);
            drive.set(duty, extend, enabled);
            sensors.applied(if enabled { v } else { 0.0 }, dt_s);
            c.last_v_mps = v;
            let sup = *c.lp.supervisor();
            if let Some(seq) = reply {
                let msg = CommandFrame {
                    seq,
                    v_cmd_mps: v,
                    state: sup.state() as u8,
                    faults: sup.faults().0,
                    flags,
                };
                let mut bytes = FrameBytes {
                    buf: [0; MAX_FRAME_LEN],
                    len: 0,
                };
                match frame::encode(&msg, &mut bytes.buf) {
                    Ok(n) => {
                        // `take`, not `[..n]`: no panic path (n <= MAX_FRAME_LEN anyway).
                        for &b in bytes.buf.iter().take(n) {
                            // The HAL's USART write cannot fail other than by `WouldBlock`.
                            let _ = nb::block!(hil_tx.write(b));
                        }
                    }
                    Err(_) => c.tx_dropped = c.tx_dropped.saturating_add(1),
                }
            }
            c.record.push(
                sup.state() == State::Running,
                c.lp.last_ref_m(),
                v,
                &sample,
                sup.faults().0,
            );
            let row = c.telemetry.tick(
                c.lp.last_ref_m(),
                v,
                sample,
                sup.state() as u8,
                sup.faults().0,
            );
            if let Some(row) = row {
                if rows.enqueue((c.telemetry.generation, row)).is_err() {
                    c.telemetry.dropped = c.telemetry.dropped.saturating_add(1);
                }
                bell.write(());
            }
            c.alive = true;
            let elapsed = clock.now_us().wrapping_sub(c.release_us);
            c.max_tick_us = c.max_tick_us.max(elapsed);
            if elapsed > DEADLINE_US {
                trip(c, Faults::OVERRUN);
                drive.set(0.0, true, false);
            }
        });
    }

    /// The ADC scan of the four channels has been moved by DMA (board only;
    /// the interrupt never fires under QEMU). Period 1 ms; deadline: before
    /// the next scan ends (1 ms). Releases `control` with the local source.
    #[task(binds = DMA2_STREAM0, priority = 3, shared = [ctl, clock, sensors])]
    fn adc_done(cx: adc_done::Context) {
        (cx.shared.ctl, cx.shared.clock, cx.shared.sensors).lock(|c, clock, sensors| {
            if !sensors.scan_done() {
                trip(c, Faults::SENSOR_RANGE);
            }
            if c.source == Source::Local {
                if !c.release(Release::Local, clock.now_us()) {
                    trip(c, Faults::OVERRUN);
                }
                rtic::pend(Interrupt::EXTI0);
            }
        });
    }

    /// The housekeeping tick (SysTick), 1 kHz; deadline 1 ms. Under QEMU it
    /// releases `control` with the local source. In HIL mode it counts the
    /// frame timeout while frames are expected. It feeds the watchdog when the
    /// control task has run since the last feed (or in HIL mode, where ticks
    /// follow frames).
    #[task(binds = SysTick, priority = 3, shared = [ctl, clock, wdg])]
    fn tick(cx: tick::Context) {
        (cx.shared.ctl, cx.shared.clock, cx.shared.wdg).lock(|c, clock, wdg| {
            UPTIME_MS.fetch_add(1, core::sync::atomic::Ordering::Relaxed);
            let _now = clock.now_us();
            #[cfg(feature = "qemu")]
            if c.source == Source::Local {
                if !c.release(Release::Local, _now) {
                    trip(c, Faults::OVERRUN);
                }
                rtic::pend(Interrupt::EXTI0);
            }
            if c.source == Source::Hil && c.lp.supervisor().drive_enabled() {
                if let Some(e) = c.link.tick(c.run.hil_timeout_ms) {
                    defmt::warn!("HIL link: {=str}", e.as_str());
                    trip(c, Faults::HIL_LINK);
                }
            } else {
                c.link.idle();
            }
            if c.alive || c.source == Source::Hil {
                c.alive = false;
                wdg.feed();
            }
        });
    }

    /// HIL link receiver (USART2 RXNE): collects COBS frames; a complete one is
    /// checked (CRC, sequence) and releases `control`. Deadline: one byte time
    /// (about 11 us at 921600 baud). Bytes are ignored unless HIL mode is on.
    #[task(binds = USART2, priority = 3, shared = [ctl, clock], local = [hil_rx, reader: FrameReader = FrameReader::new()])]
    fn hil_rx(cx: hil_rx::Context) {
        let rx = cx.local.hil_rx;
        let reader = cx.local.reader;
        (cx.shared.ctl, cx.shared.clock).lock(|c, clock| loop {
            let release = match rx.read() {
                Ok(b) => {
                    if c.source != Source::Hil {
                        reader.reset();
                        continue;
                    }
                    match reader.push(b) {
                        Some(ReadEvent::Frame(body)) => match c.link.receive(body) {
                            Ok(Some(f)) => Release::Frame(f),
                            // Before the first valid frame: skipped, no reply.
                            Ok(None) => continue,
                            Err(e) => Release::LinkError(e),
                        },
                        Some(ReadEvent::Overflow) => match c.link.overflow() {
                            Some(e) => Release::LinkError(e),
                            None => continue,
                        },
                        None => continue,
                    }
                }
                Err(nb::Error::WouldBlock) => break,
                // Overrun, framing or noise error: the frame in progress is bad.
                Err(nb::Error::Other(_)) => {
                    reader.reset();
                    if c.source != Source::Hil {
                        continue;
                    }
                    match c.link.overflow() {
                        Some(e) => Release::LinkError(e),
                        None => continue,
                    }
                }
            };
            if !c.release(release, clock.now_us()) {
                trip(c, Faults::HIL_LINK);
            }
            rtic::pend(Interrupt::EXTI0);
        });
    }

    /// Console receiver (USART1 RXNE): runs the line editor on every byte and
    /// queues finished lines for the console task (dca-core's
    /// `console::Receiver`), so that no line end is ever lost to a busy
    /// console. Deadline: one byte time (87 us at 115200 baud; the work is a
    /// few hundred cycles, a line copy at most). A byte the USART lost
    /// (overrun, framing, noise) makes the console answer that line with an
    /// error.
    #[task(binds = USART1, priority = 2, shared = [input], local = [console_rx, rx_bell])]
    fn console_rx(mut cx: console_rx::Context) {
        let rx = cx.local.console_rx;
        let mut any = false;
        cx.shared.input.lock(|input| loop {
            match rx.read() {
                Ok(b) => input.receive(b),
                Err(nb::Error::WouldBlock) => break,
                Err(nb::Error::Other(_)) => input.lost(),
            }
            any = true;
        });
        if any {
            cx.local.rx_bell.write(());
        }
    }

    /// The console: commands (dca-core's `Console`), echo, replies and the
    /// telemetry stream, all on USART1. Lowest priority, no deadline (best
    /// effort): writes block on the USART, and the MPC re-design after a
    /// parameter change runs here. Each pass answers one line, then writes the
    /// queued telemetry rows, so that a paste of many lines does not hold the
    /// stream up for long; it sleeps on the doorbell when nothing is left.
    #[task(priority = 1, shared = [ctl, tick, wdg, input], local = [console_tx, store, console, rows_out])]
    async fn console(
        mut cx: console::Context,
        mut doorbell: SignalReader<'static, ()>,
        note: Option<&'static str>,
    ) {
        let mut out = ConsoleOut(cx.local.console_tx);
        let tx = &mut out;
        let rows = cx.local.rows_out;
        let mut state = ConsoleState {
            telemetry: 0,
            generation: 0,
            header_due: false,
        };
        let _ = tx.write_str("\r\ndca-firmware ");
        let _ = tx.write_str(env!("CARGO_PKG_VERSION"));
        let _ = tx.write_str(" ready; type 'help'\r\n");
        if let Some(why) = note {
            let _ = tx.write_str("note: ");
            let _ = tx.write_str(why);
            let _ = tx.write_str(": factory settings in use\r\n");
        }
        loop {
            // Everything to echo and the next line, in one short lock.
            let mut line = [0u8; MAX_LINE];
            let mut echo = [0u8; ECHO_BYTES];
            let (n_echo, got) = {
                let (line, echo) = (&mut line, &mut echo);
                cx.shared.input.lock(move |input| {
                    let mut n = 0;
                    for slot in echo.iter_mut() {
                        let Some(b) = input.next_echo() else { break };
                        *slot = b;
                        n += 1;
                    }
                    (n, input.next(line))
                })
            };
            // Echo is printable ASCII, backspace, CR and LF: always UTF-8.
            let echoed = echo.get(..n_echo).unwrap_or(&[]);
            let _ = tx.write_str(core::str::from_utf8(echoed).unwrap_or(""));
            let idle = got.is_none();
            match got {
                Some(Received::Line(line)) => {
                    #[cfg(feature = "qemu")]
                    if line == "quit" {
                        let _ = tx.write_str("ok\r\n");
                        crate::qemu::exit(0);
                    }
                    let mut machine = Machine {
                        ctl: &mut cx.shared.ctl,
                        tick: &mut cx.shared.tick,
                        wdg: &mut cx.shared.wdg,
                        input: &mut cx.shared.input,
                        store: cx.local.store,
                        console: &mut state,
                    };
                    cx.local.console.execute(line, &mut machine, tx);
                    if state.header_due {
                        state.header_due = false;
                        let kind = cx.local.console.settings().controller.kind;
                        write_log_header(tx, kind.name());
                    }
                }
                Some(Received::Bad(e)) => cx.local.console.reject(e, tx),
                None => {}
            }
            while let Some((generation, row)) = rows.dequeue() {
                if state.telemetry != 0 && generation == state.generation {
                    let mut text: Buf<128> = Buf::new();
                    write_log_row(&mut text, &row);
                    let _ = tx.write_str(text.as_str());
                }
            }
            if idle {
                doorbell.wait().await;
            }
        }
    }
}
