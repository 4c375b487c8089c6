//! `host-sim gains`: the MPC design as JSON.

use host_sim::studies::gains::{gains, GainOverrides};

use super::args::preset;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Preset: paper, fast or limit.
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
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let over = GainOverrides {
        np: a.np,
        nc: a.nc,
        ts_s: a.ts,
        rw: a.rw,
    };
    let v = gains(preset(&a.config)?, &over)?;
    let text = if a.pretty {
        serde_json::to_string_pretty(&v)
    } else {
        serde_json::to_string(&v)
    }?;
    println!("{text}");
    Ok(())
}
