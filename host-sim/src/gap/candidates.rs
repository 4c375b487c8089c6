//! The fits of a diagnosis: every effect of docs/model.md section 12 fitted on the
//! fit runs and evaluated on the check runs, and the search for a second
//! effect on top of the best ones. The catalogue's named forms are fitted by
//! a bounded search ([`super::fit`]); `sensor_calibration` by least squares
//! ([`super::calibrate`]) and `parameters` by a grey-box re-estimate
//! ([`super::grey_box`]).

use std::collections::BTreeMap;

use rayon::prelude::*;

use super::diagnosis::{Candidate, NamedForm};
use super::fit::{minimize, Bound};
use super::grey_box::Estimate;
use super::measure::{gap, gap_bounded, Shrink};
use super::progress::Progress;
use super::replay::Replay;
use super::run::Run;
use super::{calibrate, grey_box, lsq, prefit, sensor_family};
use crate::model::effects::{CalChannel, EffectKind, Effects};
use crate::model::plant::Plant;

/// Effects fitted on runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fitted {
    /// The effects with the fitted parameters.
    pub effects: Effects,
    /// The gap of the runs with them.
    pub gap: f64,
    /// Objective evaluations the fit used.
    pub evals: usize,
}

/// One ranked candidate: the effect, its row of the diagnosis, its fit.
#[derive(Clone, Debug, PartialEq)]
pub struct CandidateFit {
    /// The effect.
    pub kind: EffectKind,
    /// What the diagnosis reports of it.
    pub candidate: Candidate,
    /// The effect with its fitted parameters.
    pub effects: Effects,
    /// For `parameters`: whether the re-estimate is plausible
    /// ([`grey_box::PLAUSIBLE`], none at a bound); true for the others.
    pub plausible: bool,
    /// Whether the effect is in its general family because its named form
    /// did not hold: the verdict's policy puts named candidates that hold
    /// first.
    pub general: bool,
}

/// Two effects fitted jointly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairFit {
    /// The first effect (one of the two best single candidates).
    pub first: EffectKind,
    /// The effect added on top of it.
    pub second: EffectKind,
    /// Both with their jointly fitted parameters.
    pub effects: Effects,
    /// Gap of the fit runs with both.
    pub fit_after: f64,
    /// Gap of the check runs with both.
    pub check_after: f64,
}

/// What every fit of a diagnosis shares: the runs, the plant, the starting
/// points and the budget.
pub struct Fitter<'a> {
    /// The runs the parameters are fitted on.
    pub fit: &'a [Run],
    /// The held-out runs, only evaluated.
    pub check: &'a [Run],
    /// The nominal model's replays of the fit runs (the sensors' fits read
    /// them).
    pub nominal_fit: &'a [Replay],
    /// The nominal plant.
    pub base: &'a Plant,
    /// Starting points of the effects whose gap is a narrow valley
    /// ([`super::prefit`]).
    pub seeds: Effects,
    /// Largest plant step of the replays, s.
    pub dt_s: f64,
    /// Objective evaluations per candidate fit (beyond the coarse grid).
    pub max_evals: usize,
    /// Starting points of the learned general families from the closures
    /// of their equations ([`super::isolate`]), in each family's units.
    pub learned: LearnedStarts,
}

/// Starting points of the learned general families (their least-squares
/// values, [`crate::model::effects::GeneralFamily::to_learned`]) by effect,
/// from the structural closures; none: start from the nominal model.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LearnedStarts(pub BTreeMap<EffectKind, Vec<f64>>);

