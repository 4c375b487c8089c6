//! TOML files: controller configurations and custom scenarios.
//!
//! A controller configuration starts from a preset and sets any controller
//! parameter of the board's settings table (`dca_app::settings::PARAMS`, the
//! paths of the console's `get`/`set`: table `[eso]`, key `beta1` is the path
//! `eso.beta1`), with the same ranges. Unknown keys and values out of range
//! are errors, so a typo never passes silently:
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
//! v_max_mps = 0.1           # x_min_m, x_max_m, xo_plausible_m
//! [model]                   # the design model: PlantParams keys (model::params)
//! m_kg = 50.0
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
//! [plant.effects.leakage]           # any effect of docs/model.md section 12
//! g_m3pspa = 1e-13
//! [plant.params]                    # the rig: PlantParams keys, [plant.params.hose]
//! m_kg = 55.0
//! ```
//!
//! Errors name the file, the line and the field.

use std::path::Path;

use dca_app::settings::{self, Param, ParamKind};
use dca_core::controller::{ControllerConfig, ControllerKind, Preset};
use dca_core::params::PlantParams;
use serde::de::{self, DeserializeSeed, Deserializer, MapAccess, Visitor};
use serde::{Deserialize, Serialize};
use toml::Spanned;

use crate::io::num::Num;
use crate::io::toml_key::KeySeed;
use crate::model::effects::Effects;
use crate::model::params::{self, ParamKey, ParamsError, ParamsToml};
use crate::model::scenario::{Command, Piecewise, PiecewiseError, Scenario, Signal};

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

/// The 1-based line of byte `offset` in `text`.
pub(crate) fn line_of(text: &str, offset: usize) -> usize {
    text[..offset.min(text.len())].matches('\n').count() + 1
}

/// Parse TOML into `T`, mapping parse and type errors to file and line.
pub(crate) fn parse<T: for<'de> Deserialize<'de>>(text: &str, file: &str) -> Result<T, FileError> {
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
            .filter(|_| {
                message.starts_with("unknown field") || message.starts_with("invalid value for")
            })
            .map(str::to_string);
        FileError {
            file: file.to_string(),
            line,
            field,
            message,
        }
    })
}

/// A parameter table's error as a file error: the line of the value, the
/// key under `prefix` (`plant.params.`, `controller.model.`, `model.` or none).
fn params_error(text: &str, file: &str, prefix: &str, e: ParamsError) -> FileError {
    FileError {
        file: file.to_string(),
        line: e.span.map(|s| line_of(text, s.start)),
        field: Some(format!("{prefix}{}", e.key)),
        message: e.message,
    }
}

/// Check a parameter table read from `text` (see [`params_error`]).
fn check_params(
    t: Option<&ParamsToml>,
    text: &str,
    file: &str,
    prefix: &str,
) -> Result<(), FileError> {
    match t {
        Some(t) => t
            .params()
            .map(|_| ())
            .map_err(|e| params_error(text, file, prefix, e)),
        None => Ok(()),
    }
}

/// A rig's physical parameters from TOML text: the keys of
/// [`dca_core::params::PlantParams`] at top level and `[hose]`
/// ([`crate::model::params`]); every key not given is nominal.
pub fn plant_params_str(text: &str, file: &str) -> Result<PlantParams, FileError> {
    let t: ParamsToml = parse(text, file)?;
    t.params().map_err(|e| params_error(text, file, "", e))
}

/// A rig file (`--plant FILE.toml`): the rig's physical parameters and its
/// unmodelled effects.
#[derive(Clone, Debug, PartialEq)]
pub struct RigFile {
    /// The rig's parameters (nominal where the file gives none).
    pub params: PlantParams,
    /// Its effects (none in the short form).
    pub effects: Effects,
    /// Other parameter sets about as consistent with the runs the rig was
    /// identified from (`[[identification.alternatives]]`, which `gap
    /// --rig-out` writes; `tune` checks its settings on them; none in the
    /// short form). Runs use `params` only.
    pub alternatives: Vec<PlantParams>,
}

/// The long form of a rig file: a scenario's `[plant]` table with only
/// `[plant.params]` and `[plant.effects.<name>]` (what `gap --rig-out` writes),
/// and the identification's alternatives.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RigToml {
    plant: RigSection,
    identification: Option<IdentificationToml>,
}

