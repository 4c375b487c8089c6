//! The rig's physical parameters ([`PlantParams`]) by key: read from TOML,
//! checked for physical sense, and drawn at random for Monte Carlo runs
//! (docs/interfaces.md section 6).
//!
//! The keys are the field names of [`PlantParams`] (SI, units in the names);
//! the hose wall ([`dca_core::params::HoseParams`]) is a nested table
//! `[hose]`, its keys written `hose.<field>` in errors, CSV columns and
//! run-log metadata:
//!
//! ```toml
//! m_kg = 55.0
//! beta_e_pa = 1.0e9
//! [hose]
//! cs0_m3pp = 6.0e-13
//! ```
//!
//! Every key not given keeps its nominal value (docs/model.md section 3).
//! Reading ([`ParamsToml`]) only records the keys, their values and where
//! they are; [`ParamsToml::params`] then checks the values against their
//! plausible ranges ([`Plausible`], docs/interfaces.md section 6), so that
//! the caller, who holds the text, can name the line of a wrong value.

use std::ops::Range;

use dca_core::params::PlantParams;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use serde::de::{DeserializeSeed, Deserializer, MapAccess, Visitor};
use serde::Deserialize;
use toml::Spanned;

use crate::io::num::Num;
use crate::io::toml_key::KeySeed;

/// The plausible range of a parameter, ends included: the values a rig of
/// this kind (a miniature hydraulic actuator with hoses, docs/model.md
/// section 3) can have, with orders of magnitude of room around the nominal
/// rig. A file's value outside it is refused ([`check_plausible`]): such a
/// value is a typing or unit mistake (`m_kg = 1e308` gives a rig that never
/// moves), not a rig. Its sign also says what is physical at all
/// ([`check`]): a range from above 0 means the value must be > 0, from 0
/// that it must be >= 0.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plausible {
    /// The smallest plausible value, in the key's unit.
    pub min: f64,
    /// The largest plausible value, in the key's unit.
    pub max: f64,
}

impl Plausible {
    /// Why `v` is not physical (NaN, infinite, or of the wrong sign), if so.
    fn physical(self, v: f64) -> Result<(), &'static str> {
        if v.is_nan() {
            Err("not a number")
        } else if !v.is_finite() {
            Err("must be finite")
        } else if self.min > 0.0 && v <= 0.0 {
            Err("must be > 0")
        } else if self.min == 0.0 && v < 0.0 {
            Err("must be >= 0")
        } else {
            Ok(())
        }
    }

    /// Whether `v` is in the range.
    pub fn contains(self, v: f64) -> bool {
        (self.min..=self.max).contains(&v)
    }
}

/// One parameter of [`PlantParams`] by key.
#[derive(Debug)]
pub struct ParamKey {
    /// The key: the field name, `hose.<field>` for the hose wall.
    pub name: &'static str,
    /// Its CSV column and run-log metadata key for the rig: `plant.<name>`.
    pub column: &'static str,
    /// Its run-log metadata key for the controller's design model: `model.<name>`.
    pub model_column: &'static str,
    /// Its unit (`kg`, `m^3/Pa`, `1` for a pure number).
    pub unit: &'static str,
    /// The values a file may give it.
    pub plausible: Plausible,
    /// Whether `sweep --perturb` draws it by default: a property of the rig
    /// that a built rig can have off its nominal value (not the atmosphere,
    /// not the stroke limits, not the prediction model's linearisation point).
    pub physical: bool,
    get: fn(&PlantParams) -> f64,
    set: fn(&mut PlantParams, f64),
}

/// Keys are equal when their names are (each name is one field).
impl PartialEq for ParamKey {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

impl Eq for ParamKey {}

impl ParamKey {
    /// The value of this parameter in `p`.
    pub fn get(&self, p: &PlantParams) -> f64 {
        (self.get)(p)
    }

    /// Set this parameter of `p` to `v` (unchecked).
    pub fn set(&self, p: &mut PlantParams, v: f64) {
        (self.set)(p, v)
    }

    /// Whether this is a key of the `[hose]` table.
    pub fn is_hose(&self) -> bool {
        self.name.starts_with("hose.")
    }

    /// The key within its table (`ce0_m3pp` for `hose.ce0_m3pp`).
    pub fn field(&self) -> &'static str {
        self.name.strip_prefix("hose.").unwrap_or(self.name)
    }
}

