//! TOML files: controller configurations and custom scenarios.
//!
//! A controller configuration starts from a preset and overrides any
//! parameter (unknown keys are errors, so a typo never passes silently):
//!
//! ```toml
//! preset = "paper"          # or "fast"
//! controller = "mpc-eso"    # optional: mpc-eso | mpc | pid | fuzzy-pid
//! [mpc_eso]                 # also [mpc]
//! np = 8
//! nc = 3
//! ts_s = 0.1
//! rw = 33.0
//! [eso]
//! beta1 = 30.0              # beta2, beta3, b0, h_s, alpha1, alpha2, delta_m
//! [td]
//! r_mps2 = 8.0              # h0_s
//! [pid]
//! kp = 2.7                  # ki, kd, ts_s
//! [fuzzy]
//! e_span_m = 0.02           # ec_span_mps, dkp_max, dki_max, dkd_max, kp, ki, kd, ts_s
//! [limits]
//! v_max_mps = 0.1           # x_min_m, x_max_m
//! ```
//!
//! A scenario file gives the duration, the reference (or an open-loop speed
//! command) and the load as signals, and optionally the controller, the plant
//! and the sensors:
//!
//! ```toml
//! name = "two-steps"
//! duration_s = 8.0
//! [reference]                       # or [open_loop] (v_cmd, m/s)
//! type = "steps"                    # constant | steps | sine | cosine | ramp | piecewise
//! times_s = [4.0]
//! values = [0.03, 0.06]
//! [load]
//! type = "sine"
//! bias = 400.0
//! amplitude = 200.0
//! frequency_hz = 0.5
//! [controller]                      # the configuration format above
//! controller = "mpc-eso"
//! preset = "fast"
//! [plant]
//! hose = "nonlinear"                # linear | rigid | ...
//! sensors = "realistic"
//! seed = 3
//! [plant.effects.leakage]           # any effect of plant.md section 12
//! g_m3pspa = 1e-13
//! ```
//!
//! Errors name the file, the line and the field.

use std::path::Path;

use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use dca_core::design::MpcParams;
use serde::Deserialize;
use toml::Spanned;

use crate::scenario::{Command, Piecewise, Scenario, Signal};

/// An error in a TOML file: file, line, field, message.
#[derive(Clone, Debug, PartialEq)]
pub struct FileError {
    /// The file.
    pub file: String,
    /// 1-based line, when known.
    pub line: Option<usize>,
    /// The field (dotted path), when known.
    pub field: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for FileError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        if let Some(k) = &self.field {
            write!(f, ": field '{k}'")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for FileError {}

fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

/// Parse TOML into `T`, mapping parse and type errors to file and line.
fn parse<T: for<'de> Deserialize<'de>>(text: &str, file: &str) -> Result<T, FileError> {
    toml::from_str(text).map_err(|e: toml::de::Error| {
        let line = e.span().map(|s| line_of(text, s.start));
        // The message names the key for unknown or mistyped fields. The
        // parser gives no message when the text ends where a value is due.
        let message = match e.message().trim() {
            "" if e.span().is_some_and(|s| s.start >= text.trim_end().len()) => {
                "unexpected end of file: a value is missing".to_string()
            }
            "" => "invalid TOML".to_string(),
            m => m.to_string(),
        };
        let field = message
            .split('`')
            .nth(1)
            .filter(|_| message.starts_with("unknown field"))
            .map(str::to_string);
        FileError {
            file: file.to_string(),
            line,
            field,
            message,
        }
    })
}

fn read(path: &Path) -> Result<String, FileError> {
    std::fs::read_to_string(path).map_err(|e| FileError {
        file: path.display().to_string(),
        line: None,
        field: None,
        message: e.to_string(),
    })
}

/// Overrides of one MPC design.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MpcOverrides {
    /// Prediction horizon.
    pub np: Option<usize>,
    /// Control horizon.
    pub nc: Option<usize>,
    /// Sample time, s.
    pub ts_s: Option<f64>,
    /// Input weight.
    pub rw: Option<f64>,
}

impl MpcOverrides {
    fn apply(&self, p: &mut MpcParams) {
        set(&mut p.np, self.np);
        set(&mut p.nc, self.nc);
        set(&mut p.ts_s, self.ts_s);
        set(&mut p.rw, self.rw);
    }
}

fn set<T>(dst: &mut T, v: Option<T>) {
    if let Some(v) = v {
        *dst = v;
    }
}

/// Overrides of the ESO.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct EsoOverrides {
    pub beta1: Option<f64>,
    pub beta2: Option<f64>,
    pub beta3: Option<f64>,
    pub b0: Option<f64>,
    pub h_s: Option<f64>,
    pub alpha1: Option<f64>,
    pub alpha2: Option<f64>,
    pub delta_m: Option<f64>,
}

