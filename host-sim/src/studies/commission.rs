//! Commissioning one rig (`sweep --commission`, docs/control.md
//! "Commissioning"): what a user does on the bench, on a simulated rig.
//!
//! 1. **Identification runs.** The rig runs the two excitations of
//!    docs/scripts/identify-fit.txt and identify-check.txt (as scenarios:
//!    the `.toml` files beside them) with the starting settings, realistic
//!    sensors, recorded at the board's 1 ms tick: a move-and-load run (steps
//!    of the position with 800 N and 300 N load steps) to fit on, and a
//!    tracking run (a 0.25 Hz cosine under a 0.4 Hz sine load) held out.
//! 2. **Diagnosis.** `gap` on the two logs writes the identified rig
//!    (`--rig-out`).
//! 3. **Tune.** `tune` on the identified rig ([`crate::studies::tune`]).
//!
//! The sweep then runs its scenario on the true rig with the tuned settings.

use std::path::{Path, PathBuf};

use dca_core::controller::{ControllerConfig, Preset};
use dca_core::params::PlantParams;

use crate::gap::diagnose::Options;
use crate::gap::validation::{check_scenario, fit_scenario};
use crate::gap::{run_gap, Outputs};
use crate::model::effects::Effects;
use crate::model::plant::{HoseModel, Plant};
use crate::model::sensors::SensorMode;
use crate::sim::config::read_plant_file;
use crate::sim::request::log_meta;
use crate::sim::{run, RunSpec};
use crate::studies::tune::{self, Robust, TuneSetup};

/// How a rig is commissioned.
#[derive(Clone, Debug)]
pub struct Commissioning {
    /// The starting settings (identification runs, tune's start).
    pub base: ControllerConfig,
    /// The preset the tuned settings are written relative to.
    pub preset: Preset,
    /// The simulated rig's hose model.
    pub hose: HoseModel,
    /// Effects of the simulated rig (unknown to the commissioning).
    pub effects: Effects,
    /// Objective evaluations of each tune.
    pub max_evals: u64,
    /// The tune's robustness check.
    pub robust: Robust,
    /// Where the identification logs, the rig file and the tuned
    /// configuration of each rig are kept (`DIR/commission-<index>/`); none:
    /// a temporary directory, removed.
    pub keep: Option<PathBuf>,
}

/// What commissioning one rig gave.
#[derive(Clone, Debug)]
pub struct Commissioned {
    /// The tuned configuration.
    pub config: ControllerConfig,
    /// The diagnosis's verdict.
    pub verdict: String,
    /// The tuned settings changed from the preset.
    pub changed: Vec<(&'static str, f64)>,
}

/// Commission the rig `rig` (drawn by the sweep's `seed`, run `index`).
pub fn commission(
    c: &Commissioning,
    rig: &PlantParams,
    seed: u64,
    index: usize,
) -> Result<Commissioned, String> {
    let (dir, temporary) = match &c.keep {
        Some(d) => (d.join(format!("commission-{index}")), false),
        None => (
            std::env::temp_dir().join(format!("dca-commission-{}-{index}", std::process::id())),
            true,
        ),
    };
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let result = steps(c, rig, seed, &dir);
    if temporary {
        std::fs::remove_dir_all(&dir).ok();
    }
    result
}

fn steps(
    c: &Commissioning,
    rig: &PlantParams,
    seed: u64,
    dir: &Path,
) -> Result<Commissioned, String> {
    let mut logs = Vec::new();
    for (name, scenario, k) in [("fit", fit_scenario(), 1), ("check", check_scenario(), 2)] {
        let spec = RunSpec {
            scenario,
            controller: c.base,
            plant: Plant::new(*rig, c.hose),
            effects: c.effects,
            sensors: SensorMode::Realistic,
            seed: seed.wrapping_mul(3).wrapping_add(k),
            dt_s: if c.hose.is_grnn() { 2.0e-4 } else { 1.0e-4 },
        };
        let trace = run(&spec).map_err(|e| format!("identification run ({name}): {e}"))?;
        let path = dir.join(format!("identify-{name}.csv"));
        trace
            .to_runlog(&log_meta(&spec))
            .write(&path)
            .map_err(|e| e.to_string())?;
        logs.push(path);
    }
    let rig_path = dir.join("rig.toml");
    let d = run_gap(
        &logs[..1],
        &logs[1..],
        Outputs {
            rig_out: Some(&rig_path),
            ..Outputs::default()
        },
        &Options::default(),
    )
    .map_err(|e| format!("diagnosis: {e}"))?;
    let identified = read_plant_file(&rig_path).map_err(|e| e.to_string())?;
    let setup = TuneSetup {
        rig: identified,
        hose: c.hose,
        base: c.base,
        preset: c.preset,
        sensors: SensorMode::Realistic,
        seed,
        max_evals: c.max_evals,
        robust: c.robust,
        progress: false,
    };
    let source = rig_path.display().to_string();
    let t = tune::tune(&setup, &source).map_err(|e| format!("tune: {e}"))?;
    std::fs::write(dir.join("tuned.toml"), &t.config_text).map_err(|e| e.to_string())?;
    Ok(Commissioned {
        config: t.config,
        verdict: d.verdict.to_string(),
        changed: t.changed,
    })
}
