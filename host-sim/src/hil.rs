//! Processor- and hardware-in-the-loop: the plant on the host, the control tick
//! somewhere else, in lockstep.
//!
//! One loop ([`run_lockstep`]) serves three controllers behind [`Stepper`]:
//! * [`SoftwareStepper`]: dca-core's `ControlLoop` in this process (the
//!   reference the others must match bit for bit);
//! * [`LinkStepper`] over QEMU ([`run_hil_qemu`]): the firmware's `qemu` build,
//!   started here with two TCP character devices (console, HIL link);
//! * [`LinkStepper`] over serial ports ([`run_hil_serial`]): a real board.
//!
//! # Timing
//! The firmware's base tick is 1 ms, so the lockstep loop ticks the controller
//! every 1 ms (t_j = j * 1e-3 s) and integrates the plant over that millisecond
//! in `round(1e-3 / dt)` RK4 steps of the spec's plant step `dt` (1e-4 s
//! nominal), the command held and the load evaluated at each plant step. One
//! run-log row is written per tick, before the plant moves (interfaces.md
//! section 1). This differs from [`crate::sim::run`], whose controller ticks at
//! the plant step: compare HIL runs with [`run_software`], not with `sim::run`.
//!
//! # The exchange
//! Per tick the host sends a [`SampleFrame`] (reference and sensor readings as
//! `f32`, `seq` = tick index) and waits for the [`CommandFrame`] with the same
//! `seq`; a missing, corrupt or out-of-sequence reply, or one reporting a
//! fault, ends the run with an error. Before the first frame the host sets the
//! firmware up over its console (`controller`, `preset`, `set`, `hil on`,
//! `arm`) so that it designs exactly the configuration of the spec.

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use dca_core::controller::{ControllerConfig, Preset, Sample};
use dca_core::frame::{self, CommandFrame, SampleFrame, MAX_FRAME_LEN};
use dca_core::settings::{Settings, BOARD_DT_S, PARAMS};
use dca_core::supervisor::ControlLoop;

use crate::rig::Rig;
use crate::scenario::{tick_time_s, Command as ScenarioCommand};
use crate::sensors::{Readings, Sensors};
use crate::sim::RunSpec;

/// Why a HIL run failed.
#[derive(Debug)]
pub enum HilError {
    /// The spec cannot run in lockstep (open loop, bad step, configuration the
    /// console cannot reproduce exactly, ...).
    Spec(String),
    /// I/O on the link or the console.
    Io(io::Error),
    /// The console answered a set-up command with an error.
    Console {
        /// The command sent.
        command: String,
        /// The reply.
        reply: String,
    },
    /// No reply within the timeout.
    Timeout {
        /// Tick index of the unanswered frame.
        tick: u32,
    },
    /// A reply that does not decode or answers another tick.
    Link {
        /// Tick index.
        tick: u32,
        /// What was wrong.
        what: String,
    },
    /// The firmware reported a fault.
    Fault {
        /// Tick index.
        tick: u32,
        /// Fault bits (dca_core::supervisor::Faults).
        faults: u16,
    },
    /// The emulator could not be started or ended badly.
    Emulator(String),
}

impl std::fmt::Display for HilError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Spec(s) => write!(f, "HIL run refused: {s}"),
            Self::Io(e) => write!(f, "HIL link I/O: {e}"),
            Self::Console { command, reply } => {
                write!(f, "console refused '{command}': {}", reply.trim())
            }
            Self::Timeout { tick } => write!(f, "no reply to the frame of tick {tick}"),
            Self::Link { tick, what } => write!(f, "bad reply at tick {tick}: {what}"),
            Self::Fault { tick, faults } => {
                let mut names = String::new();
                dca_core::console::write_faults(&mut names, *faults);
                write!(f, "firmware fault at tick {tick}: {names} ({faults:#x})")
            }
            Self::Emulator(s) => write!(f, "emulator: {s}"),
        }
    }
}

impl std::error::Error for HilError {}

