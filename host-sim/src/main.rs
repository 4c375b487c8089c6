//! host-sim command line: thin wrappers around library functions.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use dca_core::controller::Preset;
use host_sim::gains::{gains, GainOverrides};

/// Simulator and tools for the miniature double-cylinder hydraulic actuator.
#[derive(Parser, Debug)]
#[command(name = "host-sim", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Print the MPC design (matrices and gains) of both MPC variants as JSON.
    Gains {
        /// Preset: paper or fast.
        #[arg(long, default_value = "paper")]
        config: String,
        /// Prediction horizon Np (both designs).
        #[arg(long)]
        np: Option<usize>,
        /// Control horizon Nc (both designs).
        #[arg(long)]
        nc: Option<usize>,
        /// MPC sample time Ts in seconds (both designs).
        #[arg(long)]
        ts: Option<f64>,
        /// Input weight r_w (both designs).
        #[arg(long)]
        rw: Option<f64>,
        /// Print JSON (the only format; accepted for the documented command line).
        #[arg(long)]
        json: bool,
        /// Pretty-print over several lines instead of one line.
        #[arg(long)]
        pretty: bool,
    },
}

fn run(cli: Cli) -> Result<(), String> {
    match cli.command {
        Command::Gains {
            config,
            np,
            nc,
            ts,
            rw,
            json: _,
            pretty,
        } => {
            let preset = Preset::from_name(&config)
                .ok_or_else(|| format!("unknown --config '{config}': expected paper or fast"))?;
            let v = gains(
                preset,
                &GainOverrides {
                    np,
                    nc,
                    ts_s: ts,
                    rw,
                },
            )?;
            let text = if pretty {
                serde_json::to_string_pretty(&v)
            } else {
                serde_json::to_string(&v)
            }
            .map_err(|e| e.to_string())?;
            println!("{text}");
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("host-sim: error: {e}");
            ExitCode::from(2)
        }
    }
}
