//! The console's commands: one table ([`COMMANDS`]) of names, arguments, help
//! and argument counts, and one handler per command.
//!
//! `help` prints the table, the argument counts are checked from it before a
//! handler runs, and a `usage:` reply is the command's own row; adding a
//! command is one row and one handler.

use core::fmt::Write;

use super::{
    int, kv, num, write_faults, CmdError, Console, Output, Target, MAX_DECIMATION, MIN_DECIMATION,
};
use crate::frame::{self, MAX_FRAME_LEN};
use crate::record::{RecordChunk, RecordError, CHUNK_ROWS, RECORD_DT_S};
use crate::settings::{self, Settings, SettingsError, IMAGE_LEN};
use crate::supervisor::State;
use crate::text::{parse_f64, parse_u32};
use dca_core::controller::{ControllerKind, Preset};

/// What runs a command (one handler each).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Cmd {
    Help,
    Ping,
    Status,
    Arm,
    Disarm,
    Goto,
    Sine,
    Stop,
    Controller,
    Preset,
    Get,
    Set,
    Store,
    Load,
    Defaults,
    Telemetry,
    Fault,
    Clear,
    Hil,
    Echo,
    Record,
    Dump,
}

/// One console command.
#[derive(Debug, PartialEq, Eq)]
pub struct Command {
    /// The first word of the line.
    pub name: &'static str,
    /// Its arguments as `help` and `usage:` show them (`<x>` required,
    /// `[x]` optional, `a|b` one of).
    pub args: &'static str,
    /// What it does.
    pub help: &'static str,
    /// Arguments it needs.
    pub required: u8,
    /// Arguments it may take beyond those.
    pub optional: u8,
    run: Cmd,
}

impl Command {
    /// Write `usage: <name> <args>`.
    pub fn write_usage<W: Write>(&self, out: &mut W) -> core::fmt::Result {
        out.write_str("usage: ")?;
        out.write_str(self.name)?;
        if !self.args.is_empty() {
            out.write_str(" ")?;
            out.write_str(self.args)?;
        }
        Ok(())
    }

    /// The command called `name`.
    pub fn find(name: &str) -> Option<&'static Command> {
        COMMANDS.iter().find(|c| c.name == name)
    }
}

const fn c(
    name: &'static str,
    args: &'static str,
    help: &'static str,
    required: u8,
    optional: u8,
    run: Cmd,
) -> Command {
    Command {
        name,
        args,
        help,
        required,
        optional,
        run,
    }
}

/// Every command, in the order `help` lists them.
pub static COMMANDS: [Command; 22] = [
    c("help", "", "list the commands", 0, 0, Cmd::Help),
    c(
        "ping",
        "[token]",
        "answer 'pong [token]' (hosts find the start of their replies)",
        0,
        1,
        Cmd::Ping,
    ),
    c(
        "status",
        "",
        "state, faults, controller, sensors, reference, command",
        0,
        0,
        Cmd::Status,
    ),
    c(
        "arm",
        "",
        "enable the drive, holding the current position",
        0,
        0,
        Cmd::Arm,
    ),
    c("disarm", "", "disable the drive", 0, 0, Cmd::Disarm),
    c(
        "goto",
        "<mm>",
        "move to a position within the software stroke",
        1,
        0,
        Cmd::Goto,
    ),
    c(
        "sine",
        "<amplitude mm> <frequency Hz>",
        "r = r0 + a (1 - cos 2 pi f t) from the current reference",
        2,
        0,
        Cmd::Sine,
    ),
    c(
        "stop",
        "",
        "end a motion, hold the reference where it is",
        0,
        0,
        Cmd::Stop,
    ),
    c(
        "controller",
        "[mpc-eso|mpc|pid|fuzzy-pid|cmpc-eso]",
        "show or select the law (idle only)",
        0,
        1,
        Cmd::Controller,
    ),
    c(
        "preset",
        "paper|fast|limit",
        "load a preset's controller parameters (idle only)",
        1,
        0,
        Cmd::Preset,
    ),
    c("get", "[name]", "one setting, or all", 0, 1, Cmd::Get),
    c(
        "set",
        "<name> <value>",
        "change a setting (idle only; range-checked; re-designs)",
        2,
        0,
        Cmd::Set,
    ),
    c("store", "", "settings to flash", 0, 0, Cmd::Store),
    c("load", "", "settings from flash", 0, 0, Cmd::Load),
    c("defaults", "", "factory settings", 0, 0, Cmd::Defaults),
    c(
        "telemetry",
        "on [decimation 10..10000] | off",
        "stream the run log, a row every decimation ms",
        1,
        1,
        Cmd::Telemetry,
    ),
    c(
        "fault",
        "",
        "latched faults and HIL link counters",
        0,
        0,
        Cmd::Fault,
    ),
    c(
        "clear",
        "",
        "clear the faults (back to idle)",
        0,
        0,
        Cmd::Clear,
    ),
    c(
        "hil",
        "on|off",
        "samples from HIL frames instead of the sensors (idle only)",
        1,
        0,
        Cmd::Hil,
    ),
    c("echo", "on|off", "echo typed characters", 1, 0, Cmd::Echo),
    c(
        "record",
        "[seconds|off]",
        "record every control tick for S s from the next motion (alone: its state)",
        0,
        1,
        Cmd::Record,
    ),
    c(
        "dump",
        "",
        "end the record and send it as binary frames (host-sim console --capture)",
        0,
        0,
        Cmd::Dump,
    ),
];

