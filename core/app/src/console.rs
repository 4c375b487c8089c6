//! The serial console: line editing, parsing and the command set, without I/O.
//!
//! The firmware feeds received bytes to [`LineEditor`], hands each complete line
//! to [`Console::execute`] together with a [`Target`] (its view of the
//! machine) and a writer, and sends what was written. Every reply ends with a
//! line `ok` or `error: <reason>`; lines before it carry the answer. A line
//! that is malformed, unknown, over-long or refused is answered with an error
//! and changes nothing: every check happens before the first change.
//!
//! Commands (one per line, words separated by spaces):
//!
//! | command | effect |
//! |---|---|
//! | `help` | list the commands |
//! | `ping [token]` | answer `pong [token]` (hosts use it to find the start of their replies) |
//! | `status` | state, faults, controller, sensors, reference, command |
//! | `arm`, `disarm` | enable the drive holding the current position / disable it |
//! | `goto <mm>` | move to a position (within the software stroke) |
//! | `sine <amplitude mm> <frequency Hz>` | `r = r0 + a (1 - cos(2 pi f t))` from the current reference |
//! | `stop` | end a motion, hold the reference where it is |
//! | `controller [mpc-eso\|mpc\|pid\|fuzzy-pid]` | show or select the law (idle only) |
//! | `preset paper\|fast` | load a preset's controller parameters (idle only) |
//! | `get [name]` | one setting, or all |
//! | `set <name> <value>` | change a setting (idle only; range-checked; re-designs) |
//! | `store`, `load`, `defaults` | settings to flash / from flash / factory values |
//! | `telemetry on [decimation]`, `telemetry off` | stream the run log |
//! | `fault` | latched faults and HIL link counters |
//! | `clear` | clear the faults (back to idle) |
//! | `hil on\|off` | sensor samples from HIL frames instead of the ADC (idle only) |
//! | `echo on\|off` | echo typed characters |

use core::fmt::Write;

use crate::frame::LinkCounters;
use crate::settings::{self, ParamKind, Settings, SettingsError};
use crate::supervisor::{Faults, Refused, State};
use crate::text::{parse_f64, parse_u32, Buf};
use dca_core::controller::{Controller, ControllerKind, Preset};

/// Longest accepted command line, characters.
pub const MAX_LINE: usize = 80;

/// Smallest telemetry decimation: at 115200 baud a run-log row (at most about
/// 100 characters) every 10 ticks of 1 ms fits the line with margin.
pub const MIN_DECIMATION: u32 = 10;
/// Largest telemetry decimation.
pub const MAX_DECIMATION: u32 = 10_000;

/// What a received byte did to the line.
#[derive(Debug, PartialEq, Eq)]
pub enum Edit<'a> {
    /// Nothing to show.
    None,
    /// Echo this printable character.
    Echo(u8),
    /// The last character was erased (echo `"\x08 \x08"`).
    Erase,
    /// A complete, non-empty line of printable ASCII.
    Line(&'a str),
    /// A complete line that cannot be a command.
    Bad(LineError),
}

/// Why a line was refused before parsing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineError {
    /// Longer than [`MAX_LINE`].
    TooLong,
    /// A control character or a non-ASCII byte.
    InvalidCharacter,
    /// Bytes of the line were lost on the way in (the receiver reported an
    /// overrun, framing or noise error).
    Overrun,
    /// The line arrived whole but the receive queue was full.
    Discarded,
}

impl LineError {
    /// A short human-readable reason.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::TooLong => "line too long",
            Self::InvalidCharacter => "invalid character in line",
            Self::Overrun => "input overrun, line discarded",
            Self::Discarded => "input queue full, line discarded",
        }
    }

    /// The code of this error in the receive queue (below 0x20: never a
    /// character of a stored line).
    const fn code(self) -> u8 {
        match self {
            Self::TooLong => 1,
            Self::InvalidCharacter => 2,
            Self::Overrun => 3,
            Self::Discarded => 4,
        }
    }

    /// The error of a queue code.
    const fn from_code(c: u8) -> Self {
        match c {
            1 => Self::TooLong,
            2 => Self::InvalidCharacter,
            4 => Self::Discarded,
            _ => Self::Overrun,
        }
    }
}

