//! host-sim command line: parse with clap, run one subcommand (`cli/`), print
//! its error.

use std::process::ExitCode;

use clap::Parser;

mod cli;

fn main() -> ExitCode {
    match cli::run(cli::Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // `{:#}`: the context chain, outermost first, joined by ": ".
            eprintln!("host-sim: error: {e:#}");
            ExitCode::from(2)
        }
    }
}