/// The words after the command: the first two, and how many there were (up to
/// three: more than any command takes).
#[derive(Clone, Copy, Debug)]
struct Args<'a> {
    a1: Option<&'a str>,
    a2: Option<&'a str>,
    count: usize,
}

fn number(s: &str) -> Result<f64, CmdError> {
    parse_f64(s).map_err(CmdError::Number)
}

fn on_off(arg: Option<&str>, cmd: &'static Command) -> Result<bool, CmdError> {
    match arg {
        Some("on") => Ok(true),
        Some("off") => Ok(false),
        _ => Err(CmdError::Usage(cmd)),
    }
}

impl Console {
    /// Parse the line, check its argument count against the table, and run
    /// the command's handler.
    pub(super) fn run<T: Target, W: Output>(
        &mut self,
        line: &str,
        target: &mut T,
        out: &mut W,
    ) -> Result<(), CmdError> {
        let mut words = line.split_ascii_whitespace();
        let cmd = words
            .next()
            .and_then(Command::find)
            .ok_or(CmdError::Unknown)?;
        let (a1, a2) = (words.next(), words.next());
        let count = a1.is_some() as usize + a2.is_some() as usize + words.next().is_some() as usize;
        let (req, opt) = (usize::from(cmd.required), usize::from(cmd.optional));
        if count < req || count > req + opt {
            return Err(CmdError::Usage(cmd));
        }
        let args = Args { a1, a2, count };
        self.dispatch(cmd, args, target, out)
    }

    fn dispatch<T: Target, W: Output>(
        &mut self,
        cmd: &'static Command,
        args: Args<'_>,
        target: &mut T,
        out: &mut W,
    ) -> Result<(), CmdError> {
        let usage = CmdError::Usage(cmd);
        match cmd.run {
            Cmd::Help => help(out),
            Cmd::Ping => ping(args.a1, out),
            Cmd::Status => self.status(target, out),
            Cmd::Arm => target.arm()?,
            Cmd::Disarm => target.disarm(),
            Cmd::Goto => self.goto(args.a1.ok_or(usage)?, target)?,
            Cmd::Sine => self.sine(args.a1.ok_or(usage)?, args.a2.ok_or(usage)?, target)?,
            Cmd::Stop => target.stop()?,
            Cmd::Controller => self.controller(args.a1, cmd, target, out)?,
            Cmd::Preset => {
                let p = args.a1.and_then(Preset::from_name).ok_or(usage)?;
                self.commit(self.settings.with_preset(p), target)?;
            }
            Cmd::Get => self.get(args.a1, out)?,
            Cmd::Set => self.set(args.a1.ok_or(usage)?, args.a2.ok_or(usage)?, target)?,
            Cmd::Store => target
                .store(&self.settings.to_image())
                .map_err(CmdError::Store)?,
            Cmd::Load => self.load(target)?,
            Cmd::Defaults => self.commit(Settings::default(), target)?,
            Cmd::Telemetry => telemetry(args, cmd, target)?,
            Cmd::Fault => fault(target, out),
            Cmd::Clear => target.clear()?,
            Cmd::Hil => target.hil(on_off(args.a1, cmd)?)?,
            Cmd::Echo => target.echo(on_off(args.a1, cmd)?),
            Cmd::Record => self.record(args.a1, target, out)?,
            Cmd::Dump => dump(target, out)?,
        }
        Ok(())
    }