macro_rules! key {
    ($f:ident, $unit:expr, $min:expr, $max:expr, $physical:expr) => {
        ParamKey {
            name: stringify!($f),
            column: concat!("plant.", stringify!($f)),
            model_column: concat!("model.", stringify!($f)),
            unit: $unit,
            plausible: Plausible {
                min: $min,
                max: $max,
            },
            physical: $physical,
            get: |p| p.$f,
            set: |p, v| p.$f = v,
        }
    };
    (hose $f:ident, $unit:expr, $min:expr, $max:expr) => {
        ParamKey {
            name: concat!("hose.", stringify!($f)),
            column: concat!("plant.hose.", stringify!($f)),
            model_column: concat!("model.hose.", stringify!($f)),
            unit: $unit,
            plausible: Plausible {
                min: $min,
                max: $max,
            },
            physical: true,
            get: |p| p.hose.$f,
            set: |p, v| p.hose.$f = v,
        }
    };
}

/// Every parameter of [`PlantParams`], in the struct's order (the hose wall's
/// after `c_stop_nspm`), with its unit and plausible range (the nominal
/// values, docs/model.md section 3, in brackets):
///
/// * masses and areas: the moving mass 1 g to 10 t (50 kg); the four piston
///   areas 1 mm^2 to 100 cm^2, bores of about 1 to 110 mm (2-5 cm^2);
/// * damping: viscous 0 to 1e6 N s/m (200), the end stops' 0 to 1e7 N s/m
///   (2e4) and stiffness 1e4 to 1e10 N/m (1e7);
/// * the hose: radius 0.1 to 50 mm (3 mm), length 1 cm to 100 m (1 m); its
///   wall's compliances 1e-18 to 1e-9 m^3/Pa (1.2e-13 to 4.8e-13, 1e-18
///   being a steel tube), time constants 10 us to 100 s (10 ms, 0.3 s), the
///   stiffening pressure 10 kPa to 1 GPa (1 MPa);
/// * the oil: bulk modulus 1e7 (much air) to 1e10 Pa (1.2e9; mineral oil
///   without air is below 2e9); volumes: dead 1 mm^3 to 1 l (1 cm^3),
///   fittings 0 to 1 l (1 cm^3);
/// * the servo: speed limit 0.1 mm/s to 10 m/s (0.1 m/s), time constant
///   0.1 ms to 1 s (10 ms);
/// * the accumulator: precharge -0.1 to 100 MPa gauge (1 MPa; above vacuum,
///   checked with the atmosphere), gas volume 0.01 cm^3 to 100 l (0.1 l),
///   polytropic exponent 1 (isothermal) to 1.7 (adiabatic monatomic gas,
///   5/3) (1.4), its connection's conductance 1e-14 to 1e-6 m^3/(s Pa)
///   (5e-10);
/// * the stroke limits -1 to 1 m (-0.010 and 0.110 m); the atmosphere
///   10 to 200 kPa (101.325 kPa); the prediction model's linearisation
///   pressure 0 to 100 MPa (1 MPa).
pub static KEYS: [ParamKey; 29] = [
    key!(m_kg, "kg", 1e-3, 1e4, true),
    key!(ap1_m2, "m^2", 1e-6, 1e-2, true),
    key!(ap2_m2, "m^2", 1e-6, 1e-2, true),
    key!(aa1_m2, "m^2", 1e-6, 1e-2, true),
    key!(aa2_m2, "m^2", 1e-6, 1e-2, true),
    key!(c_visc_nspm, "N s/m", 0.0, 1e6, true),
    key!(hose_radius_m, "m", 1e-4, 0.05, true),
    key!(hose_length_m, "m", 0.01, 100.0, true),
    key!(beta_e_pa, "Pa", 1e7, 1e10, true),
    key!(x_min_m, "m", -1.0, 1.0, false),
    key!(x_max_m, "m", -1.0, 1.0, false),
    key!(v_dead_m3, "m^3", 1e-9, 1e-3, true),
    key!(v_fit_m3, "m^3", 0.0, 1e-3, true),
    key!(v_max_mps, "m/s", 1e-4, 10.0, true),
    key!(tau_m_s, "s", 1e-4, 1.0, true),
    key!(p_acc0_pa, "Pa", -1e5, 1e8, true),
    key!(v_gas0_m3, "m^3", 1e-8, 0.1, true),
    key!(n_poly, "1", 1.0, 1.7, true),
    key!(p_atm_pa, "Pa", 1e4, 2e5, false),
    key!(g_acc_m3pspa, "m^3/(s Pa)", 1e-14, 1e-6, true),
    key!(k_stop_npm, "N/m", 1e4, 1e10, true),
    key!(c_stop_nspm, "N s/m", 0.0, 1e7, true),
    key!(hose ce0_m3pp, "m^3/Pa", 1e-18, 1e-9),
    key!(hose cf0_m3pp, "m^3/Pa", 1e-18, 1e-9),
    key!(hose tau_f_s, "s", 1e-5, 100.0),
    key!(hose cs0_m3pp, "m^3/Pa", 1e-18, 1e-9),
    key!(hose tau_s_s, "s", 1e-5, 100.0),
    key!(hose ps_pa, "Pa", 1e4, 1e9),
    key!(p_nom_pa, "Pa", 0.0, 1e8, false),
];

