//! The hose wall: its named hysteresis (`hose_hysteresis`) and its general
//! family, the hysteresis spectrum.

use serde::Deserialize;

/// Rate-independent hose-wall hysteresis.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
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
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
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