/// `[identification]`: what the identification left open.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct IdentificationToml {
    /// Parameter tables as `[plant.params]` (nominal where not given).
    #[serde(default)]
    alternatives: Vec<ParamsToml>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RigSection {
    params: Option<ParamsToml>,
    effects: Option<Effects>,
}

/// A rig from TOML text in either form: the short one (PlantParams keys at
/// top level and `[hose]`, [`plant_params_str`]) or the long one
/// (`[plant.params]`, `[plant.params.hose]` and `[plant.effects.<name>]`, as
/// in a scenario file and as `gap --rig-out` writes). The form is the one of
/// the first table: a top-level `plant` table is the long form.
pub fn rig_str(text: &str, file: &str) -> Result<RigFile, FileError> {
    let long = toml::from_str::<toml::Table>(text)
        .map(|t| t.contains_key("plant"))
        .unwrap_or(false);
    if !long {
        return Ok(RigFile {
            params: plant_params_str(text, file)?,
            effects: Effects::default(),
            alternatives: Vec::new(),
        });
    }
    let t: RigToml = parse(text, file)?;
    let params = match &t.plant.params {
        Some(p) => p
            .params()
            .map_err(|e| params_error(text, file, "plant.params.", e))?,
        None => PlantParams::NOMINAL,
    };
    let effects = t.plant.effects.unwrap_or_default();
    effects.validate().map_err(|e| FileError {
        file: file.to_string(),
        line: None,
        field: Some("plant.effects".into()),
        message: e.to_string(),
    })?;
    let alternatives = match &t.identification {
        Some(id) => id
            .alternatives
            .iter()
            .enumerate()
            .map(|(i, a)| {
                a.params().map_err(|e| {
                    params_error(text, file, &format!("identification.alternatives[{i}]."), e)
                })
            })
            .collect::<Result<_, _>>()?,
        None => Vec::new(),
    };
    Ok(RigFile {
        params,
        effects,
        alternatives,
    })
}

/// A rig file (`--plant FILE.toml`), as [`rig_str`].
pub fn read_plant_file(path: &Path) -> Result<RigFile, FileError> {
    rig_str(&read(path)?, &path.display().to_string())
}

/// The keys of `p` that differ from nominal as TOML lines under `table`
/// (its `.hose` sub-table for the hose's): a table (`[table]`, left out for
/// the nominal rig) or, with `array`, an element of an array of tables
/// (`[[table]]`, always written).
fn params_text(p: &PlantParams, table: &str, array: bool) -> String {
    let mut s = String::new();
    let off: Vec<&ParamKey> = params::KEYS
        .iter()
        .filter(|k| k.get(p).to_bits() != k.get(&PlantParams::NOMINAL).to_bits())
        .collect();
    let (hose, top): (Vec<&ParamKey>, Vec<&ParamKey>) = off.iter().partition(|k| k.is_hose());
    if array {
        s += &format!("\n[[{table}]]\n");
    } else if !top.is_empty() {
        s += &format!("\n[{table}]\n");
    }
    for k in &top {
        s += &format!("{} = {:e}\n", k.name, k.get(p));
    }
    if !hose.is_empty() {
        s += &format!("\n[{table}.hose]\n");
        for k in &hose {
            s += &format!("{} = {:e}\n", k.field(), k.get(p));
        }
    }
    s
}

/// The text of a rig file in the long form of [`rig_str`]: `[plant.params]`
/// with every parameter that differs from nominal (shortest round-trip
/// notation, so the file reads back bit for bit), the effects'
/// `[plant.effects.<name>]` tables and the alternatives'
/// `[[identification.alternatives]]`. `header` becomes comment lines.
pub fn rig_file_text(rig: &RigFile, header: &str) -> String {
    let mut s: String = header.lines().map(|l| format!("# {l}\n")).collect();
    s += &params_text(&rig.params, "plant.params", false);
    #[derive(Serialize)]
    struct Out<'a> {
        plant: OutPlant<'a>,
    }
    #[derive(Serialize)]
    struct OutPlant<'a> {
        effects: &'a Effects,
    }
    if rig.effects != Effects::default() {
        let t = toml::to_string(&Out {
            plant: OutPlant {
                effects: &rig.effects,
            },
        })
        .expect("effects are numbers and tables: TOML can hold them");
        s += "\n";
        s += &t;
    }
    if !rig.alternatives.is_empty() {
        s += "\n# Parameter sets about as consistent with the identification runs (two standard\n\
              # deviations along the directions they determine least); `tune` checks on them.\n";
        for a in &rig.alternatives {
            s += &params_text(a, "identification.alternatives", true);
        }
    }
    s
}

