//! The hose wall: its named hysteresis (`hose_hysteresis`) and its general
//! family, the hysteresis spectrum.

use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, GeneralFamily, NamedEffect, ParamSpec, VALID_SPAN};
use super::terms::{Line, RigTerms};

/// Rate-independent hose-wall hysteresis.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HoseHysteresis {
    /// Compliance added while the play is engaged, m^3/Pa.
    pub c_m3pp: f64,
    /// Share of the hose wall compliance held while the play is not engaged (0 to 1).
    #[serde(default)]
    pub stuck_share: f64,
    /// Pressure change after a reversal over which the wall yields, Pa.
    pub yield_pa: f64,
}

/// Engagement of the hose hysteresis (0 just after a pressure reversal, 1
/// once the wall has yielded) for the hysteretic pressure `z_pa` and the
/// direction of the line pressure's rate `dp`.
pub fn hysteresis_engagement(h: &HoseHysteresis, z_pa: f64, dp: f64) -> f64 {
    let sigma = if dp > 0.0 {
        1.0
    } else if dp < 0.0 {
        -1.0
    } else {
        0.0
    };
    (0.5 * (1.0 + sigma * z_pa / h.yield_pa)).clamp(0.0, 1.0)
}

/// Rate of the hysteretic pressure: dz = dP - abs(dP) z / r.
pub fn hysteresis_rate(h: &HoseHysteresis, z_pa: f64, dp: f64) -> f64 {
    dp - dp.abs() * z_pa / h.yield_pa
}

/// The hysteretic pressure `z_pa` within +-`yield_pa`, the set its exact
/// solution never leaves (a NaN stays NaN: a diverged replay is told by it).
fn within_yield(z_pa: f64, yield_pa: f64) -> f64 {
    z_pa.clamp(-yield_pa, yield_pa)
}

/// Yields of the elements of a [`HysteresisSpectrum`], Pa: two per decade
/// from 10 kPa to 1 MPa.
pub const SPECTRUM_YIELDS_PA: [f64; 5] = [1e4, 3e4, 1e5, 3e5, 1e6];

/// The general family of the hose wall (`hose_hysteresis` in any shape): a
/// discrete Prandtl-Ishlinskii operator on each line's pressure, of both
/// kinds. Element i is a hysteretic pressure of yield
/// [`SPECTRUM_YIELDS_PA`]`[i]` (the Dahl element of the named form) with
/// its engagement e_i, 0 right after a pressure reversal and 1 once the
/// pressure has moved on by a few yields. It adds the compliance
/// `c_m3pp[i]` as far as it is engaged (a play: a wall that gives only once
/// it slips) and `stop_c_m3pp[i]` as far as it is not (a stop: a wall that
/// gives right after a reversal and locks once the pressure has moved on,
/// e.g. a braid slipping in its cover). The weights, learned from the runs,
/// shape the loop: narrow loops from small yields, wide ones from large.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HysteresisSpectrum {
    /// Compliance of each element when engaged (play), m^3/Pa (non-negative).
    pub c_m3pp: [f64; 5],
    /// Compliance of each element while not engaged (stop), m^3/Pa
    /// (non-negative; zero where absent).
    #[serde(default)]
    pub stop_c_m3pp: [f64; 5],
}

impl HysteresisSpectrum {
    /// Plays only: the compliances `c_m3pp`, no stops.
    pub fn plays(c_m3pp: [f64; 5]) -> Self {
        Self {
            c_m3pp,
            stop_c_m3pp: [0.0; 5],
        }
    }

    /// Element `i` as a Dahl element of the named form (its play's
    /// compliance; the yield its hysteretic pressure follows).
    pub fn element(&self, i: usize) -> HoseHysteresis {
        HoseHysteresis {
            c_m3pp: self.c_m3pp[i],
            stuck_share: 0.0,
            yield_pa: SPECTRUM_YIELDS_PA[i],
        }
    }

    /// The compliance element `i` adds, m^3/Pa, at its hysteretic pressure
    /// `z_pa` with the line pressure moving in the direction of `dp`: the
    /// play's as far as it is engaged, the stop's as far as it is not.
    pub fn compliance_m3pp(&self, i: usize, z_pa: f64, dp: f64) -> f64 {
        let e = hysteresis_engagement(&self.element(i), z_pa, dp);
        e * self.c_m3pp[i] + (1.0 - e) * self.stop_c_m3pp[i]
    }
}

impl NamedEffect for HoseHysteresis {
    const SUBSYSTEM: &'static str = "hose";
    const PARAMS: &'static [ParamSpec] = &[
        p("c_m3pp", 2e-13, 0.0, 5e-12),
        p("stuck_share", 0.0, 0.0, 1.0),
        p("yield_pa", 1e5, 1e3, 2e6),
    ];
    fn values(&self) -> Vec<f64> {
        vec![self.c_m3pp, self.stuck_share, self.yield_pa]
    }
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        Self {
            c_m3pp: at(0),
            stuck_share: at(1),
            yield_pa: at(2),
        }
    }
    fn check_relations(&self) -> Result<(), Broken> {
        if self.stuck_share > 1.0 || self.yield_pa <= 0.0 {
            return Err(Broken::Requirement(
                "stuck_share must be <= 1 and yield_pa > 0",
            ));
        }
        Ok(())
    }
}