/// Overrides of the tracking differentiator.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct TdOverrides {
    pub r_mps2: Option<f32>,
    pub h0_s: Option<f32>,
}

/// Overrides of the PID.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct PidOverrides {
    pub kp: Option<f32>,
    pub ki: Option<f32>,
    pub kd: Option<f32>,
    pub ts_s: Option<f32>,
}

/// Overrides of the fuzzy PID.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct FuzzyOverrides {
    pub kp: Option<f32>,
    pub ki: Option<f32>,
    pub kd: Option<f32>,
    pub ts_s: Option<f32>,
    pub e_span_m: Option<f32>,
    pub ec_span_mps: Option<f32>,
    pub dkp_max: Option<f32>,
    pub dki_max: Option<f32>,
    pub dkd_max: Option<f32>,
}

/// Overrides of the limits.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
#[allow(missing_docs)]
pub struct LimitsOverrides {
    pub v_max_mps: Option<f32>,
    pub x_min_m: Option<f32>,
    pub x_max_m: Option<f32>,
}

/// A controller configuration file (or the `[controller]` table of a scenario).
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ConfigFile {
    /// Base preset: `paper` (default) or `fast`.
    pub preset: Option<String>,
    /// Controller kind.
    pub controller: Option<String>,
    /// Plain MPC.
    pub mpc: Option<MpcOverrides>,
    /// MPC-ESO.
    pub mpc_eso: Option<MpcOverrides>,
    /// ESO.
    pub eso: Option<EsoOverrides>,
    /// TD.
    pub td: Option<TdOverrides>,
    /// PID.
    pub pid: Option<PidOverrides>,
    /// Fuzzy PID.
    pub fuzzy: Option<FuzzyOverrides>,
    /// Limits.
    pub limits: Option<LimitsOverrides>,
}

impl ConfigFile {
    /// Read a configuration file.
    pub fn read(path: &Path) -> Result<Self, FileError> {
        Self::parse_str(&read(path)?, &path.display().to_string())
    }

    /// Parse configuration text; `file` names it in errors.
    pub fn parse_str(text: &str, file: &str) -> Result<Self, FileError> {
        parse(text, file)
    }

    /// The preset named in the file (default `paper`).
    pub fn preset(&self, file: &str) -> Result<Preset, FileError> {
        match &self.preset {
            None => Ok(Preset::Paper),
            Some(p) => Preset::from_name(p).ok_or_else(|| FileError {
                file: file.to_string(),
                line: None,
                field: Some("preset".into()),
                message: format!("unknown preset '{p}' (paper or fast)"),
            }),
        }
    }

    /// The controller kind named in the file, if any.
    pub fn kind(&self, file: &str) -> Result<Option<ControllerKind>, FileError> {
        match &self.controller {
            None => Ok(None),
            Some(k) => ControllerKind::from_name(k)
                .map(Some)
                .ok_or_else(|| FileError {
                    file: file.to_string(),
                    line: None,
                    field: Some("controller".into()),
                    message: format!("unknown controller '{k}' (mpc-eso, mpc, pid or fuzzy-pid)"),
                }),
        }
    }

