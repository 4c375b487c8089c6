//! Unmodelled effects of docs/model.md section 12: composable, off by default.
//!
//! Users switch them on to emulate their own rig; the gap diagnosis adds them
//! one at a time to the nominal model as candidate explanations. Each effect
//! has documented parameters (SI, units in the names), a typical magnitude,
//! and bounds the diagnosis fits within.
//!
//! | identifier | model | parameters |
//! |---|---|---|
//! | `leakage` | internal leakage line 1 -> line 2 across the pistons, Q = G dP ((abs(dP) + 10 kPa) / 1 MPa)^(n - 1), dP = P1 - P2: laminar (n = 1) to orifice-like (n = 0.5) | `g_m3pspa` (conductance at 1 MPa, typ. 1e-13: 0.2 cm^3/s at 2 MPa), `exponent` (typ. 1) |
//! | `friction` | seal friction on the actuating piston, Coulomb + Stribeck, smoothed: F = (Fc + (Fs - Fc) exp(-(v/vs)^2)) tanh(v/v_eps) | `coulomb_n` (typ. 30), `static_n` (typ. 45), `stribeck_mps` (typ. 2e-3); v_eps = 1e-4 m/s |
//! | `leakage`, general family ([`LeakageMap`]) | internal leakage of any shape: Q = sign(dP) L(abs(dP)) + g dP (P1 + P2) / (2 MPa), L piecewise linear over 0 ... 4 MPa ([`LEAK_DP_PA`]), extended linearly | `q_m3ps` (L at the knots), `g_m3pspa` (learned) |
//! | `friction`, general family ([`FrictionMap`]) | seal friction of any shape: magnitude S(abs(v)) + k (P1 + P2) / 1 MPa against the velocity, S piecewise linear over 0 ... 0.1 m/s ([`FRICTION_SPEEDS_MPS`]) | `force_n` (S at the knots), `n_per_mpa` (learned) |
//! | `backlash` | play and axial compliance between the motor (encoder, Xi) and the power piston, which carries the hydraulic force F = AP1 P1 - AP2 P2: Xp = Xi - (play/2) tanh(F / 10 N) - F / k (a massless piston: it crosses the play where F changes sign and floats in it while F is near 0) | `play_m` (typ. 50e-6), `stiffness_npm` (typ. 2e7) |
//! | `backlash`, general family ([`ScrewMap`]) | the coupling in any shape: the power piston sits behind the motor by D(F), odd and non-decreasing in the hydraulic force, piecewise linear over abs(F) through knots at 0, 10, 30, 100, 300, 1000, 3000 N | `deflection_m` (six, learned) |
//! | `air` | entrained air: 1/beta_eff = 1/beta_e + x_a / (kappa P_abs) (P_atm / P_abs)^(1/kappa) | `fraction` (air volume fraction at P_atm, typ. 0.005), kappa = 1.4 |
//! | `sensor_delay` | the LVDT reading delayed and low-pass filtered; pressure readings low-pass filtered | `xo_delay_s` (typ. 3e-3), `xo_tau_s` (typ. 2e-3), `p_tau_s` (typ. 1e-3) |
//! | `motor_limit` | servo force (torque) limit on a reflected mass m, and a speed cap: the speed loop's force m a + F, F = AP1 P1 - AP2 P2, is clamped to +-F_max, so the acceleration limit depends on the load; the speed target is clamped to +-v_cap | `force_max_n` (typ. 2000), `mass_eq_kg` (typ. 200), `speed_max_mps` (typ. 0.1) |
//! | `motor_limit`, general family ([`ServoEnvelope`]) | the drive's force envelope over speed, learned from the encoder: the speed loop's force m a + F is clamped to +-A(abs(v)) while motoring (A piecewise linear over 0 ... 0.1 m/s, non-increasing: a torque-speed curve of any shape) and to +-A(0) while braking; no separate speed cap (A falling to 0 is one); optionally a ramp: the asked acceleration clamped to +-a_max first, whatever the load; optionally the drive's own PI speed loop in place of the ideal one ([`SpeedLoop`]: no load feed-forward, an integrator that winds up while clamped or holds, a screw loss); optionally its command path ([`CommandMap`]: the speed target it makes of a command, a dead band or a gain) | `mass_eq_kg`, `force_n` (A at the knots [`ENVELOPE_SPEEDS_MPS`]), `accel_max_mps2`, `speed_loop`, `command_map` |
//! | `hose_hysteresis`, general family ([`HysteresisSpectrum`]) | a discrete Prandtl-Ishlinskii operator per line: five Dahl elements (yields 10 kPa ... 1 MPa, no stuck share), each adding its compliance as far as it is engaged | `c_m3pp` (five compliances, learned) |
//! | `hose_hysteresis` | rate-independent wall hysteresis (Dahl type): a hysteretic pressure z per line, dz = dP - abs(dP) z / r, saturating at +-r; its engagement e = (1 + sign(dP) z / r) / 2 goes from 0 right after a pressure reversal to 1 once the pressure has moved on by a few r; the line gains the compliance e c and loses (1 - e) s Ce(P), a share s of the hose wall's compliance held after a reversal | `c_m3pp` (typ. 2e-13), `stuck_share` (typ. 0), `yield_pa` (r, typ. 1e5) |
//! | `accumulator_thermal` | gas temperature T relaxing to ambient: dT/dt = -(n - 1) T dVg/dt / Vg + (T0 - T)/tau, P_abs = P0_abs (V0/Vg)(T/T0) | `tau_s` (typ. 5) |
//! | `accumulator_thermal`, general family ([`GasRelaxation`]) | the gas spring relaxing over six time constants (0.1 ... 30 s): with u = ln(V0/Vg), ds_k/dt = (w_k u - s_k)/tau_k and P_abs = P0_abs exp(n u - sum s_k); the index after a step compression falls from n by the weights of the elements that have relaxed | `weights` (six, learned, non-negative, sum at most 1) |
//! | `sensor_delay`, general family ([`SensorFilter`]) | a lag of any shape on one of Xo, Xi, P1, P2: a non-negative impulse response over the delays [`FILTER_DELAYS_S`] (0 ... 32 ms), unit gain at rest | `channel`, `weights` (learned) |
//! | `sensor_calibration`, general family ([`SensorMap`]) | a monotone static map of any shape on one of Xo, Xi, P1, P2, Ft: piecewise linear through six knots, extended linearly | `channel`, `knots_si`, `readings_si` (learned) |
//! | `sensor_calibration` | one sensor's static map from the true value v to the recorded one: offset + gain v + quad v^2 / span (span: the channel's full scale, [`CalChannel::span`]) | `channel` (0 xo_m, 1 xi_m, 2 p1_pa, 3 p2_pa, 4 ft_n), `gain_1` (typ. 1), `offset_si` (SI unit of the channel, typ. 0), `quad_1` (typ. 0) |
//! | `parameters` | the rig's nominal parameters off by ratios ([`ParameterRatios`]): the plant is built with them ([`ParameterRatios::apply`]) | `m_kg_ratio`, `beta_e_pa_ratio`, `hose_c_ratio` (the hose wall's three compliances), `c_visc_ratio`, `tau_m_ratio`, `p_acc0_ratio`, `aa_ratio` (both actuating-piston areas); all typ. 1 |
//!
//! With every effect off the plant is exactly the nominal model of docs/model.md.
//!
//! Each part of the rig has its file, holding each effect's named form and
//! its general family side by side: `seals` (leakage, friction), `coupling`
//! (backlash), `fluid` (air), `hose` (hose hysteresis), `accumulator` (its
//! thermal relaxation), `servo` (motor limit), `sensors` (delay,
//! calibration) and `parameters`, with `common` for the piecewise-linear
//! maps they share; everything is re-exported here. Each form carries its
//! own catalogue entry ([`NamedEffect`]: part of the rig, parameters with
//! their ranges, checks, report names), each general family its own
//! ([`GeneralFamily`], with how the diagnosis learns it where it does), and
//! both the terms they add to the rig's equations ([`RigTerms`]); the
//! traits live in `catalogue` and `terms`, below the part files, and
//! `passes` goes through every active effect for the rig. This file
//! holds what spans them: one row per effect in `effects!`, from which the
//! set of active effects ([`Effects`]), the identifiers ([`EffectKind`]),
//! their dispatch, the layout of the effects' states ([`EXT_STATES`]) and
//! validation are made, and the errors.
//!
//! # Adding an effect
//!
//! A new effect touches two files: its part file and one row of `effects!`
//! below (`Kind => field: Form;`, with `, family_field: Family` for its
//! general family). In the part file go the form's struct (with
//! `Deserialize` and `Serialize`), `impl NamedEffect` (its part, its
//! parameters, how it is built from them, its checks) and `impl RigTerms`,
//! the terms it adds to the rig's equations: each a hook that adds nothing
//! unless the effect implements it (a force on the actuating piston, a flow
//! from line 1 to line 2, the servo's acceleration, a coupling between the
//! motor and the power piston, the accumulator's gas law, a line's
//! compliance, the plant's parameters and a check against them, the step
//! scale), and states of its own if it needs them ([`RigTerms::STATES`],
//! their rest values and rates; the rig lays them out from the rows and
//! hands each effect only its own). A general family is the same with
//! `impl GeneralFamily`; one the diagnosis learns by least squares also
//! says how many values it learns and how they build it
//! ([`GeneralFamily::LEARNED`], [`GeneralFamily::from_learned`]), and the
//! diagnosis fits it as any other (`gap/candidates.rs`). From these follow
//! its TOML table `[plant.effects.<field>]`, `--effect <field>:...`,
//! validation, the rig's equations ([`crate::model::rig`] calls every
//! active effect's hooks and names none), the diagnosis's bounded fit over
//! its parameters, its general family's fit, and its report names. A part
//! file of its own adds its `mod` and `pub use` lines beside the row.
//!
//! Outside these two files, on purpose: an effect that needs a place in the
//! equations no hook offers yet adds the hook to [`RigTerms`] (in `terms`),
//! its pass over the active effects (in `passes`) and its one call in `rig.rs`,
//! once for every later effect; for the diagnosis to *name* an effect, the
//! equation and dependence it shows in must map to it in the naming table
//! of `gap/closures.rs` (docs/gap.md's table); a start for a learned family
//! read off the closures of the equations is set in `gap/diagnose.rs`
//! (the screw map's); and the families with fits of their own keep them
//! (the servo envelope, `gap/prefit.rs`; the sensors' families,
//! `gap/sensor_family.rs`; `parameters`' grey-box re-estimate,
//! `gap/grey_box.rs`).

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use crate::io::num::Num;