impl GeneralFamily for HysteresisSpectrum {
    const FORM: &'static str =
        "general: a Prandtl-Ishlinskii spectrum of the hose wall (plays and stops at five yields, 10 kPa to 1 MPa)";
    const BOTH: &'static str = "the named form and the hysteresis spectrum exclude each other";
    const REQUIREMENT: &'static str =
        "hose_spectrum: every c_m3pp and stop_c_m3pp must be >= 0 and at most 5e-11";
    /// Every compliance within [0, VALID_SPAN times the named form's largest].
    fn family_valid(&self) -> bool {
        let most = VALID_SPAN * HoseHysteresis::PARAMS[0].max;
        self.c_m3pp
            .iter()
            .chain(&self.stop_c_m3pp)
            .all(|c| c.is_finite() && (0.0..=most).contains(c))
    }
    fn param_map(&self) -> Vec<(String, f64)> {
        let at = |kind: &str, c: [f64; 5]| {
            SPECTRUM_YIELDS_PA
                .iter()
                .zip(c)
                .map(|(y, c)| (format!("{kind}_at_yield_{y:.0e}_pa"), c))
                .collect::<Vec<_>>()
        };
        let mut m = at("c_m3pp", self.c_m3pp);
        m.extend(at("stop_c_m3pp", self.stop_c_m3pp));
        m
    }
    /// The plays' compliances, then the stops', in units of 1e-13 m^3/Pa.
    const LEARNED: usize = 2 * SPECTRUM_YIELDS_PA.len();
    fn from_learned(x: &[f64]) -> Option<Self> {
        const UNIT: f64 = 1e-13;
        const N: usize = SPECTRUM_YIELDS_PA.len();
        Some(Self {
            c_m3pp: std::array::from_fn(|i| x[i].max(0.0) * UNIT),
            stop_c_m3pp: std::array::from_fn(|i| x[N + i].max(0.0) * UNIT),
        })
    }
}

/// A hysteretic pressure per line (the states: line 1's, line 2's) whose
/// engagement adds the compliance and holds the stuck share of the wall's.
impl RigTerms for HoseHysteresis {
    const STATES: usize = 2;
    const ON_LINES: bool = true;
    /// The stuck share lowers the line capacitance and so shortens the
    /// fastest mode's period (the actuating piston against the lines'
    /// hydraulic stiffness); taken at the softest wall.
    fn step_scale(&self, c_oil_m3pp: f64, c_wall_m3pp: f64) -> Option<f64> {
        let (c_oil, c_wall) = (c_oil_m3pp, c_wall_m3pp);
        Some(((c_oil + (1.0 - self.stuck_share) * c_wall) / (c_oil + c_wall)).clamp(0.01, 1.0))
    }
    fn add_line_compliance(&self, line: &mut Line<'_>, own: &[f64], rates: &mut [f64]) {
        let z = own[line.index];
        let engaged = hysteresis_engagement(self, z, line.dp_paps());
        let stuck = (1.0 - engaged) * self.stuck_share * line.c_wall_m3pp;
        line.add_compliance([engaged * self.c_m3pp - stuck]);
        rates[line.index] = hysteresis_rate(self, z, line.dp_paps());
    }
    /// Each line's hysteretic pressure within +-yield.
    fn keep_states(&self, own: &mut [f64]) {
        for z in own.iter_mut() {
            *z = within_yield(*z, self.yield_pa);
        }
    }
}

/// Each element's hysteretic pressure per line (the states: line 1's five,
/// then line 2's) whose engagement weighs its play's and its stop's
/// compliances.
impl RigTerms for HysteresisSpectrum {
    const STATES: usize = 2 * SPECTRUM_YIELDS_PA.len();
    const ON_LINES: bool = true;
    fn add_line_compliance(&self, line: &mut Line<'_>, own: &[f64], rates: &mut [f64]) {
        const N: usize = SPECTRUM_YIELDS_PA.len();
        let at = N * line.index;
        let z: [f64; N] = std::array::from_fn(|i| own[at + i]);
        // Engagement from the direction before the elements act (as the
        // named form); the compliances add up.
        let dp0 = line.dp_paps();
        line.add_compliance(std::array::from_fn::<_, N, _>(|i| {
            self.compliance_m3pp(i, z[i], dp0)
        }));
        let dp = line.dp_paps();
        for (i, zi) in z.iter().enumerate() {
            rates[at + i] = hysteresis_rate(&self.element(i), *zi, dp);
        }
    }
    /// Each element's hysteretic pressure within +-its yield.
    fn keep_states(&self, own: &mut [f64]) {
        let yields = SPECTRUM_YIELDS_PA.iter().cycle();
        for (z, y) in own.iter_mut().zip(yields) {
            *z = within_yield(*z, *y);
        }
    }
}
