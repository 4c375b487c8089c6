//! `host-sim run`: one simulated run written as a run log.

use std::path::PathBuf;

use host_sim::sim::request::{execute, trace_metrics};

use super::args::{RunOpts, CONTROL_TICK_HELP};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// What to simulate.
    #[command(flatten)]
    what: RunOpts,
    /// Noise seed (default 0).
    #[arg(long)]
    seed: Option<u64>,
    /// Plant step in seconds (default 1e-4; 2e-4 for the GRNN hose).
    #[arg(long)]
    dt: Option<f64>,
    #[arg(long, value_name = "S", help = CONTROL_TICK_HELP)]
    control_tick: Option<f64>,
    /// Where to write the run log (CSV).
    #[arg(long)]
    log: PathBuf,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    a.what.check_files()?;
    let req = a.what.request(a.seed, a.dt, a.control_tick);
    let (spec, trace) = execute(&req, &a.log)?;
    let m = trace_metrics(&trace, &spec.scenario);
    eprintln!(
        "{} / {} / {} hose / {} sensors: {} rows -> {}",
        spec.scenario.name(),
        trace.controller,
        spec.plant.hose_model().name(),
        spec.sensors.name(),
        trace.rows.len(),
        a.log.display()
    );
    println!("{}", serde_json::to_string(&m)?);
    Ok(())
}
