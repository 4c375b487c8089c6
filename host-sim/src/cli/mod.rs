//! The command line (the binary's, not the library's): one module per
//! subcommand, each parsing its options, calling the library and printing.
//!
//! The top of the layers: may import from every layer of the library.

use clap::{Parser, Subcommand};

mod args;
mod bench;
mod console;
#[cfg(test)]
mod doc_commands;
mod gains;
mod gap;
mod gap_suite;
mod hil;
mod hose;
mod paper;
mod run;
mod sweep;
mod tune;

/// Simulator and tools for the miniature double-cylinder hydraulic actuator.
#[derive(Parser, Debug)]
#[command(name = "host-sim", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// The hose models of docs/model.md section 9: GRNN, RBF and BP side by side
    /// (the paper's Fig. 9), the GRNN with memory on the dynamic data, and the
    /// closed-loop deviation after the 800 N step with each hose.
    Hose(hose::Args),
    /// The gap diagnosis's validation suite: synthetic runs with hidden
    /// effects; prints the confusion table.
    GapSuite(gap_suite::Args),
    /// Hardware- or processor-in-the-loop: the plant here, the control tick on a
    /// board (--port) or in the emulated firmware (--qemu), in lockstep.
    Hil(hil::Args),
    /// The board's command console from this terminal (docs/interfaces.md section 5):
    /// interactive with line editing and history, or a script; the telemetry
    /// stream captured as a run log.
    Console(console::Args),
    /// Sim-to-real gap diagnosis of recorded run logs (docs/interfaces.md section 2).
    Gap(gap::Args),
    /// Benchmarks of the simulator (real-time factors, derivative cost, batch
    /// speed-up), printed as a table.
    Bench(bench::Args),
    /// Parameter sweep and/or Monte Carlo over noise seeds, on every core;
    /// one CSV row of metrics per run.
    Sweep(sweep::Args),
    /// The paper's experiments: 4 scenarios x 4 controllers, the table against
    /// the paper, and a Markdown report with figures.
    Paper(paper::Args),
    /// Simulate one scenario and write its run log (docs/interfaces.md section 3).
    Run(run::Args),
    /// Print the MPC design (matrices and gains) of both MPC variants as JSON.
    Gains(gains::Args),
    /// Controller settings for a rig (a `gap --rig-out` file): the design model
    /// set to it, the settings that matter searched, checked around it; writes
    /// a configuration file, a console script and a report.
    Tune(tune::Args),
}

/// Run the subcommand.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Hose(a) => hose::run(a),
        Command::GapSuite(a) => gap_suite::run(a),
        Command::Hil(a) => hil::run(a),
        Command::Console(a) => console::run(a),
        Command::Gap(a) => gap::run(a),
        Command::Bench(a) => {
            bench::run(a);
            Ok(())
        }
        Command::Sweep(a) => sweep::run(a),
        Command::Paper(a) => paper::run(a),
        Command::Run(a) => run::run(a),
        Command::Gains(a) => gains::run(a),
        Command::Tune(a) => tune::run(a),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `gap` takes --json and --report, either, both or neither.
    #[test]
    fn gap_outputs_are_optional() {
        for extra in [
            &[][..],
            &["--json", "r.json"][..],
            &["--report", "out/gap"][..],
            &["--json", "r.json", "--report", "out/gap"][..],
        ] {
            let argv = ["host-sim", "gap", "--fit", "a.csv", "--check", "b.csv"]
                .iter()
                .chain(extra);
            assert!(Cli::try_parse_from(argv).is_ok(), "{extra:?}");
        }
        // The runs stay required.
        assert!(Cli::try_parse_from(["host-sim", "gap", "--fit", "a.csv"]).is_err());
    }
}