/// Collects typed bytes into lines: CR, LF or CR LF end a line, backspace and
/// DEL erase, empty lines are ignored (unless bytes were lost in them: then
/// the line end is answered with [`LineError::Overrun`], so that a lost line
/// is never met with silence).
#[derive(Clone, Debug)]
pub struct LineEditor {
    buf: heapless::Vec<u8, MAX_LINE>,
    error: Option<LineError>,
    /// `buf` holds a line already returned.
    ended: bool,
}

impl Default for LineEditor {
    fn default() -> Self {
        Self::new()
    }
}

impl LineEditor {
    /// An empty line.
    pub const fn new() -> Self {
        Self {
            buf: heapless::Vec::new(),
            error: None,
            ended: false,
        }
    }

    /// Bytes were lost: the current line is refused at its end.
    pub fn overrun(&mut self) {
        self.error = Some(LineError::Overrun);
    }

    /// Feed one received byte.
    pub fn push(&mut self, c: u8) -> Edit<'_> {
        if core::mem::take(&mut self.ended) {
            self.buf.clear();
        }
        match c {
            b'\r' | b'\n' => {
                if let Some(e) = self.error.take() {
                    self.buf.clear();
                    return Edit::Bad(e);
                }
                if self.buf.is_empty() {
                    return Edit::None;
                }
                // The line stays in the buffer while the caller reads it; the
                // next byte starts a new one.
                self.ended = true;
                // Only printable ASCII is ever stored: always valid UTF-8.
                match core::str::from_utf8(&self.buf) {
                    Ok(s) => Edit::Line(s),
                    Err(_) => Edit::Bad(LineError::InvalidCharacter),
                }
            }
            0x08 | 0x7f => {
                if self.error.is_none() && self.buf.pop().is_some() {
                    Edit::Erase
                } else {
                    Edit::None
                }
            }
            0x20..=0x7e => {
                if self.error.is_some() {
                    return Edit::None;
                }
                if self.buf.push(c).is_err() {
                    // The line is full (MAX_LINE characters).
                    self.error = Some(LineError::TooLong);
                    return Edit::None;
                }
                Edit::Echo(c)
            }
            _ => {
                if self.error.is_none() {
                    self.error = Some(LineError::InvalidCharacter);
                }
                Edit::None
            }
        }
    }
}

/// Capacity of the console's receive queue, bytes.
///
/// The console task answers one line at a time and may be busy for a while
/// (the longest reply, `get` of every setting, is about 1.7 kB: 0.15 s at
/// 115 200 baud, while the same 0.15 s can bring 1.7 kB of input). The queue
/// holds complete lines only, each as its characters and one end byte, so
/// 2 048 bytes hold any twenty lines of the longest length ([`MAX_LINE`] + 1
/// bytes each) or a 500-byte paste of short lines three times over. Beyond it,
/// lines are still answered, with [`LineError::Discarded`].
pub const RX_QUEUE_BYTES: usize = 2048;

/// Capacity of the echo queue, bytes (echo is best effort: a full queue drops
/// echoed characters, never lines).
pub const ECHO_BYTES: usize = 64;

/// What the console task takes from the [`Receiver`].
#[derive(Debug, PartialEq, Eq)]
pub enum Received<'a> {
    /// A complete, non-empty line of printable ASCII.
    Line(&'a str),
    /// A line that is refused before parsing (one error reply).
    Bad(LineError),
}

/// The console's receive path, from the byte interrupt to the console task.
///
/// The interrupt feeds every byte to [`Receiver::receive`], which runs the
/// line editor at once and queues each finished line (or the reason it was
/// refused) in a byte ring of `N` bytes: a line end is never lost, however
/// long the console task is busy. When a line does not fit, it is counted, and
/// so is every line after it until the queue has been emptied; the console
/// task then gets one [`LineError::Discarded`] per counted line, after the
/// queued ones. So every line gets exactly one reply, in order, whatever the
/// input rate.
///
/// The interrupt and the console task share the receiver through a lock
/// (RTIC resource); each call is short (at most one line copied).
#[derive(Clone, Debug)]
pub struct Receiver<const N: usize> {
    editor: LineEditor,
    /// Finished lines: their characters, then an end byte (0 for a good line,
    /// a [`LineError`] code otherwise; both below 0x20, never a character).
    lines: heapless::Deque<u8, N>,
    /// Lines that did not fit, answered after the queue has drained.
    discarded: u32,
    /// Lines discarded since start-up (statistics).
    discarded_total: u32,
    echo_on: bool,
    echo: heapless::Deque<u8, ECHO_BYTES>,
}

