//! What a diagnosis found: the verdict, the candidates, where the gap lies,
//! the residual tests (the JSON of docs/interfaces.md section 2 and more), and
//! the replays the report plots.

use std::collections::BTreeMap;
use std::fmt;

use serde::{Serialize, Serializer};

use super::grey_box::Estimate;
use super::isolate::Isolation;
use super::measure::Shrink;
use super::replay::Replay;
use super::run::Run;
use crate::model::effects::{EffectKind, Effects};
use crate::model::plant::Plant;

/// The diagnosis's answer. In the JSON (and in messages) its identifier:
/// the effect's (docs/model.md section 12), `none` or `unexplained`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// The nominal model agrees with the runs within their noise.
    None,
    /// A gap beyond the noise that no candidate explains.
    Unexplained,
    /// This effect explains the gap.
    Effect(EffectKind),
}

impl Verdict {
    /// The identifier: the effect's name, `none` or `unexplained`.
    pub fn name(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Unexplained => "unexplained",
            Self::Effect(k) => k.name(),
        }
    }

    /// The effect named, if any.
    pub fn effect(self) -> Option<EffectKind> {
        match self {
            Self::Effect(k) => Some(k),
            Self::None | Self::Unexplained => None,
        }
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for Verdict {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl PartialEq<str> for Verdict {
    fn eq(&self, other: &str) -> bool {
        self.name() == other
    }
}

impl PartialEq<&str> for Verdict {
    fn eq(&self, other: &&str) -> bool {
        self.name() == *other
    }
}

/// One candidate effect with its fitted parameters.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Candidate {
    /// Identifier of docs/model.md section 12.
    pub effect: String,
    /// Which model of the effect was fitted: `named` (the catalogue's
    /// parametric form), the map of a `sensor_calibration`, the parameters
    /// a `parameters` re-estimate fitted.
    pub form: String,
    /// The part of the rig: seals, servo, oil, sensors, hose, accumulator, plant.
    pub subsystem: String,
    /// Fitted parameters, names with units.
    pub params: BTreeMap<String, f64>,
    /// Shrink on the fit runs.
    pub fit_shrink: f64,
    /// Shrink on the check runs.
    pub check_shrink: f64,
    /// Gap with the effect on the fit runs.
    pub fit_after: f64,
    /// Gap with the effect on the check runs.
    pub check_after: f64,
    /// Objective evaluations the fit used.
    pub evals: usize,
    /// `parameters` only: the re-estimated parameters with their intervals.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub parameters: Option<Vec<Estimate>>,
    /// Where the named form held but the general family of the same part
    /// of the rig holds clearly better on the check runs and replaced it
    /// (`params` are then the general family's): the named form's
    /// parameters and shrinks, which an engineer reads more easily.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub named: Option<NamedForm>,
}

/// The named form of a candidate that its general family refined.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct NamedForm {
    /// Its fitted parameters, names with units.
    pub params: BTreeMap<String, f64>,
    /// Its shrink on the fit runs.
    pub fit_shrink: f64,
    /// Its shrink on the check runs.
    pub check_shrink: f64,
}

/// A part of a run that carries the gap.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Where {
    /// Channel.
    pub channel: String,
    /// Run (file name).
    pub run: String,
    /// Start, s.
    pub t0_s: f64,
    /// End, s.
    pub t1_s: f64,
    /// Segment label.
    pub label: String,
    /// Fraction of that run's gap inside this part.
    pub share: f64,
}

/// Residual tests and spectrum of one channel of one run (nominal model).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ChannelReport {
    /// Run (file name).
    pub run: String,
    /// Channel.
    pub channel: String,
    /// This channel's gap (same unit as the total).
    pub gap: f64,
    /// Noise level estimated from the log, SI.
    pub noise: f64,
    /// RMS residual, SI.
    pub rms_residual: f64,
    /// Whiteness test passes at 99 %.
    pub white: bool,
    /// Portmanteau statistic of the whiteness test and its 99 % limit.
    pub whiteness_q: [f64; 2],
    /// Residual independent of the drive command at 99 %.
    pub independent_of_input: bool,
    /// Portmanteau statistic of the independence test and its 99 % limit.
    pub independence_q: [f64; 2],
    /// Share of the residual power per band (bands in `bands_hz`).
    pub band_shares: [f64; 4],
}

/// A second effect on top of the verdict's.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Second {
    /// Identifier.
    pub effect: String,
    /// Its fitted parameters.
    pub params: BTreeMap<String, f64>,
    /// Extra shrink of the remaining gap on the fit runs.
    pub fit_extra_shrink: f64,
    /// Extra shrink of the remaining gap on the check runs.
    pub check_extra_shrink: f64,
    /// Whether it adds significantly (both extra shrinks >= the threshold).
    pub significant: bool,
}

/// Two effects fitted jointly.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Combined {
    /// The two identifiers.
    pub effects: Vec<String>,
    /// Their parameters.
    pub params: BTreeMap<String, f64>,
    /// Fit runs: nominal gap, gap with both effects, shrink.
    pub fit: Shrink,
    /// Check runs: nominal gap, gap with both effects, shrink.
    pub check: Shrink,
}

/// The diagnosis (the JSON of docs/interfaces.md section 2 and more).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Diagnosis {
    /// Effect identifier, `none` or `unexplained`.
    pub verdict: Verdict,
    /// Which model of the verdict's effect held (its candidate's `form`);
    /// for `unexplained`, the violated equation, what the violation depends
    /// on and the best partial candidate; absent for `none`.
    pub form: Option<String>,
    /// The part of the rig of the verdict's effect; for `unexplained`, of
    /// the violated equation; absent for `none`.
    pub subsystem: Option<String>,
    /// Where first: which equation the runs violate and on what, before
    /// any effect is named.
    pub isolation: Isolation,
    /// The grey-box re-estimate of the nominal parameters (the `parameters`
    /// candidate's, whatever the verdict), with 95 % intervals.
    pub parameters: Vec<Estimate>,
    /// What the gap measures.
    pub gap_metric: String,
    /// Fit runs: before, after, shrink.
    pub fit: Shrink,
    /// Check runs: before, after, shrink.
    pub check: Shrink,
    /// Every effect tried, best first.
    pub candidates: Vec<Candidate>,
    /// Parts of the runs that carry the gap, largest share first.
    #[serde(rename = "where")]
    pub where_: Vec<Where>,
    /// A second effect on top of the verdict's, when one was tested.
    pub second_effect: Option<Second>,
    /// The best pair of effects fitted jointly, when one was tested.
    pub combined: Option<Combined>,
    /// Per run and channel: residual tests and spectrum.
    pub channels: Vec<ChannelReport>,
    /// Band edges of `band_shares`, Hz.
    pub bands_hz: Vec<[f64; 2]>,
    /// Why the verdict.
    pub reason: String,
    /// Wall time, s.
    pub elapsed_s: f64,
}

/// Everything the report needs besides the JSON: replays before and after.
pub struct Details {
    /// The fit runs.
    pub fit: Vec<Run>,
    /// The check runs.
    pub check: Vec<Run>,
    /// Nominal replays (fit then check).
    pub before: Vec<Replay>,
    /// Replays with the verdict's effect (fit then check), if any.
    pub after: Vec<Replay>,
    /// The verdict's effects.
    pub effects: Effects,
    /// The nominal plant the runs were replayed on.
    pub base: Plant,
}
