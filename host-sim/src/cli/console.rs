//! `host-sim console`: the board's console from this terminal.

use std::path::PathBuf;

use anyhow::Context as _;
use host_sim::hil::board::qemu::{find_qemu, firmware_elf, QemuOptions};
use host_sim::hil::board::session::{parse_script, run_session, SessionOptions, Target};

use super::args::{input_file, seconds};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Serial device of the board's console (USART1), e.g. /dev/ttyUSB0.
    #[arg(long, conflicts_with = "qemu", required_unless_present = "qemu")]
    port: Option<String>,
    /// Baud rate of the console.
    #[arg(long, default_value_t = 115_200, requires = "port")]
    baud: u32,
    /// Start the emulated firmware (QEMU netduinoplus2) instead of a board.
    #[arg(long)]
    qemu: bool,
    /// The emulated firmware's ELF (default: built with `cargo fw-qemu` if missing).
    #[arg(long, requires = "qemu")]
    elf: Option<PathBuf>,
    /// Send the lines of FILE one by one, each waiting for its reply
    /// (blank lines and `#` comments skipped; `sleep S` pauses S seconds).
    #[arg(long)]
    script: Option<PathBuf>,
    /// Write the telemetry stream (after `telemetry on`) to this run log;
    /// where the session issues `dump`, the board's record instead (1 ms).
    #[arg(long)]
    capture: Option<PathBuf>,
    /// Longest wait for a reply, s.
    #[arg(long, default_value_t = 10.0)]
    timeout: f64,
    /// A live view in the terminal of what the board streams (reference and
    /// position, pressures, force, command), the console beside it; turns the
    /// stream on (a row every 10 ms) for the session.
    #[arg(long, conflicts_with = "script")]
    scope: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let script = match &a.script {
        Some(p) => {
            input_file("--script", p)?;
            let text = std::fs::read_to_string(p).with_context(|| p.display().to_string())?;
            Some(parse_script(&text, &p.display().to_string())?)
        }
        None => None,
    };
    let target = match (a.port, a.qemu) {
        (Some(p), false) => Target::Port(p, a.baud),
        (None, true) => {
            // Before any build: a missing QEMU is said at once.
            let opts = QemuOptions::default();
            find_qemu(&opts.qemu)?;
            Target::Qemu(firmware_elf(a.elf)?, opts)
        }
        _ => anyhow::bail!("give --port DEVICE (a board) or --qemu"),
    };
    let report = run_session(&SessionOptions {
        target,
        script,
        capture: a.capture,
        timeout: seconds(a.timeout, "--timeout")?,
        scope: a.scope,
    })?;
    if let Some(p) = &report.capture_problem {
        anyhow::bail!("{p}");
    }
    if report.errors > 0 {
        anyhow::bail!("{} of {} replies were errors", report.errors, report.sent);
    }
    Ok(())
}
