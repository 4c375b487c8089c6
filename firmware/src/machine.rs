//! The state the control task shares with the other tasks, and the console's
//! view of the machine ([`Machine`], dca-core's `console::Target`).
//!
//! Everything here is plain data and logic over RTIC resource locks: no
//! register is touched except through the drivers of [`crate::hardware`].

use dca_app::console::{LogRow, Status, Target};
use dca_app::frame::{LinkError, LinkMonitor, SampleFrame};
use dca_app::record::{PackedRow, RecordError, RecordInfo, Recorder};
use dca_app::settings::{Calibration, DriveScale, Settings, IMAGE_LEN};
use dca_app::supervisor::{ControlLoop, Faults, Refused};
use dca_core::controller::{Controller, Sample};
use rtic::mutex::prelude::*;

use crate::hardware::{
    RawSample, SettingsStore, TickTimer, Watchdog, WATCHDOG_FLASH_MS, WATCHDOG_MS,
};
use crate::ConsoleInput;

/// Where the control task's samples come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, defmt::Format)]
pub enum Source {
    /// The board's ADC and encoder (the simulated source under QEMU).
    Local,
    /// HIL frames on USART2.
    Hil,
}

/// What released the pending control tick.
#[derive(Clone, Copy, Debug)]
pub enum Release {
    /// A local sample is ready (ADC scan done, or the QEMU timer).
    Local,
    /// A HIL frame was accepted.
    Frame(SampleFrame),
    /// A HIL frame was refused (lost, corrupt, out of lockstep).
    LinkError(LinkError),
}

/// The parts of the settings the control task applies itself.
#[derive(Clone, Copy, Debug)]
pub struct RunConfig {
    /// Sensor calibrations.
    pub cal: Calibration,
    /// Speed to PWM.
    pub drive: DriveScale,
    /// HIL frame timeout, ms (0: none).
    pub hil_timeout_ms: u32,
}

impl RunConfig {
    /// From the settings.
    pub fn from_settings(s: &Settings) -> Self {
        Self {
            cal: s.cal,
            drive: s.drive,
            hil_timeout_ms: s.hil_timeout_ms,
        }
    }

    /// Raw board readings to SI (the one place where units are converted).
    pub fn calibrate(&self, raw: &RawSample) -> Sample {
        let c = &self.cal;
        Sample {
            xo_m: c.lvdt.apply(raw.adc[0] as f32),
            p1_pa: c.p1.apply(raw.adc[1] as f32),
            p2_pa: c.p2.apply(raw.adc[2] as f32),
            ft_n: c.force.apply(raw.adc[3] as f32),
            xi_m: c.encoder.apply(raw.encoder as f32),
        }
    }
}

/// Telemetry bookkeeping of the control task.
#[derive(Clone, Copy, Debug, Default)]
pub struct Telemetry {
    /// Decimation, 0 when off.
    pub decimation: u32,
    /// Ticks since the last row.
    pub count: u32,
    /// Rows since the stream started.
    pub rows: u32,
    /// Rows that did not fit the queue to the console.
    pub dropped: u32,
    /// Stream number (rows of an older stream are not printed).
    pub generation: u8,
}

impl Telemetry {
    /// Count one tick; the row to send on this tick, if any.
    pub fn tick(
        &mut self,
        ref_m: f32,
        v_cmd_mps: f32,
        sample: Sample,
        state: u8,
        faults: u16,
    ) -> Option<LogRow> {
        if self.decimation == 0 {
            return None;
        }
        let due = self.count == 0;
        self.count += 1;
        if self.count >= self.decimation {
            self.count = 0;
        }
        if !due {
            return None;
        }
        let row = LogRow {
            n: self.rows,
            step_ms: self.decimation,
            ref_m,
            v_cmd_mps,
            sample,
            state,
            faults,
        };
        self.rows = self.rows.wrapping_add(1);
        Some(row)
    }
}