mod accumulator;
mod catalogue;
mod common;
mod coupling;
mod fluid;
mod hose;
mod parameters;
mod passes;
mod seals;
mod sensors;
mod servo;
mod terms;

pub use accumulator::*;
pub use catalogue::{Broken, GeneralFamily, NamedEffect, ParamSpec, KAPPA_MAX, VALID_SPAN};
pub use coupling::*;
pub use fluid::*;
pub use hose::*;
pub use parameters::*;
pub use seals::*;
pub use sensors::*;
pub use servo::*;
pub use terms::{Gas, Line, PowerPiston, Rest, RigTerms};

pub(crate) use common::segment;

/// One for each effect of a row of `effects!`.
macro_rules! one {
    ($x:ident) => {
        1
    };
}

/// The catalogue from one row per effect: `Kind => field: NamedEffect` and,
/// where the effect has one, `, family_field: GeneralFamily`. It makes the
/// set of active effects ([`Effects`]), the identifiers ([`EffectKind`]) and
/// everything that goes through every effect (names, parameters, get, set,
/// checks), in the rows' order (docs/model.md section 12).
macro_rules! effects {
    ($(
        $(#[doc = $doc:literal])*
        $kind:ident => $field:ident: $named:ty $(, $family:ident: $general:ty)?;
    )*) => {
        /// The set of active effects (all `None`: the nominal plant).
        #[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq)]
        #[serde(deny_unknown_fields)]
        pub struct Effects {
            $(
                #[doc = concat!("`", stringify!($field), "`.")]
                #[serde(skip_serializing_if = "Option::is_none")]
                pub $field: Option<$named>,
                $(
                    #[doc = concat!("`", stringify!($field),
                        "` in its general family (exclusive with the named form).")]
                    #[serde(default, skip_serializing_if = "Option::is_none")]
                    pub $family: Option<$general>,
                )?
            )*
        }

        /// The effect identifiers of docs/model.md section 12.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum EffectKind {
            $( $(#[doc = $doc])* $kind, )*
        }

        /// Number of extra states of the rig: every row's named form's and
        /// general family's [`RigTerms::STATES`], laid out in the rows'
        /// order (each row's named form, then its general family, whether
        /// on or not).
        pub const EXT_STATES: usize =
            0 $(+ <$named as RigTerms>::STATES $(+ <$general as RigTerms>::STATES)?)*;

        /// Number of effects the diagnosis fits by a bounded search.
        const N_CATALOGUE: usize = 0 $(+ <$named as NamedEffect>::SEARCHED as usize)*;

        impl EffectKind {
            /// All effects, in the order of docs/model.md section 12.
            pub const ALL: [Self; 0 $(+ one!($kind))*] = [$(Self::$kind),*];

            /// The effects of the catalogue: each a named parametric form that
            /// the diagnosis fits by a bounded search ([`Self::ALL`] but those
            /// with fits of their own, `sensor_calibration` and `parameters`).
            pub const CATALOGUE: [Self; N_CATALOGUE] = {
                let mut out = [Self::ALL[0]; N_CATALOGUE];
                let mut i = 0;
                $(
                    if <$named as NamedEffect>::SEARCHED {
                        out[i] = Self::$kind;
                        i += 1;
                    }
                )*
                let _ = i;
                out
            };

            /// The part of the rig the effect belongs to: `seals`, `servo`,
            /// `oil`, `sensors`, `hose`, `accumulator`, or `plant` (its nominal
            /// parameters throughout).
            pub fn subsystem(self) -> &'static str {
                match self {
                    $(Self::$kind => <$named as NamedEffect>::SUBSYSTEM,)*
                }
            }

            /// The identifier of docs/model.md section 12.
            pub fn name(self) -> &'static str {
                match self {
                    $(Self::$kind => stringify!($field),)*
                }
            }

            /// The parameters, in the order [`Effects::set`] takes them.
            pub fn params(self) -> &'static [ParamSpec] {
                match self {
                    $(Self::$kind => <$named as NamedEffect>::PARAMS,)*
                }
            }

            /// What the diagnosis's `form` says of the effect's general
            /// family (`general` where it has none).
            pub fn general_form(self) -> &'static str {
                match self {
                    $(Self::$kind => {
                        $( return <$general as GeneralFamily>::FORM; )?
                        #[allow(unreachable_code)]
                        "general"
                    })*
                }
            }

            /// Whether the effect, named or general, adds compliance to the
            /// lines ([`RigTerms::ON_LINES`]): it needs an explicit hose.
            pub fn on_lines(self) -> bool {
                match self {
                    $(Self::$kind => {
                        <$named as RigTerms>::ON_LINES
                            $(|| <$general as RigTerms>::ON_LINES)?
                    })*
                }
            }

            /// How many values a least-squares fit learns for the effect's
            /// general family ([`GeneralFamily::LEARNED`]); 0 where it has
            /// none or one with a fit of its own.
            pub fn learned_len(self) -> usize {
                match self {
                    $(Self::$kind => {
                        $( return <$general as GeneralFamily>::LEARNED; )?
                        #[allow(unreachable_code)]
                        0
                    })*
                }
            }

            /// Whether [`Effects::validate`] checks the parameters against
            /// their ranges.
            fn range_checked(self) -> bool {
                match self {
                    $(Self::$kind => <$named as NamedEffect>::RANGE_CHECKED,)*
                }
            }
        }

        impl Effects {
            /// No effect: the nominal plant.
            pub const NONE: Self = Self {
                $( $field: None, $( $family: None, )? )*
            };

            /// The parameters of effect `k` if active, in [`EffectKind::params`] order.
            pub fn get(&self, k: EffectKind) -> Option<Vec<f64>> {
                match k {
                    $(EffectKind::$kind => self.$field.map(|f| f.values()),)*
                }
            }

            /// Switch effect `k` on with `v` (in [`EffectKind::params`] order;
            /// missing entries take the typical value), or off with `None`.
            pub fn set(&mut self, k: EffectKind, v: Option<&[f64]>) {
                let specs = k.params();
                match k {
                    $(EffectKind::$kind => {
                        self.$field = v.map(|v| {
                            let at = |i: usize| v.get(i).copied().unwrap_or(specs[i].typical);
                            <$named as NamedEffect>::from_values(&at)
                        })
                    })*
                }
            }

            /// Whether effect `k` is on in its general family.
            pub fn in_general_family(&self, k: EffectKind) -> bool {
                match k {
                    $(EffectKind::$kind => {
                        $( return self.$family.is_some(); )?
                        #[allow(unreachable_code)]
                        false
                    })*
                }
            }

            /// The parameters of `k` by name, as reports give them: its
            /// general family's ([`GeneralFamily::param_map`]) where that is
            /// on, else its named form's ([`NamedEffect::param_map`], or each
            /// of [`EffectKind::params`] with its value; empty when off).
            pub fn param_map(&self, k: EffectKind) -> BTreeMap<String, f64> {
                let special = match k {
                    $(EffectKind::$kind => {
                        $(
                            if let Some(g) = &self.$family {
                                return g.param_map().into_iter().collect();
                            }
                        )?
                        self.$field.and_then(|x| x.param_map())
                    })*
                };
                if let Some(m) = special {
                    return m.into_iter().collect();
                }
                k.params()
                    .iter()
                    .zip(self.get(k).unwrap_or_default())
                    .map(|(p, v)| (p.name.to_string(), v))
                    .collect()
            }

            /// Visit every active effect, named form or general family, in
            /// the rows' order, with the range of its states in the rig's
            /// extra states: each row's named form, then its general family,
            /// has the next [`RigTerms::STATES`] of them, whether on or not.
            fn visit_active<V: terms::Visit>(&self, v: &mut V) {
                let mut at = 0;
                $(
                    let n = <$named as RigTerms>::STATES;
                    if let Some(x) = &self.$field {
                        v.visit(x, at..at + n);
                    }
                    at += n;
                    $(
                        let n = <$general as RigTerms>::STATES;
                        if let Some(g) = &self.$family {
                            v.visit(g, at..at + n);
                        }
                        at += n;
                    )?
                )*
                let _ = at;
            }

            /// Only effect `k`, in its general family built from the values
            /// `x` a least-squares fit learns ([`GeneralFamily::from_learned`]);
            /// `None` where `k` has no learned general family.
            pub fn learned_family(k: EffectKind, x: &[f64]) -> Option<Self> {
                match k {
                    $(EffectKind::$kind => {
                        $(
                            return <$general as GeneralFamily>::from_learned(x).map(|g| Self {
                                $family: Some(g),
                                ..Self::NONE
                            });
                        )?
                        #[allow(unreachable_code)]
                        None
                    })*
                }
            }

            /// Every active named form's bounds beyond its ranges.
            fn check_bounds(&self) -> Result<(), EffectError> {
                $(
                    if let Some(x) = &self.$field {
                        x.check_bounds().map_err(|b| b.of(EffectKind::$kind))?;
                    }
                )*
                Ok(())
            }

            /// Each general family: valid when on, and not on together with
            /// its named form.
            fn check_families(&self) -> Result<(), EffectError> {
                $($(
                    if let Some(g) = &self.$family {
                        if self.$field.is_some() {
                            return EffectError::constraint(
                                EffectKind::$kind,
                                <$general as GeneralFamily>::BOTH,
                            );
                        }
                        if !g.family_valid() {
                            return EffectError::constraint(
                                EffectKind::$kind,
                                <$general as GeneralFamily>::REQUIREMENT,
                            );
                        }
                    }
                )?)*
                Ok(())
            }

            /// The named forms' relations between their parameters.
            fn check_named_forms(&self) -> Result<(), EffectError> {
                $(
                    if let Some(x) = &self.$field {
                        x.check_relations().map_err(|b| b.of(EffectKind::$kind))?;
                    }
                )*
                Ok(())
            }
        }
    };
}

