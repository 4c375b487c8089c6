//! `host-sim paper`: the paper's experiments, table and report.

use std::path::PathBuf;

use dca_core::params::PlantParams;
use host_sim::sim::config::read_plant_file;
use host_sim::studies::paper::{run_paper, table_markdown, PaperOptions};

use super::args::{input_file, preset};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Report directory.
    #[arg(long, default_value = "out/paper")]
    out: PathBuf,
    /// Preset: paper, fast or limit.
    #[arg(long, default_value = "paper")]
    config: String,
    /// Also write every run's log into OUT/logs.
    #[arg(long)]
    logs: bool,
    /// The rig's physical parameters: a TOML file of PlantParams keys (and
    /// [hose]); the controllers keep their nominal design model.
    #[arg(long, value_name = "FILE.toml")]
    plant: Option<PathBuf>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let res = run_paper(&PaperOptions {
        out_dir: a.out,
        preset: preset(&a.config)?,
        write_logs: a.logs,
        progress: true,
        rig: match &a.plant {
            Some(p) => {
                input_file("--plant", p)?;
                let rig = read_plant_file(p)?;
                if !rig.effects.active().is_empty() {
                    anyhow::bail!(
                        "--plant {}: `paper` runs a rig's parameters, not its effects ({}); \
                         run the scenarios with `host-sim run --plant` instead",
                        p.display(),
                        rig.effects
                            .active()
                            .iter()
                            .map(|k| k.name())
                            .collect::<Vec<_>>()
                            .join(", ")
                    );
                }
                rig.params
            }
            None => PlantParams::NOMINAL,
        },
    })?;
    println!("{}", table_markdown(&res.table));
    println!("report: {}", res.report.display());
    Ok(())
}