    fn goto<T: Target>(&mut self, mm: &str, target: &mut T) -> Result<(), CmdError> {
        let x_m = number(mm)? / 1000.0;
        let st = self.settings.limits.stroke_m;
        if !(x_m >= st[0] as f64 && x_m <= st[1] as f64) {
            return Err(CmdError::Range("target outside the software stroke"));
        }
        Ok(target.goto(x_m as f32)?)
    }

    fn sine<T: Target>(&mut self, mm: &str, hz: &str, target: &mut T) -> Result<(), CmdError> {
        let a_m = number(mm)? / 1000.0;
        let f_hz = number(hz)?;
        if !(a_m > 0.0 && a_m <= 0.06) {
            return Err(CmdError::Range("amplitude must be in (0, 60] mm"));
        }
        if !(f_hz > 0.0 && f_hz <= 10.0) {
            return Err(CmdError::Range("frequency must be in (0, 10] Hz"));
        }
        let r0 = target.status().ref_m as f64;
        let top = r0 + 2.0 * a_m;
        if top > self.settings.limits.stroke_m[1] as f64 {
            return Err(CmdError::Range("sine would leave the software stroke"));
        }
        Ok(target.sine(a_m as f32, f_hz as f32)?)
    }

    fn controller<T: Target, W: Write>(
        &mut self,
        name: Option<&str>,
        cmd: &'static Command,
        target: &mut T,
        out: &mut W,
    ) -> Result<(), CmdError> {
        let Some(name) = name else {
            let _ = out.write_str(self.settings.controller.kind.name());
            let _ = out.write_str("\r\n");
            return Ok(());
        };
        let kind = ControllerKind::from_name(name).ok_or(CmdError::Usage(cmd))?;
        self.commit(self.settings.with_kind(kind), target)
    }

    fn get<W: Write>(&self, name: Option<&str>, out: &mut W) -> Result<(), CmdError> {
        match name {
            Some(name) => {
                let p = settings::find(name).ok_or(SettingsError::UnknownName)?;
                param_line(&self.settings, p, out);
            }
            None => {
                for p in &settings::PARAMS {
                    param_line(&self.settings, p, out);
                }
            }
        }
        Ok(())
    }

    fn set<T: Target>(&mut self, name: &str, value: &str, target: &mut T) -> Result<(), CmdError> {
        if settings::find(name).is_none() {
            return Err(SettingsError::UnknownName.into());
        }
        let v = number(value)?;
        let (s, c) = self.settings.with(name, v)?;
        self.apply(s, &c, target)
    }

    fn load<T: Target>(&mut self, target: &mut T) -> Result<(), CmdError> {
        let mut img = [0u8; IMAGE_LEN];
        if !target.load(&mut img) {
            return Err(CmdError::Store("no stored settings"));
        }
        let (s, c) = Settings::from_image(&img)?;
        self.apply(s, &c, target)
    }

    /// `record S`, `record off`, or the record's state.
    fn record<T: Target, W: Write>(
        &self,
        arg: Option<&str>,
        target: &mut T,
        out: &mut W,
    ) -> Result<(), CmdError> {
        match arg {
            None => {
                let i = target.record_info();
                let _ = out.write_str("record=");
                let _ = out.write_str(i.state.name());
                let _ = out.write_str(" rows=");
                int(out, u64::from(i.rows));
                let _ = out.write_str(" of ");
                int(out, u64::from(i.wanted));
                let _ = out.write_str(" capacity=");
                int(out, u64::from(i.capacity));
                let _ = out.write_str(" rows (1 ms each)\r\n");
            }
            Some("off") => target.record_off(),
            Some(s) => {
                let rows = libm::round(number(s)? / RECORD_DT_S);
                let capacity = target.record_info().capacity;
                if !(rows >= 1.0 && rows <= f64::from(capacity)) {
                    return Err(CmdError::Record(RecordError::Length));
                }
                let s = &self.settings;
                let kind = ControllerKind::ALL
                    .iter()
                    .position(|k| *k == s.controller.kind)
                    .unwrap_or(0) as u8;
                target
                    .record_arm(rows as u32, &s.cal, kind)
                    .map_err(CmdError::Record)?;
            }
        }
        Ok(())
    }

