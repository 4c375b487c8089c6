//! `host-sim paper`: the paper's experiments, table and report.

use std::path::PathBuf;

use host_sim::studies::paper::{run_paper, table_markdown, PaperOptions};

use super::args::preset;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Report directory.
    #[arg(long, default_value = "out/paper")]
    out: PathBuf,
    /// Preset: paper or fast.
    #[arg(long, default_value = "paper")]
    config: String,
    /// Also write every run's log into OUT/logs.
    #[arg(long)]
    logs: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let res = run_paper(&PaperOptions {
        out_dir: a.out,
        preset: preset(&a.config)?,
        write_logs: a.logs,
        progress: true,
    })?;
    println!("{}", table_markdown(&res.table));
    println!("report: {}", res.report.display());
    Ok(())
}
