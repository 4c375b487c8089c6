//! Processor- and hardware-in-the-loop: the plant on the host, the control tick
//! somewhere else, in lockstep.
//!
//! One loop ([`run_lockstep`]) serves three controllers behind [`Stepper`]:
//! * [`SoftwareStepper`]: dca-core's `ControlLoop` in this process (the
//!   reference the others must match bit for bit);
//! * [`LinkStepper`] over serial ports ([`run_hil_serial`]): a board's
//!   USB-serial ttys;
//! * the same over the emulated firmware's pseudo-terminals ([`run_hil_qemu`]:
//!   QEMU started here with `-serial pty`, reached exactly as a board is).
//!
//! # Timing
//! The firmware's base tick is 1 ms, so the lockstep loop ticks the controller
//! every 1 ms (t_j = j * 1e-3 s) and integrates the plant over that millisecond
//! in `round(1e-3 / dt)` RK4 steps of the spec's plant step `dt` (1e-4 s
//! nominal), the command held and the load evaluated at each plant step. One
//! run-log row is written per tick, before the plant moves (docs/interfaces.md
//! section 1). [`crate::sim::run`] ticks its controller the same way (at the
//! board's 1 ms by default) but calls dca-core's `Controller` without the
//! supervisor: [`run_software`] is the bit-exact reference of a HIL run, and
//! `sim::run` agrees with it to the run log's precision.
//!
//! # The exchange
//! Per tick the host sends a [`SampleFrame`] (reference and sensor readings as
//! `f32`, `seq` = tick index) and waits for the [`CommandFrame`] with the same
//! `seq`; a missing, corrupt or out-of-sequence reply, or one reporting a
//! fault, ends the run with an error. Before the first frame the host sets the
//! firmware up over its console (`controller`, `preset`, `set`, `hil on`,
//! `arm`) so that it designs exactly the configuration of the spec.
//!
//! # Start-up
//! The firmware supervises the link from the first valid frame on (see
//! `dca_app::frame`), so the host may take its time between `arm` and its
//! first frame. The host drops what its port received before, sends a lone
//! `0x00` (ending any partial frame in the firmware's reader) and then `seq`
//! 0, and skips received bytes that do not form a valid reply to it. A board
//! that does not answer is an error naming the port, its baud rate and what
//! was sent.

pub mod board;

use std::io::{self, Write};
use std::path::Path;
use std::time::{Duration, Instant};

use dca_app::frame::{self, CommandFrame, SampleFrame, MAX_FRAME_LEN};
use dca_app::settings::{Settings, BOARD_DT_S, PARAMS};
use dca_app::supervisor::ControlLoop;
use dca_core::controller::{ControllerConfig, Preset, Sample};

use self::board::console::{ConsoleClient, CONSOLE_BAUD};
use self::board::port::SerialLink;
use self::board::qemu::{Emulator, QemuOptions};
use self::board::record::BoardRecord;
use self::board::BoardError;
use crate::model::rig::Rig;
use crate::model::scenario::tick_time_s;
use crate::sim::closed_loop::{
    self, drive, ControlInput, Drive, Observer, Stepper, TickView, Timing,
};
use crate::sim::RunSpec;

/// The firmware's HIL link baud rate.
pub const HIL_BAUD: u32 = 921_600;

/// Why a HIL run failed.
#[derive(Debug, thiserror::Error)]
pub enum HilError {
    /// The spec cannot run in lockstep (open loop, bad step, configuration the
    /// console cannot reproduce exactly, ...).
    #[error("HIL run refused: {0}")]
    Spec(String),
    /// The console or a port.
    #[error(transparent)]
    Board(#[from] BoardError),
    /// The board's record of the run could not be read whole.
    #[error("the board's record of the run: {0}")]
    Record(#[from] crate::hil::board::record::DumpError),
    /// The first sample frame got no valid reply.
    #[error(
        "no HIL reply on {port} at {baud} baud within {secs:.1} s: sent a frame delimiter and \
         the sample frame of tick 0 and got {received} byte(s) that were no valid reply; is this \
         the HIL port (USART2), and is the board in HIL mode and armed (`hil on`, `arm` on its \
         console, or give --console)?"
    )]
    NoLink {
        /// Device path.
        port: String,
        /// Baud rate.
        baud: u32,
        /// How long it waited, s.
        secs: f64,
        /// Bytes received meanwhile.
        received: usize,
    },
    /// No reply within the timeout.
    #[error("no reply to the frame of tick {tick}")]
    Timeout {
        /// Tick index of the unanswered frame.
        tick: u32,
    },
    /// A reply that does not decode or answers another tick.
    #[error("bad reply at tick {tick}: {what}")]
    Link {
        /// Tick index.
        tick: u32,
        /// What was wrong.
        what: String,
    },
    /// The firmware reported a fault.
    #[error("firmware fault at tick {tick}: {} ({faults:#x})", fault_names(*.faults))]
    Fault {
        /// Tick index.
        tick: u32,
        /// Fault bits (dca_app::supervisor::Faults).
        faults: u16,
    },
}