impl From<io::Error> for HilError {
    fn from(e: io::Error) -> Self {
        Self::Io(e)
    }
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

/// Something that runs one control tick per call.
pub trait Stepper {
    /// Tick `seq` with this sample and reference.
    fn step(&mut self, seq: u32, sample: &Sample, ref_m: f32) -> Result<Reply, HilError>;
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
    fn step(&mut self, _seq: u32, sample: &Sample, ref_m: f32) -> Result<Reply, HilError> {
        let o = self.lp.tick(sample, Some(ref_m));
        Ok(Reply {
            v_cmd_mps: o.v_cmd_mps,
            state: o.state,
            faults: o.faults,
            flags: o.flags.0,
        })
    }
}

/// A byte stream with a settable read timeout (TCP socket or serial port).
pub trait Port: Read + Write + Send {
    /// Set the read timeout.
    fn set_timeout(&mut self, t: Duration) -> io::Result<()>;
}

impl Port for TcpStream {
    fn set_timeout(&mut self, t: Duration) -> io::Result<()> {
        self.set_read_timeout(Some(t))
    }
}

struct SerialPort(Box<dyn serialport::SerialPort>);

impl Read for SerialPort {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        self.0.read(buf)
    }
}

impl Write for SerialPort {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.write(buf)
    }
    fn flush(&mut self) -> io::Result<()> {
        self.0.flush()
    }
}

impl Port for SerialPort {
    fn set_timeout(&mut self, t: Duration) -> io::Result<()> {
        self.0.set_timeout(t).map_err(io::Error::other)
    }
}

/// The firmware's text console.
pub struct Console {
    port: BufReader<Box<dyn Port>>,
    timeout: Duration,
}

impl Console {
    /// A console on `port`; replies are awaited for at most `timeout`.
    pub fn new(mut port: Box<dyn Port>, timeout: Duration) -> io::Result<Self> {
        port.set_timeout(timeout)?;
        Ok(Self {
            port: BufReader::new(port),
            timeout,
        })
    }

    /// Read lines until one starts with `needle` (e.g. the boot banner).
    pub fn wait_for(&mut self, needle: &str) -> Result<String, HilError> {
        let start = Instant::now();
        let mut seen = String::new();
        loop {
            let line = self.read_line()?;
            seen.push_str(&line);
            if line.contains(needle) {
                return Ok(seen);
            }
            if start.elapsed() > self.timeout {
                return Err(HilError::Emulator(format!(
                    "no '{needle}' from the console"
                )));
            }
        }
    }

    fn read_line(&mut self) -> Result<String, HilError> {
        let mut line = String::new();
        match self.port.read_line(&mut line) {
            Ok(0) => Err(HilError::Emulator("console closed".into())),
            Ok(_) => Ok(line),
            Err(e)
                if matches!(
                    e.kind(),
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                ) =>
            {
                Err(HilError::Emulator("console did not answer".into()))
            }
            Err(e) => Err(e.into()),
        }
    }

    /// Send one command line; the reply lines up to and including the final
    /// `ok` or `error: ...`.
    pub fn command(&mut self, line: &str) -> Result<String, HilError> {
        let port = self.port.get_mut();
        port.write_all(line.as_bytes())?;
        port.write_all(b"\r\n")?;
        port.flush()?;
        let mut reply = String::new();
        loop {
            let l = self.read_line()?;
            let end = l.trim_end();
            reply.push_str(&l);
            if end == "ok" || end.starts_with("error:") {
                return Ok(reply);
            }
        }
    }