impl<const N: usize> Default for Receiver<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Receiver<N> {
    /// Empty, echo off.
    pub const fn new() -> Self {
        Self {
            editor: LineEditor::new(),
            lines: heapless::Deque::new(),
            discarded: 0,
            discarded_total: 0,
            echo_on: false,
            echo: heapless::Deque::new(),
        }
    }

    /// One received byte (called from the receive interrupt).
    pub fn receive(&mut self, byte: u8) {
        match self.editor.push(byte) {
            Edit::None => {}
            Edit::Echo(c) => self.echo_bytes(&[c]),
            Edit::Erase => self.echo_bytes(b"\x08 \x08"),
            Edit::Line(line) => {
                if self.echo_on {
                    push_all(&mut self.echo, b"\r\n");
                }
                enqueue(
                    &mut self.lines,
                    &mut self.discarded,
                    &mut self.discarded_total,
                    line.as_bytes(),
                    0,
                );
            }
            Edit::Bad(e) => {
                if self.echo_on {
                    push_all(&mut self.echo, b"\r\n");
                }
                enqueue(
                    &mut self.lines,
                    &mut self.discarded,
                    &mut self.discarded_total,
                    &[],
                    e.code(),
                );
            }
        }
    }

    /// The receiver lost bytes (overrun, framing or noise error): the line
    /// being typed is answered with [`LineError::Overrun`].
    pub fn lost(&mut self) {
        self.editor.overrun();
    }

    /// Echo typed characters from now on (or not).
    pub fn set_echo(&mut self, on: bool) {
        self.echo_on = on;
        if !on {
            self.echo.clear();
        }
    }

    /// Whether typed characters are echoed.
    pub fn echo(&self) -> bool {
        self.echo_on
    }

    /// The next byte to echo, if any (take them all before the next line, so
    /// that a line's echo comes before its reply).
    pub fn next_echo(&mut self) -> Option<u8> {
        self.echo.pop_front()
    }

    /// The next line, copied into `buf`: queued lines in order, then one
    /// [`LineError::Discarded`] per line that did not fit.
    pub fn next<'b>(&mut self, buf: &'b mut [u8; MAX_LINE]) -> Option<Received<'b>> {
        if self.lines.is_empty() {
            if self.discarded == 0 {
                return None;
            }
            self.discarded -= 1;
            return Some(Received::Bad(LineError::Discarded));
        }
        let mut n = 0;
        while let Some(b) = self.lines.pop_front() {
            if b < 0x20 {
                if b != 0 {
                    return Some(Received::Bad(LineError::from_code(b)));
                }
                // Stored lines are printable ASCII of at most MAX_LINE bytes.
                return Some(match buf.get(..n).map(core::str::from_utf8) {
                    Some(Ok(s)) => Received::Line(s),
                    _ => Received::Bad(LineError::InvalidCharacter),
                });
            }
            if let Some(slot) = buf.get_mut(n) {
                *slot = b;
                n += 1;
            }
        }
        // A line without its end byte cannot be queued (see `enqueue`).
        Some(Received::Bad(LineError::Overrun))
    }

    /// Bytes waiting in the line queue.
    pub fn queued_bytes(&self) -> usize {
        self.lines.len()
    }

    /// Lines answered with [`LineError::Discarded`] since start-up.
    pub fn discarded_total(&self) -> u32 {
        self.discarded_total
    }

    fn echo_bytes(&mut self, bytes: &[u8]) {
        if self.echo_on {
            push_all(&mut self.echo, bytes);
        }
    }
}