fn fault_names(faults: u16) -> String {
    let mut names = String::new();
    dca_app::console::write_faults(&mut names, faults);
    names
}

/// The answer of one control tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reply {
    /// Drive command, m/s.
    pub v_cmd_mps: f32,
    /// Supervisor state.
    pub state: u8,
    /// Latched faults.
    pub faults: u16,
    /// Controller flags.
    pub flags: u8,
}

impl Drive for Reply {
    fn v_cmd_mps(&self) -> f64 {
        self.v_cmd_mps as f64
    }
}

/// The frame sequence number of control tick `tick`.
fn seq_of(tick: u64) -> Result<u32, HilError> {
    u32::try_from(tick).map_err(|_| HilError::Spec("run too long".into()))
}

/// The core in this process: an armed `ControlLoop`, exactly as the firmware
/// runs it in HIL mode.
pub struct SoftwareStepper {
    lp: ControlLoop,
}

impl SoftwareStepper {
    /// A loop designed from `settings`, armed.
    pub fn new(settings: &Settings) -> Result<Self, HilError> {
        let c = settings
            .validate()
            .map_err(|e| HilError::Spec(e.as_str().to_string()))?;
        let mut lp = ControlLoop::new(c, settings.limits, BOARD_DT_S);
        lp.arm()
            .map_err(|e| HilError::Spec(e.as_str().to_string()))?;
        Ok(Self { lp })
    }
}

impl Stepper for SoftwareStepper {
    type Output = Reply;
    type Error = HilError;

    fn step(&mut self, input: &ControlInput<'_>) -> Result<Reply, HilError> {
        seq_of(input.tick)?;
        let o = self.lp.tick(input.sample, Some(input.ref_m as f32));
        Ok(Reply {
            v_cmd_mps: o.v_cmd_mps,
            state: o.state,
            faults: o.faults,
            flags: o.flags.0,
        })
    }
}

/// The console commands that make a freshly booted firmware design exactly
/// `cfg` (kind, preset, then every parameter that differs from the preset).
/// Fails if a value cannot be typed exactly (more than 15 significant digits)
/// or is not a console parameter.
pub fn setup_commands(cfg: &ControllerConfig) -> Result<Vec<String>, HilError> {
    let mut want_cfg = *cfg;
    want_cfg.base_dt_s = BOARD_DT_S;
    let want = Settings {
        controller: want_cfg,
        ..Settings::default()
    };
    let (preset, base) = Preset::ALL
        .iter()
        .map(|p| (*p, Settings::preset(*p, cfg.kind)))
        .min_by_key(|(_, s)| PARAMS.iter().filter(|p| p.get(s) != p.get(&want)).count())
        .expect("two presets");
    let mut cmds = vec![
        format!("controller {}", cfg.kind.name()),
        format!("preset {}", preset.name()),
    ];
    let mut reached = base;
    for p in &PARAMS {
        let v = p.get(&want);
        if v.to_bits() == p.get(&base).to_bits() {
            continue;
        }
        let text = match p.kind {
            dca_app::settings::ParamKind::F64 => format!("{v:e}"),
            dca_app::settings::ParamKind::F32 => format!("{:e}", v as f32),
            _ => format!("{v}"),
        };
        let digits = text
            .split('e')
            .next()
            .unwrap_or("")
            .chars()
            .filter(|c| c.is_ascii_digit())
            .count();
        if digits > 15 {
            return Err(HilError::Spec(format!(
                "{} = {text} has more than 15 significant digits: the console cannot set it exactly",
                p.name
            )));
        }
        reached = reached
            .with(p.name, v)
            .map_err(|e| HilError::Spec(format!("{} = {text}: {}", p.name, e.as_str())))?
            .0;
        cmds.push(format!("set {} {text}", p.name));
    }
    if reached.controller != want.controller {
        return Err(HilError::Spec(
            "the configuration differs from the presets in values the console cannot set".into(),
        ));
    }
    Ok(cmds)
}

