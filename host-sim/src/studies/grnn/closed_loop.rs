//! Closed-loop comparison of the hose models (docs/model.md section 11, item 18):
//! MPC-ESO ("paper" configuration) on the `stepload` scenario with the nominal
//! (true) hose, a rigid hose, the paper's static GRNN hose and the memory GRNN
//! hose; the figure of merit is the deviation after the 800 N load step,
//! max |e| over [4, 7) s.

use std::time::Instant;

use dca_app::settings::BOARD_DT_S;
use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use dca_core::params::PlantParams;
use rayon::prelude::*;

use crate::model::plant::{HoseModel, Plant, NOMINAL_DT_S};
use crate::model::scenario::Scenario;
use crate::model::sensors::SensorMode;
use crate::sim::metrics::{self, Kind};
use crate::sim::{run, RunSpec, SimError, Trace};

/// Plant step of the GRNN hose models (docs/model.md section 4), s.
pub const GRNN_DT_S: f64 = 2e-4;

/// The plant step a hose model is run at: 2e-4 s for the GRNN hoses, the
/// nominal 1e-4 s otherwise.
pub fn dt_for(model: HoseModel) -> f64 {
    if model.is_grnn() {
        GRNN_DT_S
    } else {
        NOMINAL_DT_S
    }
}

/// One row of [`stepload_comparison`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct LoadDeviation {
    /// Hose model name (`nonlinear`, `rigid`, `grnn`, `grnn-memory`).
    pub hose: String,
    /// Plant step used, s.
    pub dt_s: f64,
    /// max |r - Xo| in [4, 7) s (after the 800 N step), mm.
    pub deviation_4_mm: f64,
    /// max |r - Xo| in [7, 10) s (after the step down to 400 N), mm.
    pub deviation_7_mm: f64,
    /// RMSE over t >= 4 s, mm.
    pub rmse_after_4_mm: f64,
}

/// The `stepload` run of MPC-ESO ("paper") on a plant at step `dt_s`, ideal sensors.
pub fn stepload_trace(plant: Plant, dt_s: f64) -> Result<Trace, SimError> {
    run(&RunSpec {
        plant,
        dt_s,
        ..stepload_defaults()
    })
}

fn stepload_defaults() -> RunSpec {
    RunSpec {
        scenario: Scenario::by_name("stepload").expect("nominal scenario"),
        controller: ControllerConfig {
            base_dt_s: BOARD_DT_S,
            ..ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso)
        },
        plant: Plant::nominal(),
        sensors: SensorMode::Ideal,
        seed: 0,
        dt_s: NOMINAL_DT_S,
        effects: Default::default(),
    }
}

/// Load deviations of a `stepload` trace (true Xo against the reference).
pub fn load_deviation(hose: &str, dt_s: f64, trace: &Trace) -> LoadDeviation {
    let pts = trace.points(true);
    let m = metrics::compute(&pts, Kind::Step, &[4.0, 7.0]);
    LoadDeviation {
        hose: hose.to_string(),
        dt_s,
        deviation_4_mm: m.load[0].deviation_mm,
        deviation_7_mm: m.load[1].deviation_mm,
        rmse_after_4_mm: m.rmse_after_4_mm.unwrap_or(f64::NAN),
    }
}

/// The hose models of the comparison, in table order.
pub const COMPARED: [HoseModel; 4] = [
    HoseModel::Nonlinear,
    HoseModel::Rigid,
    HoseModel::Grnn,
    HoseModel::GrnnMemory,
];

/// MPC-ESO ("paper") on `stepload` with each hose of [`COMPARED`] (nominal
/// parameters, ideal sensors; GRNN hoses at 2e-4 s, the others at 1e-4 s).
/// The memory GRNN hose dominates the run time (about 5 s; the others well
/// under 1 s each, release build).
pub fn stepload_comparison() -> Result<Vec<LoadDeviation>, SimError> {
    COMPARED
        .par_iter()
        .map(|&m| {
            let dt = dt_for(m);
            let tr = stepload_trace(Plant::new(PlantParams::NOMINAL, m), dt)?;
            Ok(load_deviation(m.name(), dt, &tr))
        })
        .collect()
}

/// A Markdown table of [`stepload_comparison`].
pub fn comparison_table(rows: &[LoadDeviation]) -> String {
    let mut s = String::from(
        "| hose model | dt [s] | max abs e, 4-7 s [mm] | max abs e, 7-10 s [mm] | RMSE t >= 4 s [mm] |\n|---|---|---|---|---|\n",
    );
    for r in rows {
        s += &format!(
            "| {} | {:.0e} | {:.3} | {:.3} | {:.3} |\n",
            r.hose, r.dt_s, r.deviation_4_mm, r.deviation_7_mm, r.rmse_after_4_mm
        );
    }
    s
}

/// Real-time factor (simulated seconds per wall-clock second) of one run of
/// `scenario` (open loop, or closed loop with MPC-ESO "paper") on `plant` at
/// step `dt_s`. Wall-clock dependent: for reports, not for assertions.
pub fn real_time_factor(plant: Plant, scenario: &str, dt_s: f64) -> Result<f64, SimError> {
    let sc = Scenario::by_name(scenario)
        .ok_or_else(|| SimError::Config(format!("no scenario {scenario}")))?;
    let duration = sc.duration_s();
    let spec = RunSpec {
        scenario: sc,
        plant,
        dt_s,
        ..stepload_defaults()
    };
    let t = Instant::now();
    run(&spec)?;
    Ok(duration / t.elapsed().as_secs_f64())
}