impl Fitter<'_> {
    /// Fit the parameters of `kinds` jointly (starting from their values in
    /// `start`, else in the seeds, else the typical ones; other effects of
    /// `start` stay fixed) on the fit runs.
    pub fn fit_effects(&self, start: &Effects, kinds: &[EffectKind], max_evals: usize) -> Fitted {
        let mut bounds = Vec::new();
        let mut x0 = Vec::new();
        for k in kinds {
            let now = start.get(*k).or_else(|| self.seeds.get(*k));
            for (i, p) in k.params().iter().enumerate() {
                bounds.push(Bound {
                    lo: p.min,
                    hi: p.max,
                });
                x0.push(
                    now.as_ref()
                        .and_then(|v| v.get(i).copied())
                        .unwrap_or(p.typical),
                );
            }
        }
        let apply = |x: &[f64]| {
            let mut e = *start;
            let mut at = 0;
            for k in kinds {
                let n = k.params().len();
                e.set(*k, Some(&x[at..at + n]));
                at += n;
            }
            e
        };
        let mut objective = |x: &[f64], stop: f64| {
            let e = apply(x);
            if e.validate().is_err() {
                return f64::INFINITY;
            }
            gap_bounded(self.fit, self.base, &e, self.dt_s, stop)
        };
        let r = minimize(&mut objective, &bounds, &x0, 9, max_evals);
        Fitted {
            effects: apply(&r.x),
            gap: r.value,
            evals: r.evals,
        }
    }

    /// Fit one effect on the nominal model: the coarse grid and the budget.
    fn fit_effect(&self, kind: EffectKind) -> Fitted {
        self.fit_effects(&Effects::NONE, &[kind], grid_size(kind) + self.max_evals)
    }

    /// The effects `kinds` fitted on the fit runs and evaluated on the check
    /// runs (in parallel), ranked by the shrink on the fit runs, best first.
    /// `before_*` are the nominal model's gaps; `explains(fit_after,
    /// check_after)` is the verdict policy's test of a fitted model (where a
    /// named form fails it, the general family of its part is fitted).
    pub fn rank(
        &self,
        kinds: &[EffectKind],
        before_fit: f64,
        before_check: f64,
        explains: &(dyn Fn(f64, f64) -> bool + Sync),
        progress: &Progress,
    ) -> Vec<CandidateFit> {
        let mut cands: Vec<CandidateFit> = kinds
            .par_iter()
            .map(|&k| {
                let (mut f, mut form, estimates, plausible) = self.fit_kind(k);
                let mut after_check = gap(self.check, self.base, &f.effects, self.dt_s);
                let mut general = false;
                // The named form first; where it does not hold, the general
                // family of the same part of the rig.
                let named_fit = Shrink::new(before_fit, f.gap).shrink;
                if !explains(f.gap, after_check) && worth_general(k, named_fit) {
                    // The force sensor's map only where the named map found
                    // the force sensor the best channel.
                    let on_force = f
                        .effects
                        .sensor_calibration
                        .is_some_and(|c| c.channel == CalChannel::Ft);
                    if let Some((g, g_check)) = self.fit_general(k, on_force, before_fit) {
                        if explains(g.gap, g_check) {
                            form = format!(
                                "{} (the named form: fit shrink {:.0} %, check shrink {:.0} %)",
                                k.general_form(),
                                100.0 * named_fit,
                                100.0 * Shrink::new(before_check, after_check).shrink,
                            );
                            (f, after_check) = (g, g_check);
                            general = true;
                        } else {
                            form = format!(
                                "{form} ({} tried: fit shrink {:.0} %, check shrink {:.0} %)",
                                k.general_form(),
                                100.0 * Shrink::new(before_fit, g.gap).shrink,
                                100.0 * Shrink::new(before_check, g_check).shrink,
                            );
                        }
                    }
                }
                progress.done(k.name());
                let mut params = f.effects.param_map(k);
                if let Some(est) = &estimates {
                    params = estimate_params(est);
                }
                CandidateFit {
                    kind: k,
                    candidate: Candidate {
                        effect: k.name().to_string(),
                        form,
                        subsystem: k.subsystem().to_string(),
                        params,
                        fit_shrink: Shrink::new(before_fit, f.gap).shrink,
                        check_shrink: Shrink::new(before_check, after_check).shrink,
                        fit_after: f.gap,
                        check_after: after_check,
                        evals: f.evals,
                        parameters: estimates,
                        named: None,
                    },
                    effects: f.effects,
                    plausible,
                    general,
                }
            })
            .collect();
        cands.sort_by(|a, b| b.candidate.fit_shrink.total_cmp(&a.candidate.fit_shrink));
        cands
    }

    /// The chosen candidate `c` (its named form held) refined by the general
    /// family of its part of the rig, where that family explains the gap
    /// (`explains`) and `refines` it (the policy's test of the named
    /// candidate against the family's gaps on the fit and check runs); the
    /// named form's parameters and shrinks are kept beside it. `None` where
    /// `c` is already general, its part has no general family, or the family
    /// does not refine it.
    pub fn refine(
        &self,
        c: &CandidateFit,
        before_fit: f64,
        before_check: f64,
        explains: &dyn Fn(f64, f64) -> bool,
        refines: &dyn Fn(&Candidate, f64, f64) -> bool,
    ) -> Option<CandidateFit> {
        // Refined already: its named form is kept beside it.
        if c.general || c.candidate.named.is_some() || c.kind == EffectKind::Parameters {
            return None;
        }
        // A calibration verdict: the force sensor's map is tried whatever
        // channel the named map took (a force error shows in the pressures
        // first, and a pressure map can hold in its place).
        let (g, g_check) = self.fit_general(c.kind, true, before_fit)?;
        if !(explains(g.gap, g_check) && refines(&c.candidate, g.gap, g_check)) {
            return None;
        }
        let named = &c.candidate;
        let mut out = c.clone();
        out.candidate.form = format!(
            "{} (refines the named form, which held too: fit shrink {:.0} %, check shrink {:.0} %)",
            c.kind.general_form(),
            100.0 * named.fit_shrink,
            100.0 * named.check_shrink,
        );
        out.candidate.params = g.effects.param_map(c.kind);
        out.candidate.fit_shrink = Shrink::new(before_fit, g.gap).shrink;
        out.candidate.check_shrink = Shrink::new(before_check, g_check).shrink;
        out.candidate.fit_after = g.gap;
        out.candidate.check_after = g_check;
        out.candidate.evals += g.evals;
        out.candidate.named = Some(NamedForm {
            params: named.params.clone(),
            fit_shrink: named.fit_shrink,
            check_shrink: named.check_shrink,
        });
        out.effects = g.effects;
        Some(out)
    }

    /// The general family of `k`'s part of the rig fitted on the fit runs
    /// (whose nominal gap is `before_fit`), with its gap there and on the
    /// check runs; `None` where `k` has no general family or it fits no
    /// better than the nominal model. `force_map`: for `sensor_calibration`,
    /// also the force sensor's map (fitted through the replays, some 30 of
    /// them; the other sensors' maps cost one).
    fn fit_general(
        &self,
        k: EffectKind,
        force_map: bool,
        before_fit: f64,
    ) -> Option<(Fitted, f64)> {
        let (effects, gap_fit) = match k {
            EffectKind::MotorLimit => {
                let (env, _, _) = prefit::servo_envelope(self.fit, self.base)?;
                let effects = Effects {
                    servo_envelope: Some(env),
                    ..Effects::NONE
                };
                (effects, gap(self.fit, self.base, &effects, self.dt_s))
            }
            EffectKind::SensorDelay => {
                let f = sensor_family::fit_filter(
                    self.fit,
                    self.nominal_fit,
                    self.base,
                    self.dt_s,
                    before_fit,
                )?;
                (f.effects, f.gap)
            }
            EffectKind::SensorCalibration => {
                let f = sensor_family::fit_map(
                    self.fit,
                    self.nominal_fit,
                    self.base,
                    self.dt_s,
                    before_fit,
                );
                let force = force_map
                    .then(|| {
                        let stop = f.map_or(before_fit, |f| f.gap);
                        sensor_family::fit_force_map(self.fit, self.base, self.dt_s, stop)
                    })
                    .flatten();
                let f = force.or(f)?;
                (f.effects, f.gap)
            }
            _ if k.learned_len() > 0 => self.fit_learned(k, before_fit)?,
            _ => return None,
        };
        let fit = Fitted {
            effects,
            gap: gap_fit,
            evals: 1,
        };
        Some((fit, gap(self.check, self.base, &effects, self.dt_s)))
    }

    /// The learned general family of `k` by least squares on the fit runs'
    /// block-mean residuals: its [`EffectKind::learned_len`] non-negative
    /// values in the family's units ([`Effects::learned_family`] builds it
    /// from them), Levenberg-Marquardt from the learned start of `k` if any
    /// ([`LearnedStarts`]), else from zero (the nominal model), at most
    /// [`LEARNED_ITERS`] Jacobians; the family with the gap there. `None`
    /// when `k` has no learned family, the plant cannot take the effect (an
    /// implicit GRNN hose) or it does not lower the fit runs' nominal gap
    /// `before_fit`.
    fn fit_learned(&self, k: EffectKind, before_fit: f64) -> Option<(Effects, f64)> {
        let n = k.learned_len();
        Effects::learned_family(k, &vec![0.0; n])?;
        let with = |x: &[f64]| Effects::learned_family(k, x).unwrap_or(Effects::NONE);
        let f = |x: &[f64]| lsq::residuals(self.fit, self.base, &with(x), self.dt_s);
        let x0: Vec<f64> = match self.learned.0.get(&k) {
            Some(s) if s.len() == n => s.iter().map(|v| v.clamp(0.0, 50.0)).collect(),
            _ => vec![0.0; n],
        };
        let r = lsq::levenberg_marquardt(
            &f,
            &x0,
            None,
            &vec![0.1; n],
            &vec![0.0; n],
            &vec![50.0; n],
            LEARNED_ITERS,
        )?;
        let e = with(&r.x);
        let g = gap(self.fit, self.base, &e, self.dt_s);
        (g < before_fit).then_some((e, g))
    }

    /// Fit one candidate on the fit runs: its effects and gap, the form that
    /// held, the re-estimated parameters (`parameters` only) and whether
    /// they are plausible.
    fn fit_kind(&self, k: EffectKind) -> (Fitted, String, Option<Vec<Estimate>>, bool) {
        let nominal = || Fitted {
            effects: Effects::NONE,
            gap: gap(self.fit, self.base, &Effects::NONE, self.dt_s),
            evals: 1,
        };
        match k {
            EffectKind::SensorCalibration => {
                match calibrate::fit(self.fit, self.nominal_fit, self.base, self.dt_s) {
                    Some(c) => (
                        Fitted {
                            effects: c.effects,
                            gap: c.gap,
                            evals: c.evals,
                        },
                        c.form,
                        None,
                        true,
                    ),
                    None => (nominal(), "none fitted".into(), None, true),
                }
            }
            EffectKind::Parameters => match grey_box::fit(self.fit, self.base, self.dt_s) {
                Some(g) => {
                    let keys: Vec<&str> = g.estimates.iter().map(|e| e.key.as_str()).collect();
                    let form = if keys.is_empty() {
                        "grey-box re-estimate: no parameter lowers the residual".to_string()
                    } else {
                        format!("grey-box re-estimate of {}", keys.join(", "))
                    };
                    (
                        Fitted {
                            effects: g.effects,
                            gap: gap(self.fit, self.base, &g.effects, self.dt_s),
                            evals: g.evals + 1,
                        },
                        form,
                        Some(g.estimates),
                        g.plausible,
                    )
                }
                None => (nominal(), "none fitted".into(), Some(Vec::new()), false),
            },
            _ => (self.fit_effect(k), "named".into(), None, true),
        }
    }

    /// The best pair: each of the two best single candidates with every other
    /// effect of the catalogue, screened on the start point and the coarse
    /// grid only, the best of them refitted jointly (a first candidate outside
    /// the catalogue, `sensor_calibration` or `parameters`, keeps its fit)
    /// and evaluated on the check runs.
    pub fn best_pair(&self, ranked: &[CandidateFit]) -> Option<PairFit> {
        let tries: Vec<(&CandidateFit, EffectKind)> = ranked
            .iter()
            .take(2)
            .flat_map(|c| {
                EffectKind::CATALOGUE
                    .into_iter()
                    .filter(move |k| *k != c.kind)
                    .map(move |k2| (c, k2))
            })
            .collect();
        let screened: Vec<(EffectKind, EffectKind, Fitted)> = tries
            .par_iter()
            .map(|&(c, k2)| {
                let budget = 1 + grid_size(k2) + k2.params().len();
                (c.kind, k2, self.fit_effects(&c.effects, &[k2], budget))
            })
            .collect();
        let (first, second, start) = screened
            .into_iter()
            .min_by(|a, b| a.2.gap.total_cmp(&b.2.gap))?;
        // A first effect in its general family keeps its fit, as one
        // outside the catalogue does.
        let free: Vec<EffectKind> = [first, second]
            .into_iter()
            .filter(|k| EffectKind::CATALOGUE.contains(k))
            .filter(|k| !start.effects.in_general_family(*k))
            .collect();
        let joint = self.fit_effects(&start.effects, &free, 2 * self.max_evals);
        Some(PairFit {
            first,
            second,
            effects: joint.effects,
            fit_after: joint.gap,
            check_after: gap(self.check, self.base, &joint.effects, self.dt_s),
        })
    }
}