/// State shared by the control task (priority 3), the interrupt handlers and
/// the console.
pub struct Ctl {
    /// Supervisor, reference and controller.
    pub lp: ControlLoop,
    /// Calibrations, drive scaling, HIL timeout.
    pub run: RunConfig,
    /// Sample source.
    pub source: Source,
    /// HIL link bookkeeping.
    pub link: LinkMonitor,
    /// The release waiting for the control task.
    pub pending: Option<Release>,
    /// When the pending release happened, us ([`crate::hardware::UsClock`]).
    pub release_us: u32,
    /// Telemetry.
    pub telemetry: Telemetry,
    /// Longest control tick, us.
    pub max_tick_us: u32,
    /// The control task ran since the watchdog was last fed.
    pub alive: bool,
    /// Command of the last tick, m/s.
    pub last_v_mps: f32,
    /// HIL reply frames that could not be queued.
    pub tx_dropped: u32,
    /// The on-board record (its rows in main SRAM and the CCM RAM).
    pub record: Recorder<'static>,
}

impl Ctl {
    /// Idle, local source, nothing pending, the record off.
    pub fn new(
        controller: Controller,
        settings: &Settings,
        dt_s: f64,
        record: Recorder<'static>,
    ) -> Self {
        Self {
            lp: ControlLoop::new(controller, settings.limits, dt_s),
            run: RunConfig::from_settings(settings),
            source: Source::Local,
            link: LinkMonitor::new(),
            pending: None,
            release_us: 0,
            telemetry: Telemetry::default(),
            max_tick_us: 0,
            alive: false,
            last_v_mps: 0.0,
            tx_dropped: 0,
            record,
        }
    }

    /// Record a release; returns false when one was already pending (the
    /// control task is late: the caller trips an overrun).
    pub fn release(&mut self, r: Release, now_us: u32) -> bool {
        let free = self.pending.is_none();
        self.pending = Some(r);
        self.release_us = now_us;
        free
    }
}

/// What the console task needs beyond the shared state.
pub struct ConsoleState {
    /// Telemetry decimation requested (0: off); the console writes the run-log
    /// header when it goes on.
    pub telemetry: u32,
    /// Stream number of the current telemetry stream.
    pub generation: u8,
    /// A header is due after the current reply.
    pub header_due: bool,
}

/// The console's view of the machine: locks of the shared resources plus the
/// console's own state.
pub struct Machine<'a, C, K, W, I>
where
    C: Mutex<T = Ctl>,
    K: Mutex<T = TickTimer>,
    W: Mutex<T = Watchdog>,
    I: Mutex<T = ConsoleInput>,
{
    /// The shared control state.
    pub ctl: &'a mut C,
    /// The control timer (paused around flash writes).
    pub tick: &'a mut K,
    /// The watchdog (extended around flash writes).
    pub wdg: &'a mut W,
    /// The console's receive path (its echo flag).
    pub input: &'a mut I,
    /// Settings storage.
    pub store: &'a mut SettingsStore,
    /// Console flags.
    pub console: &'a mut ConsoleState,
}

