//! The coupling between the motor and the power piston: the named `backlash`
//! and its general family, the screw map.

use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, GeneralFamily, NamedEffect, ParamSpec};
use super::terms::{PowerPiston, Rest, RigTerms};

use super::common::{interp, segment};

/// Play between motor and power piston.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Backlash {
    /// Total play, m.
    pub play_m: f64,
    /// Axial stiffness of the screw, nut and coupling, N/m.
    #[serde(default = "default_stiffness")]
    pub stiffness_npm: f64,
}

fn default_stiffness() -> f64 {
    2e7
}

/// Force over which the piston crosses from one flank of the play to the other, N.
pub const BACKLASH_FLANK_N: f64 = 10.0;

/// Offset of the motor ahead of the power piston under the backlash when
/// the hydraulic force `f_load_n` (positive opposing extension) holds the
/// piston against a flank, m: (play / 2) tanh(F / F_flank) + F / k.
pub fn backlash_offset_m(b: &Backlash, f_load_n: f64) -> f64 {
    0.5 * b.play_m * libm::tanh(f_load_n / BACKLASH_FLANK_N) + f_load_n / b.stiffness_npm
}

/// Derivative of [`backlash_offset_m`] with respect to the force, m/N.
pub fn backlash_compliance_mpn(b: &Backlash, f_load_n: f64) -> f64 {
    let t = libm::tanh(f_load_n / BACKLASH_FLANK_N);
    0.5 * b.play_m * (1.0 - t * t) / BACKLASH_FLANK_N + 1.0 / b.stiffness_npm
}

/// Forces of the knots of a [`ScrewMap`], N (0 first): dense where a play is
/// crossed, up to the power piston's force under the largest loads.
pub const SCREW_FORCES_N: [f64; 7] = [0.0, 10.0, 30.0, 100.0, 300.0, 1000.0, 3000.0];

/// Largest deflection a [`ScrewMap`] may give at a knot, m.
pub const SCREW_DEFLECTION_MAX_M: f64 = 0.02;

/// The general family of `backlash` (the coupling between the motor and the
/// power piston in any shape): the power piston sits behind the motor (the
/// encoder's Xi) by `D(F)`, F the hydraulic force on it, `D` odd and
/// non-decreasing, `D(F) = sign(F) L(abs(F))` with `L` piecewise linear
/// through 0 at 0 and `deflection_m` at the knots [`SCREW_FORCES_N`]
/// (extended along its last segment). A steep first segment is a play
/// crossed where the force turns; a straight `L` a linear spring (the named
/// form's stiffness); one that flattens with force a Hertzian contact, one
/// that steepens a preload that gives.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ScrewMap {
    /// `L` at the knots after the first, m (non-negative, non-decreasing).
    pub deflection_m: [f64; 6],
}

impl ScrewMap {
    /// `L` at every knot of [`SCREW_FORCES_N`] (0 at 0 N), m.
    fn knots_m(&self) -> [f64; 7] {
        let mut d = [0.0; 7];
        d[1..].copy_from_slice(&self.deflection_m);
        d
    }

    /// The deflection `D(F)` of the power piston behind the motor, m.
    pub fn offset_m(&self, f_n: f64) -> f64 {
        interp(&SCREW_FORCES_N, &self.knots_m(), f_n.abs(), false).copysign(f_n)
    }

    /// The derivative of [`Self::offset_m`] with respect to the force, m/N.
    pub fn compliance_mpn(&self, f_n: f64) -> f64 {
        let (xs, ys) = (&SCREW_FORCES_N, self.knots_m());
        let i = segment(xs, f_n.abs());
        (ys[i + 1] - ys[i]) / (xs[i + 1] - xs[i])
    }

    /// Whether the map is usable: deflections finite, non-negative,
    /// non-decreasing, at most [`SCREW_DEFLECTION_MAX_M`], the first
    /// positive (a coupling with no compliance at all is the nominal rig).
    pub fn is_valid(&self) -> bool {
        let d = &self.deflection_m;
        d.iter()
            .all(|x| x.is_finite() && (0.0..=SCREW_DEFLECTION_MAX_M).contains(x))
            && d.windows(2).all(|w| w[1] >= w[0])
            && d[0] > 0.0
    }
}