/// Jacobians of a learned general family's least-squares fit.
const LEARNED_ITERS: usize = 6;

/// Points of the coarse grid of a one-effect fit: 9 for one parameter, 5 x 5
/// for two, 3 x 3 x 3 for three.
fn grid_size(kind: EffectKind) -> usize {
    match kind.params().len() {
        1 => 9,
        2 => 25,
        _ => 27,
    }
}

/// The re-estimated parameters as candidate parameters: each key with its
/// value and its 95 % interval (`<key>`, `<key>_ci95_lo`, `<key>_ci95_hi`).
pub fn estimate_params(est: &[Estimate]) -> BTreeMap<String, f64> {
    let mut m = BTreeMap::new();
    for e in est {
        m.insert(e.key.clone(), e.value);
        m.insert(format!("{}_ci95_lo", e.key), e.ci95[0]);
        m.insert(format!("{}_ci95_hi", e.key), e.ci95[1]);
    }
    m
}

/// Whether to fit `kind`'s general family after its named form shrank the
/// fit runs' gap by `named_fit_shrink`: the learned families (of the hose
/// wall, the seals, the coupling and the accumulator: least-squares fits of
/// six to ten values, some 60 replays) only where the named form shows the
/// effect at least in part (10 %); the servo's envelope gates itself on the
/// encoder's gap ([`prefit::servo_envelope`]); the sensors' families cost
/// one replay.
fn worth_general(kind: EffectKind, named_fit_shrink: f64) -> bool {
    kind.learned_len() == 0 || named_fit_shrink >= 0.1
}
