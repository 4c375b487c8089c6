//! The serial console, without I/O: its receive path, the command set and
//! the telemetry stream.
//!
//! The firmware feeds received bytes to a [`Receiver`] (the line editor and the
//! queue of finished lines), hands each line to [`Console::execute`] together
//! with a [`Target`] (its view of the machine) and a writer, and sends what was
//! written. Every reply ends with a line `ok` or `error: <reason>`; lines
//! before it carry the answer. A line that is malformed, unknown, over-long or
//! refused is answered with an error and changes nothing: every check happens
//! before the first change.
//!
//! The commands are the table [`COMMANDS`]: their names, arguments, help, how
//! many arguments each takes and which handler runs it; `help`, the argument
//! checks and the `usage:` replies all come from it (after the menu of
//! quartiq/stabilizer's serial settings).
//!
//! * [`rx`]: line editing and the receive queue;
//! * [`commands`]: the command table and the handlers;
//! * [`log`]: the run-log header and rows of the telemetry stream.

use core::fmt::Write;

use crate::frame::LinkCounters;
use crate::record::{PackedRow, RecordError, RecordInfo};
use crate::settings::{Calibration, ParamKind, Settings, SettingsError};
use crate::supervisor::{Faults, Refused};
use crate::text::Buf;
use dca_core::controller::Controller;

pub mod commands;
pub mod log;
pub mod rx;

pub use commands::{Command, COMMANDS};
pub use log::{write_log_header, write_log_row, LogRow};
pub use rx::{Edit, LineEditor, LineError, Received, Receiver, ECHO_BYTES, RX_QUEUE_BYTES};

/// Longest accepted command line, characters.
pub const MAX_LINE: usize = 80;

/// Smallest telemetry decimation: at 115200 baud a run-log row (at most about
/// 100 characters) every 10 ticks of 1 ms fits the line with margin.
pub const MIN_DECIMATION: u32 = 10;
/// Largest telemetry decimation.
pub const MAX_DECIMATION: u32 = 10_000;

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
    /// Arm a record of `rows` control ticks packed with `cal` (the earlier
    /// record is dropped); `controller` is the law's index for the dump.
    fn record_arm(
        &mut self,
        rows: u32,
        cal: &Calibration,
        controller: u8,
    ) -> Result<(), RecordError>;
    /// Drop the record.
    fn record_off(&mut self);
    /// End a record being taken, keeping its rows.
    fn record_end(&mut self);
    /// Where the record stands.
    fn record_info(&mut self) -> RecordInfo;
    /// Copy recorded rows `first ..` into `out`; the number copied.
    fn record_rows(&mut self, first: u32, out: &mut [PackedRow]) -> usize;
}

/// Where the console's replies go: text, and the binary frames of `dump`
/// (written between the reply's first line and its `ok`).
pub trait Output: Write {
    /// Write raw bytes.
    fn write_bytes(&mut self, bytes: &[u8]);
}

/// Why a command failed (the text after `error: `).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CmdError {
    /// The first word is not a command.
    Unknown,
    /// Missing or extra arguments, or an argument that is not one of the
    /// command's words: the reply is the command's usage.
    Usage(&'static Command),
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
    /// The record refused.
    Record(RecordError),
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
    /// Write the reason (the text after `error: `).
    pub fn write_reason<W: Write>(&self, out: &mut W) {
        let _ = match self {
            Self::Unknown => out.write_str("unknown command (try 'help')"),
            Self::Usage(c) => c.write_usage(out),
            Self::Number(e) => out.write_str(e.as_str()),
            Self::Range(r) => out.write_str(r),
            Self::Settings(e) => out.write_str(e.as_str()),
            Self::Refused(r) => out.write_str(r.as_str()),
            Self::Line(e) => out.write_str(e.as_str()),
            Self::Store(s) => out.write_str(s),
            Self::Record(e) => out.write_str(e.as_str()),
        };
    }
}

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
    pub fn execute<T: Target, W: Output>(&mut self, line: &str, target: &mut T, out: &mut W) {
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
        e.write_reason(out);
        let _ = out.write_str("\r\n");
    }

    /// Put `s` in force (design first, then the target, then commit).
    fn commit<T: Target>(&mut self, s: Settings, target: &mut T) -> Result<(), CmdError> {
        let c = s.validate()?;
        self.apply(s, &c, target)
    }

    /// Put `s`, already designed as `c`, in force at the target, then here.
    fn apply<T: Target>(
        &mut self,
        s: Settings,
        c: &Controller,
        target: &mut T,
    ) -> Result<(), CmdError> {
        target.apply(&s, c)?;
        self.settings = s;
        Ok(())
    }
}
