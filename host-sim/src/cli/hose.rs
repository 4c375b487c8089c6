//! `host-sim hose`: the hose-model studies and their report.

use std::path::PathBuf;

use host_sim::studies::grnn::report::{hose_report, HoseOptions};

use super::args::input_file;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Quasi-static hose data (default: the shipped sample data).
    #[arg(long)]
    quasistatic: Option<PathBuf>,
    /// Dynamic hose data (default: the shipped sample data).
    #[arg(long)]
    dynamic: Option<PathBuf>,
    /// Report directory.
    #[arg(long, default_value = "out/hose")]
    out: PathBuf,
    /// Also the leave-one-run-out comparison of the static and memory GRNNs
    /// (about 1.5 minutes).
    #[arg(long)]
    memory: bool,
    /// Also the closed-loop comparison of the hose models (MPC-ESO, stepload).
    #[arg(long)]
    closed_loop: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    for (option, p) in [("--quasistatic", &a.quasistatic), ("--dynamic", &a.dynamic)] {
        if let Some(p) = p {
            input_file(option, p)?;
        }
    }
    let opts = HoseOptions {
        quasistatic: a.quasistatic,
        dynamic: a.dynamic,
        out_dir: a.out,
        memory: a.memory,
        closed_loop: a.closed_loop,
    };
    let report = hose_report(&opts, |table| println!("{table}"))?;
    eprintln!("report: {}", report.display());
    Ok(())
}