/// The text of `path`, or the error naming it.
pub(crate) fn read(path: &Path) -> Result<String, FileError> {
    std::fs::read_to_string(path).map_err(|e| FileError {
        file: path.display().to_string(),
        line: None,
        field: None,
        message: e.to_string(),
    })
}

/// A controller configuration file (or the `[controller]` table of a
/// scenario): a preset, a controller kind and parameters by path.
///
/// The tables and keys are those of the board's settings table
/// ([`dca_app::settings::PARAMS`], the one the console's `get`/`set` use),
/// restricted to the controller's tables
/// ([`dca_app::settings::CONTROLLER_TABLES`]): `[eso] beta1 = 30.0` sets the
/// path `eso.beta1`. Every value is range- and type-checked as it is read, so
/// that a file accepts exactly what `set eso.beta1 30` accepts on the board;
/// a new parameter in that table is a new key here, with no other edit.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ConfigFile {
    /// Base preset: `paper` (default) or `fast`.
    pub preset: Option<String>,
    /// Controller kind.
    pub controller: Option<String>,
    /// The parameters set, as (path, value as stored), in file order.
    pub params: Vec<(&'static str, f64)>,
    /// The controller's design model (`[model]`; in a scenario file
    /// `[controller.model]`): plant parameters by key, nominal if absent.
    pub model: Option<ParamsToml>,
}

/// Why a controller parameter given by path (in a file or a sweep) was
/// refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ParamError {
    /// No controller parameter has this path.
    #[error("'{path}' is not a controller parameter{hint}")]
    Unknown {
        /// The path as given.
        path: String,
        /// What was expected, or why the path is not one.
        hint: String,
    },
    /// The value is out of range or of the wrong type.
    #[error(
        "'{path}' = {}: {reason} (accepted: {} to {})",
        Num(*value),
        Num(*min),
        Num(*max)
    )]
    Value {
        /// The parameter's path.
        path: &'static str,
        /// The value as given.
        value: f64,
        /// Why it was refused.
        reason: &'static str,
        /// The smallest accepted value.
        min: f64,
        /// The largest accepted value.
        max: f64,
    },
}

/// The keys of one controller table, as "`a`, `b`, ...".
fn keys_of(table: &str) -> String {
    settings::PARAMS
        .iter()
        .filter(|p| p.table() == table)
        .map(|p| format!("`{}`", p.key()))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The controller parameter at `path`.
pub fn controller_param(path: &str) -> Result<&'static Param, ParamError> {
    match settings::find(path) {
        Some(p) if p.is_controller() => Ok(p),
        Some(_) => Err(ParamError::Unknown {
            path: path.to_string(),
            hint: ": it is a setting of the board (calibration, drive, supervisor or HIL)".into(),
        }),
        None => {
            let table = path.split_once('.').map_or(path, |(t, _)| t);
            let hint = if settings::CONTROLLER_TABLES.contains(&table) {
                format!("; [{table}] has {}", keys_of(table))
            } else {
                format!(
                    "; the tables are {}",
                    settings::CONTROLLER_TABLES.join(", ")
                )
            };
            Err(ParamError::Unknown {
                path: path.to_string(),
                hint,
            })
        }
    }
}

/// `v` for the controller parameter `p`, as it is stored.
pub fn check_value(p: &'static Param, v: f64) -> Result<f64, ParamError> {
    p.check(v).map_err(|e| ParamError::Value {
        path: p.name,
        value: v,
        reason: e.as_str(),
        min: p.min,
        max: p.max,
    })
}