    /// Send a command that must succeed.
    pub fn must(&mut self, line: &str) -> Result<String, HilError> {
        let reply = self.command(line)?;
        if reply.trim_end().ends_with("ok") {
            Ok(reply)
        } else {
            Err(HilError::Console {
                command: line.to_string(),
                reply,
            })
        }
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
            dca_core::settings::ParamKind::F64 => format!("{v:e}"),
            dca_core::settings::ParamKind::F32 => format!("{:e}", v as f32),
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

/// Lockstep over a byte link: one sample frame out, one command frame back.
pub struct LinkStepper {
    link: Box<dyn Port>,
    rx: Vec<u8>,
    timeout: Duration,
}

impl LinkStepper {
    /// Frames over `link`, replies awaited for at most `timeout`.
    pub fn new(mut link: Box<dyn Port>, timeout: Duration) -> io::Result<Self> {
        link.set_timeout(timeout)?;
        Ok(Self {
            link,
            rx: Vec::with_capacity(2 * MAX_FRAME_LEN),
            timeout,
        })
    }

    fn read_frame(&mut self, tick: u32) -> Result<Vec<u8>, HilError> {
        let start = Instant::now();
        let mut buf = [0u8; 256];
        loop {
            if let Some(i) = self.rx.iter().position(|b| *b == 0) {
                let body: Vec<u8> = self.rx.drain(..=i).take(i).collect();
                if body.is_empty() {
                    continue;
                }
                return Ok(body);
            }
            if start.elapsed() > self.timeout {
                return Err(HilError::Timeout { tick });
            }
            match self.link.read(&mut buf) {
                Ok(0) => return Err(HilError::Emulator("HIL link closed".into())),
                Ok(n) => self.rx.extend_from_slice(&buf[..n]),
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut
                    ) =>
                {
                    return Err(HilError::Timeout { tick })
                }
                Err(e) => return Err(e.into()),
            }
        }
    }
}

impl Stepper for LinkStepper {
    fn step(&mut self, seq: u32, sample: &Sample, ref_m: f32) -> Result<Reply, HilError> {
        let msg = SampleFrame {
            seq,
            ref_m,
            xo_m: sample.xo_m,
            xi_m: sample.xi_m,
            p1_pa: sample.p1_pa,
            p2_pa: sample.p2_pa,
            ft_n: sample.ft_n,
        };
        let mut out = [0u8; MAX_FRAME_LEN];
        let n = frame::encode(&msg, &mut out).map_err(|e| HilError::Link {
            tick: seq,
            what: e.as_str().into(),
        })?;
        self.link.write_all(&out[..n])?;
        self.link.flush()?;
        let mut body = self.read_frame(seq)?;
        let r: CommandFrame = frame::decode(&mut body).map_err(|e| HilError::Link {
            tick: seq,
            what: e.as_str().into(),
        })?;
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

    /// Write the run log (interfaces.md section 1) with the optional columns
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

/// Run `spec` in lockstep with `stepper` (see the module documentation for
/// the timing). The controller configuration of `spec` must already be in
/// force at the stepper. The plant carries the spec's effects; the sensors are
/// read once per control tick (a sensor delay is counted in control ticks).
pub fn run_lockstep(
    spec: &RunSpec,
    stepper: &mut dyn Stepper,
    source: &str,
) -> Result<HilTrace, HilError> {
    let scenario = &spec.scenario;
    let ScenarioCommand::Reference(reference) = scenario.command() else {
        return Err(HilError::Spec(format!(
            "scenario '{}' is open loop: nothing to run in the loop",
            scenario.name()
        )));
    };
    let dt = spec.dt_s;
    let sub = (BOARD_DT_S / dt).round();
    if !(dt > 0.0 && sub >= 1.0 && (sub * dt - BOARD_DT_S).abs() < 1e-12) {
        return Err(HilError::Spec(format!(
            "plant step {dt} s must divide the 1 ms control tick"
        )));
    }
    let sub = sub as u64;
    let rig = Rig::new(spec.plant.clone(), spec.effects)
        .map_err(|e| HilError::Spec(format!("effects refused: {}", e.0)))?;
    let mut sensors = Sensors::new(spec.sensors, spec.seed);
    if let Some(d) = &spec.effects.sensor_delay {
        sensors = sensors.with_delay(d, BOARD_DT_S);
    }
    let mut s = rig.initial_state(scenario.load().value(0.0));
    let n_ticks = scenario.n_steps(BOARD_DT_S);
    let mut rows = Vec::with_capacity(n_ticks as usize);
    for j in 0..n_ticks {
        let k0 = j * sub;
        let t = tick_time_s(k0, dt);
        let x = s.x;
        let truth = Readings {
            xi_m: x.xi_m,
            xo_m: x.xo_m,
            p1_pa: x.p1_pa,
            p2_pa: x.p2_pa,
            ft_n: scenario.load().value(t),
        };
        let sample = sensors.read(&truth).to_sample();
        let ref_m = reference.value(t) as f32;
        let seq = u32::try_from(j).map_err(|_| HilError::Spec("run too long".into()))?;
        let reply = stepper.step(seq, &sample, ref_m)?;
        rows.push(HilRow {
            t_s: tick_time_s(j, BOARD_DT_S),
            ref_m,
            sample,
            reply,
        });
        let v = reply.v_cmd_mps as f64;
        for k in k0..k0 + sub {
            let ft = scenario.load().value(tick_time_s(k, dt));
            rig.step(&mut s, v, ft, dt);
        }
    }
    Ok(HilTrace {
        scenario: scenario.name().to_string(),
        controller: spec.controller.kind.name().to_string(),
        source: source.to_string(),
        rows,
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

/// Set the firmware up for `spec` over its console and enter HIL mode, armed.
fn prepare(console: &mut Console, spec: &RunSpec) -> Result<(), HilError> {
    for c in setup_commands(&spec.controller)? {
        console.must(&c)?;
    }
    console.must("hil on")?;
    console.must("arm")?;
    Ok(())
}

/// How to start QEMU.
#[derive(Clone, Debug)]
pub struct QemuOptions {
    /// The emulator binary.
    pub qemu: PathBuf,
    /// Longest wait for any reply.
    pub timeout: Duration,
    /// Where QEMU's stdout (defmt frames over semihosting) goes; discarded if
    /// `None`.
    pub defmt_out: Option<PathBuf>,
}

impl Default for QemuOptions {
    fn default() -> Self {
        Self {
            qemu: PathBuf::from("qemu-system-arm"),
            timeout: Duration::from_secs(10),
            defmt_out: None,
        }
    }
}

/// A running emulated firmware (`qemu` build on netduinoplus2) with its
/// console (USART1) and HIL link (USART2) on TCP sockets.
pub struct Emulator {
    child: Child,
    /// The console.
    pub console: Console,
    /// The HIL link (raw bytes).
    pub link: Option<TcpStream>,
}

impl Emulator {
    /// Start QEMU on `elf` and wait for the console's banner.
    ///
    /// `-icount shift=3,sleep=on`: instruction-driven virtual time while the
    /// CPU runs (deterministic control ticks and deadline checks), real time
    /// while it sleeps, so that the firmware's HIL timeout measures the host's
    /// real response time instead of racing ahead of it.
    pub fn start(elf: &Path, opts: &QemuOptions) -> Result<Self, HilError> {
        if !elf.exists() {
            return Err(HilError::Emulator(format!(
                "no firmware ELF at {} (build it with `cargo fw-qemu`)",
                elf.display()
            )));
        }
        let console_l = TcpListener::bind("127.0.0.1:0")?;
        let link_l = TcpListener::bind("127.0.0.1:0")?;
        let chardev = |id: &str, l: &TcpListener| -> io::Result<String> {
            Ok(format!(
                "socket,id={id},host=127.0.0.1,port={},nodelay=on",
                l.local_addr()?.port()
            ))
        };
        let stdout = match &opts.defmt_out {
            Some(p) => Stdio::from(std::fs::File::create(p)?),
            None => Stdio::null(),
        };
        let child = Command::new(&opts.qemu)
            .args([
                "-machine",
                "netduinoplus2",
                "-nographic",
                "-monitor",
                "none",
            ])
            .args(["-semihosting-config", "enable=on,target=native"])
            .args(["-icount", "shift=3,sleep=on"])
            .args(["-chardev", &chardev("con", &console_l)?])
            .args(["-chardev", &chardev("hil", &link_l)?])
            .args(["-serial", "chardev:con", "-serial", "chardev:hil"])
            .arg("-kernel")
            .arg(elf)
            .stdin(Stdio::null())
            .stdout(stdout)
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| {
                HilError::Emulator(format!("cannot start {}: {e}", opts.qemu.display()))
            })?;
        let accept = |l: &TcpListener| -> Result<TcpStream, HilError> {
            l.set_nonblocking(true)?;
            let start = Instant::now();
            loop {
                match l.accept() {
                    Ok((s, _)) => {
                        s.set_nonblocking(false)?;
                        s.set_nodelay(true)?;
                        return Ok(s);
                    }
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                        if start.elapsed() > opts.timeout {
                            return Err(HilError::Emulator("QEMU did not connect".into()));
                        }
                        std::thread::sleep(Duration::from_millis(5));
                    }
                    Err(e) => return Err(e.into()),
                }
            }
        };
        let mut emu = Self {
            child,
            console: Console::new(Box::new(accept(&console_l)?), opts.timeout)?,
            link: Some(accept(&link_l)?),
        };
        emu.console.wait_for("ready")?;
        Ok(emu)
    }

    /// End the emulator with the console's `quit`; its exit status must be 0.
    pub fn quit(mut self) -> Result<(), HilError> {
        self.console.must("quit")?;
        let status = self.child.wait()?;
        if status.success() {
            Ok(())
        } else {
            let mut err = String::new();
            if let Some(mut e) = self.child.stderr.take() {
                let _ = e.read_to_string(&mut err);
            }
            Err(HilError::Emulator(format!(
                "QEMU exited with {status}: {err}"
            )))
        }
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        // Only if still running (after `quit` it has exited): never leave one behind.
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

/// Run `spec` through the emulated firmware: start QEMU on `elf`, set it up,
/// run the lockstep loop over the HIL link, and end QEMU.
pub fn run_hil_qemu(spec: &RunSpec, elf: &Path, opts: &QemuOptions) -> Result<HilTrace, HilError> {
    let mut emu = Emulator::start(elf, opts)?;
    prepare(&mut emu.console, spec)?;
    let link = emu.link.take().expect("link set at start");
    let mut stepper = LinkStepper::new(Box::new(link), opts.timeout)?;
    let trace = run_lockstep(spec, &mut stepper, "qemu")?;
    emu.console.must("disarm")?;
    emu.console.must("hil off")?;
    emu.quit()?;
    Ok(trace)
}

/// Serial ports of a board.
#[derive(Clone, Debug)]
pub struct SerialOptions {
    /// The HIL link's baud rate (the firmware's is 921600).
    pub baud: u32,
    /// The console port (115200 baud); when given, the run sets the board up
    /// (`controller`, `preset`, `set`, `hil on`, `arm`) and disarms it at the
    /// end; otherwise the user has typed `hil on` and `arm` and the board's
    /// settings must match the spec.
    pub console: Option<String>,
    /// Longest wait for a reply.
    pub timeout: Duration,
}

impl Default for SerialOptions {
    fn default() -> Self {
        Self {
            baud: 921_600,
            console: None,
            timeout: Duration::from_secs(2),
        }
    }
}

fn open_serial(port: &str, baud: u32, timeout: Duration) -> Result<Box<dyn Port>, HilError> {
    let p = serialport::new(port, baud)
        .timeout(timeout)
        .open()
        .map_err(|e| HilError::Io(io::Error::other(format!("{port}: {e}"))))?;
    Ok(Box::new(SerialPort(p)))
}

/// Run `spec` against a real board: the HIL link on `port`, the plant here.
pub fn run_hil_serial(
    spec: &RunSpec,
    port: &str,
    opts: &SerialOptions,
) -> Result<HilTrace, HilError> {
    let mut console = match &opts.console {
        Some(c) => Some(Console::new(
            open_serial(c, 115_200, opts.timeout)?,
            opts.timeout,
        )?),
        None => None,
    };
    if let Some(c) = console.as_mut() {
        prepare(c, spec)?;
    }
    let link = open_serial(port, opts.baud, opts.timeout)?;
    let mut stepper = LinkStepper::new(link, opts.timeout)?;
    let trace = run_lockstep(spec, &mut stepper, "serial");
    if let Some(c) = console.as_mut() {
        c.must("disarm")?;
        c.must("hil off")?;
    }
    trace
}
