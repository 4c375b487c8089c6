//! The fits of a diagnosis: every effect of docs/model.md section 12 fitted on the
//! fit runs and evaluated on the check runs, and the search for a second
//! effect on top of the best ones.

use std::collections::BTreeMap;

use rayon::prelude::*;

use super::diagnosis::Candidate;
use super::fit::{minimize, Bound};
use super::measure::{gap, gap_bounded, Shrink};
use super::progress::Progress;
use super::run::Run;
use crate::model::effects::{EffectKind, Effects};
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
    /// The nominal plant.
    pub base: &'a Plant,
    /// Starting points of the effects whose gap is a narrow valley
    /// ([`super::prefit`]).
    pub seeds: Effects,
    /// Largest plant step of the replays, s.
    pub dt_s: f64,
    /// Objective evaluations per candidate fit (beyond the coarse grid).
    pub max_evals: usize,
}

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

    /// Every effect fitted on the fit runs and evaluated on the check runs
    /// (in parallel), ranked by the shrink on the fit runs, best first.
    /// `before_*` are the nominal model's gaps.
    pub fn rank(
        &self,
        before_fit: f64,
        before_check: f64,
        progress: &Progress,
    ) -> Vec<CandidateFit> {
        let mut cands: Vec<CandidateFit> = EffectKind::ALL
            .par_iter()
            .map(|&k| {
                let f = self.fit_effect(k);
                let after_check = gap(self.check, self.base, &f.effects, self.dt_s);
                progress.done(k.name());
                CandidateFit {
                    kind: k,
                    candidate: Candidate {
                        effect: k.name().to_string(),
                        params: params_map(&f.effects, k),
                        fit_shrink: Shrink::new(before_fit, f.gap).shrink,
                        check_shrink: Shrink::new(before_check, after_check).shrink,
                        fit_after: f.gap,
                        check_after: after_check,
                        evals: f.evals,
                    },
                    effects: f.effects,
                }
            })
            .collect();
        cands.sort_by(|a, b| b.candidate.fit_shrink.total_cmp(&a.candidate.fit_shrink));
        cands
    }

    /// The best pair: each of the two best single candidates with every other
    /// effect, screened on the start point and the coarse grid only, the best
    /// of them refitted jointly and evaluated on the check runs.
    pub fn best_pair(&self, ranked: &[CandidateFit]) -> Option<PairFit> {
        let tries: Vec<(&CandidateFit, EffectKind)> = ranked
            .iter()
            .take(2)
            .flat_map(|c| {
                EffectKind::ALL
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
        let joint = self.fit_effects(&start.effects, &[first, second], 2 * self.max_evals);
        Some(PairFit {
            first,
            second,
            effects: joint.effects,
            fit_after: joint.gap,
            check_after: gap(self.check, self.base, &joint.effects, self.dt_s),
        })
    }
}

/// Points of the coarse grid of a one-effect fit: 9 for one parameter, 5 x 5
/// for two, 3 x 3 x 3 for three.
fn grid_size(kind: EffectKind) -> usize {
    match kind.params().len() {
        1 => 9,
        2 => 25,
        _ => 27,
    }
}

/// The parameters of `kind` in `e` by name.
pub fn params_map(e: &Effects, kind: EffectKind) -> BTreeMap<String, f64> {
    kind.params()
        .iter()
        .zip(e.get(kind).unwrap_or_default())
        .map(|(p, v)| (p.name.to_string(), v))
        .collect()
}