/// Push what fits of `bytes` (echo is best effort).
fn push_all<const M: usize>(q: &mut heapless::Deque<u8, M>, bytes: &[u8]) {
    for &b in bytes {
        if q.push_back(b).is_err() {
            return;
        }
    }
}

/// Queue one line (`chars`, then the end byte `end`) whole, or count it as
/// discarded. Once a line was discarded, later lines are discarded too until
/// the queue has drained, so that the replies keep the order of the lines.
fn enqueue<const N: usize>(
    q: &mut heapless::Deque<u8, N>,
    discarded: &mut u32,
    total: &mut u32,
    chars: &[u8],
    end: u8,
) {
    let fits = q.capacity() - q.len() > chars.len();
    if *discarded > 0 || !fits {
        *discarded = discarded.saturating_add(1);
        *total = total.saturating_add(1);
        return;
    }
    for &b in chars.iter().chain(core::iter::once(&end)) {
        // Cannot fail: the space was checked above.
        let _ = q.push_back(b);
    }
}

/// A snapshot of the machine for `status`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Status {
    /// Supervisor state.
    pub state: u8,
    /// Latched faults.
    pub faults: u16,
    /// Last sample: Xo, Xi (m), P1, P2 (Pa), Ft (N).
    pub sample: dca_core::controller::Sample,
    /// Reference of the last tick, m.
    pub ref_m: f32,
    /// Command of the last tick, m/s.
    pub v_cmd_mps: f32,
    /// Control ticks since boot.
    pub ticks: u64,
    /// HIL mode on.
    pub hil: bool,
    /// Telemetry decimation, 0 when off.
    pub telemetry: u32,
    /// HIL link counters.
    pub link: LinkCounters,
    /// Longest control tick seen, us (0 when not measured).
    pub max_tick_us: u32,
}

/// The machine as the console sees it (implemented by the firmware, and by a
/// model in the tests). Every method either does all of its effect or none.
pub trait Target {
    /// A snapshot for `status` and for range checks against the reference.
    fn status(&mut self) -> Status;
    /// Put new settings and their designed controller in force. Refused unless
    /// idle (or in fault).
    fn apply(&mut self, settings: &Settings, controller: &Controller) -> Result<(), Refused>;
    /// idle -> armed.
    fn arm(&mut self) -> Result<(), Refused>;
    /// -> idle.
    fn disarm(&mut self);
    /// Move to `x_m`.
    fn goto(&mut self, x_m: f32) -> Result<(), Refused>;
    /// Start a sine.
    fn sine(&mut self, amplitude_m: f32, freq_hz: f32) -> Result<(), Refused>;
    /// End a motion.
    fn stop(&mut self) -> Result<(), Refused>;
    /// Clear the faults.
    fn clear(&mut self) -> Result<(), Refused>;
    /// Write a settings image to non-volatile storage.
    fn store(&mut self, image: &[u8]) -> Result<(), &'static str>;
    /// Read the stored settings image into `buf`; false when none is readable.
    fn load(&mut self, buf: &mut [u8]) -> bool;
    /// Telemetry on with a decimation, or off (`None`).
    fn telemetry(&mut self, decimation: Option<u32>);
    /// HIL mode on or off (idle only).
    fn hil(&mut self, on: bool) -> Result<(), Refused>;
    /// Echo typed characters.
    fn echo(&mut self, on: bool);
}

/// Why a command failed (the text after `error: `).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CmdError {
    /// The first word is not a command.
    Unknown,
    /// Missing or extra arguments.
    Usage(&'static str),
    /// An argument is not a number.
    Number(crate::text::NumError),
    /// An argument is out of its range.
    Range(&'static str),
    /// A setting was refused.
    Settings(SettingsError),
    /// The supervisor refused.
    Refused(Refused),
    /// The line itself.
    Line(LineError),
    /// Storage failed.
    Store(&'static str),
}

impl From<Refused> for CmdError {
    fn from(r: Refused) -> Self {
        Self::Refused(r)
    }
}

impl From<SettingsError> for CmdError {
    fn from(e: SettingsError) -> Self {
        Self::Settings(e)
    }
}

impl CmdError {
    /// The reason.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::Unknown => "unknown command (try 'help')",
            Self::Usage(u) => u,
            Self::Number(e) => e.as_str(),
            Self::Range(r) => r,
            Self::Settings(e) => e.as_str(),
            Self::Refused(r) => r.as_str(),
            Self::Line(e) => e.as_str(),
            Self::Store(s) => s,
        }
    }
}