/// Set the controller parameter `path` of `cfg` to `v` (checked).
pub fn set_param(cfg: &mut ControllerConfig, path: &str, v: f64) -> Result<(), ParamError> {
    let p = controller_param(path)?;
    let v = check_value(p, v)?;
    settings::set_controller(cfg, p.name, v).map_err(|e| ParamError::Value {
        path: p.name,
        value: v,
        reason: e.as_str(),
        min: p.min,
        max: p.max,
    })
}

/// The top-level keys of a configuration file.
enum FileKey {
    Preset,
    Controller,
    Model,
    Table(&'static str),
}

/// The top-level key `v` of a configuration file.
fn file_key(v: &str) -> Result<FileKey, String> {
    match v {
        "preset" => Ok(FileKey::Preset),
        "controller" => Ok(FileKey::Controller),
        "model" => Ok(FileKey::Model),
        _ => match settings::CONTROLLER_TABLES.iter().find(|t| **t == v) {
            Some(t) => Ok(FileKey::Table(t)),
            None => Err(format!(
                "unknown field `{v}`, expected one of `preset`, `controller`, `model`, {}",
                settings::CONTROLLER_TABLES
                    .map(|t| format!("`{t}`"))
                    .join(", ")
            )),
        },
    }
}

/// The key `v` of the parameter table `table`.
fn param_key(table: &str, v: &str) -> Result<&'static Param, String> {
    settings::PARAMS
        .iter()
        .find(|p| p.table() == table && p.key() == v)
        .ok_or_else(|| format!("unknown field `{v}`, expected one of {}", keys_of(table)))
}

/// Reads a parameter's value (a TOML integer or float; a flag may also be a
/// boolean) and checks it; an error is at the value (its line).
struct ValueSeed(&'static Param);

impl<'de> DeserializeSeed<'de> for ValueSeed {
    type Value = f64;

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<f64, D::Error> {
        d.deserialize_any(self)
    }
}

impl Visitor<'_> for ValueSeed {
    type Value = f64;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "a number for `{}`", self.0.name)
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<f64, E> {
        let p = self.0;
        p.check(v).map_err(|e| {
            E::custom(format!(
                "invalid value for `{}`: {}: {} (accepted: {} to {})",
                p.name,
                Num(v),
                e.as_str(),
                Num(p.min),
                Num(p.max)
            ))
        })
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<f64, E> {
        self.visit_f64(v as f64)
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<f64, E> {
        self.visit_f64(v as f64)
    }

    fn visit_bool<E: de::Error>(self, v: bool) -> Result<f64, E> {
        match self.0.kind {
            ParamKind::Bool => Ok(if v { 1.0 } else { 0.0 }),
            _ => Err(E::invalid_type(de::Unexpected::Bool(v), &self)),
        }
    }
}

/// Reads one parameter table into the file's list.
struct TableSeed<'a> {
    table: &'static str,
    out: &'a mut Vec<(&'static str, f64)>,
}

impl<'de> DeserializeSeed<'de> for TableSeed<'_> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de> Visitor<'de> for TableSeed<'_> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(f, "the table [{}]", self.table)
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let table = self.table;
        while let Some(p) = map.next_key_seed(KeySeed {
            expecting: "a key of a controller parameter table",
            lookup: |v: &str| param_key(table, v),
        })? {
            let v = map.next_value_seed(ValueSeed(p))?;
            self.out.push((p.name, v));
        }
        Ok(())
    }
}

struct FileVisitor;

impl<'de> Visitor<'de> for FileVisitor {
    type Value = ConfigFile;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a controller configuration")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<ConfigFile, A::Error> {
        let mut file = ConfigFile::default();
        while let Some(key) = map.next_key_seed(KeySeed {
            expecting: "a key of a controller configuration",
            lookup: file_key,
        })? {
            match key {
                FileKey::Preset => file.preset = Some(map.next_value()?),
                FileKey::Controller => file.controller = Some(map.next_value()?),
                FileKey::Model => file.model = Some(map.next_value()?),
                FileKey::Table(table) => map.next_value_seed(TableSeed {
                    table,
                    out: &mut file.params,
                })?,
            }
        }
        Ok(file)
    }
}

impl<'de> Deserialize<'de> for ConfigFile {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        d.deserialize_map(FileVisitor)
    }
}