effects! {
    /// Internal leakage.
    Leakage => leakage: Leakage, leakage_map: LeakageMap;
    /// Seal friction.
    Friction => friction: Friction, friction_map: FrictionMap;
    /// Ball-screw play.
    Backlash => backlash: Backlash, screw_map: ScrewMap;
    /// Entrained air.
    Air => air: Air;
    /// Measurement delay.
    SensorDelay => sensor_delay: SensorDelay, sensor_filter: SensorFilter;
    /// Servo limits.
    MotorLimit => motor_limit: MotorLimit, servo_envelope: ServoEnvelope;
    /// Hose hysteresis.
    HoseHysteresis => hose_hysteresis: HoseHysteresis, hose_spectrum: HysteresisSpectrum;
    /// Accumulator thermal drift.
    AccumulatorThermal => accumulator_thermal: AccumulatorThermal, gas_relaxation: GasRelaxation;
    /// A sensor's calibration.
    SensorCalibration => sensor_calibration: SensorCalibration, sensor_map: SensorMap;
    /// The nominal parameters re-estimated.
    Parameters => parameters: ParameterRatios;
}

impl EffectKind {
    /// Parse an identifier.
    pub fn by_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == s)
    }
}

impl Effects {
    /// True when no effect is active.
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// The active effects.
    pub fn active(&self) -> Vec<EffectKind> {
        EffectKind::ALL
            .into_iter()
            .filter(|k| self.get(*k).is_some())
            .collect()
    }