    /// Apply the overrides to `cfg`. The TD steps with the ESO, so `eso.h_s`
    /// also sets the TD's step.
    pub fn apply(&self, cfg: &mut ControllerConfig) {
        if let Some(m) = &self.mpc {
            m.apply(&mut cfg.mpc);
        }
        if let Some(m) = &self.mpc_eso {
            m.apply(&mut cfg.mpc_eso);
        }
        if let Some(e) = &self.eso {
            let p = &mut cfg.eso;
            set(&mut p.beta1, e.beta1);
            set(&mut p.beta2, e.beta2);
            set(&mut p.beta3, e.beta3);
            set(&mut p.b0, e.b0);
            set(&mut p.h_s, e.h_s);
            set(&mut p.alpha1, e.alpha1);
            set(&mut p.alpha2, e.alpha2);
            set(&mut p.delta_m, e.delta_m);
            cfg.td.h_s = cfg.eso.h_s as f32;
        }
        if let Some(t) = &self.td {
            set(&mut cfg.td.r_mps2, t.r_mps2);
            set(&mut cfg.td.h0_s, t.h0_s);
        }
        if let Some(p) = &self.pid {
            set(&mut cfg.pid.kp, p.kp);
            set(&mut cfg.pid.ki, p.ki);
            set(&mut cfg.pid.kd, p.kd);
            set(&mut cfg.pid.ts_s, p.ts_s);
        }
        if let Some(f) = &self.fuzzy {
            let q = &mut cfg.fuzzy;
            set(&mut q.base.kp, f.kp);
            set(&mut q.base.ki, f.ki);
            set(&mut q.base.kd, f.kd);
            set(&mut q.base.ts_s, f.ts_s);
            set(&mut q.e_span_m, f.e_span_m);
            set(&mut q.ec_span_mps, f.ec_span_mps);
            set(&mut q.dkp_max, f.dkp_max);
            set(&mut q.dki_max, f.dki_max);
            set(&mut q.dkd_max, f.dkd_max);
        }
        if let Some(l) = &self.limits {
            set(&mut cfg.limits.v_max_mps, l.v_max_mps);
            set(&mut cfg.limits.x_min_m, l.x_min_m);
            set(&mut cfg.limits.x_max_m, l.x_max_m);
        }
    }

    /// The full configuration for `kind`: the file's preset with its overrides.
    pub fn resolve(&self, kind: ControllerKind, file: &str) -> Result<ControllerConfig, FileError> {
        let mut cfg = ControllerConfig::preset(self.preset(file)?, kind);
        self.apply(&mut cfg);
        Ok(cfg)
    }
}

/// A signal in a scenario file.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SignalSpec {
    /// A constant.
    Constant {
        /// The value.
        value: f64,
    },
    /// Piecewise constant: `values[i]` before `times_s[i]`, the last value after.
    Steps {
        /// Switching instants, s, strictly increasing.
        times_s: Vec<f64>,
        /// One more value than instants.
        values: Vec<f64>,
    },
    /// `bias + amplitude sin(2 pi f (t - t0))`.
    Sine {
        /// Offset.
        #[serde(default)]
        bias: f64,
        /// Amplitude.
        amplitude: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase origin, s.
        #[serde(default)]
        t0_s: f64,
    },
    /// `bias + amplitude cos(2 pi f (t - t0))`.
    Cosine {
        /// Offset.
        #[serde(default)]
        bias: f64,
        /// Amplitude.
        amplitude: f64,
        /// Frequency, Hz.
        frequency_hz: f64,
        /// Phase origin, s.
        #[serde(default)]
        t0_s: f64,
    },
    /// `start + slope (t - t0)`.
    Ramp {
        /// Value at t0.
        start: f64,
        /// Slope per second.
        slope_per_s: f64,
        /// Time origin, s.
        #[serde(default)]
        t0_s: f64,
    },
    /// Switching between signals: `pieces[i]` before `thresholds_s[i]`.
    Piecewise {
        /// Switching instants, s, strictly increasing.
        thresholds_s: Vec<f64>,
        /// One more piece than thresholds.
        pieces: Vec<SignalSpec>,
    },
}