impl ConfigFile {
    /// Read a configuration file.
    pub fn read(path: &Path) -> Result<Self, FileError> {
        Self::parse_str(&read(path)?, &path.display().to_string())
    }

    /// Parse configuration text; `file` names it in errors.
    pub fn parse_str(text: &str, file: &str) -> Result<Self, FileError> {
        let c: Self = parse(text, file)?;
        check_params(c.model.as_ref(), text, file, "model.")?;
        Ok(c)
    }

    /// The controller's design model: the nominal plant with the `[model]`
    /// table's values.
    pub fn model(&self, file: &str) -> Result<PlantParams, FileError> {
        match &self.model {
            None => Ok(PlantParams::NOMINAL),
            Some(t) => t.params().map_err(|e| FileError {
                file: file.to_string(),
                line: None,
                field: Some(format!("model.{}", e.key)),
                message: e.message,
            }),
        }
    }

    /// The preset named in the file (default `paper`).
    pub fn preset(&self, file: &str) -> Result<Preset, FileError> {
        match &self.preset {
            None => Ok(Preset::Paper),
            Some(p) => Preset::from_name(p).ok_or_else(|| FileError {
                file: file.to_string(),
                line: None,
                field: Some("preset".into()),
                message: format!("unknown preset '{p}' (paper, fast or limit)"),
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
                    message: format!(
                        "unknown controller '{k}' (mpc-eso, mpc, pid, fuzzy-pid or cmpc-eso)"
                    ),
                }),
        }
    }

    /// Apply the parameters to `cfg`, in file order. The TD steps with the
    /// ESO, so `eso.h_s` also sets the TD's step.
    pub fn apply(&self, cfg: &mut ControllerConfig) -> Result<(), ParamError> {
        self.params
            .iter()
            .try_for_each(|(path, v)| set_param(cfg, path, *v))
    }

