//! `host-sim tune`: controller settings for a rig (docs/interfaces.md section 8).

use std::path::PathBuf;

use dca_core::controller::ControllerKind;
use host_sim::io::files;
use host_sim::model::plant::HoseModel;
use host_sim::model::sensors::SensorMode;
use host_sim::sim::config::read_plant_file;
use host_sim::sim::request::config_from_arg;
use host_sim::studies::tune::{self, keys_left_out, Robust, TuneError, TuneSetup};

use super::args::input_file;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The rig: a rig file (`gap --rig-out` writes one; a `--plant` file).
    #[arg(long, value_name = "RIG.toml")]
    plant: PathBuf,
    /// The controller tuned: cmpc-eso or mpc-eso.
    #[arg(long, default_value = "cmpc-eso")]
    controller: String,
    /// The starting settings: a preset (paper, fast, limit) or a configuration file.
    #[arg(long, default_value = "limit")]
    config: String,
    /// Where to write the tuned configuration (usable as --config everywhere).
    #[arg(long, value_name = "TUNED.toml")]
    out: PathBuf,
    /// Also write a console script (`set` lines, then `store`) for the board.
    #[arg(long, value_name = "TUNED.txt")]
    script: Option<PathBuf>,
    /// Also write a Markdown report with the before/after table and plots to DIR.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    /// The simulated rig's hose model.
    #[arg(long, default_value = "nonlinear")]
    hose: String,
    /// Sensors of the tuning runs: realistic or ideal.
    #[arg(long, default_value = "realistic")]
    sensors: String,
    /// Noise seed of the tuning runs.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Largest number of objective evaluations (each: four scenarios).
    #[arg(long, default_value_t = 60)]
    evals: u64,
    /// Robustness check: rigs drawn within +-F of the identified parameters.
    #[arg(long, value_name = "F", default_value_t = 0.1)]
    robust: f64,
    /// Robustness check: how many rigs are drawn.
    #[arg(long, value_name = "N", default_value_t = 6)]
    robust_draws: u64,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    input_file("--plant", &a.plant)?;
    if !(a.robust.is_finite() && (0.0..0.5).contains(&a.robust)) {
        anyhow::bail!(
            "--robust {}: expected a fraction in [0, 0.5), e.g. 0.1",
            a.robust
        );
    }
    if a.evals < 4 {
        anyhow::bail!("--evals {}: at least 4", a.evals);
    }
    let rig = read_plant_file(&a.plant)?;
    let kind = ControllerKind::from_name(&a.controller)
        .ok_or_else(|| anyhow::anyhow!("unknown --controller '{}'", a.controller))?;
    let mut base = config_from_arg(&a.config, kind)?;
    base.base_dt_s = dca_app::settings::BOARD_DT_S;
    let hose = HoseModel::by_name(&a.hose)
        .ok_or_else(|| anyhow::anyhow!("unknown --hose '{}'", a.hose))?;
    let sensors = SensorMode::by_name(&a.sensors)
        .ok_or_else(|| anyhow::anyhow!("unknown --sensors '{}': ideal or realistic", a.sensors))?;
    let left = keys_left_out(&rig.params);
    if !left.is_empty() {
        eprintln!(
            "note: the design model keeps these rig parameters nominal (no model.* setting on the \
             board): {}",
            left.join(", ")
        );
    }
    let setup = TuneSetup {
        rig,
        hose,
        base,
        preset: tune::preset_of(Some(&a.config))?,
        sensors,
        seed: a.seed,
        max_evals: a.evals,
        robust: Robust {
            draws: a.robust_draws,
            fraction: a.robust,
        },
        progress: true,
    };
    let source = a.plant.display().to_string();
    let t = match tune::tune(&setup, &source) {
        Ok(t) => t,
        Err(e) => {
            // A refusal's report: which candidate failed where.
            if let (TuneError::Refused { reason, candidates }, Some(dir)) = (&e, &a.report) {
                let p = tune::write_refusal(dir, reason, candidates, &source)?;
                eprintln!("the refusal's report: {}", p.display());
            }
            return Err(e.into());
        }
    };
    files::write(&a.out, &t.config_text)?;
    let mut written = vec![a.out.display().to_string()];
    if let Some(p) = &a.script {
        files::write(p, &t.script_text)?;
        written.push(p.display().to_string());
    }
    if let Some(dir) = &a.report {
        written.push(tune::write_report(dir, &t, &source)?.display().to_string());
    }
    println!("| figure | before | after |\n|---|---:|---:|");
    for (label, unit, b, after) in tune::table_rows(&t) {
        println!("| {label} | {b:.4} {unit} | {after:.4} {unit} |");
    }
    eprintln!(
        "{} settings changed, {} evaluations, {} candidates refused by the robustness check, \
         {:.1} s -> {}",
        t.changed.len(),
        t.evals,
        t.rejected(),
        t.elapsed_s,
        written.join(", ")
    );
    Ok(())
}
