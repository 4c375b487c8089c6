//! `host-sim run`: one simulated run from the command line (docs/interfaces.md
//! section 3), resolved into a [`RunSpec`] and written as a run log.
//!
//! Precedence: a command-line option wins over the scenario file's setting,
//! which wins over the default (`paper`, `nonlinear`, `ideal`, seed 0).

use std::path::Path;

use dca_app::settings::BOARD_DT_S;
use dca_core::controller::{ControllerConfig, ControllerKind, Preset};

use crate::io::num::Num;
use crate::io::runlog::LogError;
use crate::model::effects::{EffectError, Effects};
use crate::model::params;
use crate::model::plant::{HoseModel, Plant, NOMINAL_DT_S};
use crate::model::scenario::{tick_time_s, Command, Scenario, Signal};
use crate::model::sensors::SensorMode;
use crate::sim::config::{read_plant_file, ConfigFile, FileError, ScenarioFile};
use crate::sim::metrics::{self, Kind, Metrics};
use crate::sim::{run, steps_per_ms, RunSpec, SimError, Trace};

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
    /// The controller's tick, s (default the board's, 1e-3; `--control-tick`).
    pub control_tick_s: Option<f64>,
    /// Effects, `name` or `name:param=value,...` (added to the scenario file's).
    pub effects: Vec<String>,
    /// A TOML file of the rig's physical parameters (`--plant`; it replaces
    /// the scenario file's `[plant.params]`; default: nominal).
    pub plant: Option<String>,
}

