//! The catalogue's vocabulary, below every part file: what one parameter
//! is ([`ParamSpec`]), what a named form and a general family tell the
//! catalogue ([`NamedEffect`], [`GeneralFamily`]; what they add to the
//! rig's equations is their [`RigTerms`], in `terms`) and what a form's
//! parameters may break ([`Broken`]). `mod.rs` puts the effect's identifier
//! on it ([`super::EffectError`]).

use super::terms::RigTerms;

/// One parameter of an effect: name (with unit), typical value, fit bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// Name with unit suffix, as in the configuration files.
    pub name: &'static str,
    /// A typical magnitude on a rig of this size.
    pub typical: f64,
    /// Smallest value a fit may take.
    pub min: f64,
    /// Largest value a fit may take.
    pub max: f64,
}

/// How far beyond its fit range a parameter may be set: an effect can be
/// emulated stronger than the diagnosis would fit it, but not by orders of
/// magnitude (a leakage conductance of 1 instead of 1e-13 makes the plant
/// non-finite after one step).
pub const VALID_SPAN: f64 = 10.0;

/// Largest polytropic index of the entrained air (a monatomic gas, 5/3).
pub const KAPPA_MAX: f64 = 5.0 / 3.0;

pub(super) const fn p(name: &'static str, typical: f64, min: f64, max: f64) -> ParamSpec {
    ParamSpec {
        name,
        typical,
        min,
        max,
    }
}

/// What a form's parameters break; the catalogue names the effect.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Broken {
    /// A relation between the parameters: what must hold.
    Requirement(&'static str),
    /// The air's polytropic exponent outside [1, [`KAPPA_MAX`]].
    Kappa(f64),
}

/// An effect's named form as the catalogue sees it: its part of the rig,
/// its parameters, and the relations they must keep; its terms in the
/// rig's equations are its [`RigTerms`]. Each part file implements both
/// beside the form.
pub trait NamedEffect: Copy + RigTerms {
    /// The part of the rig ([`EffectKind::subsystem`](super::EffectKind::subsystem)).
    const SUBSYSTEM: &'static str;
    /// The parameters, in the order of [`NamedEffect::values`].
    const PARAMS: &'static [ParamSpec];
    /// Whether the diagnosis fits it by a bounded search over its parameters
    /// ([`EffectKind::CATALOGUE`](super::EffectKind::CATALOGUE)); false where it has a fit of its own.
    const SEARCHED: bool = true;
    /// Whether every value must lie in [0, [`VALID_SPAN`] times its fit
    /// bound]; false where [`NamedEffect::check_relations`] checks the ranges.
    const RANGE_CHECKED: bool = true;
    /// The parameter values, in [`NamedEffect::PARAMS`] order.
    fn values(&self) -> Vec<f64>;
    /// The form with parameter `i` at `at(i)`.
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self;
    /// Bounds beyond the ranges, checked right after every effect's ranges.
    fn check_bounds(&self) -> Result<(), Broken> {
        Ok(())
    }
    /// Relations between the parameters, checked after the general families.
    fn check_relations(&self) -> Result<(), Broken> {
        Ok(())
    }
    /// The parameters by name for reports where they are not simply
    /// [`NamedEffect::PARAMS`] with [`NamedEffect::values`].
    fn param_map(&self) -> Option<Vec<(String, f64)>> {
        None
    }
}

/// An effect's general family: the broader model of the same part, never on
/// together with the named form; its terms in the rig's equations are its
/// [`RigTerms`]. A family the diagnosis learns by least squares
/// (`gap/candidates.rs`) says how many values it learns and how they build
/// it ([`GeneralFamily::LEARNED`], [`GeneralFamily::from_learned`]).
pub trait GeneralFamily: Copy + RigTerms {
    /// The error when it is on together with its named form.
    const BOTH: &'static str;
    /// What its parameters must satisfy (the error when they do not).
    const REQUIREMENT: &'static str;
    /// What the diagnosis's `form` says of it (`general: ...`).
    const FORM: &'static str;
    /// How many values the diagnosis learns by least squares (each
    /// non-negative, in a unit of the family's choosing that makes them of
    /// order 1 to 50); 0 where it has a fit of its own.
    const LEARNED: usize = 0;
    /// Whether its parameters satisfy [`GeneralFamily::REQUIREMENT`].
    fn family_valid(&self) -> bool;
    /// Its parameters by name for reports (names carry their units).
    fn param_map(&self) -> Vec<(String, f64)>;
    /// The family from [`GeneralFamily::LEARNED`] learned values `x` (a
    /// negative one counts as 0); `None` where it is not learned.
    fn from_learned(_x: &[f64]) -> Option<Self> {
        None
    }
    /// The learned values that give this family, as near as they can (a
    /// start for the fit, e.g. from the closures of the equations); `None`
    /// where it has none.
    fn to_learned(&self) -> Option<Vec<f64>> {
        None
    }
}