const HELP: &[&str] = &[
    "help | status | fault | clear | ping [token]",
    "arm | disarm | stop",
    "goto <mm>",
    "sine <amplitude mm> <frequency Hz>  (r0 + a (1 - cos 2 pi f t))",
    "controller [mpc-eso|mpc|pid|fuzzy-pid]",
    "preset paper|fast",
    "get [name] | set <name> <value>",
    "store | load | defaults",
    "telemetry on [decimation 10..10000] | telemetry off",
    "hil on|off | echo on|off",
    "(settings, controller, preset, hil: only while idle)",
];

/// The one text buffer size of the console (one copy of the formatting code).
pub type Text = Buf<128>;

/// Write a number with 9 (f64) or 7 (f32) significant digits.
fn num<W: Write>(out: &mut W, v: f64, kind: ParamKind) {
    let mut b: Text = Buf::new();
    match kind {
        ParamKind::F64 => b.push_f64(v),
        ParamKind::F32 => b.push_f32(v as f32),
        ParamKind::Int | ParamKind::Bool => b.push_i64(v as i64),
    }
    let _ = out.write_str(b.as_str());
}

fn int<W: Write>(out: &mut W, v: u64) {
    let mut b: Text = Buf::new();
    b.push_u64(v);
    let _ = out.write_str(b.as_str());
}

fn kv<W: Write>(out: &mut W, key: &str, v: f32) {
    let _ = out.write_str(key);
    let _ = out.write_str("=");
    num(out, v as f64, ParamKind::F32);
}

/// Write the names of the fault bits in `faults`, space-separated, or `none`.
pub fn write_faults<W: Write>(out: &mut W, faults: u16) {
    if faults == 0 {
        let _ = out.write_str("none");
        return;
    }
    let mut first = true;
    for (bit, name) in Faults::NAMES {
        if faults & bit != 0 {
            if !first {
                let _ = out.write_str(",");
            }
            let _ = out.write_str(name);
            first = false;
        }
    }
}

fn number(s: &str) -> Result<f64, CmdError> {
    parse_f64(s).map_err(CmdError::Number)
}

fn on_off(arg: Option<&str>, usage: &'static str) -> Result<bool, CmdError> {
    match arg {
        Some("on") => Ok(true),
        Some("off") => Ok(false),
        _ => Err(CmdError::Usage(usage)),
    }
}

/// The console: owns the settings (the machine gets copies through
/// [`Target::apply`]).
#[derive(Clone, Debug)]
pub struct Console {
    settings: Settings,
}

impl Console {
    /// A console over settings already in force.
    pub fn new(settings: Settings) -> Self {
        Self { settings }
    }

    /// The settings in force.
    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Answer one line: zero or more answer lines, then `ok` or `error: ...`,
    /// each ended by CR LF.
    pub fn execute<T: Target, W: Write>(&mut self, line: &str, target: &mut T, out: &mut W) {
        match self.run(line, target, out) {
            Ok(()) => {
                let _ = out.write_str("ok\r\n");
            }
            Err(e) => Self::error(&e, out),
        }
    }

    /// Answer a line the editor refused.
    pub fn reject<W: Write>(&self, e: LineError, out: &mut W) {
        Self::error(&CmdError::Line(e), out);
    }

    fn error<W: Write>(e: &CmdError, out: &mut W) {
        let _ = out.write_str("error: ");
        let _ = out.write_str(e.as_str());
        let _ = out.write_str("\r\n");
    }

    /// Put `s` in force (design first, then the target, then commit).
    fn commit<T: Target>(&mut self, s: Settings, target: &mut T) -> Result<(), CmdError> {
        let c = s.validate()?;
        target.apply(&s, &c)?;
        self.settings = s;
        Ok(())
    }