/// The parameter with key `name` (`m_kg`, `hose.ps_pa`).
pub fn find(name: &str) -> Option<&'static ParamKey> {
    KEYS.iter().find(|k| k.name == name)
}

/// The keys `sweep --perturb` draws by default ([`ParamKey::physical`]).
pub fn physical_keys() -> Vec<&'static ParamKey> {
    KEYS.iter().filter(|k| k.physical).collect()
}

/// The keys of one table (top level, or `[hose]`), as "`a`, `b`, ...".
fn keys_of(hose: bool) -> String {
    let mut names: Vec<String> = KEYS
        .iter()
        .filter(|k| k.is_hose() == hose)
        .map(|k| format!("`{}`", k.field()))
        .collect();
    if !hose {
        names.push("`hose`".into());
    }
    names.join(", ")
}

/// Why a parameter set is not physical, or a key or value of a file is wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{message}")]
pub struct ParamsError {
    /// The key at fault (`m_kg`, `hose.ps_pa`).
    pub key: &'static str,
    /// Where its value is in the file's text (byte offsets), when read from one.
    pub span: Option<Range<usize>>,
    /// What is wrong.
    pub message: String,
}

fn fail(key: &'static str, message: String) -> ParamsError {
    ParamsError {
        key,
        span: None,
        message,
    }
}

/// `1e308 kg`, `1.4` (no unit for a pure number, nor for NaN or infinity).
fn with_unit(v: f64, unit: &str) -> String {
    if unit == "1" || !v.is_finite() {
        Num(v).to_string()
    } else {
        format!("{} {unit}", Num(v))
    }
}

/// Check that every value of `p` is within its [`Plausible`] range, and
/// then [`check`]: what a file must give.
pub fn check_plausible(p: &PlantParams) -> Result<(), ParamsError> {
    for k in &KEYS {
        let v = k.get(p);
        k.plausible
            .physical(v)
            .map_err(|why| fail(k.name, format!("{}: {why}", with_unit(v, k.unit))))?;
        let r = k.plausible;
        if !r.contains(v) {
            return Err(fail(
                k.name,
                format!(
                    "{} is outside the plausible range {} to {}",
                    with_unit(v, k.unit),
                    Num(r.min),
                    with_unit(r.max, k.unit)
                ),
            ));
        }
    }
    check(p)
}

/// Check that `p` is physical: every value finite and of its sign
/// ([`Plausible`]), the stroke `x_min_m < x_max_m` containing the initial
/// position 0, and the accumulator's absolute precharge `p_acc0_pa +
/// p_atm_pa` above 0. (A Monte Carlo draw, within a factor 2 of a plausible
/// value, may leave the plausible range: it is checked here only.)
pub fn check(p: &PlantParams) -> Result<(), ParamsError> {
    for k in &KEYS {
        let v = k.get(p);
        k.plausible
            .physical(v)
            .map_err(|why| fail(k.name, format!("{}: {why}", with_unit(v, k.unit))))?;
    }
    if p.x_min_m >= p.x_max_m {
        return Err(fail(
            "x_max_m",
            format!(
                "x_min_m = {} must be below x_max_m = {}",
                Num(p.x_min_m),
                Num(p.x_max_m)
            ),
        ));
    }
    if !(p.x_min_m <= 0.0 && p.x_max_m >= 0.0) {
        let key = if p.x_min_m > 0.0 {
            "x_min_m"
        } else {
            "x_max_m"
        };
        return Err(fail(
            key,
            format!(
                "the stroke [{}, {}] m must contain the initial position 0",
                Num(p.x_min_m),
                Num(p.x_max_m)
            ),
        ));
    }
    if p.p_acc0_pa + p.p_atm_pa <= 0.0 {
        return Err(fail(
            "p_acc0_pa",
            format!(
                "p_acc0_pa = {} is below vacuum (-p_atm_pa = {})",
                Num(p.p_acc0_pa),
                Num(-p.p_atm_pa)
            ),
        ));
    }
    Ok(())
}

/// One key of a file with its value as written and where the value is.
#[derive(Clone, Debug, PartialEq)]
struct Entry {
    key: &'static ParamKey,
    span: Range<usize>,
    value: toml::Value,
}