    /// The full configuration for `kind`: the file's preset with its parameters.
    pub fn resolve(&self, kind: ControllerKind, file: &str) -> Result<ControllerConfig, FileError> {
        let mut cfg = ControllerConfig::preset(self.preset(file)?, kind);
        if self.model.is_some() {
            cfg.plant = self.model(file)?;
        }
        self.apply(&mut cfg).map_err(|e| FileError {
            file: file.to_string(),
            line: None,
            field: match &e {
                ParamError::Unknown { path, .. } => Some(path.clone()),
                ParamError::Value { path, .. } => Some(path.to_string()),
            },
            message: e.to_string(),
        })?;
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

/// Why a signal of a scenario file could not be built (the caller names the
/// file, the line and the field).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SignalError {
    /// A parameter is not finite: NaN (not a number) or infinite.
    #[error("{name} = {}: {}", Num(*value), if value.is_nan() { "not a number" } else { "must be finite" })]
    NotFinite {
        /// The parameter (`values[1]` for an element of a list).
        name: String,
        /// Its value.
        value: f64,
    },
    /// The steps or pieces do not form a piecewise signal.
    #[error(transparent)]
    Piecewise(#[from] PiecewiseError),
}

impl SignalSpec {
    /// Build the signal; `Err` says what is wrong for the caller to locate.
    pub fn build(&self) -> Result<Signal, SignalError> {
        let finite = |name: &str, v: f64| {
            if v.is_finite() {
                Ok(v)
            } else {
                Err(SignalError::NotFinite {
                    name: name.to_string(),
                    value: v,
                })
            }
        };
        Ok(match self {
            Self::Constant { value } => Signal::Constant(finite("value", *value)?),
            Self::Steps { times_s, values } => {
                for (i, v) in values.iter().enumerate() {
                    finite(&format!("values[{i}]"), *v)?;
                }
                Signal::Piecewise(Piecewise::constants(times_s.clone(), values)?)
            }
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
            } => Signal::Piecewise(Piecewise::new(
                thresholds_s.clone(),
                pieces.iter().map(|p| p.build()).collect::<Result<_, _>>()?,
            )?),
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
    pub effects: Option<crate::model::effects::Effects>,
    /// The rig's physical parameters, e.g. `[plant.params] m_kg = 55.0`
    /// (nominal where not given; checked by [`ScenarioFile::load_str`]).
    pub params: Option<ParamsToml>,
}

impl PlantSection {
    /// The rig's parameters: nominal with the `[plant.params]` values.
    pub fn plant_params(&self, file: &str) -> Result<PlantParams, FileError> {
        match &self.params {
            None => Ok(PlantParams::NOMINAL),
            Some(t) => t.params().map_err(|e| FileError {
                file: file.to_string(),
                line: None,
                field: Some(format!("plant.params.{}", e.key)),
                message: e.message,
            }),
        }
    }
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
                if d.is_nan() {
                    "NaN: not a number; seconds in (0, 3600] are expected".to_string()
                } else {
                    format!("{} s: must be in (0, 3600]", Num(d))
                },
            ));
        }
        // Finite parameters can still give infinite or NaN values within
        // the run (an overflowing amplitude, frequency or slope).
        let build = |s: &Spanned<SignalSpec>, field: &str| {
            let sig = s
                .get_ref()
                .build()
                .map_err(|e| at(s.span(), field, e.to_string()))?;
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
            check_params(c.model.as_ref(), text, file, "controller.model.")?;
        }
        if let Some(p) = &f.plant {
            check_params(p.params.as_ref(), text, file, "plant.params.")?;
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

    /// The file's tables and keys are the controller paths of the console's
    /// settings table, with its ranges; errors point at the line.
    #[test]
    fn every_controller_setting_is_a_key_with_its_range() {
        for p in settings::PARAMS.iter() {
            if p.table() == "model" {
                // `[model]` is a plant-parameter table: the board's range of
                // each design-model key is the simulator's plausible range.
                let k = crate::model::params::find(p.key()).expect("a plant key");
                assert_eq!(
                    (p.min, p.max),
                    (k.plausible.min, k.plausible.max),
                    "{}",
                    p.name
                );
                continue;
            }
            let text = format!("[{}]\n{} = {:?}\n", p.table(), p.key(), p.max);
            let r = ConfigFile::parse_str(&text, "c.toml");
            if !p.is_controller() {
                let e = r.unwrap_err();
                assert_eq!(e.line, Some(1), "{}: {e}", p.name);
                continue;
            }
            let c = r.unwrap_or_else(|e| panic!("{}: {e}", p.name));
            assert_eq!(c.params, vec![(p.name, p.check(p.max).unwrap())]);
            let mut cfg = ControllerConfig::preset(Preset::Paper, ControllerKind::Pid);
            c.apply(&mut cfg).unwrap();
            let s = dca_app::settings::Settings {
                controller: cfg,
                ..Default::default()
            };
            assert_eq!(p.get(&s), p.check(p.max).unwrap(), "{}", p.name);
            // Just above the range: refused, at the value's line.
            let above = p.max * 1.5 + 1.0;
            let text = format!(
                "preset = \"fast\"\n[{}]\n{} = {above:?}\n",
                p.table(),
                p.key()
            );
            let e = ConfigFile::parse_str(&text, "c.toml").unwrap_err();
            assert_eq!((e.line, e.field.as_deref()), (Some(3), Some(p.name)), "{e}");
            assert!(e.message.contains("out of range"), "{e}");
        }
        // Newly a key: the plausibility bound of the LVDT reading.
        let c = ConfigFile::parse_str("[limits]\nxo_plausible_m = 0.5\n", "c.toml").unwrap();
        let cfg = c.resolve(ControllerKind::MpcEso, "c.toml").unwrap();
        assert_eq!(cfg.xo_plausible_m, 0.5);
        // Whole numbers for the horizons; an integer is a float's equal.
        let e = ConfigFile::parse_str("[mpc]\nnp = 6.5\n", "c.toml").unwrap_err();
        assert!(e.message.contains("whole number"), "{e}");
        let a = ConfigFile::parse_str("[mpc]\nrw = 50\n", "c.toml").unwrap();
        let b = ConfigFile::parse_str("[mpc]\nrw = 50.0\n", "c.toml").unwrap();
        assert_eq!(a, b);
        // Not a number.
        let e = ConfigFile::parse_str("[pid]\nkp = \"high\"\n", "c.toml").unwrap_err();
        assert_eq!(e.line, Some(2), "{e}");
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

    /// The rig's parameters (`[plant.params]`, `--plant`) and the controller's
    /// design model (`[controller.model]`, `[model]`): unknown keys and
    /// non-physical values are errors naming the file, the line and the key.
    #[test]
    fn plant_params_and_design_model() {
        let head = "duration_s = 5.0\n[reference]\ntype = \"constant\"\nvalue = 0.05\n";
        let ok = format!(
            "{head}[controller]\ncontroller = \"mpc\"\n[controller.model]\nm_kg = 60.0\n\
             [plant.params]\nm_kg = 55\n[plant.params.hose]\nps_pa = 2e6\n"
        );
        let s = ScenarioFile::load_str(&ok, "s.toml", "s").unwrap();
        let rig = s.plant.plant_params("s.toml").unwrap();
        assert_eq!((rig.m_kg, rig.hose.ps_pa), (55.0, 2e6));
        let c = s.controller.unwrap();
        let cfg = c.resolve(ControllerKind::Mpc, "s.toml").unwrap();
        assert_eq!(cfg.plant.m_kg, 60.0);
        assert_eq!(cfg.plant.beta_e_pa, PlantParams::NOMINAL.beta_e_pa);
        // Without a model the design model is the nominal plant.
        let c = ConfigFile::parse_str("[mpc]\nrw = 50.0\n", "c.toml").unwrap();
        let cfg = c.resolve(ControllerKind::Mpc, "c.toml").unwrap();
        assert_eq!(cfg.plant, PlantParams::NOMINAL);
        for (tail, line, field, what) in [
            ("[plant.params]\nm_gk = 1.0\n", 6, "m_gk", "unknown field"),
            (
                "[plant.params]\nm_kg = 1.0\nbeta_e_pa = -1e9\n",
                7,
                "plant.params.beta_e_pa",
                "> 0",
            ),
            (
                "[plant.params]\nx_max_m = 0.2\nx_min_m = 0.3\n",
                7,
                "plant.params.x_min_m",
                "below",
            ),
            (
                "[plant.params.hose]\ntau_s_s = 0\n",
                6,
                "plant.params.hose.tau_s_s",
                "> 0",
            ),
            (
                "[plant.params.hose]\nbeta = 0\n",
                6,
                "beta",
                "unknown field",
            ),
            (
                "[controller.model]\n\nn_poly = inf\n",
                7,
                "controller.model.n_poly",
                "finite",
            ),
            (
                "[controller.model]\nm_kg = \"x\"\n",
                6,
                "controller.model.m_kg",
                "a number",
            ),
        ] {
            let text = format!("{head}{tail}");
            let e = ScenarioFile::load_str(&text, "s.toml", "s").unwrap_err();
            assert_eq!(
                (e.line, e.field.as_deref()),
                (Some(line), Some(field)),
                "{tail}: {e}"
            );
            assert!(e.message.contains(what), "{tail}: {e}");
            assert!(
                e.to_string().starts_with(&format!("s.toml:{line}: ")),
                "{e}"
            );
        }
        // A configuration file's [model]; a --plant file at top level.
        let e = ConfigFile::parse_str("preset = \"fast\"\n[model]\nv_dead_m3 = 0.0\n", "c.toml")
            .unwrap_err();
        assert_eq!(
            (e.line, e.field.as_deref()),
            (Some(3), Some("model.v_dead_m3")),
            "{e}"
        );
        let p = plant_params_str("m_kg = 52.5\n[hose]\ncs0_m3pp = 5e-13\n", "p.toml").unwrap();
        assert_eq!((p.m_kg, p.hose.cs0_m3pp), (52.5, 5e-13));
        for (text, line, field) in [
            ("m_kg = 50.0\nmass_kg = 1.0\n", 2, "mass_kg"),
            ("m_kg = 50.0\n\np_acc0_pa = -1e6\n", 3, "p_acc0_pa"),
            ("[plant]\nm_kg = 1.0\n", 1, "plant"),
        ] {
            let e = plant_params_str(text, "p.toml").unwrap_err();
            assert_eq!(
                (e.line, e.field.as_deref()),
                (Some(line), Some(field)),
                "{text}: {e}"
            );
        }
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

    /// A value that is not a number is said to be one, not "too large"; a
    /// huge one is printed readably.
    #[test]
    fn nan_and_huge_values_are_named() {
        let steps = "duration_s = 3.0\n[reference]\ntype = \"steps\"\ntimes_s = [1.0]\n\
                     values = [0.0, nan]\n";
        let e = ScenarioFile::load_str(steps, "s.toml", "s").unwrap_err();
        assert_eq!(
            e.to_string(),
            "s.toml:2: field 'reference': values[1] = NaN: not a number"
        );
        let inf = steps.replace("nan", "inf");
        let e = ScenarioFile::load_str(&inf, "s.toml", "s").unwrap_err();
        assert!(
            e.message.ends_with("values[1] = inf: must be finite"),
            "{e}"
        );
        let sine = "duration_s = 3.0\n[reference]\ntype = \"sine\"\namplitude = nan\n\
                    frequency_hz = 1.0\n";
        let e = ScenarioFile::load_str(sine, "s.toml", "s").unwrap_err();
        assert!(e.message.ends_with("amplitude = NaN: not a number"), "{e}");
        let long = "duration_s = 1e308\n[reference]\ntype = \"constant\"\nvalue = 0.05\n";
        let e = ScenarioFile::load_str(long, "s.toml", "s").unwrap_err();
        assert_eq!(
            e.to_string(),
            "s.toml:1: field 'duration_s': 1e308 s: must be in (0, 3600]"
        );
        let e = ScenarioFile::load_str(
            "duration_s = 5.0\n[reference]\ntype = \"constant\"\nvalue = 0.05\n\
             [plant.params]\nm_kg = 1e308\n",
            "s.toml",
            "s",
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "s.toml:6: field 'plant.params.m_kg': invalid value for `m_kg`: 1e308 kg is \
             outside the plausible range 0.001 to 10000 kg"
        );
    }

    /// A rig file in the long form (what `gap --rig-out` writes) reads back
    /// bit for bit, parameters and effects; errors name file, line and key.
    #[test]
    fn rig_files_round_trip() {
        let mut effects = Effects::default();
        effects
            .parse_arg("leakage:g_m3pspa=1.2345678901234e-13")
            .unwrap();
        effects.parse_arg("friction").unwrap();
        let mut params = PlantParams::NOMINAL;
        params.m_kg = 57.123456789;
        params.hose.cs0_m3pp = 4.1e-13;
        // The identification's alternatives: one off in a top-level key and
        // a hose key, one in a hose key alone, one nominal.
        let mut a = params;
        a.beta_e_pa = 1.234567891e9;
        a.hose.ce0_m3pp = 9.87654321e-14;
        let mut b = PlantParams::NOMINAL;
        b.hose.tau_s_s = 0.41;
        let alternatives = vec![a, b, PlantParams::NOMINAL];
        let rig = RigFile {
            params,
            effects,
            alternatives,
        };
        let text = rig_file_text(&rig, "a header\nof two lines");
        assert!(text.starts_with("# a header\n# of two lines\n"), "{text}");
        assert_eq!(rig_str(&text, "r.toml").unwrap(), rig, "{text}");
        // The short form still reads, without effects.
        let short = rig_str("m_kg = 52.5\n", "s.toml").unwrap();
        assert_eq!(
            (short.params.m_kg, short.effects),
            (52.5, Effects::default())
        );
        for (text, line, field) in [
            (
                "[plant.params]\nm_kg = -1.0\n",
                Some(2),
                "plant.params.m_kg",
            ),
            ("[plant.effects.leakage]\ng = 1e-13\n", Some(2), "g"),
            ("[plant]\nhose = \"rigid\"\n", Some(2), "hose"),
            (
                "[plant.params]\nm_kg = 50.0\n[[identification.alternatives]]\nm_kg = 50.0\n\
                 [[identification.alternatives]]\nm_kg = 0.0\n",
                Some(6),
                "identification.alternatives[1].m_kg",
            ),
        ] {
            let e = rig_str(text, "r.toml").unwrap_err();
            assert_eq!(
                (e.line, e.field.as_deref()),
                (line, Some(field)),
                "{text}: {e}"
            );
        }
    }
}