impl SignalSpec {
    /// Build the signal; `Err` carries a message for the caller to locate.
    pub fn build(&self) -> Result<Signal, String> {
        let finite = |name: &str, v: f64| {
            if v.is_finite() {
                Ok(v)
            } else {
                Err(format!("{name} must be finite"))
            }
        };
        Ok(match self {
            Self::Constant { value } => Signal::Constant(finite("value", *value)?),
            Self::Steps { times_s, values } => Signal::Piecewise(
                Piecewise::constants(times_s.clone(), values).map_err(|e| e.to_string())?,
            ),
            Self::Sine {
                bias,
                amplitude,
                frequency_hz,
                t0_s,
            }
            | Self::Cosine {
                bias,
                amplitude,
                frequency_hz,
                t0_s,
            } => {
                let (bias, amplitude, t0_s) = (
                    finite("bias", *bias)?,
                    finite("amplitude", *amplitude)?,
                    finite("t0_s", *t0_s)?,
                );
                let omega_radps =
                    2.0 * std::f64::consts::PI * finite("frequency_hz", *frequency_hz)?;
                if matches!(self, Self::Sine { .. }) {
                    Signal::Sine {
                        bias,
                        amplitude,
                        omega_radps,
                        t0_s,
                    }
                } else {
                    Signal::Cosine {
                        bias,
                        amplitude,
                        omega_radps,
                        t0_s,
                    }
                }
            }
            Self::Ramp {
                start,
                slope_per_s,
                t0_s,
            } => Signal::Ramp {
                start: finite("start", *start)?,
                slope_per_s: finite("slope_per_s", *slope_per_s)?,
                t0_s: finite("t0_s", *t0_s)?,
            },
            Self::Piecewise {
                thresholds_s,
                pieces,
            } => Signal::Piecewise(
                Piecewise::new(
                    thresholds_s.clone(),
                    pieces.iter().map(|p| p.build()).collect::<Result<_, _>>()?,
                )
                .map_err(|e| e.to_string())?,
            ),
        })
    }
}

/// The `[plant]` table of a scenario file.
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PlantSection {
    /// Hose model name.
    pub hose: Option<String>,
    /// Sensor mode: ideal or realistic.
    pub sensors: Option<String>,
    /// Noise seed.
    pub seed: Option<u64>,
    /// Plant step, s.
    pub dt_s: Option<f64>,
    /// Unmodelled effects, e.g. `[plant.effects.leakage] g_m3pspa = 1e-13`.
    pub effects: Option<crate::effects::Effects>,
}

/// A scenario file.
#[derive(Clone, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ScenarioFile {
    /// Scenario name (default: the file stem).
    pub name: Option<String>,
    /// Duration, s.
    pub duration_s: Spanned<f64>,
    /// Position reference (closed loop), m.
    pub reference: Option<Spanned<SignalSpec>>,
    /// Open-loop speed command, m/s.
    pub open_loop: Option<Spanned<SignalSpec>>,
    /// Load force, N (default 0).
    pub load: Option<Spanned<SignalSpec>>,
    /// Controller configuration.
    pub controller: Option<ConfigFile>,
    /// Plant and sensors.
    pub plant: Option<PlantSection>,
}

/// A scenario read from a file, with the settings it carries.
#[derive(Clone, Debug)]
pub struct LoadedScenario {
    /// The scenario.
    pub scenario: Scenario,
    /// Its controller table, if any.
    pub controller: Option<ConfigFile>,
    /// Its plant table, if any.
    pub plant: PlantSection,
}