/// A parameter table as read from TOML: the keys given, in file order, with
/// their values and positions. [`ParamsToml::params`] checks them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ParamsToml {
    entries: Vec<Entry>,
}

impl ParamsToml {
    /// Whether no key was given.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The nominal parameters with the file's values, each within its
    /// plausible range ([`check_plausible`]); an error names the key and,
    /// where there is one, the span of its value.
    pub fn params(&self) -> Result<PlantParams, ParamsError> {
        let mut p = PlantParams::NOMINAL;
        for e in &self.entries {
            let v = match &e.value {
                toml::Value::Float(v) => *v,
                toml::Value::Integer(i) => *i as f64,
                other => {
                    return Err(ParamsError {
                        key: e.key.name,
                        span: Some(e.span.clone()),
                        message: format!(
                            "invalid value for `{}`: expected a number, found a {}",
                            e.key.name,
                            other.type_str()
                        ),
                    })
                }
            };
            e.key.set(&mut p, v);
        }
        check_plausible(&p).map_err(|mut err| {
            // Point at the key's value; for a relation (the stroke, the
            // precharge) at the last of its keys the file gave.
            let related: &[&str] = match err.key {
                "x_min_m" | "x_max_m" => &["x_min_m", "x_max_m"],
                "p_acc0_pa" => &["p_acc0_pa", "p_atm_pa"],
                _ => &[],
            };
            let hit = self.entries.iter().rev().find(|e| {
                if related.is_empty() {
                    e.key.name == err.key
                } else {
                    related.contains(&e.key.name)
                }
            });
            if let Some(e) = hit {
                err.key = e.key.name;
                err.span = Some(e.span.clone());
            }
            err.message = format!("invalid value for `{}`: {}", err.key, err.message);
            err
        })?;
        Ok(p)
    }
}

/// A key of the top-level table or of `[hose]`.
pub(crate) enum Key {
    Param(&'static ParamKey),
    Hose,
}

/// The key `v` of the top-level table (`hose: false`) or of `[hose]`.
pub(crate) fn lookup_key(v: &str, hose: bool) -> Result<Key, String> {
    if v == "hose" && !hose {
        return Ok(Key::Hose);
    }
    KEYS.iter()
        .find(|k| k.is_hose() == hose && k.field() == v)
        .map(Key::Param)
        .ok_or_else(|| format!("unknown field `{v}`, expected one of {}", keys_of(hose)))
}

/// Reads a table keyed by plant parameter (the top-level table, `hose:
/// false`, or `[hose]`) into `out`: each key with its value as `V` and where
/// the value is. `expecting` names the top-level table and `[hose]` in type
/// errors. Plant-parameter files and tolerance specs
/// ([`crate::sim::tolerance`]) both read their keys through it.
pub(crate) struct KeyedTable<'a, V> {
    /// Reading `[hose]`.
    pub hose: bool,
    /// What the top-level table and `[hose]` are, for messages.
    pub expecting: [&'static str; 2],
    /// The keys read, in file order.
    pub out: &'a mut Vec<(&'static ParamKey, Spanned<V>)>,
}

impl<'de, V: Deserialize<'de>> DeserializeSeed<'de> for KeyedTable<'_, V> {
    type Value = ();

    fn deserialize<D: Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_map(self)
    }
}

impl<'de, V: Deserialize<'de>> Visitor<'de> for KeyedTable<'_, V> {
    type Value = ();

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str(self.expecting[usize::from(self.hose)])
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let hose = self.hose;
        while let Some(key) = map.next_key_seed(KeySeed {
            expecting: "a plant parameter",
            lookup: |v: &str| lookup_key(v, hose),
        })? {
            match key {
                Key::Hose => map.next_value_seed(KeyedTable {
                    hose: true,
                    expecting: self.expecting,
                    out: &mut *self.out,
                })?,
                Key::Param(k) => {
                    let v: Spanned<V> = map.next_value()?;
                    self.out.push((k, v));
                }
            }
        }
        Ok(())
    }
}

impl<'de> Deserialize<'de> for ParamsToml {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let mut read: Vec<(&'static ParamKey, Spanned<toml::Value>)> = Vec::new();
        KeyedTable {
            hose: false,
            expecting: ["a table of plant parameters", "the table [hose]"],
            out: &mut read,
        }
        .deserialize(d)?;
        let entries = read
            .into_iter()
            .map(|(key, v)| Entry {
                key,
                span: v.span(),
                value: v.into_inner(),
            })
            .collect();
        Ok(Self { entries })
    }
}