/// Lockstep over a serial link: one sample frame out, one command frame back.
pub struct LinkStepper {
    link: SerialLink,
    rx: Vec<u8>,
    timeout: Duration,
    /// A valid reply has arrived (the firmware supervises the link).
    live: bool,
}

impl LinkStepper {
    /// Frames over `link`, replies awaited for at most `timeout`.
    pub fn new(mut link: SerialLink, timeout: Duration) -> Result<Self, HilError> {
        link.set_timeout(Duration::from_millis(20))?;
        Ok(Self {
            link,
            rx: Vec::with_capacity(2 * MAX_FRAME_LEN),
            timeout,
            live: false,
        })
    }

    /// The next frame body, or `None` when the timeout passed.
    fn read_frame(&mut self, until: Instant) -> Result<Option<Vec<u8>>, HilError> {
        let mut buf = [0u8; 256];
        loop {
            if let Some(i) = self.rx.iter().position(|b| *b == 0) {
                let body: Vec<u8> = self.rx.drain(..=i).take(i).collect();
                if body.is_empty() {
                    continue;
                }
                return Ok(Some(body));
            }
            if Instant::now() > until {
                return Ok(None);
            }
            let n = self.link.read_some(&mut buf)?;
            self.rx.extend_from_slice(&buf[..n]);
        }
    }

    /// The reply to the first frame: bytes that are no valid reply to tick 0
    /// (left over from before, noise) are skipped.
    fn first_reply(&mut self) -> Result<CommandFrame, HilError> {
        let start = Instant::now();
        let until = start + self.timeout;
        let mut received = 0;
        while let Some(mut body) = self.read_frame(until)? {
            received += body.len() + 1;
            if let Ok(r) = frame::decode::<CommandFrame>(&mut body) {
                if r.seq == 0 {
                    return Ok(r);
                }
            }
        }
        Err(HilError::NoLink {
            port: self.link.name().to_string(),
            baud: self.link.baud(),
            secs: start.elapsed().as_secs_f64(),
            received: received + self.rx.len(),
        })
    }
}

impl Stepper for LinkStepper {
    type Output = Reply;
    type Error = HilError;

    fn step(&mut self, input: &ControlInput<'_>) -> Result<Reply, HilError> {
        let seq = seq_of(input.tick)?;
        let sample = input.sample;
        let msg = SampleFrame {
            seq,
            ref_m: input.ref_m as f32,
            xo_m: sample.xo_m,
            xi_m: sample.xi_m,
            p1_pa: sample.p1_pa,
            p2_pa: sample.p2_pa,
            ft_n: sample.ft_n,
        };
        let mut out = [0u8; MAX_FRAME_LEN + 1];
        let start = usize::from(!self.live);
        let n = frame::encode(&msg, &mut out[start..]).map_err(|e| HilError::Link {
            tick: seq,
            what: e.as_str().into(),
        })?;
        // Before the first frame, a lone delimiter ends whatever partial frame
        // the firmware's reader holds (out[0] is 0).
        self.link.send(&out[..start + n])?;
        let r = if self.live {
            let until = Instant::now() + self.timeout;
            let mut body = self
                .read_frame(until)?
                .ok_or(HilError::Timeout { tick: seq })?;
            frame::decode::<CommandFrame>(&mut body).map_err(|e| HilError::Link {
                tick: seq,
                what: e.as_str().into(),
            })?
        } else {
            let r = self.first_reply()?;
            self.live = true;
            r
        };
        if r.faults != 0 {
            return Err(HilError::Fault {
                tick: seq,
                faults: r.faults,
            });
        }
        if r.seq != seq {
            return Err(HilError::Link {
                tick: seq,
                what: format!("reply for tick {}", r.seq),
            });
        }
        Ok(Reply {
            v_cmd_mps: r.v_cmd_mps,
            state: r.state,
            faults: r.faults,
            flags: r.flags,
        })
    }
}

/// One logged tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HilRow {
    /// t_j, s.
    pub t_s: f64,
    /// Reference sent, m.
    pub ref_m: f32,
    /// The readings sent.
    pub sample: Sample,
    /// The reply.
    pub reply: Reply,
}