    fn run<T: Target, W: Write>(
        &mut self,
        line: &str,
        target: &mut T,
        out: &mut W,
    ) -> Result<(), CmdError> {
        let mut words = line.split_ascii_whitespace();
        let Some(cmd) = words.next() else {
            return Err(CmdError::Unknown);
        };
        let a1 = words.next();
        let a2 = words.next();
        let extra = words.next().is_some();
        // Arity check: (no. of required, no. of optional) arguments.
        let arity = |req: usize, opt: usize, usage: &'static str| {
            let n = a1.is_some() as usize + a2.is_some() as usize + extra as usize;
            if n < req || n > req + opt {
                Err(CmdError::Usage(usage))
            } else {
                Ok(())
            }
        };
        match cmd {
            "help" => {
                arity(0, 0, "usage: help")?;
                for h in HELP {
                    let _ = out.write_str(h);
                    let _ = out.write_str("\r\n");
                }
            }
            "ping" => {
                arity(0, 1, "usage: ping [token]")?;
                let _ = out.write_str("pong");
                if let Some(t) = a1 {
                    let _ = out.write_str(" ");
                    let _ = out.write_str(t);
                }
                let _ = out.write_str("\r\n");
            }
            "status" => {
                arity(0, 0, "usage: status")?;
                self.status(target, out);
            }
            "arm" => {
                arity(0, 0, "usage: arm")?;
                target.arm()?;
            }
            "disarm" => {
                arity(0, 0, "usage: disarm")?;
                target.disarm();
            }
            "goto" => {
                const U: &str = "usage: goto <mm>";
                arity(1, 0, U)?;
                let x_m = number(a1.ok_or(CmdError::Usage(U))?)? / 1000.0;
                let st = self.settings.limits.stroke_m;
                if !(x_m >= st[0] as f64 && x_m <= st[1] as f64) {
                    return Err(CmdError::Range("target outside the software stroke"));
                }
                target.goto(x_m as f32)?;
            }
            "sine" => {
                const U: &str = "usage: sine <amplitude mm> <frequency Hz>";
                arity(2, 0, U)?;
                let a_m = number(a1.ok_or(CmdError::Usage(U))?)? / 1000.0;
                let f_hz = number(a2.ok_or(CmdError::Usage(U))?)?;
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
                target.sine(a_m as f32, f_hz as f32)?;
            }
            "stop" => {
                arity(0, 0, "usage: stop")?;
                target.stop()?;
            }
            "controller" => {
                const U: &str = "usage: controller [mpc-eso|mpc|pid|fuzzy-pid]";
                arity(0, 1, U)?;
                match a1 {
                    None => {
                        let _ = out.write_str(self.settings.controller.kind.name());
                        let _ = out.write_str("\r\n");
                    }
                    Some(name) => {
                        let kind = ControllerKind::from_name(name).ok_or(CmdError::Usage(U))?;
                        self.commit(self.settings.with_kind(kind), target)?;
                    }
                }
            }
            "preset" => {
                const U: &str = "usage: preset paper|fast";
                arity(1, 0, U)?;
                let p = a1.and_then(Preset::from_name).ok_or(CmdError::Usage(U))?;
                self.commit(self.settings.with_preset(p), target)?;
            }
            "get" => {
                arity(0, 1, "usage: get [name]")?;
                match a1 {
                    Some(name) => {
                        let p = settings::find(name)
                            .ok_or(CmdError::Settings(SettingsError::UnknownName))?;
                        Self::param_line(&self.settings, p, out);
                    }
                    None => {
                        for p in &settings::PARAMS {
                            Self::param_line(&self.settings, p, out);
                        }
                    }
                }
            }
            "set" => {
                const U: &str = "usage: set <name> <value>";
                arity(2, 0, U)?;
                let name = a1.ok_or(CmdError::Usage(U))?;
                if settings::find(name).is_none() {
                    return Err(SettingsError::UnknownName.into());
                }
                let v = number(a2.ok_or(CmdError::Usage(U))?)?;
                let (s, c) = self.settings.with(name, v)?;
                target.apply(&s, &c)?;
                self.settings = s;
            }
            "store" => {
                arity(0, 0, "usage: store")?;
                target
                    .store(&self.settings.to_image())
                    .map_err(CmdError::Store)?;
            }
            "load" => {
                arity(0, 0, "usage: load")?;
                let mut img = [0u8; settings::IMAGE_LEN];
                if !target.load(&mut img) {
                    return Err(CmdError::Store("no stored settings"));
                }
                let (s, c) = Settings::from_image(&img)?;
                target.apply(&s, &c)?;
                self.settings = s;
            }
            "defaults" => {
                arity(0, 0, "usage: defaults")?;
                self.commit(Settings::default(), target)?;
            }
            "telemetry" => {
                const U: &str = "usage: telemetry on [decimation] | telemetry off";
                arity(1, 1, U)?;
                if on_off(a1, U)? {
                    let d = match a2 {
                        None => 100,
                        Some(s) => parse_u32(s).ok_or(CmdError::Usage(U))?,
                    };
                    if !(MIN_DECIMATION..=MAX_DECIMATION).contains(&d) {
                        return Err(CmdError::Range("decimation must be in 10..10000"));
                    }
                    target.telemetry(Some(d));
                } else if a2.is_some() {
                    return Err(CmdError::Usage(U));
                } else {
                    target.telemetry(None);
                }
            }
            "fault" => {
                arity(0, 0, "usage: fault")?;
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
            "clear" => {
                arity(0, 0, "usage: clear")?;
                target.clear()?;
            }
            "hil" => {
                const U: &str = "usage: hil on|off";
                arity(1, 0, U)?;
                target.hil(on_off(a1, U)?)?;
            }
            "echo" => {
                const U: &str = "usage: echo on|off";
                arity(1, 0, U)?;
                target.echo(on_off(a1, U)?);
            }
            _ => return Err(CmdError::Unknown),
        }
        Ok(())
    }

