//! Scenario batches on every core: parameter sweeps and Monte Carlo seeds.
//!
//! A sweep is the Cartesian product of parameter values (`path=v1,v2,...`,
//! where `path` is a controller parameter of the board's settings table, as
//! in a configuration file and the console's `set`, e.g.
//! `mpc_eso.rw=10,33,100` or `eso.beta1=20,30`) and noise seeds. Every
//! combination is one run of the same scenario; the runs go to a rayon pool
//! and each yields one row of metrics.
//!
//! Monte Carlo over the rig ([`Perturb`], `sweep --perturb F`): for each seed
//! the listed plant parameters are drawn uniformly within +-F of the rig's
//! value ([`crate::model::params::draw`]), or each by its tolerance in a
//! spec (`sweep --perturb-spec FILE`, [`crate::sim::tolerance`]); the
//! controller keeps its design model, so each run tests robustness to a rig
//! that is not the model. The drawn values are `plant.<key>` columns of the
//! CSV and metadata lines of the run logs (`--logs DIR`).
//!
//! The floor of each rig ([`BatchOptions::floor`], `sweep --floor`): the
//! same drawn rig (same seed, hose and effects), ideal sensors, driven open
//! loop by [`floor_scenario`], the servo at full speed from the instant of
//! the 800 N step; the dip of Xo below its level at that instant is the
//! least 800 N deviation any controller within the servo's speed reaches
//! on that rig (docs/control.md, "The floor of the load deviation").

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use dca_core::controller::ControllerConfig;
use dca_core::params::PlantParams;

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::io::files::{self, PathError};
use crate::io::num::Num;
use crate::io::runlog::LogError;
use crate::model::params::{self, ParamKey, ParamsError, Spread};
use crate::model::plant::Plant;
use crate::model::scenario::{Command, Piecewise, Scenario, Signal};
use crate::model::sensors::SensorMode;
use crate::sim::config::{check_value, controller_param, set_param, ParamError};
use crate::sim::metrics::Metrics;
use crate::sim::request::{log_meta_with, resolve, trace_metrics, RequestError, RunRequest};
use crate::sim::tolerance::ToleranceSpec;
use crate::sim::{run, SimError};