/// A finished lockstep run.
#[derive(Clone, Debug)]
pub struct HilTrace {
    /// Scenario name.
    pub scenario: String,
    /// Controller name.
    pub controller: String,
    /// Where the control ticks ran (`software`, `qemu`, `serial`).
    pub source: String,
    /// One row per control tick.
    pub rows: Vec<HilRow>,
}

impl HilTrace {
    /// The drive commands as `f32` bit patterns, one per tick.
    pub fn command_bits(&self) -> Vec<u32> {
        self.rows
            .iter()
            .map(|r| r.reply.v_cmd_mps.to_bits())
            .collect()
    }

    /// The first tick where two runs' commands differ (bit patterns), if any;
    /// also when one run is longer.
    pub fn first_difference(&self, other: &Self) -> Option<usize> {
        let a = self.command_bits();
        let b = other.command_bits();
        a.iter()
            .zip(&b)
            .position(|(x, y)| x != y)
            .or_else(|| (a.len() != b.len()).then(|| a.len().min(b.len())))
    }

    /// Write the run log (docs/interfaces.md section 1) with the optional columns
    /// `state`, `faults` and `flags`.
    pub fn write_log(&self, out: &mut impl Write) -> io::Result<()> {
        writeln!(out, "# dca-log v1")?;
        writeln!(out, "# controller={}", self.controller)?;
        writeln!(out, "# scenario={}", self.scenario)?;
        writeln!(out, "# source=hil-{}", self.source)?;
        writeln!(
            out,
            "t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n,state,faults,flags"
        )?;
        for r in &self.rows {
            let s = &r.sample;
            writeln!(
                out,
                "{:.3},{:.7},{:.7},{:.8},{:.8},{:.1},{:.1},{:.2},{},{},{}",
                r.t_s,
                r.ref_m,
                r.reply.v_cmd_mps,
                s.xi_m,
                s.xo_m,
                s.p1_pa,
                s.p2_pa,
                s.ft_n,
                r.reply.state,
                r.reply.faults,
                r.reply.flags
            )?;
        }
        Ok(())
    }
}

/// The lockstep run's observer: one [`HilRow`] per control tick.
struct HilLog {
    rows: Vec<HilRow>,
}

impl<S: Stepper<Output = Reply, Error = HilError>> Observer<S> for HilLog {
    fn observe(&mut self, t: &TickView<'_, Reply>, _stepper: &S) -> Result<(), HilError> {
        self.rows.push(HilRow {
            t_s: tick_time_s(t.tick, BOARD_DT_S),
            ref_m: t.ref_m as f32,
            sample: *t.sample,
            reply: *t.output,
        });
        Ok(())
    }
}

/// Run `spec` in lockstep with `stepper` (see the module documentation for
/// the timing). The controller configuration of `spec` must already be in
/// force at the stepper. The plant carries the spec's effects; the sensors are
/// read once per control tick (a sensor delay is counted in control ticks).
pub fn run_lockstep<S: Stepper<Output = Reply, Error = HilError>>(
    spec: &RunSpec,
    stepper: &mut S,
    source: &str,
) -> Result<HilTrace, HilError> {
    let scenario = &spec.scenario;
    if scenario.is_open_loop() {
        return Err(HilError::Spec(format!(
            "scenario '{}' is open loop: nothing to run in the loop",
            scenario.name()
        )));
    }
    let dt = spec.dt_s;
    let sub = (BOARD_DT_S / dt).round();
    if !(dt > 0.0 && sub >= 1.0 && (sub * dt - BOARD_DT_S).abs() < 1e-12) {
        return Err(HilError::Spec(format!(
            "plant step {dt} s must divide the 1 ms control tick"
        )));
    }
    let rig = Rig::new(spec.plant.clone(), spec.effects)
        .map_err(|e| HilError::Spec(format!("effects refused: {e}")))?;
    let mut sensors = closed_loop::sensors(spec.sensors, spec.seed, &spec.effects, BOARD_DT_S);
    let timing = Timing {
        dt_s: dt,
        steps_per_tick: sub as u64,
        ticks: scenario.n_steps(BOARD_DT_S),
    };
    let mut log = HilLog {
        rows: Vec::with_capacity(timing.ticks as usize),
    };
    drive(scenario, &rig, &mut sensors, &timing, stepper, &mut log)?;
    Ok(HilTrace {
        scenario: scenario.name().to_string(),
        controller: spec.controller.kind.name().to_string(),
        source: source.to_string(),
        rows: log.rows,
    })
}

