//! The hose wall: its named hysteresis (`hose_hysteresis`) and its general
//! family, the hysteresis spectrum.

use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, GeneralFamily, NamedEffect, ParamSpec, VALID_SPAN};

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

/// Yields of the elements of a [`HysteresisSpectrum`], Pa: two per decade
/// from 10 kPa to 1 MPa.
pub const SPECTRUM_YIELDS_PA: [f64; 5] = [1e4, 3e4, 1e5, 3e5, 1e6];

/// The general family of the hose wall (`hose_hysteresis` in any shape): a
/// discrete Prandtl-Ishlinskii operator on each line's pressure. Element i
/// is a hysteretic pressure of yield [`SPECTRUM_YIELDS_PA`]`[i]` (the Dahl
/// element of the named form, without a stuck share) that adds the
/// compliance `c_m3pp[i]` as far as it is engaged; the wall's hysteretic
/// volume is the weighted sum of the elements' outputs. The weights, learned
/// from the runs, shape the loop: narrow loops from small yields, wide ones
/// from large.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HysteresisSpectrum {
    /// Compliance of each element when engaged, m^3/Pa (non-negative).
    pub c_m3pp: [f64; 5],
}

impl HysteresisSpectrum {
    /// Element `i` as a Dahl element of the named form.
    pub fn element(&self, i: usize) -> HoseHysteresis {
        HoseHysteresis {
            c_m3pp: self.c_m3pp[i],
            stuck_share: 0.0,
            yield_pa: SPECTRUM_YIELDS_PA[i],
        }
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
        "general: a Prandtl-Ishlinskii spectrum of the hose wall (five yields, 10 kPa to 1 MPa)";
    const BOTH: &'static str = "the named form and the hysteresis spectrum exclude each other";
    const REQUIREMENT: &'static str = "hose_spectrum: every c_m3pp must be >= 0 and at most 5e-11";
    /// Every compliance within [0, VALID_SPAN times the named form's largest].
    fn family_valid(&self) -> bool {
        let most = VALID_SPAN * HoseHysteresis::PARAMS[0].max;
        self.c_m3pp
            .iter()
            .all(|c| c.is_finite() && (0.0..=most).contains(c))
    }
    fn param_map(&self) -> Vec<(String, f64)> {
        SPECTRUM_YIELDS_PA
            .iter()
            .zip(self.c_m3pp)
            .map(|(y, c)| (format!("c_m3pp_at_yield_{y:.0e}_pa"), c))
            .collect()
    }
}