/// The ChaCha stream of the parameter draws (the sensor noise of the same
/// seed uses stream 0, so the two never share numbers). A `normal` or
/// `lognormal` key draws from stream `DRAW_STREAM + 1 + i`, `i` its index in
/// [`KEYS`].
const DRAW_STREAM: u64 = 0x6463_615f_6d63; // "dca_mc"

/// Where the `normal` and `lognormal` draws are cut, in standard deviations
/// (a draw beyond is drawn again): within it lie 99.73 % of the untruncated
/// distribution, and a `normal` spread with sigma below 1 / 3 keeps the
/// value's sign.
pub const TRUNCATE_SIGMAS: f64 = 3.0;

/// How one parameter is drawn around its base value `v0`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Spread {
    /// `v0 (1 + w (2u - 1))`, u uniform in [0, 1): within +-`half_width` (`w`,
    /// a fraction) of `v0`. `sweep --perturb F` draws every key so.
    Uniform {
        /// The half-width as a fraction of the value.
        half_width: f64,
    },
    /// `v0 (1 + sigma z)`, z standard normal truncated at +-[`TRUNCATE_SIGMAS`].
    Normal {
        /// The standard deviation (before truncation) as a fraction of the value.
        sigma: f64,
    },
    /// `v0 exp(sigma z)`, z as for [`Spread::Normal`]: the median is `v0`, the
    /// value keeps its sign, the spread is a factor rather than a difference.
    LogNormal {
        /// The standard deviation (before truncation) of the natural logarithm.
        sigma: f64,
    },
}

impl Spread {
    /// Its fraction: the half-width or sigma.
    pub fn fraction(self) -> f64 {
        match self {
            Self::Uniform { half_width } => half_width,
            Self::Normal { sigma } | Self::LogNormal { sigma } => sigma,
        }
    }

    /// The interval every draw around `v0` lies in (ends included; for a
    /// negative `v0` the ends swap).
    pub fn bounds(self, v0: f64) -> (f64, f64) {
        let k = TRUNCATE_SIGMAS;
        let (lo, hi) = match self {
            Self::Uniform { half_width: w } => (v0 * (1.0 - w), v0 * (1.0 + w)),
            Self::Normal { sigma } => (v0 * (1.0 - k * sigma), v0 * (1.0 + k * sigma)),
            Self::LogNormal { sigma } => (v0 * libm::exp(-k * sigma), v0 * libm::exp(k * sigma)),
        };
        (lo.min(hi), lo.max(hi))
    }
}

impl std::fmt::Display for Spread {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Uniform { half_width } => write!(f, "uniform +-{}", Num(*half_width)),
            Self::Normal { sigma } => write!(f, "normal sigma {}", Num(*sigma)),
            Self::LogNormal { sigma } => write!(f, "lognormal sigma {}", Num(*sigma)),
        }
    }
}

/// A standard normal number truncated at +-[`TRUNCATE_SIGMAS`], the first
/// one within of key `index`'s own stream for `seed`.
fn truncated_normal(seed: u64, index: usize) -> f64 {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(DRAW_STREAM + 1 + index as u64);
    loop {
        let z: f64 = rng.sample(StandardNormal);
        if z.abs() <= TRUNCATE_SIGMAS {
            return z;
        }
    }
}