    /// Parse a command-line effect: `name` (typical parameters) or
    /// `name:param=value,param=value`.
    pub fn parse_arg(&mut self, s: &str) -> Result<(), EffectError> {
        let (name, rest) = s.split_once(':').unwrap_or((s, ""));
        let k = EffectKind::by_name(name.trim()).ok_or_else(|| EffectError::UnknownEffect {
            name: name.to_string(),
        })?;
        let specs = k.params();
        let mut v: Vec<f64> = specs.iter().map(|p| p.typical).collect();
        for kv in rest.split(',').filter(|s| !s.trim().is_empty()) {
            let (pn, pv) = kv
                .split_once('=')
                .ok_or_else(|| EffectError::NotParamValue {
                    effect: name.to_string(),
                    item: kv.to_string(),
                })?;
            let i = specs
                .iter()
                .position(|p| p.name == pn.trim())
                .ok_or_else(|| EffectError::UnknownParam {
                    effect: name.to_string(),
                    param: pn.to_string(),
                    kind: k,
                })?;
            v[i] = pv
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| EffectError::NotFinite {
                    effect: name.to_string(),
                    value: pv.to_string(),
                })?;
        }
        self.set(k, Some(&v));
        self.validate()
    }

    /// Check every active effect's parameters: each within its range, then
    /// the general families (valid, and never together with their named
    /// form), then the named forms' own relations; the first failure is the
    /// error.
    pub fn validate(&self) -> Result<(), EffectError> {
        self.check_ranges()?;
        self.check_families()?;
        self.check_named_forms()
    }

    /// Every parameter of an active named effect within its range, then
    /// each named form's further bounds ([`NamedEffect::check_bounds`]).
    fn check_ranges(&self) -> Result<(), EffectError> {
        for k in self.active() {
            if !k.range_checked() {
                continue;
            }
            let v = self.get(k).unwrap_or_default();
            for (x, s) in v.iter().zip(k.params()) {
                let most = VALID_SPAN * s.max;
                if !(x.is_finite() && *x >= 0.0 && *x <= most) {
                    return Err(EffectError::OutOfRange {
                        kind: k,
                        param: s.name,
                        value: *x,
                        most,
                        max: s.max,
                    });
                }
            }
        }
        self.check_bounds()
    }
}

