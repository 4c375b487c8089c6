//! `host-sim hil`: hardware- or processor-in-the-loop runs.

use std::path::PathBuf;

use anyhow::Context as _;
use host_sim::hil::board::qemu::{find_qemu, firmware_elf, QemuOptions};
use host_sim::hil::{run_hil_qemu_with, run_hil_serial_with, run_software, SerialOptions};
use host_sim::sim::request::resolve;

use super::args::{seconds, RunOpts};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Serial device of the board's HIL link (e.g. /dev/ttyACM0).
    #[arg(long, conflicts_with = "qemu")]
    port: Option<String>,
    /// Serial device of the board's console: the run sets the board up itself.
    #[arg(long, requires = "port")]
    console: Option<String>,
    /// Longest wait for a reply on the HIL link, s.
    #[arg(long, default_value_t = 2.0)]
    timeout: f64,
    /// Set the firmware's link timeout (`hil.timeout_ms`) through the console
    /// before arming (needs --console or --qemu). Default: the board's own
    /// setting (factory 100 ms); with --qemu 60000 (its largest), since the emulated board's
    /// clock follows a host that is not real time.
    #[arg(long)]
    link_timeout_ms: Option<u32>,
    /// Start the emulated firmware (QEMU netduinoplus2) instead of a board.
    #[arg(long)]
    qemu: bool,
    /// The emulated firmware's ELF (default: built with `cargo fw-qemu` if missing).
    #[arg(long, requires = "qemu")]
    elf: Option<PathBuf>,
    /// What to simulate.
    #[command(flatten)]
    what: RunOpts,
    /// Noise seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Also run the same loop in software and check the drive commands are
    /// bit-identical.
    #[arg(long)]
    compare: bool,
    /// Where to write the run log (CSV; optional).
    #[arg(long)]
    log: Option<PathBuf>,
    /// Also have the board record every tick of the run (`record S`, then
    /// `dump`; needs --console or --qemu) and write that record here as a
    /// 1 ms run log.
    #[arg(long, value_name = "OUT.csv")]
    record: Option<PathBuf>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    a.what.check_files()?;
    // The board's tick (the default): the only one a board runs.
    let spec = resolve(&a.what.request(a.seed, None, None))?;
    let record = a.record.is_some();
    let (trace, board_record) = match (a.port, a.qemu) {
        (Some(port), false) => {
            if a.link_timeout_ms.is_some() && a.console.is_none() {
                anyhow::bail!("--link-timeout-ms needs --console (it is set there)");
            }
            if record && a.console.is_none() {
                anyhow::bail!("--record needs --console (the record is asked for there)");
            }
            let opts = SerialOptions {
                console: a.console,
                timeout: seconds(a.timeout, "--timeout")?,
                link_timeout_ms: a.link_timeout_ms,
                record,
                ..Default::default()
            };
            run_hil_serial_with(&spec, &port, &opts)?
        }
        (None, true) => {
            // Before any build: a missing QEMU is said at once.
            find_qemu(&QemuOptions::default().qemu)?;
            let elf = firmware_elf(a.elf)?;
            let q = QemuOptions::default();
            run_hil_qemu_with(&spec, &elf, &q, a.link_timeout_ms, record)?
        }
        _ => anyhow::bail!("give --port DEVICE (a board) or --qemu (the emulated firmware)"),
    };
    if let (Some(path), Some(rec)) = (&a.record, &board_record) {
        rec.write(path, &[("scenario", spec.scenario.name().to_string())])?;
        eprintln!(
            "the board's record: {} rows of 1 ms -> {}",
            rec.rows.len(),
            path.display()
        );
    }
    match &a.log {
        Some(log) => {
            let mut out = std::fs::File::create(log).with_context(|| log.display().to_string())?;
            trace
                .write_log(&mut out)
                .with_context(|| log.display().to_string())?;
            eprintln!(
                "{} control ticks in the loop -> {}",
                trace.rows.len(),
                log.display()
            );
        }
        None => eprintln!("{} control ticks in the loop", trace.rows.len()),
    }
    if a.compare {
        let sw = run_software(&spec)?;
        match trace.first_difference(&sw) {
            None => eprintln!(
                "drive commands bit-identical to the software loop ({} ticks)",
                sw.rows.len()
            ),
            Some(i) => {
                anyhow::bail!("drive commands differ from the software loop first at tick {i}")
            }
        }
    }
    Ok(())
}