/// Settings that run `cfg` at the board's tick with the default limits.
fn settings_for(cfg: &ControllerConfig) -> Settings {
    let mut c = *cfg;
    c.base_dt_s = BOARD_DT_S;
    Settings {
        controller: c,
        ..Settings::default()
    }
}

/// The software reference of a HIL run: the same lockstep loop with the core
/// in this process.
pub fn run_software(spec: &RunSpec) -> Result<HilTrace, HilError> {
    let mut s = SoftwareStepper::new(&settings_for(&spec.controller))?;
    run_lockstep(spec, &mut s, "software")
}

/// Set the firmware up for `spec` over its console (and its link timeout,
/// when given) and enter HIL mode, armed.
fn prepare(
    console: &mut ConsoleClient,
    spec: &RunSpec,
    link_timeout_ms: Option<u32>,
) -> Result<(), HilError> {
    for c in setup_commands(&spec.controller)? {
        console.must(&c)?;
    }
    if let Some(ms) = link_timeout_ms {
        console.must(&format!("set hil.timeout_ms {ms}"))?;
    }
    console.must("hil on")?;
    console.must("arm")?;
    Ok(())
}

/// Serial ports of a board.
#[derive(Clone, Debug)]
pub struct SerialOptions {
    /// The HIL link's baud rate (the firmware's is [`HIL_BAUD`]).
    pub baud: u32,
    /// The console port (115200 baud); when given, the run sets the board up
    /// (`controller`, `preset`, `set`, `hil on`, `arm`) and disarms it at the
    /// end; otherwise the user has typed `hil on` and `arm` and the board's
    /// settings must match the spec.
    pub console: Option<String>,
    /// Longest wait for a reply.
    pub timeout: Duration,
    /// The firmware's link timeout (`hil.timeout_ms`) to set through the
    /// console before arming; `None` keeps the board's setting.
    pub link_timeout_ms: Option<u32>,
    /// Have the board record every tick of the run (needs `console`).
    pub record: bool,
}

impl Default for SerialOptions {
    fn default() -> Self {
        Self {
            baud: HIL_BAUD,
            console: None,
            timeout: Duration::from_secs(2),
            link_timeout_ms: None,
            record: false,
        }
    }
}

/// The lockstep run over an open console (optional) and HIL port; with
/// `record` (and a console) the board also records every tick of the run
/// (`record S` before, `dump` after).
fn run_on_ports(
    spec: &RunSpec,
    console: Option<&mut ConsoleClient>,
    link: SerialLink,
    timeout: Duration,
    link_timeout_ms: Option<u32>,
    source: &str,
    record: bool,
) -> Result<(HilTrace, Option<BoardRecord>), HilError> {
    let mut console = console;
    if let Some(c) = console.as_deref_mut() {
        prepare(c, spec, link_timeout_ms)?;
        if record {
            let ticks = spec.scenario.n_steps(BOARD_DT_S);
            c.must(&format!("record {:.3}", ticks as f64 * BOARD_DT_S))?;
        }
    }
    let mut stepper = LinkStepper::new(link, timeout)?;
    let trace = run_lockstep(spec, &mut stepper, source);
    if let Some(c) = console {
        // Back to idle even after a failed run, then report the run's error.
        let end = c.must("disarm").and_then(|_| c.must("hil off"));
        let trace = trace?;
        end?;
        let rec = if record {
            Some(BoardRecord::from_reply(&c.command("dump")?)?)
        } else {
            None
        };
        return Ok((trace, rec));
    }
    trace.map(|t| (t, None))
}

/// Refuse a controller whose design model differs from the nominal plant in
/// a parameter the board cannot hold: the board designs its controllers on
/// its settings' `model.*` parameters (set by [`setup_commands`]) and on
/// nominal values for the rest. The rig simulated here (`--plant`) may be
/// anything.
pub fn check_board_model(spec: &RunSpec) -> Result<(), HilError> {
    let nominal = dca_core::params::PlantParams::NOMINAL;
    let off: Vec<&str> = crate::model::params::KEYS
        .iter()
        .filter(|k| k.get(&spec.controller.plant).to_bits() != k.get(&nominal).to_bits())
        .filter(|k| dca_app::settings::find(&format!("model.{}", k.name)).is_none())
        .map(|k| k.name)
        .collect();
    if off.is_empty() {
        return Ok(());
    }
    Err(HilError::Spec(format!(
        "the controller's design model differs from the nominal plant in {}, which the board \
         has no model.* setting for (it designs on nominal values there); remove them from \
         [model] / [controller.model] (the rig's parameters, --plant or [plant.params], may \
         differ)",
        off.join(", ")
    )))
}

