//! `host-sim gap`: the sim-to-real gap diagnosis of recorded run logs.

use std::path::PathBuf;

use host_sim::gap::diagnose::Options;
use host_sim::gap::run_gap;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A run log used to localise the gap and fit the candidate effects (repeatable).
    #[arg(long = "fit", required = true)]
    fit: Vec<PathBuf>,
    /// A held-out run log, only used to evaluate what was fitted (repeatable).
    #[arg(long = "check", required = true)]
    check: Vec<PathBuf>,
    /// Where to write the JSON report.
    #[arg(long)]
    json: PathBuf,
    /// Directory for the Markdown report with plots.
    #[arg(long)]
    report: Option<PathBuf>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let opts = Options {
        progress: true,
        ..Default::default()
    };
    let d = run_gap(&a.fit, &a.check, &a.json, a.report.as_deref(), &opts)?;
    eprintln!(
        "verdict: {} (fit {:.2} -> {:.2}, check {:.2} -> {:.2}, {:.1} s) -> {}",
        d.verdict,
        d.fit.before,
        d.fit.after,
        d.check.before,
        d.check.after,
        d.elapsed_s,
        a.json.display()
    );
    Ok(())
}