/// A command-line effect that does not parse, or effect parameters out of range.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum EffectError {
    /// No effect has this name.
    #[error("unknown effect '{name}': expected one of {}", effect_names())]
    UnknownEffect {
        /// The name given.
        name: String,
    },
    /// A parameter item without `=`.
    #[error("effect {effect}: '{item}' is not param=value")]
    NotParamValue {
        /// The effect as named.
        effect: String,
        /// The item.
        item: String,
    },
    /// The effect has no parameter of this name.
    #[error(
        "effect {effect}: unknown parameter '{param}' (expected {})",
        param_names(*kind)
    )]
    UnknownParam {
        /// The effect as named.
        effect: String,
        /// The parameter given.
        param: String,
        /// The effect.
        kind: EffectKind,
    },
    /// A value that is not a finite number.
    #[error("effect {effect}: '{value}' is not a finite number")]
    NotFinite {
        /// The effect as named.
        effect: String,
        /// The value given.
        value: String,
    },
    /// A parameter outside [0, VALID_SPAN times its fit bound].
    #[error(
        "effect {}: {param} = {} must be in [0, {}] ({span} times the \
         largest value a fit takes, {})",
        kind.name(),
        Num(*value),
        Num(*most),
        Num(*max),
        span = VALID_SPAN
    )]
    OutOfRange {
        /// The effect.
        kind: EffectKind,
        /// The parameter.
        param: &'static str,
        /// Its value.
        value: f64,
        /// The largest value accepted.
        most: f64,
        /// The largest value a fit takes.
        max: f64,
    },
    /// The air's polytropic exponent outside [1, KAPPA_MAX].
    #[error(
        "effect air: kappa = {} must be in [1, {kappa_max:.3}] (isothermal to \
         adiabatic monatomic gas)",
        Num(*.0),
        kappa_max = KAPPA_MAX
    )]
    Kappa(f64),
    /// Parameters that break a relation the effect needs.
    #[error("effect {}: {requirement}", kind.name())]
    Constraint {
        /// The effect.
        kind: EffectKind,
        /// What must hold.
        requirement: &'static str,
    },
}

impl EffectError {
    /// `Err` of a broken relation of effect `kind`.
    fn constraint<T>(kind: EffectKind, requirement: &'static str) -> Result<T, Self> {
        Err(Self::Constraint { kind, requirement })
    }
}

impl Broken {
    /// The error of effect `kind` whose parameters break this.
    fn of(self, kind: EffectKind) -> EffectError {
        match self {
            Self::Requirement(requirement) => EffectError::Constraint { kind, requirement },
            Self::Kappa(kappa) => EffectError::Kappa(kappa),
        }
    }
}

fn effect_names() -> String {
    let all: Vec<&str> = EffectKind::ALL.iter().map(|k| k.name()).collect();
    all.join(", ")
}