impl<C, K, W, I> Target for Machine<'_, C, K, W, I>
where
    C: Mutex<T = Ctl>,
    K: Mutex<T = TickTimer>,
    W: Mutex<T = Watchdog>,
    I: Mutex<T = ConsoleInput>,
{
    fn status(&mut self) -> Status {
        let telemetry = self.console.telemetry;
        self.ctl.lock(|c| status(c, telemetry))
    }

    fn apply(&mut self, settings: &Settings, controller: &Controller) -> Result<(), Refused> {
        self.ctl.lock(|c| {
            c.lp.reconfigure(*controller, settings.limits)?;
            c.run = RunConfig::from_settings(settings);
            Ok(())
        })
    }

    fn arm(&mut self) -> Result<(), Refused> {
        self.ctl.lock(|c| {
            c.lp.arm()?;
            c.link.restart();
            Ok(())
        })
    }

    fn disarm(&mut self) {
        self.ctl.lock(|c| c.lp.disarm());
    }

    fn goto(&mut self, x_m: f32) -> Result<(), Refused> {
        self.ctl.lock(|c| {
            if c.source == Source::Hil {
                return Err(Refused::NotIdle);
            }
            c.lp.goto(x_m)
        })
    }

    fn sine(&mut self, amplitude_m: f32, freq_hz: f32) -> Result<(), Refused> {
        self.ctl.lock(|c| {
            if c.source == Source::Hil {
                return Err(Refused::NotIdle);
            }
            c.lp.sine(amplitude_m, freq_hz)
        })
    }

    fn stop(&mut self) -> Result<(), Refused> {
        self.ctl.lock(|c| c.lp.stop())
    }

    fn clear(&mut self) -> Result<(), Refused> {
        self.ctl.lock(|c| {
            c.lp.supervisor_mut().clear()?;
            c.link.restart();
            c.pending = None;
            Ok(())
        })
    }

    fn store(&mut self, image: &[u8]) -> Result<(), &'static str> {
        let Ok(image) = <&[u8; IMAGE_LEN]>::try_from(image) else {
            return Err("settings image has the wrong length");
        };
        let idle = self.ctl.lock(|c| c.lp.supervisor().require_idle().is_ok());
        if !idle {
            return Err(Refused::NotIdle.as_str());
        }
        // The CPU stalls while the flash is erased: no ticks (the timer is
        // paused, so no ADC scan is left half done) and a long watchdog.
        let store = &mut *self.store;
        let wdg = &mut *self.wdg;
        let tick = &mut *self.tick;
        let ctl = &mut *self.ctl;
        let r = (wdg, tick).lock(|wdg, tick| {
            wdg.set_timeout_ms(WATCHDOG_FLASH_MS);
            tick.pause();
            let r = store.write(image);
            tick.start();
            wdg.set_timeout_ms(WATCHDOG_MS);
            r
        });
        ctl.lock(|c| {
            c.pending = None;
            c.alive = true;
        });
        r
    }

    fn load(&mut self, buf: &mut [u8]) -> bool {
        let mut img = [0u8; IMAGE_LEN];
        if buf.len() != IMAGE_LEN || !self.store.read(&mut img) {
            return false;
        }
        buf.copy_from_slice(&img);
        true
    }

    fn telemetry(&mut self, decimation: Option<u32>) {
        let d = decimation.unwrap_or(0);
        let generation = self.console.generation.wrapping_add(1);
        self.console.telemetry = d;
        self.console.generation = generation;
        self.console.header_due = d != 0;
        self.ctl.lock(|c| {
            c.telemetry = Telemetry {
                decimation: d,
                dropped: c.telemetry.dropped,
                generation,
                ..Telemetry::default()
            };
        });
    }

    fn hil(&mut self, on: bool) -> Result<(), Refused> {
        self.ctl.lock(|c| {
            c.lp.supervisor().require_idle()?;
            c.source = if on { Source::Hil } else { Source::Local };
            c.link.restart();
            c.pending = None;
            Ok(())
        })
    }

    fn echo(&mut self, on: bool) {
        self.input.lock(|i| i.set_echo(on));
    }

    fn record_arm(
        &mut self,
        rows: u32,
        cal: &Calibration,
        controller: u8,
    ) -> Result<(), RecordError> {
        self.ctl.lock(|c| c.record.arm(rows, cal, controller))
    }

    fn record_off(&mut self) {
        self.ctl.lock(|c| c.record.off());
    }

    fn record_end(&mut self) {
        self.ctl.lock(|c| c.record.end());
    }

    fn record_info(&mut self) -> RecordInfo {
        self.ctl.lock(|c| c.record.info())
    }

    /// One short lock per call (a dump asks for three rows at a time).
    fn record_rows(&mut self, first: u32, out: &mut [PackedRow]) -> usize {
        self.ctl.lock(|c| c.record.rows(first, out))
    }
}

/// A status snapshot of `c` for the console.
pub fn status(c: &Ctl, telemetry: u32) -> Status {
    Status {
        state: c.lp.supervisor().state() as u8,
        faults: c.lp.supervisor().faults().0,
        sample: *c.lp.last_sample(),
        ref_m: if c.lp.supervisor().drive_enabled() {
            c.lp.reference_now()
        } else {
            c.lp.last_ref_m()
        },
        v_cmd_mps: c.last_v_mps,
        ticks: c.lp.ticks(),
        hil: c.source == Source::Hil,
        telemetry,
        link: c.link.counters(),
        max_tick_us: c.max_tick_us,
    }
}

/// Trip a fault and log it once.
pub fn trip(c: &mut Ctl, bits: u16) {
    let before = c.lp.supervisor().faults().0;
    c.lp.supervisor_mut().trip(bits);
    if !Faults(before).has(bits) {
        defmt::warn!("fault {=u16:#x} (latched {=u16:#x})", bits, before | bits);
    }
}