/// Draw a rig for Monte Carlo seed `seed`: each parameter of `spreads` by
/// its [`Spread`] around its value in `base`. One uniform number is drawn for
/// every key of [`KEYS`] in order, used or not, and a normal one from the
/// key's own stream, so a key's value depends only on the seed, its spread
/// and its base value, not on which other keys are drawn or how. Returns the
/// rig and the drawn values in [`KEYS`] order.
pub fn draw(
    base: &PlantParams,
    spreads: &[(&'static ParamKey, Spread)],
    seed: u64,
) -> (PlantParams, Vec<(&'static ParamKey, f64)>) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(DRAW_STREAM);
    let mut p = *base;
    let mut drawn = Vec::new();
    for (i, k) in KEYS.iter().enumerate() {
        let u: f64 = rng.random();
        let Some(&(_, spread)) = spreads.iter().find(|(q, _)| *q == k) else {
            continue;
        };
        let v0 = k.get(base);
        let v = match spread {
            Spread::Uniform { half_width } => v0 * (1.0 + half_width * (2.0 * u - 1.0)),
            Spread::Normal { sigma } => v0 * (1.0 + sigma * truncated_normal(seed, i)),
            Spread::LogNormal { sigma } => v0 * libm::exp(sigma * truncated_normal(seed, i)),
        };
        k.set(&mut p, v);
        drawn.push((k, v));
    }
    (p, drawn)
}

/// A name in `--perturb-keys` that is no plant parameter.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("'{name}' is not a plant parameter; the keys are {keys}")]
pub struct UnknownKey {
    /// The name as given.
    pub name: String,
    /// Every key, comma-separated.
    pub keys: String,
}

/// The keys named in `list` (`k1,k2,...`; `hose.<field>` for the hose wall).
pub fn parse_keys(list: &str) -> Result<Vec<&'static ParamKey>, UnknownKey> {
    let mut out: Vec<&'static ParamKey> = Vec::new();
    for name in list.split(',').map(str::trim) {
        let k = find(name).ok_or_else(|| UnknownKey {
            name: name.to_string(),
            keys: KEYS.iter().map(|k| k.name).collect::<Vec<_>>().join(", "),
        })?;
        if !out.contains(&k) {
            out.push(k);
        }
    }
    Ok(out)
}

/// `(column, value)` for every key whose value in `p` differs from the
/// nominal one or that is in `always`, in [`KEYS`] order; the column is
/// `plant.<key>` (`model: false`) or `model.<key>`. Values are written `{:e}`
/// (shortest round trip).
pub fn columns(
    p: &PlantParams,
    always: &[&'static ParamKey],
    model: bool,
) -> Vec<(&'static str, String)> {
    KEYS.iter()
        .filter(|k| {
            k.get(p).to_bits() != k.get(&PlantParams::NOMINAL).to_bits() || always.contains(k)
        })
        .map(|k| {
            (
                if model { k.model_column } else { k.column },
                format!("{:e}", k.get(p)),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use dca_core::params::HoseParams;

    fn uniform(keys: &[&'static ParamKey], w: f64) -> Vec<(&'static ParamKey, Spread)> {
        let s = Spread::Uniform { half_width: w };
        keys.iter().map(|k| (*k, s)).collect()
    }

    fn read(text: &str) -> Result<PlantParams, String> {
        let t: ParamsToml = toml::from_str(text).map_err(|e| e.to_string())?;
        t.params().map_err(|e| e.to_string())
    }

    /// Every field of `PlantParams` has exactly one key (a new field fails
    /// to compile here until it is added to `KEYS`).
    #[test]
    fn every_field_is_a_key() {
        let PlantParams {
            m_kg: _,
            ap1_m2: _,
            ap2_m2: _,
            aa1_m2: _,
            aa2_m2: _,
            c_visc_nspm: _,
            hose_radius_m: _,
            hose_length_m: _,
            beta_e_pa: _,
            x_min_m: _,
            x_max_m: _,
            v_dead_m3: _,
            v_fit_m3: _,
            v_max_mps: _,
            tau_m_s: _,
            p_acc0_pa: _,
            v_gas0_m3: _,
            n_poly: _,
            p_atm_pa: _,
            g_acc_m3pspa: _,
            k_stop_npm: _,
            c_stop_nspm: _,
            hose:
                HoseParams {
                    ce0_m3pp: _,
                    cf0_m3pp: _,
                    tau_f_s: _,
                    cs0_m3pp: _,
                    tau_s_s: _,
                    ps_pa: _,
                },
            p_nom_pa: _,
        } = PlantParams::NOMINAL;
        // 23 + 6 fields; each key sets its own field and no other.
        assert_eq!(KEYS.len(), 29);
        for (i, k) in KEYS.iter().enumerate() {
            let mut p = PlantParams::NOMINAL;
            let v = k.get(&p) * 1.5 + 1e-3;
            k.set(&mut p, v);
            for (j, o) in KEYS.iter().enumerate() {
                let changed = o.get(&p).to_bits() != o.get(&PlantParams::NOMINAL).to_bits();
                assert_eq!(changed, i == j, "{} changed {}", k.name, o.name);
            }
        }
        check(&PlantParams::NOMINAL).unwrap();
    }

    /// The nominal rig is well inside every range (a factor 5 from each end
    /// where the range starts above 0), and each range's ends are accepted.
    #[test]
    fn the_nominal_rig_is_plausible() {
        check_plausible(&PlantParams::NOMINAL).unwrap();
        for k in &KEYS {
            let (v, r) = (k.get(&PlantParams::NOMINAL), k.plausible);
            assert!(r.min < r.max, "{}", k.name);
            if r.min > 0.0 && k.name != "n_poly" && k.name != "p_atm_pa" {
                assert!(v >= 5.0 * r.min && v <= r.max / 5.0, "{}: {v}", k.name);
            }
        }
        // Each end is accepted where the relations allow it.
        for k in KEYS
            .iter()
            .filter(|k| k.name != "x_min_m" && k.name != "x_max_m")
        {
            for end in [k.plausible.min, k.plausible.max] {
                let mut p = PlantParams::NOMINAL;
                k.set(&mut p, end);
                let r = check_plausible(&p);
                assert!(r.is_ok(), "{} = {end}: {r:?}", k.name);
            }
        }
    }

    #[test]
    fn keys_and_hose_table() {
        let p = read("m_kg = 60\nbeta_e_pa = 1.0e9\n[hose]\nps_pa = 2e6\n").unwrap();
        assert_eq!(p.m_kg, 60.0);
        assert_eq!(p.beta_e_pa, 1.0e9);
        assert_eq!(p.hose.ps_pa, 2e6);
        assert_eq!(p.hose.ce0_m3pp, HoseParams::NOMINAL.ce0_m3pp);
        assert_eq!(read("").unwrap(), PlantParams::NOMINAL);
        for (text, what) in [
            ("m_gk = 1.0\n", "m_gk"),
            ("[hose]\nm_kg = 1.0\n", "m_kg"),
            ("[hose]\n[hose.x]\n", "x"),
            (
                "m_kg = -1.0\n",
                "invalid value for `m_kg`: -1 kg: must be > 0",
            ),
            (
                "m_kg = nan\n",
                "invalid value for `m_kg`: NaN: not a number",
            ),
            ("m_kg = inf\n", "must be finite"),
            (
                "m_kg = 1e308\n",
                "invalid value for `m_kg`: 1e308 kg is outside the plausible range 0.001 to \
                 10000 kg",
            ),
            (
                "[hose]\ncs0_m3pp = 1e-6\n",
                "invalid value for `hose.cs0_m3pp`: 1e-6 m^3/Pa is outside the plausible range \
                 1e-18 to 1e-9 m^3/Pa",
            ),
            (
                "n_poly = 0.9\n",
                "`n_poly`: 0.9 is outside the plausible range 1 to 1.7",
            ),
            ("m_kg = \"heavy\"\n", "expected a number"),
            ("x_min_m = 0.2\n", "x_min_m"),
            ("x_max_m = -0.02\n", "x_max_m"),
            (
                "p_acc0_pa = -2e5\n",
                "-200000 Pa is outside the plausible range -100000 to 1e8 Pa",
            ),
            ("p_acc0_pa = -1e5\np_atm_pa = 5e4\n", "vacuum"),
        ] {
            let e = read(text).unwrap_err();
            assert!(e.contains(what), "{text:?}: {e}");
        }
    }

    #[test]
    fn draws_are_within_bounds_deterministic_and_per_seed() {
        let keys = uniform(&physical_keys(), 0.2);
        assert!(!keys
            .iter()
            .any(|(k, _)| k.name == "p_atm_pa" || k.name == "x_min_m"));
        let base = PlantParams::NOMINAL;
        let (a, da) = draw(&base, &keys, 7);
        let (b, _) = draw(&base, &keys, 7);
        let (c, _) = draw(&base, &keys, 8);
        assert_eq!(a, b);
        assert_eq!(da.len(), keys.len());
        for (k, v) in &da {
            let v0 = k.get(&base);
            assert!(
                (v - v0).abs() <= 0.2 * v0.abs() * (1.0 + 1e-12),
                "{}",
                k.name
            );
            assert_ne!(
                v.to_bits(),
                k.get(&c).to_bits(),
                "{} same for two seeds",
                k.name
            );
            assert_eq!(k.get(&a).to_bits(), v.to_bits());
        }
        check(&a).unwrap();
        // Unlisted keys stay nominal; a key's draw does not depend on the others.
        let m = find("m_kg").unwrap();
        let (only_m, d) = draw(&base, &uniform(&[m], 0.2), 7);
        assert_eq!(d.len(), 1);
        assert_eq!(only_m.m_kg, a.m_kg);
        assert_eq!(only_m.beta_e_pa, base.beta_e_pa);
        assert_eq!(parse_keys("m_kg, hose.ps_pa,m_kg").unwrap().len(), 2);
        assert!(parse_keys("mass").unwrap_err().to_string().contains("m_kg"));
    }

    /// `sweep --perturb F` draws what it drew before the spreads were
    /// generalised: values printed by the former `draw(base, keys, F, seed)`
    /// for F = 0.3 and every physical key, bit for bit.
    #[test]
    fn uniform_draws_are_those_of_the_former_code() {
        let keys = uniform(&physical_keys(), 0.3);
        for (seed, name, bits) in [
            (0, "m_kg", 0x4049_fc1e_6f70_170a_u64),
            (0, "beta_e_pa", 0x41cf_5b55_a024_6d6a),
            (0, "tau_m_s", 0x3f80_dbe0_00c3_b8a5),
            (0, "hose.ps_pa", 0x4128_5098_5912_21de),
            (1, "m_kg", 0x404b_b574_e133_1fc4),
            (1, "beta_e_pa", 0x41d3_afb4_4dad_ec4b),
            (1, "tau_m_s", 0x3f82_d7fa_941d_fed8),
            (1, "hose.ps_pa", 0x4131_e29e_f27b_44a6),
        ] {
            let k = find(name).unwrap();
            let (p, _) = draw(&PlantParams::NOMINAL, &keys, seed);
            assert_eq!(
                k.get(&p).to_bits(),
                bits,
                "seed {seed}, {name}: {:e}",
                k.get(&p)
            );
            // The same value when drawn alone, and when the others are not uniform.
            let (q, _) = draw(&PlantParams::NOMINAL, &uniform(&[k], 0.3), seed);
            assert_eq!(k.get(&q).to_bits(), bits);
            let mixed: Vec<_> = keys
                .iter()
                .map(|&(o, s)| {
                    (
                        o,
                        if o == k {
                            s
                        } else {
                            Spread::Normal { sigma: 0.1 }
                        },
                    )
                })
                .collect();
            let (r, _) = draw(&PlantParams::NOMINAL, &mixed, seed);
            assert_eq!(k.get(&r).to_bits(), bits);
        }
    }

    /// Normal and lognormal draws: deterministic per seed, within their
    /// truncation, and over 4000 fixed seeds with the mean and standard
    /// deviation of a normal truncated at 3 sigma (sd 0.98658 sigma).
    #[test]
    fn normal_and_lognormal_draws_have_their_moments() {
        let m = find("m_kg").unwrap();
        let beta = find("beta_e_pa").unwrap();
        let spreads = [
            (m, Spread::Normal { sigma: 0.1 }),
            (beta, Spread::LogNormal { sigma: 0.3 }),
        ];
        let base = PlantParams::NOMINAL;
        assert_eq!(draw(&base, &spreads, 5), draw(&base, &spreads, 5));
        let n = 4000;
        let (mut zs, mut ls) = (Vec::new(), Vec::new());
        for seed in 0..n {
            let (p, d) = draw(&base, &spreads, seed);
            assert_eq!(d.len(), 2);
            for (k, s) in &spreads {
                let (lo, hi) = s.bounds(k.get(&base));
                assert!((lo..=hi).contains(&k.get(&p)), "seed {seed}: {}", k.name);
            }
            zs.push((p.m_kg / base.m_kg - 1.0) / 0.1);
            ls.push(libm::log(p.beta_e_pa / base.beta_e_pa) / 0.3);
        }
        // The truncated standard normal's sd: 1 - 2 k phi(k) / (2 Phi(k) - 1).
        let k = TRUNCATE_SIGMAS;
        let phi = libm::exp(-k * k / 2.0) / (2.0 * std::f64::consts::PI).sqrt();
        let sd_want = (1.0 - 2.0 * k * phi / libm::erf(k / 2f64.sqrt())).sqrt();
        assert!((sd_want - 0.98658).abs() < 1e-5, "{sd_want}");
        for (what, z) in [("normal", &zs), ("lognormal", &ls)] {
            let mean = z.iter().sum::<f64>() / n as f64;
            let sd = (z.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
            // Standard errors: 1 / sqrt(n) = 0.016 for the mean, about
            // 1 / sqrt(2 n) = 0.011 for the sd; the bounds are 4 of them.
            assert!(mean.abs() < 0.064, "{what}: mean {mean}");
            assert!((sd - sd_want).abs() < 0.045, "{what}: sd {sd}");
            assert!(z.iter().all(|x| x.abs() <= k + 1e-9), "{what}");
            // Truncated, not clipped: no mass piles up at the ends.
            assert!(!z.iter().any(|x| x.abs() > k - 1e-9), "{what}");
        }
        // Bounds: a band for uniform, the truncation for the others.
        let u = Spread::Uniform { half_width: 0.1 };
        assert_eq!(u.bounds(-2.0), (-2.2, -1.8));
        let (lo, hi) = Spread::LogNormal { sigma: 0.25 }.bounds(1.0);
        assert!((lo - libm::exp(-0.75)).abs() < 1e-15 && (hi - libm::exp(0.75)).abs() < 1e-15);
        assert_eq!(
            Spread::Normal { sigma: 0.05 }.to_string(),
            "normal sigma 0.05"
        );
    }
}
