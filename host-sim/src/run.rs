//! `host-sim run`: one simulated run from the command line (interfaces.md
//! section 3), resolved into a [`RunSpec`] and written as a run log.
//!
//! Precedence: a command-line option wins over the scenario file's setting,
//! which wins over the default (`paper`, `nonlinear`, `ideal`, seed 0).

use std::path::Path;

use dca_core::controller::{ControllerConfig, ControllerKind, Preset};

use crate::config::{ConfigFile, ScenarioFile};
use crate::metrics::{self, Kind, Metrics};
use crate::plant::{HoseModel, Plant, NOMINAL_DT_S};
use crate::runlog::RunLog;
use crate::scenario::{Command, Scenario, Signal};
use crate::sensors::SensorMode;
use crate::sim::{run, RunSpec, Trace};

/// What the user asked for (the command-line options of `run`).
#[derive(Clone, Debug, Default)]
pub struct RunRequest {
    /// A nominal scenario name or a TOML file.
    pub scenario: String,
    /// Controller name (else the scenario file's).
    pub controller: Option<String>,
    /// `paper`, `fast` or a TOML file (else the scenario file's, else `paper`).
    pub config: Option<String>,
    /// Hose model name.
    pub hose: Option<String>,
    /// `ideal` or `realistic`.
    pub sensors: Option<String>,
    /// Noise seed.
    pub seed: Option<u64>,
    /// Plant step, s (default 1e-4).
    pub dt_s: Option<f64>,
    /// Effects, `name` or `name:param=value,...` (added to the scenario file's).
    pub effects: Vec<String>,
}

fn is_toml(s: &str) -> bool {
    s.ends_with(".toml")
}

/// The controller configuration named by `--config` (a preset or a file).
pub fn config_from_arg(arg: &str, kind: ControllerKind) -> Result<ControllerConfig, String> {
    if is_toml(arg) {
        let f = ConfigFile::read(Path::new(arg)).map_err(|e| e.to_string())?;
        f.resolve(kind, arg).map_err(|e| e.to_string())
    } else {
        let preset = Preset::from_name(arg).ok_or_else(|| {
            format!("unknown --config '{arg}': expected paper, fast or a .toml file")
        })?;
        Ok(ControllerConfig::preset(preset, kind))
    }
}

/// Resolve a request into a run specification.
pub fn resolve(req: &RunRequest) -> Result<RunSpec, String> {
    let (scenario, file_cfg, plant_sec) = if is_toml(&req.scenario) {
        let s = ScenarioFile::load(Path::new(&req.scenario)).map_err(|e| e.to_string())?;
        (s.scenario, s.controller, s.plant)
    } else {
        let s = Scenario::by_name(&req.scenario).ok_or_else(|| {
            format!(
                "unknown --scenario '{}': expected step, sine, stepload, sineload, openloop or a .toml file",
                req.scenario
            )
        })?;
        (s, None, Default::default())
    };
    let file = req.scenario.as_str();
    let kind_name = match (&req.controller, &file_cfg) {
        (Some(k), _) => Some(k.clone()),
        (None, Some(c)) => c.controller.clone(),
        (None, None) => None,
    };
    let kind = match kind_name {
        Some(k) => ControllerKind::from_name(&k).ok_or_else(|| {
            format!("unknown controller '{k}': expected mpc-eso, mpc, pid or fuzzy-pid")
        })?,
        None if scenario.is_open_loop() => ControllerKind::MpcEso,
        None => {
            return Err("no controller: give --controller (mpc-eso, mpc, pid, fuzzy-pid)".into())
        }
    };
    let controller = match (&req.config, &file_cfg) {
        (Some(arg), _) => config_from_arg(arg, kind)?,
        (None, Some(c)) => c.resolve(kind, file).map_err(|e| e.to_string())?,
        (None, None) => ControllerConfig::preset(Preset::Paper, kind),
    };
    let hose_name = req
        .hose
        .clone()
        .or(plant_sec.hose)
        .unwrap_or_else(|| "nonlinear".into());
    let hose = HoseModel::by_name(&hose_name).ok_or_else(|| {
        format!("unknown hose '{hose_name}': expected nonlinear, linear or rigid")
    })?;
    let sensors_name = req
        .sensors
        .clone()
        .or(plant_sec.sensors)
        .unwrap_or_else(|| "ideal".into());
    let sensors = SensorMode::by_name(&sensors_name)
        .ok_or_else(|| format!("unknown sensors '{sensors_name}': expected ideal or realistic"))?;
    // plant.md section 4: the implicit GRNN hose runs at 2e-4 s.
    let default_dt = if hose_name.starts_with("grnn") {
        2.0e-4
    } else {
        NOMINAL_DT_S
    };
    let dt_s = req.dt_s.or(plant_sec.dt_s).unwrap_or(default_dt);
    let mut effects = plant_sec.effects.unwrap_or_default();
    effects
        .validate()
        .map_err(|e| format!("{}: {e}", req.scenario))?;
    for arg in &req.effects {
        effects
            .parse_arg(arg)
            .map_err(|e| format!("--effect: {e}"))?;
    }
    Ok(RunSpec {
        scenario,
        controller,
        plant: Plant::new(dca_core::params::PlantParams::NOMINAL, hose),
        effects,
        sensors,
        seed: req.seed.or(plant_sec.seed).unwrap_or(0),
        dt_s,
    })
}