impl ScenarioFile {
    /// Read and validate a scenario file.
    pub fn load(path: &Path) -> Result<LoadedScenario, FileError> {
        let text = read(path)?;
        let name = path.display().to_string();
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().to_string())
            .unwrap_or_else(|| "custom".into());
        Self::load_str(&text, &name, &stem)
    }

    /// Parse and validate scenario text; `file` names it in errors.
    pub fn load_str(
        text: &str,
        file: &str,
        default_name: &str,
    ) -> Result<LoadedScenario, FileError> {
        let f: ScenarioFile = parse(text, file)?;
        let at = |span: std::ops::Range<usize>, field: &str, message: String| FileError {
            file: file.to_string(),
            line: Some(line_of(text, span.start)),
            field: Some(field.to_string()),
            message,
        };
        let d = *f.duration_s.get_ref();
        if !(d.is_finite() && d > 0.0 && d <= 3600.0) {
            return Err(at(
                f.duration_s.span(),
                "duration_s",
                format!("{d} s: must be in (0, 3600]"),
            ));
        }
        // Finite parameters can still give infinite or NaN values within
        // the run (an overflowing amplitude, frequency or slope).
        let build = |s: &Spanned<SignalSpec>, field: &str| {
            let sig = s.get_ref().build().map_err(|m| at(s.span(), field, m))?;
            if !sig.is_finite_over(0.0, d) {
                return Err(at(
                    s.span(),
                    field,
                    format!(
                        "not finite within 0 to {d} s: a value, frequency or slope is too large"
                    ),
                ));
            }
            Ok(sig)
        };
        let command = match (&f.reference, &f.open_loop) {
            (Some(r), None) => Command::Reference(build(r, "reference")?),
            (None, Some(v)) => Command::OpenLoop(build(v, "open_loop")?),
            (Some(_), Some(v)) => {
                return Err(at(
                    v.span(),
                    "open_loop",
                    "give either [reference] or [open_loop], not both".into(),
                ))
            }
            (None, None) => {
                return Err(FileError {
                    file: file.to_string(),
                    line: None,
                    field: Some("reference".into()),
                    message: "missing: give [reference] (closed loop) or [open_loop]".into(),
                })
            }
        };
        let load = match &f.load {
            Some(l) => build(l, "load")?,
            None => Signal::Constant(0.0),
        };
        if let Some(c) = &f.controller {
            c.preset(file)?;
            c.kind(file)?;
        }
        Ok(LoadedScenario {
            scenario: Scenario::new(
                f.name.clone().unwrap_or_else(|| default_name.to_string()),
                d,
                command,
                load,
            ),
            controller: f.controller,
            plant: f.plant.unwrap_or_default(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const EXAMPLE: &str = r#"
name = "two-steps"
duration_s = 8.0
[reference]
type = "steps"
times_s = [4.0]
values = [0.03, 0.06]
[load]
type = "sine"
bias = 400.0
amplitude = 200.0
frequency_hz = 0.5
[controller]
controller = "pid"
preset = "fast"
[pid]
"#;

    #[test]
    fn example_scenario_loads() {
        // The trailing [pid] table is top-level, which is an unknown field.
        let e = ScenarioFile::load_str(EXAMPLE, "ex.toml", "ex").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("pid"), "{e}");
        assert_eq!(e.line, Some(16), "{e}");
        let ok = EXAMPLE.replace("[pid]\n", "[controller.pid]\nkp = 3.0\n");
        let s = ScenarioFile::load_str(&ok, "ex.toml", "ex").unwrap();
        assert_eq!(s.scenario.name(), "two-steps");
        assert_eq!(s.scenario.reference_m(3.9), Some(0.03));
        assert_eq!(s.scenario.reference_m(4.0), Some(0.06));
        assert!((s.scenario.load_n(0.5) - 600.0).abs() < 1e-9);
        let c = s.controller.unwrap();
        let cfg = c.resolve(c.kind("ex").unwrap().unwrap(), "ex").unwrap();
        assert_eq!(cfg.kind, ControllerKind::Pid);
        assert_eq!(cfg.pid.kp, 3.0);
        assert_eq!(cfg.pid.ts_s, 0.01); // from the fast preset
    }

    #[test]
    fn errors_name_line_and_field() {
        let text = "duration_s = 5.0\n[reference]\ntype = \"steps\"\ntimes_s = [2.0, 1.0]\nvalues = [0, 1, 2]\n";
        let e = ScenarioFile::load_str(text, "s.toml", "s").unwrap_err();
        assert_eq!(
            (e.line, e.field.as_deref()),
            (Some(2), Some("reference")),
            "{e}"
        );
        assert!(e.message.contains("strictly increasing"), "{e}");

        let text = "duration_s = -1.0\n[reference]\ntype = \"constant\"\nvalue = 0.05\n";
        let e = ScenarioFile::load_str(text, "s.toml", "s").unwrap_err();
        assert_eq!(
            (e.line, e.field.as_deref()),
            (Some(1), Some("duration_s")),
            "{e}"
        );

        let text = "duration_s = 5.0\n[reference]\ntype = \"constant\"\nvalue = \"high\"\n";
        let e = ScenarioFile::load_str(text, "s.toml", "s").unwrap_err();
        assert!(e.line.is_some(), "{e}");
        assert!(e.to_string().starts_with("s.toml:"), "{e}");

        let text = "duration_s = 5.0\n[reference]\ntype = \"constant\"\nvalu = 0.05\n";
        let e = ScenarioFile::load_str(text, "s.toml", "s").unwrap_err();
        assert!(e.message.contains("valu"), "{e}");

        let text = "duration_s = 5.0\n";
        let e = ScenarioFile::load_str(text, "s.toml", "s").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("reference"), "{e}");
    }

    #[test]
    fn config_overrides_and_unknown_keys() {
        let c: ConfigFile = parse(
            "preset = \"paper\"\n[mpc_eso]\nrw = 50.0\n[eso]\nh_s = 0.004\n",
            "c.toml",
        )
        .unwrap();
        let cfg = c.resolve(ControllerKind::MpcEso, "c.toml").unwrap();
        assert_eq!(cfg.mpc_eso.rw, 50.0);
        assert_eq!(cfg.mpc_eso.np, 8);
        assert_eq!(cfg.eso.h_s, 0.004);
        assert_eq!(cfg.td.h_s, 0.004);
        let e = parse::<ConfigFile>("[eso]\nbeta4 = 1.0\n", "c.toml").unwrap_err();
        assert_eq!(e.field.as_deref(), Some("beta4"), "{e}");
        assert_eq!(e.line, Some(2), "{e}");
        let bad: ConfigFile = parse("preset = \"slow\"\n", "c.toml").unwrap();
        assert!(bad.preset("c.toml").is_err());
    }

    /// Found while fuzzing: finite parameters whose signal overflows within
    /// the run were accepted (a 1e308 Hz sine is NaN at every tick).
    #[test]
    fn signals_that_overflow_within_the_run_are_refused() {
        let head = "duration_s = 10.0\n[reference]\ntype = \"constant\"\nvalue = 0.05\n[load]\n";
        for load in [
            "type = \"sine\"\namplitude = 1.0\nfrequency_hz = 1e308\n",
            "type = \"cosine\"\nbias = 1e308\namplitude = 1e308\nfrequency_hz = 1.0\n",
            "type = \"ramp\"\nstart = 1e308\nslope_per_s = 1e307\n",
        ] {
            let e = ScenarioFile::load_str(&format!("{head}{load}"), "s.toml", "s").unwrap_err();
            assert_eq!((e.line, e.field.as_deref()), (Some(5), Some("load")), "{e}");
            assert!(e.message.contains("not finite"), "{e}");
        }
        let ok = format!("{head}type = \"ramp\"\nstart = 1e300\nslope_per_s = 1e300\n");
        assert!(ScenarioFile::load_str(&ok, "s.toml", "s").is_ok());
    }

    /// Found by fuzzing: a file ending where a value is due gave an error
    /// with an empty message ("c.toml:2: ").
    #[test]
    fn a_missing_value_at_the_end_is_named() {
        for text in [
            "[eso]\nbeta4 =",
            "np =",
            "duration_s = 5.0\n[reference]\ntype =  \n",
        ] {
            let e = ConfigFile::parse_str(text, "c.toml").unwrap_err();
            assert!(!e.message.is_empty(), "{text:?}: {e}");
            assert!(e.line.is_some(), "{text:?}: {e}");
        }
        let e = ConfigFile::parse_str("[eso]\nbeta1 =", "c.toml").unwrap_err();
        assert_eq!(
            e.to_string(),
            "c.toml:2: unexpected end of file: a value is missing"
        );
    }
}