    fn status<T: Target, W: Write>(&self, target: &mut T, out: &mut W) {
        let st = target.status();
        let state = State::from_u8(st.state).map_or("?", State::name);
        let _ = out.write_str("state=");
        let _ = out.write_str(state);
        let _ = out.write_str(" faults=");
        write_faults(out, st.faults);
        let _ = out.write_str(" controller=");
        let _ = out.write_str(self.settings.controller.kind.name());
        let _ = out.write_str(if st.hil { " hil=on" } else { " hil=off" });
        let _ = out.write_str(" telemetry=");
        int(out, st.telemetry as u64);
        let _ = out.write_str("\r\n");
        kv(out, "xo_m", st.sample.xo_m);
        kv(out, " xi_m", st.sample.xi_m);
        kv(out, " p1_pa", st.sample.p1_pa);
        kv(out, " p2_pa", st.sample.p2_pa);
        kv(out, " ft_n", st.sample.ft_n);
        let _ = out.write_str("\r\n");
        kv(out, "ref_m", st.ref_m);
        kv(out, " vcmd_mps", st.v_cmd_mps);
        let _ = out.write_str(" ticks=");
        int(out, st.ticks);
        let _ = out.write_str(" max_tick_us=");
        int(out, st.max_tick_us as u64);
        let _ = out.write_str("\r\n");
    }
}

/// One line per command: `name args: help`.
fn help<W: Write>(out: &mut W) {
    for c in &COMMANDS {
        let _ = out.write_str(c.name);
        if !c.args.is_empty() {
            let _ = out.write_str(" ");
            let _ = out.write_str(c.args);
        }
        let _ = out.write_str(": ");
        let _ = out.write_str(c.help);
        let _ = out.write_str("\r\n");
    }
}

fn ping<W: Write>(token: Option<&str>, out: &mut W) {
    let _ = out.write_str("pong");
    if let Some(t) = token {
        let _ = out.write_str(" ");
        let _ = out.write_str(t);
    }
    let _ = out.write_str("\r\n");
}

fn telemetry<T: Target>(
    args: Args<'_>,
    cmd: &'static Command,
    target: &mut T,
) -> Result<(), CmdError> {
    if !on_off(args.a1, cmd)? {
        if args.count > 1 {
            return Err(CmdError::Usage(cmd));
        }
        target.telemetry(None);
        return Ok(());
    }
    let d = match args.a2 {
        None => 100,
        Some(s) => parse_u32(s).ok_or(CmdError::Usage(cmd))?,
    };
    if !(MIN_DECIMATION..=MAX_DECIMATION).contains(&d) {
        return Err(CmdError::Range("decimation must be in 10..10000"));
    }
    target.telemetry(Some(d));
    Ok(())
}

/// `dump`: end the record, answer `dump rows=N frames=F`, then the frames
/// (crate::record's module documentation).
fn dump<T: Target, W: Output>(target: &mut T, out: &mut W) -> Result<(), CmdError> {
    target.record_end();
    let info = target.record_info();
    if info.rows == 0 {
        return Err(CmdError::Record(RecordError::Empty));
    }
    let head = info.head;
    let _ = out.write_str("dump rows=");
    int(out, u64::from(head.rows));
    let _ = out.write_str(" frames=");
    int(out, u64::from(head.frames()));
    let _ = out.write_str("\r\n");
    let mut buf = [0u8; MAX_FRAME_LEN];
    // The head and the chunks always fit a frame (tested): a failed encode
    // sends nothing, so the reader sees a frame missing.
    if let Ok(n) = frame::encode(&head, &mut buf) {
        out.write_bytes(buf.get(..n).unwrap_or(&[]));
    }
    for seq in 1..head.frames() {
        let mut chunk = RecordChunk {
            seq,
            ..RecordChunk::default()
        };
        target.record_rows((seq - 1) * CHUNK_ROWS as u32, &mut chunk.rows);
        if let Ok(n) = frame::encode(&chunk, &mut buf) {
            out.write_bytes(buf.get(..n).unwrap_or(&[]));
        }
    }
    Ok(())
}

fn fault<T: Target, W: Write>(target: &mut T, out: &mut W) {
    let st = target.status();
    let _ = out.write_str("faults=");
    write_faults(out, st.faults);
    let _ = out.write_str("\r\nlink good=");
    int(out, st.link.good as u64);
    let _ = out.write_str(" corrupt=");
    int(out, st.link.corrupt as u64);
    let _ = out.write_str(" lost=");
    int(out, st.link.lost as u64);
    let _ = out.write_str(" late=");
    int(out, st.link.late as u64);
    let _ = out.write_str(" skipped=");
    int(out, st.link.skipped as u64);
    let _ = out.write_str("\r\n");
}

fn param_line<W: Write>(s: &Settings, p: &settings::Param, out: &mut W) {
    let _ = out.write_str(p.name);
    let _ = out.write_str(" = ");
    num(out, p.get(s), p.kind);
    let _ = out.write_str("\r\n");
}