/// The metadata lines a simulated run's log carries.
pub fn log_meta(spec: &RunSpec) -> Vec<(&'static str, String)> {
    let effects: Vec<String> = spec
        .effects
        .active()
        .iter()
        .map(|k| {
            let v = spec.effects.get(*k).unwrap_or_default();
            let kv: Vec<String> = k
                .params()
                .iter()
                .zip(v)
                .map(|(p, x)| format!("{}={x:e}", p.name))
                .collect();
            format!("{}:{}", k.name(), kv.join(","))
        })
        .collect();
    vec![
        (
            "effects",
            if effects.is_empty() {
                "none".into()
            } else {
                effects.join(";")
            },
        ),
        ("hose", spec.plant.hose_model().name().to_string()),
        ("sensors", spec.sensors.name().to_string()),
        ("seed", spec.seed.to_string()),
        ("dt_s", spec.dt_s.to_string()),
        ("source", format!("host-sim {}", env!("CARGO_PKG_VERSION"))),
    ]
}

/// Section 8 metrics of a trace, choosing the metric set from its scenario.
pub fn trace_metrics(trace: &Trace, scenario: &Scenario) -> Metrics {
    let points = trace.points(false);
    let constant_ref = matches!(scenario.command(), Command::Reference(Signal::Constant(_)));
    let kind = if constant_ref {
        Kind::Step
    } else {
        Kind::Tracking
    };
    let loads: &[f64] = if scenario.name() == "stepload" {
        &[4.0, 7.0]
    } else {
        &[]
    };
    metrics::compute(&points, kind, loads)
}

/// Run the request, write the log to `log`, and return the trace.
pub fn execute(req: &RunRequest, log: &Path) -> Result<(RunSpec, Trace), String> {
    let spec = resolve(req)?;
    let trace = run(&spec).map_err(|e| e.to_string())?;
    RunLog::from_trace(&trace, &log_meta(&spec))
        .write(log)
        .map_err(|e| e.to_string())?;
    Ok((spec, trace))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn req(s: &str) -> RunRequest {
        RunRequest {
            scenario: s.into(),
            controller: Some("pid".into()),
            ..RunRequest::default()
        }
    }

    #[test]
    fn defaults_and_overrides() {
        let spec = resolve(&req("step")).unwrap();
        assert_eq!(spec.controller.kind, ControllerKind::Pid);
        assert_eq!(spec.sensors, SensorMode::Ideal);
        assert_eq!(spec.dt_s, 1e-4);
        let spec = resolve(&RunRequest {
            config: Some("fast".into()),
            sensors: Some("realistic".into()),
            seed: Some(9),
            ..req("sine")
        })
        .unwrap();
        assert_eq!(spec.controller.pid.ts_s, 0.01);
        assert_eq!(spec.sensors, SensorMode::Realistic);
        assert_eq!(spec.seed, 9);
    }

    #[test]
    fn effects_from_the_command_line() {
        let spec = resolve(&RunRequest {
            effects: vec!["leakage:g_m3pspa=2e-13".into(), "friction".into()],
            ..req("stepload")
        })
        .unwrap();
        assert_eq!(spec.effects.leakage.unwrap().g_m3pspa, 2e-13);
        assert!(spec.effects.friction.is_some());
        let meta = log_meta(&spec);
        assert!(
            meta[0]
                .1
                .starts_with("leakage:g_m3pspa=2e-13,exponent=1e0;friction:"),
            "{:?}",
            meta[0]
        );
        let e = resolve(&RunRequest {
            effects: vec!["gremlins".into()],
            ..req("step")
        })
        .unwrap_err();
        assert!(e.contains("--effect") && e.contains("gremlins"), "{e}");
    }

    #[test]
    fn bad_names_are_explained() {
        for (r, what) in [
            (req("jump"), "--scenario"),
            (
                RunRequest {
                    controller: Some("lqr".into()),
                    ..req("step")
                },
                "controller",
            ),
            (
                RunRequest {
                    config: Some("slow".into()),
                    ..req("step")
                },
                "--config",
            ),
            (
                RunRequest {
                    hose: Some("steel".into()),
                    ..req("step")
                },
                "hose",
            ),
            (
                RunRequest {
                    controller: None,
                    ..req("step")
                },
                "--controller",
            ),
        ] {
            let e = resolve(&r).unwrap_err();
            assert!(e.contains(what), "{e}");
        }
    }
}