/// Why a request could not be resolved or run.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RequestError {
    /// A configuration or scenario file is wrong.
    #[error(transparent)]
    File(#[from] FileError),
    /// `--config` names no preset and no TOML file.
    #[error("unknown --config '{0}': expected paper, fast or a .toml file")]
    UnknownConfig(String),
    /// `--scenario` names no nominal scenario and no TOML file.
    #[error(
        "unknown --scenario '{0}': expected step, sine, stepload, sineload, openloop or a .toml file"
    )]
    UnknownScenario(String),
    /// An unknown controller name.
    #[error("unknown controller '{0}': expected mpc-eso, mpc, pid, fuzzy-pid or cmpc-eso")]
    UnknownController(String),
    /// A closed-loop scenario without a controller.
    #[error("no controller: give --controller (mpc-eso, mpc, pid, fuzzy-pid or cmpc-eso) or `controller = ...` in the configuration file")]
    NoController,
    /// An unknown hose model name.
    #[error("unknown hose '{0}': expected nonlinear, linear or rigid")]
    UnknownHose(String),
    /// An unknown sensor mode.
    #[error("unknown sensors '{0}': expected ideal or realistic")]
    UnknownSensors(String),
    /// The scenario file's effects are out of range (the file named).
    #[error("{file}: {error}")]
    FileEffects {
        /// The scenario file.
        file: String,
        /// Why.
        error: EffectError,
    },
    /// A closed-loop scenario's reference leaves the stroke that the
    /// controller clamps it to (its limits `x_min_m`, `x_max_m`).
    #[error(
        "{scenario}: the reference leaves the stroke {} to {} m (the controller's limits \
         x_min_m, x_max_m), to which the controller would clamp it: {} m at t = {} s{}; \
         give a reference within the stroke",
        Num(*min_m),
        Num(*max_m),
        Num(*first_m),
        Num(*first_t_s),
        if furthest_t_s == first_t_s {
            String::new()
        } else {
            format!(", furthest {} m at t = {} s", Num(*furthest_m), Num(*furthest_t_s))
        }
    )]
    ReferenceOutsideStroke {
        /// The scenario as given (a name or a file).
        scenario: String,
        /// The stroke's lower end, m.
        min_m: f64,
        /// The stroke's upper end, m.
        max_m: f64,
        /// The first reference outside, m.
        first_m: f64,
        /// Its time, s.
        first_t_s: f64,
        /// The reference furthest outside, m.
        furthest_m: f64,
        /// Its time, s.
        furthest_t_s: f64,
    },
    /// An `--effect` argument is wrong.
    #[error("--effect: {0}")]
    EffectArg(EffectError),
    /// The run was refused or diverged.
    #[error(transparent)]
    Sim(#[from] SimError),
    /// The run log could not be written.
    #[error(transparent)]
    Log(#[from] LogError),
}

fn is_toml(s: &str) -> bool {
    s.ends_with(".toml")
}

/// The controller configuration named by `--config` (a preset or a file).
pub fn config_from_arg(arg: &str, kind: ControllerKind) -> Result<ControllerConfig, RequestError> {
    if is_toml(arg) {
        let f = ConfigFile::read(Path::new(arg))?;
        Ok(f.resolve(kind, arg)?)
    } else {
        let preset =
            Preset::from_name(arg).ok_or_else(|| RequestError::UnknownConfig(arg.to_string()))?;
        Ok(ControllerConfig::preset(preset, kind))
    }
}

/// Resolve a request into a run specification.
pub fn resolve(req: &RunRequest) -> Result<RunSpec, RequestError> {
    let (scenario, file_cfg, plant_sec) = if is_toml(&req.scenario) {
        let s = ScenarioFile::load(Path::new(&req.scenario))?;
        (s.scenario, s.controller, s.plant)
    } else {
        let s = Scenario::by_name(&req.scenario)
            .ok_or_else(|| RequestError::UnknownScenario(req.scenario.clone()))?;
        (s, None, Default::default())
    };
    let file = req.scenario.as_str();
    // A `--config FILE.toml` is read once: its `controller` key names the
    // controller unless `--controller` does, before the scenario file's.
    let config_file = match &req.config {
        Some(arg) if is_toml(arg) => Some(ConfigFile::read(Path::new(arg))?),
        _ => None,
    };
    let kind_name = req
        .controller
        .clone()
        .or_else(|| config_file.as_ref().and_then(|c| c.controller.clone()))
        .or_else(|| file_cfg.as_ref().and_then(|c| c.controller.clone()));
    let kind = match kind_name {
        Some(k) => ControllerKind::from_name(&k).ok_or(RequestError::UnknownController(k))?,
        None if scenario.is_open_loop() => ControllerKind::MpcEso,
        None => return Err(RequestError::NoController),
    };
    let mut controller = match (&req.config, &file_cfg) {
        (Some(arg), _) => match &config_file {
            Some(f) => f.resolve(kind, arg)?,
            None => config_from_arg(arg, kind)?,
        },
        (None, Some(c)) => c.resolve(kind, file)?,
        (None, None) => ControllerConfig::preset(Preset::Paper, kind),
    };
    // The board's tick unless a study asks for another (checked by the run).
    controller.base_dt_s = req.control_tick_s.unwrap_or(BOARD_DT_S);
    // A rig file replaces the scenario's [plant.params], and its effects
    // (if it has any) the scenario's [plant.effects].
    let (rig, file_effects) = match &req.plant {
        Some(path) => {
            let r = read_plant_file(Path::new(path))?;
            let effects = (r.effects != Effects::default()).then_some(r.effects);
            (r.params, effects)
        }
        None => (plant_sec.plant_params(file)?, None),
    };
    let hose_name = req
        .hose
        .clone()
        .or(plant_sec.hose)
        .unwrap_or_else(|| "nonlinear".into());
    let hose = HoseModel::by_name(&hose_name)
        .ok_or_else(|| RequestError::UnknownHose(hose_name.clone()))?;
    let sensors_name = req
        .sensors
        .clone()
        .or(plant_sec.sensors)
        .unwrap_or_else(|| "ideal".into());
    let sensors = SensorMode::by_name(&sensors_name)
        .ok_or_else(|| RequestError::UnknownSensors(sensors_name.clone()))?;
    // docs/model.md section 4: the implicit GRNN hose runs at 2e-4 s.
    let default_dt = if hose_name.starts_with("grnn") {
        2.0e-4
    } else {
        NOMINAL_DT_S
    };
    let dt_s = req.dt_s.or(plant_sec.dt_s).unwrap_or(default_dt);
    let mut effects = file_effects.or(plant_sec.effects).unwrap_or_default();
    effects
        .validate()
        .map_err(|error| RequestError::FileEffects {
            file: req.scenario.clone(),
            error,
        })?;
    for arg in &req.effects {
        effects.parse_arg(arg).map_err(RequestError::EffectArg)?;
    }
    let spec = RunSpec {
        scenario,
        controller,
        plant: Plant::new(rig, hose),
        effects,
        sensors,
        seed: req.seed.or(plant_sec.seed).unwrap_or(0),
        dt_s,
    };
    check_reference(&spec, &req.scenario)?;
    Ok(spec)
}

/// Refuse a reference that leaves the stroke at any control tick of the
/// run (every plant step; the controller would clamp it there and flag
/// it, docs/interfaces.md section 1). A plant step the run refuses is left
/// to the run.
fn check_reference(spec: &RunSpec, scenario: &str) -> Result<(), RequestError> {
    let Command::Reference(r) = spec.scenario.command() else {
        return Ok(());
    };
    if steps_per_ms(spec.dt_s).is_err() {
        return Ok(());
    }
    let lim = spec.controller.limits;
    // As the controller compares: in f32.
    let excess = |v: f64| {
        let v = v as f32;
        if v.is_nan() {
            f32::INFINITY
        } else {
            (lim.x_min_m - v).max(v - lim.x_max_m)
        }
    };
    let mut first: Option<(f64, f64)> = None;
    let mut furthest = (0.0, 0.0, 0.0f32);
    for k in 0..spec.scenario.n_steps(spec.dt_s) {
        let t = tick_time_s(k, spec.dt_s);
        let v = r.value(t);
        let e = excess(v);
        if e > 0.0 {
            first.get_or_insert((v, t));
            if e > furthest.2 {
                furthest = (v, t, e);
            }
        }
    }
    match first {
        None => Ok(()),
        Some((first_m, first_t_s)) => Err(RequestError::ReferenceOutsideStroke {
            scenario: scenario.to_string(),
            min_m: lim.x_min_m.into(),
            max_m: lim.x_max_m.into(),
            first_m,
            first_t_s,
            furthest_m: furthest.0,
            furthest_t_s: furthest.1,
        }),
    }
}

/// The metadata lines a simulated run's log carries.
pub fn log_meta(spec: &RunSpec) -> Vec<(&'static str, String)> {
    log_meta_with(spec, &[])
}

/// The metadata lines of a run's log, with `plant.<key>=<value>` for every
/// rig parameter off its nominal value or in `drawn`, and `model.<key>=<value>`
/// for every parameter of the controller's design model off its nominal value.
pub fn log_meta_with(
    spec: &RunSpec,
    drawn: &[&'static params::ParamKey],
) -> Vec<(&'static str, String)> {
    let mut effects: Vec<String> = spec
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
    // The general families, which have no named parameters.
    if let Some(s) = &spec.effects.servo_envelope {
        let f: Vec<String> = s.force_n.iter().map(|f| format!("{f:e}")).collect();
        effects.push(format!(
            "servo_envelope:mass_eq_kg={:e},force_n=[{}]",
            s.mass_eq_kg,
            f.join(" ")
        ));
    }
    if let Some(h) = &spec.effects.hose_spectrum {
        let c: Vec<String> = h.c_m3pp.iter().map(|c| format!("{c:e}")).collect();
        effects.push(format!("hose_spectrum:c_m3pp=[{}]", c.join(" ")));
    }
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:e}"))
            .collect::<Vec<_>>()
            .join(" ")
    };
    if let Some(l) = &spec.effects.leakage_map {
        effects.push(format!(
            "leakage_map:q_m3ps=[{}],g_m3pspa={:e}",
            list(&l.q_m3ps),
            l.g_m3pspa
        ));
    }
    if let Some(f) = &spec.effects.friction_map {
        effects.push(format!(
            "friction_map:force_n=[{}],n_per_mpa={:e}",
            list(&f.force_n),
            f.n_per_mpa
        ));
    }
    if let Some(m) = &spec.effects.screw_map {
        effects.push(format!(
            "screw_map:deflection_m=[{}]",
            list(&m.deflection_m)
        ));
    }
    if let Some(g) = &spec.effects.gas_relaxation {
        effects.push(format!("gas_relaxation:weights=[{}]", list(&g.weights)));
    }
    if let Some(f) = &spec.effects.sensor_filter {
        effects.push(format!(
            "sensor_filter:channel={},weights=[{}]",
            f.channel.name(),
            list(&f.weights)
        ));
    }
    if let Some(m) = &spec.effects.sensor_map {
        effects.push(format!(
            "sensor_map:channel={},knots_si=[{}],readings_si=[{}]",
            m.channel.name(),
            list(&m.knots_si),
            list(&m.readings_si)
        ));
    }
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
    ]
    .into_iter()
    .chain(
        (!spec.scenario.is_open_loop())
            .then(|| ("control_tick_s", spec.controller.base_dt_s.to_string())),
    )
    .chain(params::columns(spec.plant.params(), drawn, false))
    .chain(params::columns(&spec.controller.plant, &[], true))
    .chain(std::iter::once((
        "source",
        format!("host-sim {}", env!("CARGO_PKG_VERSION")),
    )))
    .collect()
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
pub fn execute(req: &RunRequest, log: &Path) -> Result<(RunSpec, Trace), RequestError> {
    let spec = resolve(req)?;
    let trace = run(&spec)?;
    trace.to_runlog(&log_meta(&spec)).write(log)?;
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

    /// A configuration file's `controller` key names the controller; the
    /// command line's `--controller` wins over it.
    #[test]
    fn the_configuration_file_names_the_controller() {
        let dir = std::env::temp_dir().join(format!("dca-request-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("limit.toml");
        std::fs::write(&path, "preset = \"limit\"\ncontroller = \"cmpc-eso\"\n").unwrap();
        let config = Some(path.display().to_string());
        let spec = resolve(&RunRequest {
            scenario: "step".into(),
            config: config.clone(),
            ..RunRequest::default()
        })
        .unwrap();
        assert_eq!(spec.controller.kind, ControllerKind::CmpcEso);
        let spec = resolve(&RunRequest {
            config,
            ..req("step")
        })
        .unwrap();
        assert_eq!(spec.controller.kind, ControllerKind::Pid);
        let none = resolve(&RunRequest {
            scenario: "step".into(),
            ..RunRequest::default()
        });
        assert!(matches!(none, Err(RequestError::NoController)));
        std::fs::remove_dir_all(&dir).unwrap();
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
        .unwrap_err()
        .to_string();
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
            let e = resolve(&r).unwrap_err().to_string();
            assert!(e.contains(what), "{e}");
        }
    }

    /// `--plant FILE` sets the rig (replacing the scenario file's
    /// `[plant.params]`); the log names every parameter off nominal; without
    /// it the rig is nominal and the log has no such lines.
    #[test]
    fn plant_file_sets_the_rig() {
        let dir = std::env::temp_dir().join(format!("dca-plant-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let plant = dir.join("rig.toml");
        std::fs::write(&plant, "m_kg = 60.0\n[hose]\nps_pa = 2e6\n").unwrap();
        let spec = resolve(&req("step")).unwrap();
        assert_eq!(*spec.plant.params(), dca_core::params::PlantParams::NOMINAL);
        assert!(!log_meta(&spec).iter().any(|(k, _)| k.starts_with("plant.")));
        let spec = resolve(&RunRequest {
            plant: Some(plant.display().to_string()),
            ..req("step")
        })
        .unwrap();
        assert_eq!(spec.plant.params().m_kg, 60.0);
        assert_eq!(
            spec.controller.plant,
            dca_core::params::PlantParams::NOMINAL
        );
        let meta = log_meta(&spec);
        let plant_meta: Vec<_> = meta
            .iter()
            .filter(|(k, _)| k.starts_with("plant."))
            .collect();
        assert_eq!(
            plant_meta,
            [
                &("plant.m_kg", "6e1".to_string()),
                &("plant.hose.ps_pa", "2e6".to_string())
            ]
        );
        std::fs::write(&plant, "m_kg = 60.0\nbeta_e_pa = 0\n").unwrap();
        let e = resolve(&RunRequest {
            plant: Some(plant.display().to_string()),
            ..req("step")
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("rig.toml:2: field 'beta_e_pa'"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    /// A reference outside the stroke is refused before the run, naming
    /// the scenario file and the stroke; one that stays inside runs.
    #[test]
    fn a_reference_outside_the_stroke_is_refused() {
        let dir = std::env::temp_dir().join(format!("dca-stroke-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("minus5.toml");
        let write = |reference: &str| {
            std::fs::write(&file, format!("duration_s = 3.0\n[reference]\n{reference}")).unwrap();
        };
        let name = file.display().to_string();
        write("type = \"constant\"\nvalue = -5.0\n");
        let e = resolve(&req(&name)).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "{name}: the reference leaves the stroke -0.01 to 0.11 m (the controller's \
                 limits x_min_m, x_max_m), to which the controller would clamp it: -5 m at \
                 t = 0 s; give a reference within the stroke"
            )
        );
        // A step that leaves it later, and a sine whose peak does.
        write("type = \"steps\"\ntimes_s = [1.0, 2.0]\nvalues = [0.05, 0.2, 0.3]\n");
        let e = resolve(&req(&name)).unwrap_err().to_string();
        assert!(
            e.contains("0.2 m at t = 1 s, furthest 0.3 m at t = 2 s"),
            "{e}"
        );
        write("type = \"sine\"\nbias = 0.05\namplitude = 0.07\nfrequency_hz = 0.5\n");
        assert!(matches!(
            resolve(&req(&name)),
            Err(RequestError::ReferenceOutsideStroke { .. })
        ));
        // Inside: the stroke's ends themselves are reachable references.
        write("type = \"steps\"\ntimes_s = [1.0]\nvalues = [-0.01, 0.11]\n");
        resolve(&req(&name)).unwrap();
        // Open loop has no reference.
        std::fs::write(
            &file,
            "duration_s = 1.0\n[open_loop]\ntype = \"constant\"\nvalue = 0.01\n",
        )
        .unwrap();
        resolve(&req(&name)).unwrap();
        std::fs::remove_dir_all(&dir).ok();
    }

    /// Plant steps outside 1e-6 .. 1e-3 s are refused, not run for days.
    #[test]
    fn plant_steps_are_bounded() {
        for dt in [1e-9, 2e-3, 0.0, -1e-4, f64::NAN, 1e308] {
            let spec = resolve(&RunRequest {
                dt_s: Some(dt),
                ..req("step")
            })
            .unwrap();
            let e = run(&spec).unwrap_err().to_string();
            assert!(e.contains("must be within 1e-6 to 0.001 s"), "{dt}: {e}");
        }
        assert_eq!(steps_per_ms(1e-4).unwrap(), 10);
        assert_eq!(steps_per_ms(1e-6).unwrap(), 1000);
    }
}