    fn param_line<W: Write>(s: &Settings, p: &settings::Param, out: &mut W) {
        let _ = out.write_str(p.name);
        let _ = out.write_str(" = ");
        num(out, p.get(s), p.kind);
        let _ = out.write_str("\r\n");
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

/// The run-log header the telemetry stream starts with (interfaces.md section
/// 1), for `controller`; CR LF line ends.
pub fn write_log_header<W: Write>(out: &mut W, controller: &str) {
    let _ = out.write_str("# dca-log v1\r\n# controller=");
    let _ = out.write_str(controller);
    let _ = out.write_str("\r\n# source=dca-firmware telemetry\r\n");
    let _ = out.write_str("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n,state,faults\r\n");
}

/// One telemetry row.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LogRow {
    /// Row index since the stream started.
    pub n: u32,
    /// Time between rows, ms.
    pub step_ms: u32,
    /// Reference, m.
    pub ref_m: f32,
    /// Drive command, m/s.
    pub v_cmd_mps: f32,
    /// The sample.
    pub sample: dca_core::controller::Sample,
    /// Supervisor state.
    pub state: u8,
    /// Latched faults.
    pub faults: u16,
}

/// Format one run-log row (the columns of [`write_log_header`]), CR LF ended.
/// Time is `n * step_ms` exactly, printed with 3 decimals.
pub fn write_log_row<const N: usize>(out: &mut Buf<N>, row: &LogRow) {
    let t_ms = row.n as u64 * row.step_ms as u64;
    let (s, ms) = crate::text::div_rem(t_ms, 1000);
    out.push_u64(s);
    out.push_byte(b'.');
    out.push_byte(b'0' + (ms / 100) as u8);
    out.push_byte(b'0' + (ms / 10 % 10) as u8);
    out.push_byte(b'0' + (ms % 10) as u8);
    let s = &row.sample;
    for (v, d) in [
        (row.ref_m, 7),
        (row.v_cmd_mps, 7),
        (s.xi_m, 8),
        (s.xo_m, 8),
        (s.p1_pa, 1),
        (s.p2_pa, 1),
        (s.ft_n, 2),
    ] {
        out.push_byte(b',');
        out.push_fixed(v as f64, d);
    }
    out.push_byte(b',');
    out.push_u64(row.state as u64);
    out.push_byte(b',');
    out.push_u64(row.faults as u64);
    out.push_str("\r\n");
}