/// Why a sweep parameter, the sweep or one of its runs failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SweepError {
    /// Not `path=v1,v2,...`.
    #[error("'{0}': expected path=v1,v2,...")]
    Syntax(String),
    /// The path is not `table.key`.
    #[error("'{0}': expected table.key, e.g. mpc_eso.rw")]
    Path(String),
    /// A value is not a finite number.
    #[error("'{path}': '{value}' is not a finite number")]
    Value {
        /// The parameter's path.
        path: String,
        /// The value as given.
        value: String,
    },
    /// The path is not a controller parameter, or a value is refused.
    #[error(transparent)]
    Param(#[from] ParamError),
    /// The base request (or a run's) does not resolve.
    #[error(transparent)]
    Request(#[from] RequestError),
    /// A run was refused or diverged.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// `--perturb` or `--perturb-keys` is wrong.
    #[error("{0}")]
    Perturb(String),
    /// A drawn rig is not physical (e.g. a fraction near 1).
    #[error("drawn rig not physical: `{}`: {}", .0.key, .0.message)]
    Draw(ParamsError),
    /// Commissioning the drawn rig failed (`--commission`).
    #[error("commissioning: {0}")]
    Commission(String),
    /// The run-log directory could not be created.
    #[error("--logs: {0}")]
    LogDir(String),
    /// A run's log could not be written.
    #[error(transparent)]
    Log(#[from] LogError),
}

/// Where the draws of a [`Perturb`] come from.
#[derive(Clone, Debug, PartialEq)]
pub enum PerturbSource {
    /// `--perturb F`: every listed key uniformly within +-F.
    Fraction(f64),
    /// `--perturb-spec FILE`: the tolerances of the spec in that file.
    Spec(String),
}

/// Monte Carlo draws of the rig's parameters: which keys, how each is drawn.
#[derive(Clone, Debug, PartialEq)]
pub struct Perturb {
    /// The parameters drawn, each with its spread.
    pub spreads: Vec<(&'static ParamKey, Spread)>,
    /// `--perturb F` or `--perturb-spec FILE`.
    pub source: PerturbSource,
}

impl Perturb {
    /// `--perturb F`: `fraction` (in [0, 1)) and the keys `k1,k2,...`
    /// (default: the physical ones, [`params::physical_keys`]), each drawn
    /// uniformly within +-`fraction`.
    pub fn new(fraction: f64, keys: Option<&str>) -> Result<Self, SweepError> {
        if !(fraction.is_finite() && (0.0..1.0).contains(&fraction)) {
            return Err(SweepError::Perturb(format!(
                "--perturb {}: expected a fraction in [0, 1), e.g. 0.1 for +-10 %",
                Num(fraction)
            )));
        }
        let keys = match keys {
            None => params::physical_keys(),
            Some(list) => params::parse_keys(list)
                .map_err(|e| SweepError::Perturb(format!("--perturb-keys: {e}")))?,
        };
        let spread = Spread::Uniform {
            half_width: fraction,
        };
        Ok(Self {
            spreads: keys.into_iter().map(|k| (k, spread)).collect(),
            source: PerturbSource::Fraction(fraction),
        })
    }

    /// `--perturb-spec FILE`: the keys of the spec, each by its tolerance.
    pub fn from_spec(spec: &ToleranceSpec) -> Self {
        Self {
            spreads: spec.tolerances.iter().map(|t| (t.key, t.spread)).collect(),
            source: PerturbSource::Spec(spec.file.clone()),
        }
    }

    /// The rig for `seed` around `base` ([`params::draw`]) and the drawn values.
    pub fn draw(
        &self,
        base: &PlantParams,
        seed: u64,
    ) -> (PlantParams, Vec<(&'static ParamKey, f64)>) {
        params::draw(base, &self.spreads, seed)
    }

    /// How the rig is drawn, for a report (Markdown): the source and every key.
    pub fn describe(&self) -> String {
        match &self.source {
            PerturbSource::Fraction(f) => {
                let keys: Vec<&str> = self.spreads.iter().map(|(k, _)| k.name).collect();
                format!(
                    "Rig drawn per seed uniformly within +-{} of its value: {}",
                    Num(*f),
                    keys.join(", ")
                )
            }
            PerturbSource::Spec(file) => {
                let keys: Vec<String> = self
                    .spreads
                    .iter()
                    .map(|(k, s)| format!("`{}` {s}", k.name))
                    .collect();
                format!(
                    "Rig drawn per seed from the tolerance spec `{file}` (normal and lognormal \
                     truncated at {} sigma): {}",
                    Num(params::TRUNCATE_SIGMAS),
                    keys.join(", ")
                )
            }
        }
    }
}

/// Commissioning of each run's rig before the run (`sweep --commission`):
/// from the rig, the seed and the run's index, the tuned configuration that
/// replaces the request's controller and the columns to report
/// (`tuned.<name>`, value), or why it failed. The sweep calls it; what it
/// does (identification runs, diagnosis, tune) lies in `studies`.
#[derive(Clone)]
#[allow(clippy::type_complexity)]
pub struct Retune(
    pub  Arc<
        dyn Fn(
                &PlantParams,
                u64,
                usize,
            ) -> Result<(ControllerConfig, Vec<(String, String)>), String>
            + Send
            + Sync,
    >,
);

impl std::fmt::Debug for Retune {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Retune(..)")
    }
}

/// What a batch does besides the metrics.
#[derive(Clone, Debug, Default)]
pub struct BatchOptions {
    /// Commission each run's rig first (`--commission`).
    pub retune: Option<Retune>,
    /// Draw the rig per seed.
    pub perturb: Option<Perturb>,
    /// Write each run's log as `DIR/run-<index>.csv`.
    pub logs: Option<PathBuf>,
    /// Show a progress bar.
    pub progress: bool,
    /// Also run each rig's floor ([`floor_scenario`]): `floor_mm` and
    /// `excess_mm` columns.
    pub floor: bool,
}

/// One swept parameter: a configuration path and its values.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepParam {
    /// Dotted path into the configuration format, e.g. `mpc_eso.rw`.
    pub path: String,
    /// Values to try.
    pub values: Vec<f64>,
}

impl SweepParam {
    /// Parse `path=v1,v2,...`.
    pub fn parse(s: &str) -> Result<Self, SweepError> {
        let (path, vals) = s
            .split_once('=')
            .ok_or_else(|| SweepError::Syntax(s.to_string()))?;
        let parts: Vec<&str> = path.split('.').collect();
        if !(2..=3).contains(&parts.len()) || parts.iter().any(|p| p.is_empty()) {
            return Err(SweepError::Path(path.to_string()));
        }
        let values = vals
            .split(',')
            .map(|v| {
                v.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| SweepError::Value {
                        path: path.to_string(),
                        value: v.to_string(),
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        // Check the path and every value now (each run applies one value),
        // against the table the configuration files and the console use.
        let p = controller_param(path)?;
        for v in &values {
            check_value(p, *v)?;
        }
        Ok(Self {
            path: p.name.to_string(),
            values,
        })
    }
}

/// One finished run of a batch.
#[derive(Clone, Debug)]
pub struct BatchRow {
    /// The run's index (its log is `run-<index>.csv`).
    pub index: usize,
    /// Parameter values of this run, in sweep order.
    pub params: Vec<(String, f64)>,
    /// The rig's drawn values, `(plant.<key>, value)` (empty without `--perturb`).
    pub plant: Vec<(&'static str, f64)>,
    /// Noise seed.
    pub seed: u64,
    /// Metrics, or why the run failed (e.g. a design refused).
    pub result: Result<Metrics, SweepError>,
    /// What commissioning set (`tuned.<name>`, value; empty without it).
    pub tuned: Vec<(String, String)>,
    /// The floor of this rig's 800 N deviation, mm ([`floor_mm`]; `None`
    /// unless asked for).
    pub floor_mm: Option<Result<f64, SweepError>>,
}

impl BatchRow {
    /// The first load window's deviation minus this rig's floor, mm (both
    /// must exist).
    pub fn excess_mm(&self) -> Option<f64> {
        let dev = self.result.as_ref().ok()?.load.first()?.deviation_mm;
        Some(dev - *self.floor_mm.as_ref()?.as_ref().ok()?)
    }
}

/// Instant of the floor run's load step, s (stepload's 800 N step).
const FLOOR_STEP_S: f64 = 4.0;
/// How long the servo runs at full speed from the step, s.
const FLOOR_PUSH_S: f64 = 0.2;
/// Where the floor run's first move starts, s.
const FLOOR_MOVE_FROM_S: f64 = 0.5;
/// Where the first move ends on the nominal rig (Xo to about 50 mm), s.
const FLOOR_MOVE_TO_S: f64 = 0.9167;
/// The load's position at the step: stepload's reference there, m.
const FLOOR_XO_M: f64 = 0.05;
/// How close the floor run brings the load to [`FLOOR_XO_M`] before the step, m.
const FLOOR_XO_TOL_M: f64 = 1e-4;
/// Floor runs at most to bring it there ([`floor_mm`]).
const FLOOR_TRIES: usize = 5;

/// docs/control.md's `floor.toml`: the servo at 0.1 m/s from 0.5 s to
/// 0.9167 s (Xo to about 50 mm on the nominal rig), then at full speed
/// (0.1 m/s, for 200 ms: well past the dip's lowest point; on draws 0, 5, 13
/// and 15 of `--perturb 0.3` 30 ms gave the same floor)
/// from the instant of the 800 N step at 4 s; 4.3 s long.
pub fn floor_scenario() -> Scenario {
    floor_scenario_moving_to(FLOOR_MOVE_TO_S)
}

/// [`floor_scenario`] with the first move ending at `move_to_s` (before the step).
fn floor_scenario_moving_to(move_to_s: f64) -> Scenario {
    let steps = |t: Vec<f64>, v: &[f64]| {
        Signal::Piecewise(Piecewise::constants(t, v).expect("valid by construction"))
    };
    Scenario::new(
        "floor",
        4.3,
        Command::OpenLoop(steps(
            vec![
                FLOOR_MOVE_FROM_S,
                move_to_s,
                FLOOR_STEP_S,
                FLOOR_STEP_S + FLOOR_PUSH_S,
            ],
            &[0.0, 0.1, 0.0, 0.1, 0.0],
        )),
        steps(vec![FLOOR_STEP_S], &[0.0, 800.0]),
    )
}

/// The floor of the 800 N deviation on the rig of `base` (or `rig`), mm:
/// the true Xo's dip below its level at the step in [`floor_scenario`],
/// ideal sensors, the base's hose, effects and plant step.
///
/// The first move is lengthened or shortened until the load stands where
/// stepload holds it at the step (50 mm within 0.1 mm; the secant through
/// the load's start and each run's position, at most five runs):
/// on a rig whose piston areas differ from the model's, the nominal move
/// takes it elsewhere (84 mm on draw 5 of `--perturb 0.3`, AP1/AA1 2.0).
/// The dip hardly depends on it (on draws 0..23 of `--perturb 0.3` the
/// floor moved by at most 0.02 mm), but the floor is then taken where the
/// deviation it bounds is.
pub fn floor_mm(
    base: &RunRequest,
    seed: u64,
    rig: Option<&dca_core::params::PlantParams>,
) -> Result<f64, SweepError> {
    floor_run(base, seed, rig).map(|(dip_mm, _)| dip_mm)
}

/// [`floor_mm`] and where the load stood at the step, m.
fn floor_run(
    base: &RunRequest,
    seed: u64,
    rig: Option<&dca_core::params::PlantParams>,
) -> Result<(f64, f64), SweepError> {
    let mut spec = resolve(&RunRequest {
        seed: Some(seed),
        ..base.clone()
    })?;
    if let Some(p) = rig {
        params::check(p).map_err(SweepError::Draw)?;
        spec.plant = Plant::new(*p, spec.plant.hose_model());
    }
    spec.sensors = SensorMode::Ideal;
    let mut move_to_s = FLOOR_MOVE_TO_S;
    let mut dip_mm = f64::NAN;
    let mut at_step = f64::NAN;
    for _ in 0..FLOOR_TRIES {
        spec.scenario = floor_scenario_moving_to(move_to_s);
        let trace = run(&spec)?;
        let start = trace.rows.first().map_or(f64::NAN, |r| r.truth.xo_m);
        let after = trace
            .rows
            .iter()
            .skip_while(|r| r.t_s < FLOOR_STEP_S - 1e-9)
            .map(|r| r.truth.xo_m);
        at_step = after.clone().next().unwrap_or(f64::NAN);
        dip_mm = (at_step - after.fold(f64::INFINITY, f64::min)) * 1e3;
        let moved = at_step - start;
        if (at_step - FLOOR_XO_M).abs() <= FLOOR_XO_TOL_M || moved.is_nan() || moved.abs() <= 1e-3 {
            break;
        }
        let next =
            FLOOR_MOVE_FROM_S + (move_to_s - FLOOR_MOVE_FROM_S) * (FLOOR_XO_M - start) / moved;
        // The servo must be at rest well before the step.
        move_to_s = next.clamp(FLOOR_MOVE_FROM_S + 0.01, FLOOR_STEP_S - 0.5);
    }
    Ok((dip_mm, at_step))
}

/// Run every combination of `params` and `seeds` on `base` (in parallel).
pub fn sweep(
    base: &RunRequest,
    params: &[SweepParam],
    seeds: &[u64],
    progress: bool,
) -> Result<Vec<BatchRow>, SweepError> {
    sweep_with(
        base,
        params,
        seeds,
        &BatchOptions {
            progress,
            ..BatchOptions::default()
        },
    )
}

/// The jobs of a sweep: every combination of the parameters' values, times
/// every seed (seeds innermost).
fn jobs(params: &[SweepParam], seeds: &[u64]) -> Vec<(Vec<(String, f64)>, u64)> {
    let mut combos: Vec<Vec<(String, f64)>> = vec![Vec::new()];
    for p in params {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                p.values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push((p.path.clone(), *v));
                    c
                })
            })
            .collect();
    }
    combos
        .into_iter()
        .flat_map(|c| seeds.iter().map(move |s| (c.clone(), *s)))
        .collect()
}

/// One run of a batch: the request with `seed`, the swept values, the rig
/// `rig` (drawn or the base's), the log if asked for.
fn one_run(
    base: &RunRequest,
    assign: &[(String, f64)],
    (seed, index): (u64, usize),
    rig: Option<&(PlantParams, Vec<&'static ParamKey>)>,
    log: Option<&Path>,
    retune: Option<&Retune>,
    tuned: &mut Vec<(String, String)>,
) -> Result<Metrics, SweepError> {
    let mut spec = resolve(&RunRequest {
        seed: Some(seed),
        ..base.clone()
    })?;
    if let Some((p, _)) = rig {
        params::check(p).map_err(SweepError::Draw)?;
        spec.plant = Plant::new(*p, spec.plant.hose_model());
    }
    if let Some(r) = retune {
        let (cfg, columns) =
            (r.0)(spec.plant.params(), seed, index).map_err(SweepError::Commission)?;
        spec.controller = ControllerConfig {
            base_dt_s: spec.controller.base_dt_s,
            ..cfg
        };
        *tuned = columns;
    }
    for (path, v) in assign {
        set_param(&mut spec.controller, path, *v)?;
    }
    let trace = run(&spec)?;
    if let Some(path) = log {
        let drawn = rig.map(|r| r.1.as_slice()).unwrap_or_default();
        trace.to_runlog(&log_meta_with(&spec, drawn)).write(path)?;
    }
    Ok(trace_metrics(&trace, &spec.scenario))
}

/// [`sweep`] with Monte Carlo draws of the rig and run logs ([`BatchOptions`]).
pub fn sweep_with(
    base: &RunRequest,
    params: &[SweepParam],
    seeds: &[u64],
    opts: &BatchOptions,
) -> Result<Vec<BatchRow>, SweepError> {
    // The base request must resolve on its own.
    let base_rig = *resolve(base)?.plant.params();
    if let Some(dir) = &opts.logs {
        files::create_dir_all(dir).map_err(|e| SweepError::LogDir(e.to_string()))?;
    }
    let jobs = jobs(params, seeds);
    let bar = if opts.progress {
        ProgressBar::new(jobs.len() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("[{elapsed_precise}] {bar:40} {pos}/{len} runs, eta {eta}")
            .expect("valid template"),
    );
    let rows = jobs
        .into_par_iter()
        .enumerate()
        .map(|(index, (assign, seed))| {
            let rig = opts.perturb.as_ref().map(|pt| pt.draw(&base_rig, seed));
            let plant = rig
                .as_ref()
                .map(|(_, d)| d.iter().map(|(k, v)| (k.column, *v)).collect())
                .unwrap_or_default();
            let rig = rig.map(|(p, d)| (p, d.into_iter().map(|(k, _)| k).collect::<Vec<_>>()));
            let log = opts
                .logs
                .as_ref()
                .map(|d| d.join(format!("run-{index}.csv")));
            let mut tuned = Vec::new();
            let result = one_run(
                base,
                &assign,
                (seed, index),
                rig.as_ref(),
                log.as_deref(),
                opts.retune.as_ref(),
                &mut tuned,
            );
            let floor_mm = opts
                .floor
                .then(|| floor_mm(base, seed, rig.as_ref().map(|r| &r.0)));
            bar.inc(1);
            BatchRow {
                index,
                params: assign,
                plant,
                seed,
                result,
                tuned,
                floor_mm,
            }
        })
        .collect();
    bar.finish_and_clear();
    Ok(rows)
}

fn opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.6}")).unwrap_or_default()
}

/// Write the batch as CSV: parameters, seed, the main metrics, error.
pub fn write_csv(rows: &[BatchRow], path: &Path) -> Result<(), PathError> {
    let mut s = String::new();
    let names: Vec<String> = rows
        .first()
        .map(|r| r.params.iter().map(|p| p.0.clone()).collect())
        .unwrap_or_default();
    let mut header = names.clone();
    header.extend(
        rows.first()
            .map(|r| r.plant.iter().map(|p| p.0.to_string()).collect::<Vec<_>>())
            .unwrap_or_default(),
    );
    // The commissioning's columns: every name any row has, in first-seen order.
    let mut tuned_names: Vec<String> = Vec::new();
    for (n, _) in rows.iter().flat_map(|r| &r.tuned) {
        if !tuned_names.contains(n) {
            tuned_names.push(n.clone());
        }
    }
    header.extend(tuned_names.iter().map(|n| format!("tuned.{n}")));
    header.extend(
        [
            "seed",
            "rise_time_s",
            "overshoot_pct",
            "sse_mm",
            "ise_mm2s",
            "load_dev_pct",
            "load_settling_s",
            "rmse_after_4_mm",
            "rmse_after_2_mm",
            "error",
        ]
        .map(String::from),
    );
    let floor = rows.first().is_some_and(|r| r.floor_mm.is_some());
    if floor {
        header.extend(["floor_mm", "excess_mm"].map(String::from));
    }
    let _ = writeln!(s, "{}", header.join(","));
    for r in rows {
        let mut f: Vec<String> = r.params.iter().map(|p| format!("{}", p.1)).collect();
        f.extend(r.plant.iter().map(|p| format!("{:e}", p.1)));
        f.extend(tuned_names.iter().map(|n| {
            r.tuned
                .iter()
                .find(|(m, _)| m == n)
                .map(|(_, v)| v.clone())
                .unwrap_or_default()
        }));
        f.push(r.seed.to_string());
        match &r.result {
            Ok(m) => {
                let l = m.load.first();
                f.extend([
                    opt(m.rise_time_s),
                    opt(m.overshoot_pct),
                    opt(m.sse_mm),
                    opt(Some(m.ise_mm2s)),
                    opt(l.map(|l| l.deviation_pct)),
                    opt(l.map(|l| l.settling_s)),
                    opt(m.rmse_after_4_mm),
                    opt(m.rmse_after_2_mm),
                    String::new(),
                ]);
            }
            Err(e) => {
                f.extend(std::iter::repeat_n(String::new(), 8));
                f.push(format!("\"{}\"", e.to_string().replace('"', "'")));
            }
        }
        if floor {
            let fl = r.floor_mm.as_ref().and_then(|f| f.as_ref().ok().copied());
            f.extend([opt(fl), opt(r.excess_mm())]);
        }
        let _ = writeln!(s, "{}", f.join(","));
    }
    files::write(path, s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_params() {
        let p = SweepParam::parse("mpc_eso.rw=10, 33,100").unwrap();
        assert_eq!(p.values, vec![10.0, 33.0, 100.0]);
        assert!(SweepParam::parse("rw=10").is_err());
        assert!(SweepParam::parse("mpc_eso.rw").is_err());
        assert!(SweepParam::parse("mpc_eso.rw=ten").is_err());
        let e = SweepParam::parse("eso.beta9=1").unwrap_err().to_string();
        assert!(e.contains("beta9"), "{e}");
        assert!(SweepParam::parse("mpc.np=6.5").is_err());
        // Found by fuzzing: only the first value was checked, so a sweep
        // started and then refused its later runs.
        let e = SweepParam::parse("mpc.nc=2,4.5").unwrap_err().to_string();
        assert!(e.contains("whole number"), "{e}");
        // The ranges are the console's: refused before any run.
        let e = SweepParam::parse("mpc.nc=2,40").unwrap_err().to_string();
        assert!(e.contains("out of range") && e.contains("1 to 8"), "{e}");
        let e = SweepParam::parse("eso.beta9=1").unwrap_err().to_string();
        assert!(e.contains("beta1"), "the keys of [eso] are listed: {e}");
        let e = SweepParam::parse("drive.invert=1").unwrap_err().to_string();
        assert!(e.contains("board"), "{e}");
        // Every controller parameter of the table is a sweep path.
        for p in dca_app::settings::PARAMS
            .iter()
            .filter(|p| p.is_controller())
        {
            let v = p.min;
            let q = SweepParam::parse(&format!("{}={v:?}", p.name)).unwrap();
            assert_eq!(q.path, p.name);
        }
    }

    #[test]
    fn sweep_runs_every_combination_and_reports_refused_designs() {
        let base = RunRequest {
            scenario: "step".into(),
            controller: Some("mpc".into()),
            ..RunRequest::default()
        };
        let params = [
            SweepParam::parse("mpc.rw=10,33").unwrap(),
            SweepParam::parse("mpc.nc=2,8").unwrap(),
        ];
        let rows = sweep(&base, &params, &[0, 1], false).unwrap();
        assert_eq!(rows.len(), 8);
        // nc = 8 is a valid setting but exceeds the preset's np = 6: the
        // design is refused, not a crash.
        for r in &rows {
            let nc = r.params[1].1;
            assert_eq!(r.result.is_ok(), nc == 2.0, "{:?}", r.params);
        }
        // A larger input weight moves more gently: a longer rise time.
        let rise = |rw: f64| {
            rows.iter()
                .find(|r| r.params[0].1 == rw && r.params[1].1 == 2.0)
                .and_then(|r| r.result.as_ref().ok()?.rise_time_s)
                .unwrap()
        };
        assert!(rise(33.0) > rise(10.0), "{} vs {}", rise(33.0), rise(10.0));
    }

    /// The floor of the nominal rig is docs/control.md's 1.09 mm; on drawn
    /// rigs it follows the draw; the CSV carries it and the excess.
    #[test]
    fn floor_per_rig_and_excess_columns() {
        let base = RunRequest {
            scenario: "stepload".into(),
            controller: Some("mpc-eso".into()),
            sensors: Some("realistic".into()),
            ..RunRequest::default()
        };
        let nominal = floor_mm(&base, 0, None).unwrap();
        assert!((nominal - 1.092).abs() < 0.005, "{nominal} mm");
        // A rig of twice the model's AP1/AA1: the nominal move would take
        // the load to about 80 mm; the floor is taken at stepload's 50 mm.
        let mut wide = PlantParams::NOMINAL;
        wide.aa1_m2 *= 0.6;
        wide.aa2_m2 *= 0.6;
        let (dip, at_step) = floor_run(&base, 0, Some(&wide)).unwrap();
        assert!(
            (at_step - FLOOR_XO_M).abs() <= FLOOR_XO_TOL_M,
            "{at_step} m"
        );
        assert!(dip > 0.3 && dip < 5.0, "{dip} mm");
        let opts = BatchOptions {
            perturb: Some(Perturb::new(0.3, None).unwrap()),
            floor: true,
            ..BatchOptions::default()
        };
        let rows = sweep_with(&base, &[], &[0, 1], &opts).unwrap();
        let floors: Vec<f64> = rows
            .iter()
            .map(|r| *r.floor_mm.as_ref().unwrap().as_ref().unwrap())
            .collect();
        assert!(floors.iter().all(|f| (0.3..5.0).contains(f)), "{floors:?}");
        assert!((floors[0] - floors[1]).abs() > 1e-3, "{floors:?}");
        for (r, f) in rows.iter().zip(&floors) {
            let dev = r.result.as_ref().unwrap().load[0].deviation_mm;
            assert_eq!(r.excess_mm(), Some(dev - f));
            assert!(dev > *f, "run {}: {dev} mm below the floor {f} mm", r.index);
        }
        let csv = std::env::temp_dir().join(format!("dca-floor-{}.csv", std::process::id()));
        write_csv(&rows, &csv).unwrap();
        let text = std::fs::read_to_string(&csv).unwrap();
        std::fs::remove_file(&csv).ok();
        assert!(text
            .lines()
            .next()
            .unwrap()
            .ends_with(",error,floor_mm,excess_mm"));
        let last = text.lines().nth(1).unwrap().rsplit(',').next().unwrap();
        assert_eq!(last, format!("{:.6}", rows[0].excess_mm().unwrap()));
    }

    /// A small Monte Carlo: 4 draws at F = 0.1 on stepload, every run
    /// finishes; the drawn values are CSV columns and metadata lines of the
    /// logs, which the run-log reader reads.
    #[test]
    fn monte_carlo_draws_rigs_and_logs_them() {
        let dir = std::env::temp_dir().join(format!("dca-mc-{}", std::process::id()));
        let base = RunRequest {
            scenario: "stepload".into(),
            controller: Some("mpc-eso".into()),
            sensors: Some("realistic".into()),
            ..RunRequest::default()
        };
        let opts = BatchOptions {
            perturb: Some(Perturb::new(0.1, None).unwrap()),
            logs: Some(dir.join("logs")),
            ..BatchOptions::default()
        };
        let rows = sweep_with(&base, &[], &[0, 1, 2, 3], &opts).unwrap();
        assert_eq!(rows.len(), 4);
        let n = params::physical_keys().len();
        for r in &rows {
            let m = r.result.as_ref().unwrap();
            let dev = m.load[0].deviation_mm;
            assert!(dev.is_finite() && dev < 10.0, "run {}: {dev} mm", r.index);
            assert_eq!(r.plant.len(), n);
            for (col, v) in &r.plant {
                let k = params::KEYS.iter().find(|k| k.column == *col).unwrap();
                let v0 = k.get(&dca_core::params::PlantParams::NOMINAL);
                assert!((v - v0).abs() <= 0.1 * v0.abs() * (1.0 + 1e-12), "{col}");
            }
            let log = crate::io::runlog::RunLog::read(
                &dir.join("logs").join(format!("run-{}.csv", r.index)),
            )
            .unwrap();
            assert_eq!(
                log.meta("plant.m_kg"),
                Some(format!("{:e}", r.plant[0].1).as_str())
            );
            assert!(log.meta("plant.p_atm_pa").is_none());
            assert_eq!(log.t_s.len(), 10_000);
        }
        assert_ne!(rows[0].plant[0].1, rows[1].plant[0].1);
        let csv = dir.join("mc.csv");
        write_csv(&rows, &csv).unwrap();
        let text = std::fs::read_to_string(&csv).unwrap();
        let header = text.lines().next().unwrap();
        assert!(header.starts_with("plant.m_kg,plant.ap1_m2,"), "{header}");
        assert!(header.contains("plant.hose.ps_pa,seed,"), "{header}");
        // Bad fractions and keys are refused before any run.
        assert!(Perturb::new(1.0, None).is_err());
        assert!(Perturb::new(f64::NAN, None).is_err());
        let e = Perturb::new(0.1, Some("m_kg,mass"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("mass") && e.contains("beta_e_pa"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    /// The shipped spec through [`Perturb`]: the same rig for the same seed,
    /// every key within its tolerance, every rig physical, the values in
    /// [`params::KEYS`] order (the CSV's `plant.<key>` columns).
    #[test]
    fn spec_draws_are_reproducible_and_within_tolerance() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/tolerances/dca-rig.toml");
        let spec = crate::sim::tolerance::read_spec(&path).unwrap();
        let pt = Perturb::from_spec(&spec);
        assert_eq!(pt.source, PerturbSource::Spec(path.display().to_string()));
        let base = PlantParams::NOMINAL;
        let order: Vec<&str> = params::physical_keys().iter().map(|k| k.name).collect();
        for seed in 0..200 {
            let (p, drawn) = pt.draw(&base, seed);
            assert_eq!((p, drawn.clone()), pt.draw(&base, seed));
            params::check(&p).unwrap();
            let names: Vec<&str> = drawn.iter().map(|(k, _)| k.name).collect();
            assert_eq!(names, order);
            for t in &spec.tolerances {
                let (lo, hi) = t.spread.bounds(t.key.get(&base));
                assert!((lo..=hi).contains(&t.key.get(&p)), "{seed}: {}", t.key.name);
            }
        }
        assert_ne!(pt.draw(&base, 0).0, pt.draw(&base, 1).0);
        // A key not in the spec is not drawn.
        let only = Perturb::from_spec(
            &crate::sim::tolerance::spec_str(
                "[hose.ps_pa]\ndist = \"uniform\"\nhalf_width = 0.5\nreason = \"r\"\n",
                "s.toml",
            )
            .unwrap(),
        );
        let (p, drawn) = only.draw(&base, 3);
        assert_eq!(drawn.len(), 1);
        assert_eq!(p.m_kg, base.m_kg);
        assert_ne!(p.hose.ps_pa, base.hose.ps_pa);
    }
}