/// Run `spec` against a real board: the HIL link on `port`, the plant here.
pub fn run_hil_serial(
    spec: &RunSpec,
    port: &str,
    opts: &SerialOptions,
) -> Result<HilTrace, HilError> {
    run_hil_serial_with(spec, port, opts).map(|(t, _)| t)
}

/// [`run_hil_serial`], and with `opts.record` (and a console) the board's
/// own record of every tick of the run.
pub fn run_hil_serial_with(
    spec: &RunSpec,
    port: &str,
    opts: &SerialOptions,
) -> Result<(HilTrace, Option<BoardRecord>), HilError> {
    if opts.record && opts.console.is_none() {
        return Err(HilError::Spec(
            "the board's record needs its console (`record`, `dump`)".into(),
        ));
    }
    check_board_model(spec)?;
    let mut console = match &opts.console {
        Some(c) => Some(ConsoleClient::connect(
            SerialLink::open(c, CONSOLE_BAUD, Duration::from_millis(50))?,
            opts.timeout.max(Duration::from_secs(5)),
        )?),
        None => None,
    };
    let link = SerialLink::open(port, opts.baud, Duration::from_millis(20))?;
    run_on_ports(
        spec,
        console.as_mut(),
        link,
        opts.timeout,
        opts.link_timeout_ms,
        "serial",
        opts.record,
    )
}

/// The firmware's link timeout (`hil.timeout_ms`) [`run_hil_qemu`] sets unless
/// told otherwise, ms: the largest the setting takes. The emulated board keeps
/// time by the host's clock (QEMU's `-icount sleep=on`), and the host is not
/// real time: on a loaded machine a round trip through QEMU took up to 0.94 s
/// (a build and a fuzzer running), and 5 s were exceeded once (a release
/// build with LTO, two gap diagnoses and CI's own work on two cores), far
/// beyond the factory 100 ms a board keeps. The host owns the emulator and
/// ends it, so waiting longer costs nothing; the factory timeout itself is
/// tested by the fault injection.
pub const EMULATED_LINK_TIMEOUT_MS: u32 = 60_000;

/// Run `spec` through the emulated firmware: start QEMU on `elf` with its
/// USARTs on ptys, then exactly the board's path ([`run_hil_serial`]'s), and
/// end QEMU. `link_timeout_ms` as in [`SerialOptions`], except that `None`
/// sets [`EMULATED_LINK_TIMEOUT_MS`] rather than keeping the factory setting.
pub fn run_hil_qemu(
    spec: &RunSpec,
    elf: &Path,
    opts: &QemuOptions,
    link_timeout_ms: Option<u32>,
) -> Result<HilTrace, HilError> {
    run_hil_qemu_with(spec, elf, opts, link_timeout_ms, false).map(|(t, _)| t)
}

/// [`run_hil_qemu`], and with `record` the emulated board's own record of
/// every tick of the run (`record S` before the run, `dump` after it; see
/// dca_app::record).
pub fn run_hil_qemu_with(
    spec: &RunSpec,
    elf: &Path,
    opts: &QemuOptions,
    link_timeout_ms: Option<u32>,
    record: bool,
) -> Result<(HilTrace, Option<BoardRecord>), HilError> {
    let link_timeout_ms = Some(link_timeout_ms.unwrap_or(EMULATED_LINK_TIMEOUT_MS));
    check_board_model(spec)?;
    let emu = Emulator::start(elf, opts)?;
    let mut console = ConsoleClient::connect(
        SerialLink::open(&emu.console_tty, CONSOLE_BAUD, Duration::from_millis(50))?,
        opts.timeout,
    )?;
    let link = SerialLink::open(&emu.hil_tty, HIL_BAUD, Duration::from_millis(20))?;
    let trace = run_on_ports(
        spec,
        Some(&mut console),
        link,
        opts.timeout,
        link_timeout_ms,
        "qemu",
        record,
    )?;
    emu.quit(&mut console)?;
    Ok(trace)
}