fn param_names(kind: EffectKind) -> String {
    let all: Vec<&str> = kind.params().iter().map(|p| p.name).collect();
    all.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The range of the rig's extra states that the one active effect of
    /// `e` owns.
    fn own_states(e: &Effects) -> std::ops::Range<usize> {
        use terms::RigTerms;
        struct Own(Vec<std::ops::Range<usize>>);
        impl terms::Visit for Own {
            fn visit<T: RigTerms>(&mut self, _: &T, at: std::ops::Range<usize>) {
                self.0.push(at);
            }
        }
        let mut own = Own(Vec::new());
        e.visit_active(&mut own);
        assert_eq!(own.0.len(), 1, "one active effect");
        own.0.remove(0)
    }

    /// At the replay's plant step (0.5 ms) a load step moves the pressure
    /// by many of the smallest element's yields in one step, where RK4
    /// alone overshoots the hysteretic pressure and diverges: each element
    /// stays within its yield and the rig stays finite, for the named form
    /// at its smallest yield as for the spectrum (line 1's elements, then
    /// line 2's).
    #[test]
    fn hysteretic_pressures_stay_within_their_yields_on_fast_load_steps() {
        use crate::model::plant::Plant;
        use crate::model::rig::Rig;
        let spectrum = Effects {
            hose_spectrum: Some(HysteresisSpectrum {
                c_m3pp: [1e-13; 5],
                stop_c_m3pp: [1e-13; 5],
            }),
            ..Effects::NONE
        };
        let mut named = Effects::NONE;
        named.set(EffectKind::HoseHysteresis, Some(&[1e-13, 0.0, 1e3]));
        for (e, yields) in [(spectrum, &SPECTRUM_YIELDS_PA[..]), (named, &[1e3][..])] {
            let own = own_states(&e);
            assert_eq!(own.len(), 2 * yields.len());
            let r = Rig::new(Plant::nominal(), e).unwrap();
            let mut s = r.initial_state(0.0);
            let mut moved = [0.0f64; 2];
            for k in 0..2000 {
                let ft = if (k / 100) % 2 == 1 { 1500.0 } else { 0.0 };
                r.step(&mut s, 0.0, ft, 5e-4);
                assert!(s.is_finite(), "step {k}");
                let z = &s.ext.values()[own.clone()];
                for (i, zi) in z.iter().enumerate() {
                    let y = yields[i % yields.len()];
                    assert!(zi.abs() <= y, "step {k}, element {i}: {zi} beyond {y}");
                    moved[i / yields.len()] = moved[i / yields.len()].max(zi.abs() / y);
                }
            }
            // On each line some element was driven to its yield.
            assert!(moved.iter().all(|m| *m > 0.99), "{moved:?}");
        }
    }

    #[test]
    fn parse_and_set_round_trip() {
        let mut e = Effects::NONE;
        assert!(e.is_none());
        e.parse_arg("leakage:g_m3pspa=2e-13").unwrap();
        e.parse_arg("friction").unwrap();
        assert_eq!(e.get(EffectKind::Leakage), Some(vec![2e-13, 1.0]));
        assert_eq!(e.get(EffectKind::Friction).unwrap()[0], 30.0);
        assert_eq!(e.active(), vec![EffectKind::Leakage, EffectKind::Friction]);
        e.set(EffectKind::Leakage, None);
        assert_eq!(e.active(), vec![EffectKind::Friction]);
        for bad in [
            "magic",
            "leakage:g=1",
            "leakage:g_m3pspa=x",
            "air:fraction=-1",
            "motor_limit:mass_eq_kg=0",
            "leakage:exponent=0",
            "backlash:stiffness_npm=0",
            "hose_hysteresis:stuck_share=1.5",
        ] {
            let mut e = Effects::NONE;
            assert!(e.parse_arg(bad).is_err(), "{bad}");
        }
        let toml: Effects =
            toml::from_str("[air]\nfraction = 0.01\n[backlash]\nplay_m = 1e-4\n").unwrap();
        assert_eq!(toml.air.unwrap().kappa, 1.4);
        assert_eq!(toml.backlash.unwrap().play_m, 1e-4);
        assert!(toml::from_str::<Effects>("[air]\nfractoin = 0.01\n").is_err());
    }

    #[test]
    fn every_effect_has_params_within_bounds() {
        for k in EffectKind::ALL {
            assert_eq!(EffectKind::by_name(k.name()), Some(k));
            for s in k.params() {
                assert!(
                    s.min <= s.typical && s.typical <= s.max,
                    "{} {}",
                    k.name(),
                    s.name
                );
            }
            let mut e = Effects::NONE;
            e.set(k, Some(&[]));
            assert_eq!(e.active(), vec![k]);
            assert_eq!(
                e.get(k).unwrap(),
                k.params().iter().map(|p| p.typical).collect::<Vec<_>>()
            );
            e.validate().unwrap();
        }
    }

    /// Every learned general family, from zero (the nominal model) and from
    /// the top of the fit's range, is a valid family of its own effect,
    /// with no other effect on; the screw map's learned values give it
    /// back.
    #[test]
    fn learned_families_build_from_their_values() {
        let mut learned = Vec::new();
        for k in EffectKind::ALL {
            let n = k.learned_len();
            if n == 0 {
                assert_eq!(Effects::learned_family(k, &[]), None, "{}", k.name());
                continue;
            }
            learned.push(k);
            for x in [0.0, 50.0] {
                let e = Effects::learned_family(k, &vec![x; n]).unwrap();
                assert!(e.in_general_family(k), "{}", k.name());
                assert!(EffectKind::ALL
                    .into_iter()
                    .all(|o| o == k || e.param_map(o).is_empty()));
                e.validate().unwrap();
            }
        }
        assert_eq!(learned.len(), 5, "{learned:?}");
        let x = [3.0, 0.0, 1.5, 2.0, 0.0, 7.0];
        let screw = Effects::learned_family(EffectKind::Backlash, &x)
            .and_then(|e| e.screw_map)
            .unwrap();
        let back = screw.to_learned().unwrap();
        for (a, b) in back.iter().zip(x) {
            // The first increment carries the map's 1 nm floor.
            assert!((a - b).abs() < 1.1e-4, "{back:?}");
        }
    }

    #[test]
    fn leakage_exponent_bends_the_flow_law() {
        let lam = Leakage {
            g_m3pspa: 1e-13,
            exponent: 1.0,
        };
        let orifice = Leakage {
            exponent: 0.5,
            ..lam
        };
        // Both give about G x 1 MPa at 1 MPa; the orifice law grows as sqrt(dP).
        let q = |l: &Leakage, dp: f64| leak_flow_m3ps(l, dp, 0.0);
        assert_eq!(q(&lam, 4e6), 1e-13 * 4e6);
        assert!((q(&orifice, 1e6) / 1e-7 - 1.0).abs() < 0.01);
        assert!((q(&orifice, 4e6) / q(&orifice, 1e6) - 2.0).abs() < 0.01);
        assert_eq!(q(&orifice, -4e6), -q(&orifice, 4e6));
        assert_eq!(q(&orifice, 0.0), 0.0);
    }

    #[test]
    fn seal_maps_take_the_named_forms_and_more() {
        // A flat friction map is Coulomb friction; the pressure term adds
        // k (P1 + P2) / 1 MPa.
        let coulomb = Friction {
            coulomb_n: 40.0,
            static_n: 40.0,
            stribeck_mps: 2e-3,
        };
        let flat = FrictionMap {
            force_n: [40.0; 6],
            n_per_mpa: 0.0,
        };
        for v in [-0.2, -0.01, -1e-4, 0.0, 3e-5, 1e-3, 0.05, 0.3] {
            assert_eq!(
                flat.force(v, 2e6, 1e6),
                friction_force_n(&coulomb, v),
                "{v}"
            );
        }
        let pressed = FrictionMap {
            n_per_mpa: 5.0,
            ..flat
        };
        assert!((pressed.force(0.01, 2e6, 1e6) + 55.0).abs() < 1e-9);
        // Between knots the magnitude is linear; beyond the last, flat.
        let curve = FrictionMap {
            force_n: [60.0, 40.0, 30.0, 30.0, 50.0, 90.0],
            n_per_mpa: 0.0,
        };
        assert!((curve.force(1.25e-3, 0.0, 0.0) + 35.0).abs() < 1e-9);
        assert!((curve.force(-0.5, 0.0, 0.0) - 90.0).abs() < 1e-9);
        // A straight leakage map is the named laminar leakage; the level
        // term adds g dP (P1 + P2) / (2 MPa); the flow is odd in dP.
        let laminar = Leakage {
            g_m3pspa: 1e-13,
            exponent: 1.0,
        };
        let straight = LeakageMap {
            q_m3ps: std::array::from_fn(|i| 1e-13 * LEAK_DP_PA[i + 1]),
            g_m3pspa: 0.0,
        };
        for (p1, p2) in [
            (3e6, 1e6),
            (1e6, 3e6),
            (7e6, 0.0),
            (2e6, 2e6),
            (1.3e6, 1.2e6),
        ] {
            let (a, b) = (straight.flow(p1, p2), leak_flow_m3ps(&laminar, p1, p2));
            assert!(
                (a - b).abs() <= 1e-12 * b.abs().max(1e-12),
                "{p1} {p2}: {a} {b}"
            );
        }
        let level = LeakageMap {
            g_m3pspa: 2e-14,
            ..straight
        };
        let extra = level.flow(3e6, 1e6) - straight.flow(3e6, 1e6);
        assert!((extra - 2e-14 * 2e6 * 2.0).abs() < 1e-20);
        assert_eq!(level.flow(1e6, 3e6), -level.flow(3e6, 1e6));
        // Negative or non-finite values are refused.
        let mut e = Effects::NONE;
        e.friction_map = Some(FrictionMap {
            n_per_mpa: -1.0,
            ..flat
        });
        assert!(e.validate().is_err());
        e.friction_map = Some(flat);
        e.friction = Some(coulomb);
        assert!(
            e.validate().is_err(),
            "named and general exclude each other"
        );
    }

    #[test]
    fn servo_envelope_limits_motoring_by_speed_and_braking_at_rest_force() {
        let s = ServoEnvelope {
            mass_eq_kg: 100.0,
            force_n: [1000.0, 1000.0, 800.0, 400.0, 0.0, 0.0],
            accel_max_mps2: None,
            speed_loop: None,
            command_map: None,
        };
        assert!(s.is_valid());
        assert_eq!(s.available_n(0.0), 1000.0);
        assert!((s.available_n(-0.05) - 600.0).abs() < 1e-9);
        assert_eq!(s.available_n(0.2), 0.0);
        // Motoring at 50 mm/s against 300 N: 600 N available, 3 m/s^2.
        assert!((s.accel(50.0, 0.05, 300.0) - 3.0).abs() < 1e-12);
        // Braking from 50 mm/s: the force at rest (1000 N) against 300 N.
        assert!((s.accel(-50.0, 0.05, 300.0) + 13.0).abs() < 1e-12);
        // Small requests are met; at 80 mm/s nothing is left to push on.
        assert_eq!(s.accel(1.0, 0.05, 0.0), 1.0);
        assert!(s.accel(10.0, 0.08, 0.0).abs() < 1e-12);
        // A ramp clamps what the loop asks for before the force does.
        let ramped = ServoEnvelope {
            accel_max_mps2: Some(2.0),
            speed_loop: None,
            ..s
        };
        assert_eq!(ramped.accel(50.0, 0.05, 300.0), 2.0);
        assert_eq!(ramped.accel(-50.0, 0.05, 300.0), -2.0);
        assert_eq!(ramped.accel(1.0, 0.05, 0.0), 1.0);
        assert!(ramped.accel(10.0, 0.08, 0.0).abs() < 1e-12);
        // A constant envelope is the named force limit without a speed cap.
        let flat = ServoEnvelope {
            mass_eq_kg: 100.0,
            force_n: [500.0; 6],
            accel_max_mps2: None,
            speed_loop: None,
            command_map: None,
        };
        let m = MotorLimit {
            force_max_n: 500.0,
            mass_eq_kg: 100.0,
            speed_max_mps: 0.1,
        };
        for (a, v, f) in [
            (50.0, 0.03, 300.0),
            (-50.0, 0.03, 300.0),
            (2.0, -0.01, -100.0),
        ] {
            assert_eq!(flat.accel(a, v, f), motor_accel(&m, a, f));
        }
        // Rising envelopes and the two servo models at once are refused.
        let mut e = Effects::NONE;
        e.servo_envelope = Some(ServoEnvelope {
            mass_eq_kg: 100.0,
            force_n: [500.0, 600.0, 0.0, 0.0, 0.0, 0.0],
            accel_max_mps2: None,
            speed_loop: None,
            command_map: None,
        });
        assert!(e.validate().is_err());
        e.servo_envelope = Some(flat);
        assert!(e.validate().is_ok());
        e.set(EffectKind::MotorLimit, Some(&[500.0, 100.0, 0.1]));
        assert!(e.validate().is_err());
    }

    /// The drive's own speed loop: unsaturated and fast, the nominal servo
    /// up to its lag; saturated, a windup integrator catches up on the lost
    /// position afterwards (the speed overshoots the reference) where a
    /// held one does not; invalid loops are refused.
    #[test]
    fn a_speed_loop_follows_the_nominal_servo_and_winds_up_when_clamped() {
        let tau = dca_core::params::PlantParams::NOMINAL.tau_m_s;
        let run = |env: &ServoEnvelope, f_load_n: f64| -> (f64, f64, f64) {
            // 0.1 m/s commanded for 0.3 s from rest, midpoint steps of 0.1 ms;
            // the largest speed over the reference, the speed and the
            // nominal servo's at 0.3 s.
            let (mut v, mut own, mut v_nom, mut over) = (0.0, [0.0, f_load_n], 0.0, 0.0f64);
            let h = 1e-4;
            for _ in 0..3000 {
                let r = |v: f64, own: [f64; 2]| {
                    servo_rates(Servo::Envelope(env), (0.1, tau), v, f_load_n, own)
                };
                let (a1, d1) = r(v, own);
                let om = [own[0] + 0.5 * h * d1[0], own[1] + 0.5 * h * d1[1]];
                let (a2, d2) = r(v + 0.5 * h * a1, om);
                v += h * a2;
                own = [own[0] + h * d2[0], own[1] + h * d2[1]];
                v_nom += h * (0.1 - (v_nom + 0.5 * h * (0.1 - v_nom) / tau)) / tau;
                over = over.max(v - own[0]);
            }
            (over, v, v_nom)
        };
        let lp = SpeedLoop {
            bandwidth_radps: 2000.0,
            integral_radps: 200.0,
            windup: true,
            damping_nspm: 1000.0,
        };
        let strong = ServoEnvelope {
            mass_eq_kg: 50.0,
            force_n: [1e5; 6],
            accel_max_mps2: None,
            speed_loop: Some(lp),
            command_map: None,
        };
        assert!(strong.is_valid());
        let (over, v, v_nom) = run(&strong, 400.0);
        assert!(
            over < 1e-3 && (v - v_nom).abs() < 1e-3,
            "{over} {v} {v_nom}"
        );
        // 600 N against a 400 N load and 100 N of loss at full speed: the
        // start is clamped, then the integrator drives the speed past the
        // reference; held, it does not.
        let weak = ServoEnvelope {
            force_n: [600.0; 6],
            ..strong
        };
        let (over_windup, _, _) = run(&weak, 400.0);
        let held = ServoEnvelope {
            speed_loop: Some(SpeedLoop {
                windup: false,
                ..lp
            }),
            ..weak
        };
        let (over_held, _, _) = run(&held, 400.0);
        assert!(over_windup > 5e-3, "{over_windup}");
        assert!(over_held < 0.5 * over_windup, "{over_held} {over_windup}");
        for bad in [
            SpeedLoop {
                bandwidth_radps: 1e4,
                ..lp
            },
            SpeedLoop {
                integral_radps: 3000.0,
                ..lp
            },
            SpeedLoop {
                damping_nspm: -1.0,
                ..lp
            },
        ] {
            let e = ServoEnvelope {
                speed_loop: Some(bad),
                ..strong
            };
            assert!(!e.is_valid(), "{bad:?}");
        }
    }

    #[test]
    fn motor_force_limit_depends_on_the_load() {
        let m = MotorLimit {
            force_max_n: 500.0,
            mass_eq_kg: 100.0,
            speed_max_mps: 0.1,
        };
        // Free: +-5 m/s^2. Against 300 N: 2 m/s^2 out, 8 m/s^2 back.
        assert_eq!(motor_accel(&m, 50.0, 0.0), 5.0);
        assert_eq!(motor_accel(&m, 1.0, 0.0), 1.0);
        assert!((motor_accel(&m, 50.0, 300.0) - 2.0).abs() < 1e-12);
        assert!((motor_accel(&m, -50.0, 300.0) + 8.0).abs() < 1e-12);
        // Beyond the stall force the screw is pushed back.
        assert!(motor_accel(&m, 0.0, 800.0) < 0.0);
    }

    #[test]
    fn backlash_flank_follows_the_force() {
        let b = Backlash {
            play_m: 100e-6,
            stiffness_npm: 1e7,
        };
        assert_eq!(backlash_offset_m(&b, 0.0), 0.0);
        assert!((backlash_offset_m(&b, 500.0) - (50e-6 + 50e-6)).abs() < 1e-9);
        assert!((backlash_offset_m(&b, -500.0) + 100e-6).abs() < 1e-9);
    }

    #[test]
    fn friction_opposes_motion_with_breakaway_peak() {
        let f = Friction {
            coulomb_n: 30.0,
            static_n: 45.0,
            stribeck_mps: 2e-3,
        };
        assert_eq!(friction_force_n(&f, 0.0), 0.0);
        assert!(friction_force_n(&f, 1e-3) < -40.0);
        assert!((friction_force_n(&f, 0.05) + 30.0).abs() < 1e-6);
        assert!((friction_force_n(&f, -0.05) - 30.0).abs() < 1e-6);
    }

    #[test]
    fn air_softens_most_at_low_pressure() {
        let a = Air {
            fraction: 0.005,
            kappa: 1.4,
        };
        let beta = |p: f64| 1.0 / compressibility_ppa(&a, 1.2e9, p, 101_325.0);
        assert!(beta(0.5e6) < 0.6e9, "{}", beta(0.5e6));
        assert!(beta(3.0e6) > beta(0.5e6) * 2.0);
        assert!(beta(3.0e6) < 1.2e9);
        let none = Air {
            fraction: 0.0,
            kappa: 1.4,
        };
        assert_eq!(
            compressibility_ppa(&none, 1.2e9, 1e6, 101_325.0),
            1.0 / 1.2e9
        );
    }

    #[test]
    fn hysteresis_engages_after_the_pressure_moves_on() {
        let h = HoseHysteresis {
            c_m3pp: 1e-13,
            stuck_share: 0.5,
            yield_pa: 1e5,
        };
        // Rising pressure from z = 0: half engaged, then saturating towards 1.
        let mut z = 0.0;
        assert_eq!(hysteresis_engagement(&h, z, 1.0), 0.5);
        for _ in 0..1000 {
            z += hysteresis_rate(&h, z, 1e3) * 1.0e-3 * 1e3;
        }
        assert!(z > 0.99e5 && z <= 1e5, "{z}");
        assert!(hysteresis_engagement(&h, z, 1.0) > 0.99);
        // Right after the reversal: not engaged.
        assert!(hysteresis_engagement(&h, z, -1.0) < 0.01);
        assert_eq!(hysteresis_rate(&h, 1e5, 5.0), 0.0);
        assert_eq!(hysteresis_rate(&h, 1e5, -5.0), -10.0);
    }

    #[test]
    fn backlash_compliance_is_the_offset_slope() {
        let b = Backlash {
            play_m: 100e-6,
            stiffness_npm: 1e7,
        };
        for f in [-300.0, -5.0, 0.0, 3.0, 40.0, 800.0] {
            let num = (backlash_offset_m(&b, f + 1e-4) - backlash_offset_m(&b, f - 1e-4)) / 2e-4;
            let g = backlash_compliance_mpn(&b, f);
            assert!((num - g).abs() <= 1e-6 * g, "{f}: {num:e} vs {g:e}");
        }
    }
}