impl NamedEffect for Backlash {
    const SUBSYSTEM: &'static str = "servo";
    const PARAMS: &'static [ParamSpec] = &[
        p("play_m", 50e-6, 0.0, 2e-3),
        p("stiffness_npm", 2e7, 1e6, 1e10),
    ];
    fn values(&self) -> Vec<f64> {
        vec![self.play_m, self.stiffness_npm]
    }
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        Self {
            play_m: at(0),
            stiffness_npm: at(1),
        }
    }
    fn check_relations(&self) -> Result<(), Broken> {
        if self.stiffness_npm <= 0.0 {
            return Err(Broken::Requirement("stiffness_npm must be > 0"));
        }
        Ok(())
    }
}

impl GeneralFamily for ScrewMap {
    const FORM: &'static str =
        "general: the coupling's deflection of any shape over the force on the power piston (play, spring, contact)";
    const BOTH: &'static str = "the named form and the screw map exclude each other";
    const REQUIREMENT: &'static str =
        "screw_map: deflection_m finite, non-negative, non-decreasing, the first > 0, \
         each at most 0.02 m";
    fn family_valid(&self) -> bool {
        self.is_valid()
    }
    fn param_map(&self) -> Vec<(String, f64)> {
        SCREW_FORCES_N[1..]
            .iter()
            .zip(self.deflection_m)
            .map(|(f, d)| (format!("deflection_m_at_{f:.0}_n"), d))
            .collect()
    }
    /// The deflection's increments between the knots in units of 10 um
    /// (so that it never falls), the first at least 1 nm (a map needs some
    /// compliance there).
    const LEARNED: usize = 6;
    fn from_learned(x: &[f64]) -> Option<Self> {
        const UNIT_M: f64 = 1e-5;
        let mut d = [0.0; 6];
        let mut acc = 1e-9;
        for (di, xi) in d.iter_mut().zip(x) {
            acc += xi.max(0.0) * UNIT_M;
            *di = acc;
        }
        Some(Self { deflection_m: d })
    }
    /// The increments of the deflection over the running largest, in
    /// units of 10 um.
    fn to_learned(&self) -> Option<Vec<f64>> {
        let mut prev = 0.0;
        let steps = self.deflection_m.iter().map(|d| {
            let step = (d - prev).max(0.0);
            prev = prev.max(*d);
            step / 1e-5
        });
        Some(steps.collect())
    }
}

/// A coupling between the motor and the power piston, whose position is
/// the one state.
impl RigTerms for Backlash {
    const STATES: usize = 1;
    /// The power piston on the flank the hydraulic force holds it against.
    fn rest_states(&self, rest: &Rest, own: &mut [f64]) {
        own[0] = rest.xi_m - backlash_offset_m(self, rest.piston_force_n);
    }
    fn coupling(&self, own: &[f64], f_n: f64) -> Option<PowerPiston> {
        Some(PowerPiston {
            xp_m: own[0],
            compliance_mpn: backlash_compliance_mpn(self, f_n),
        })
    }
    fn power_piston_rates(&self, vp_mps: f64, rates: &mut [f64]) {
        rates[0] = vp_mps;
    }
}

/// A coupling between the motor and the power piston, whose position is
/// the one state.
impl RigTerms for ScrewMap {
    const STATES: usize = 1;
    /// The power piston deflected by the hydraulic force.
    fn rest_states(&self, rest: &Rest, own: &mut [f64]) {
        own[0] = rest.xi_m - self.offset_m(rest.piston_force_n);
    }
    fn coupling(&self, own: &[f64], f_n: f64) -> Option<PowerPiston> {
        Some(PowerPiston {
            xp_m: own[0],
            compliance_mpn: self.compliance_mpn(f_n),
        })
    }
    fn power_piston_rates(&self, vp_mps: f64, rates: &mut [f64]) {
        rates[0] = vp_mps;
    }
}
