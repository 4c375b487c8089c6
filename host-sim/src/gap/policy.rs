//! The verdict's policy: the thresholds, and the decisions taken on the gaps
//! the fits produced (which effect, if any, and whether a second one adds
//! significantly). No prose here ([`super::reasons`]) and no fitting
//! ([`super::candidates`]).

use super::candidates::{CandidateFit, PairFit};
use super::diagnosis::{Candidate, Verdict};
use super::measure::{Shrink, CLEAN_GAP};
use crate::model::effects::EffectKind;

/// Nominal gap (pooled over all runs) below which the verdict is `none`.
pub const NONE_GAP: f64 = 1.0;
/// Smallest shrink, on the fit and on the check runs, that explains a gap.
pub const MIN_SHRINK: f64 = 0.3;
/// Extra shrink of the remaining gap a second effect must give (fit and check).
pub const SECOND_SHRINK: f64 = 0.3;
/// `parameters` against a named effect that also explains the gap: the
/// re-estimate wins only when it leaves at most (1 - PARAMS_MARGIN) times
/// the effect's gap ([`params_clearly_better`]). A named effect that holds
/// about as well wins (a wrong bulk modulus must not absorb entrained air).
pub const PARAMS_MARGIN: f64 = 0.1;
/// A general family replaces the verdict's named form that held only when
/// it leaves at most (1 - REFINE_MARGIN) times the named form's gap on the
/// check runs ([`general_refines`]).
pub const REFINE_MARGIN: f64 = 0.2;

/// Whether the general family of the verdict's effect, which explains the
/// gap and leaves `fit_after` and `check_after`, replaces its named form
/// `named` that explains it too: the named form leaves a gap beyond the
/// noise on the check runs (otherwise they cannot tell the two apart), and
/// the general family leaves below (1 - [`REFINE_MARGIN`]) times it there
/// and less on the fit runs. A refinement changes how far the effect's gap
/// shrinks (and so whether `parameters` beats it), never which effect is
/// named first.
pub fn general_refines(named: &Candidate, fit_after: f64, check_after: f64) -> bool {
    may_be_refined(named)
        && check_after < (1.0 - REFINE_MARGIN) * named.check_after
        && fit_after < named.fit_after
}

/// Whether a general family may replace the named form `named` at all
/// ([`general_refines`]): its check runs show a gap beyond the noise. Where
/// they do not, the family is not fitted (the servo's envelope alone is some
/// 20 s on one core).
pub fn may_be_refined(named: &Candidate) -> bool {
    named.check_after >= NONE_GAP
}

/// Share of the gap the verdict's model must remove: "most of the gap". On
/// the check runs where they show a gap beyond the noise; where they do not
/// (they do not excite the effect), on the fit runs, with the check runs
/// kept within the noise. A model that leaves more than half the gap on
/// held-out runs is at best one contributor among others, and a name that
/// explains a third of a gap costs an engineer more than `unexplained`.
pub const MOST: f64 = 0.5;

/// Whether a model that leaves the fit and check runs at `fit_after` and
/// `check_after` explains most of the gap ([`MOST`]).
pub fn explains_most(before_fit: f64, before_check: f64, fit_after: f64, check_after: f64) -> bool {
    if before_check >= NONE_GAP {
        Shrink::new(before_check, check_after).shrink >= MOST
            && Shrink::new(before_fit, fit_after).shrink >= MIN_SHRINK
    } else {
        Shrink::new(before_fit, fit_after).shrink >= MOST && check_after < NONE_GAP
    }
}

/// Whether candidate `c` holds: plausible, and it explains the gap.
fn holds(before_fit: f64, before_check: f64, c: &CandidateFit) -> bool {
    c.plausible
        && explains(
            before_fit,
            before_check,
            c.candidate.fit_after,
            c.candidate.check_after,
        )
}

/// The best named candidate of `ranked` (an effect, not `parameters`, not
/// a general family), where it holds: the one a verdict names first. The
/// diagnosis refines it by its part's general family before the verdict is
/// decided, so that `parameters` is weighed against the effect's best model.
pub fn best_named_holding(
    before_fit: f64,
    before_check: f64,
    ranked: &[CandidateFit],
    allowed: &dyn Fn(EffectKind) -> bool,
) -> Option<usize> {
    ranked
        .iter()
        .position(|c| c.kind != EffectKind::Parameters && !c.general && allowed(c.kind))
        .filter(|i| holds(before_fit, before_check, &ranked[*i]))
}

/// Whether the `parameters` re-estimate `p` beats the named effect `e` when
/// both explain the gap: it leaves the check runs below (1 -
/// [`PARAMS_MARGIN`]) times `e`'s gap there; or, when both leave the check
/// runs within the noise (they cannot tell the two apart), `e` leaves more
/// on the fit runs than clean runs show ([`CLEAN_GAP`]) and `p` leaves
/// below (1 - [`PARAMS_MARGIN`]) times it. Ties go to the named effect: re-estimating
/// parameters must not absorb it.
pub fn params_clearly_better(p: &Candidate, e: &Candidate) -> bool {
    let clearly = |p: f64, e: f64| p < (1.0 - PARAMS_MARGIN) * e;
    if clearly(p.check_after, e.check_after) {
        return true;
    }
    p.check_after < NONE_GAP
        && e.check_after < NONE_GAP
        && e.fit_after >= CLEAN_GAP
        && clearly(p.fit_after, e.fit_after)
}

/// A pair's gaps as a candidate's, for [`params_clearly_better`].
fn pair_gaps(pair: Option<&PairFit>) -> Candidate {
    let (fit_after, check_after) = pair.map_or((f64::INFINITY, f64::INFINITY), |p| {
        (p.fit_after, p.check_after)
    });
    Candidate {
        effect: String::new(),
        form: String::new(),
        subsystem: String::new(),
        params: Default::default(),
        fit_shrink: 0.0,
        check_shrink: 0.0,
        fit_after,
        check_after,
        evals: 0,
        parameters: None,
        named: None,
    }
}

/// The held-out runs confirm a model change that took their gap from
/// `before` to `after`: it shrinks by at least `min_shrink`, or it ends
/// within the noise (runs that show no gap beyond the noise do not excite
/// the effect: they can refute it, not confirm it).
pub fn confirms(before: f64, after: f64, min_shrink: f64) -> bool {
    Shrink::new(before, after).shrink >= min_shrink || after < NONE_GAP
}

/// Whether a model change explains the gap: it shrinks the fit runs' gap
/// (`before_fit` to `fit_after`) by [`MIN_SHRINK`] and the check runs
/// confirm it ([`confirms`]).
pub fn explains(before_fit: f64, before_check: f64, fit_after: f64, check_after: f64) -> bool {
    Shrink::new(before_fit, fit_after).shrink >= MIN_SHRINK
        && confirms(before_check, check_after, MIN_SHRINK)
}

/// Whether to search for a second effect: the runs show a gap beyond the
/// noise (`pooled`) and the best single candidate leaves one on the fit runs.
pub fn wants_pair(pooled: f64, best: &CandidateFit, second_effect: bool) -> bool {
    pooled >= NONE_GAP && second_effect && best.candidate.fit_after >= NONE_GAP
}

/// Whether changes that leave the check runs at the gap `before_check` can
/// only fail to refute an effect, not confirm it (they do not excite it).
pub fn check_within_noise(before_check: f64) -> bool {
    before_check < NONE_GAP
}

/// The second effect of a pair, on top of the verdict's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SecondEffect {
    /// The effect of the pair that is not the verdict's.
    pub other: EffectKind,
    /// Extra shrink of the remaining gap on the fit runs.
    pub fit_extra: f64,
    /// Extra shrink of the remaining gap on the check runs.
    pub check_extra: f64,
    /// Both extra shrinks reach [`SECOND_SHRINK`].
    pub significant: bool,
}

/// The decision.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decision {
    /// The verdict.
    pub verdict: Verdict,
    /// Index of the verdict's effect among the ranked candidates.
    pub chosen: Option<usize>,
    /// The pair's other effect, when a pair was fitted (and the runs show a
    /// gap beyond the noise).
    pub second: Option<SecondEffect>,
}

/// Decide on the ranked candidates (best first) and the pair, given the
/// nominal gaps: pooled over all runs, of the fit runs and of the check runs.
///
/// `none` when the pooled gap is within the noise. Else a candidate
/// *explains* the gap when it shrinks it by [`MIN_SHRINK`] on the fit runs
/// and the check runs confirm it ([`confirms`]); `parameters` must moreover
/// be plausible (every ratio within [`super::grey_box::PLAUSIBLE`], none at
/// its bound). Of the best candidate other than `parameters` (E) and the
/// `parameters` candidate (P): both explain: P only when it is clearly
/// better ([`params_clearly_better`]), else E; only E explains: E; only P
/// explains: P, unless a pair of two named effects explains the gap too and
/// P is not clearly better than the pair (then the pair's first effect);
/// neither: the pair's first effect when the pair explains the gap
/// together; else `unexplained`. E is the best candidate in a named form;
/// only when it does not explain the gap, the best one in its general
/// family that does (named forms first).
pub fn decide(
    pooled: f64,
    before_fit: f64,
    before_check: f64,
    ranked: &[CandidateFit],
    pair: Option<&PairFit>,
    allowed: &dyn Fn(EffectKind) -> bool,
) -> Decision {
    if pooled < NONE_GAP {
        return Decision {
            verdict: Verdict::None,
            chosen: None,
            second: None,
        };
    }
    let holds = |i: &usize| holds(before_fit, before_check, &ranked[*i]);
    let explains = |fit_after: f64, check_after: f64| {
        explains(before_fit, before_check, fit_after, check_after)
    };
    // The best named candidate if it holds; else the best general family
    // that holds (the named forms are tried first: a flexible family must
    // not take the verdict from a named form that explains the gap).
    let effect = best_named_holding(before_fit, before_check, ranked, allowed).or_else(|| {
        (0..ranked.len())
            .filter(|i| {
                ranked[*i].kind != EffectKind::Parameters
                    && ranked[*i].general
                    && allowed(ranked[*i].kind)
            })
            .find(holds)
    });
    let params = ranked
        .iter()
        .position(|c| c.kind == EffectKind::Parameters && allowed(c.kind))
        .filter(holds);
    // The pair's effect a verdict may name: its first where allowed, else
    // its second.
    let pair_choice = pair
        .filter(|p| explains(p.fit_after, p.check_after))
        .and_then(|p| {
            [p.first, p.second].into_iter().find_map(|k| {
                ranked
                    .iter()
                    .position(|c| c.kind == k)
                    .filter(|i| ranked[*i].plausible && allowed(k))
            })
        });
    let named_pair = pair_choice.filter(|_| {
        pair.is_some_and(|p| {
            p.first != EffectKind::Parameters && p.second != EffectKind::Parameters
        })
    });
    let chosen = match (effect, params) {
        (Some(e), Some(p)) => Some(
            if params_clearly_better(&ranked[p].candidate, &ranked[e].candidate) {
                p
            } else {
                e
            },
        ),
        (Some(i), None) => Some(i),
        (None, Some(i)) => {
            // Two named effects together that explain the gap as well as
            // the re-estimate: an added effect is needed after all.
            let c = &ranked[i].candidate;
            match named_pair {
                Some(j) if !params_clearly_better(c, &pair_gaps(pair)) => Some(j),
                _ => Some(i),
            }
        }
        (None, None) => pair_choice,
    };
    let verdict = chosen.map_or(Verdict::Unexplained, |i| Verdict::Effect(ranked[i].kind));
    let second = pair.map(|p| {
        // The extra shrink the other effect gives on top of the verdict's
        // (on top of the nominal model when nothing explains the gap).
        let (base_fit, base_check) = match chosen {
            Some(i) => (
                ranked[i].candidate.fit_after,
                ranked[i].candidate.check_after,
            ),
            None => (before_fit, before_check),
        };
        let other = if verdict == Verdict::Effect(p.first) {
            p.second
        } else {
            p.first
        };
        let fit_extra = Shrink::new(base_fit, p.fit_after).shrink;
        let check_extra = Shrink::new(base_check, p.check_after).shrink;
        SecondEffect {
            other,
            fit_extra,
            check_extra,
            // Strict for the second effect: the check runs must shrink, not
            // merely stay within the noise (an extra effect fitted on top
            // overfits easily).
            significant: fit_extra >= SECOND_SHRINK && check_extra >= SECOND_SHRINK,
        }
    });
    Decision {
        verdict,
        chosen,
        second,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::Effects;

    fn cand(fit_after: f64, check_after: f64) -> Candidate {
        Candidate {
            effect: "x".into(),
            form: "named".into(),
            subsystem: "plant".into(),
            params: Default::default(),
            fit_shrink: 0.0,
            check_shrink: 0.0,
            fit_after,
            check_after,
            evals: 1,
            parameters: None,
            named: None,
        }
    }

    fn fitted(kind: EffectKind, fit_after: f64, check_after: f64) -> CandidateFit {
        CandidateFit {
            kind,
            candidate: cand(fit_after, check_after),
            effects: Effects::NONE,
            plausible: true,
            general: false,
        }
    }

    /// `parameters` beats a named form that leaves clearly more on the check
    /// runs, but not the same effect refined by its general family: the
    /// refinement happens before the verdict, on the best named candidate
    /// that holds.
    #[test]
    fn parameters_meet_the_refined_effect() {
        let (fit, check) = (10.0, 5.0);
        let named = vec![
            fitted(EffectKind::Backlash, 2.0, 2.0),
            fitted(EffectKind::Parameters, 1.5, 1.6),
        ];
        assert_eq!(best_named_holding(fit, check, &named, &|_| true), Some(0));
        let d = decide(8.0, fit, check, &named, None, &|_| true);
        assert_eq!(d.verdict, Verdict::Effect(EffectKind::Parameters));
        let mut refined = named.clone();
        refined[0] = fitted(EffectKind::Backlash, 1.2, 1.3);
        assert_eq!(best_named_holding(fit, check, &refined, &|_| true), Some(0));
        let d = decide(8.0, fit, check, &refined, None, &|_| true);
        assert_eq!(d.verdict, Verdict::Effect(EffectKind::Backlash));
        assert_eq!(d.chosen, Some(0));
        // A named candidate that does not hold is not refined.
        let weak = vec![fitted(EffectKind::Backlash, 9.0, 4.9)];
        assert_eq!(best_named_holding(fit, check, &weak, &|_| true), None);
    }

    #[test]
    fn parameters_win_only_when_clearly_better() {
        // Clearly lower on excited check runs.
        assert!(params_clearly_better(&cand(0.4, 1.0), &cand(0.4, 2.0)));
        // About as good on the check runs: the named effect.
        assert!(!params_clearly_better(&cand(0.3, 1.9), &cand(2.0, 2.0)));
        // Both check runs within the noise: the fit runs decide, when the
        // effect leaves a gap there.
        assert!(params_clearly_better(&cand(0.3, 0.47), &cand(0.8, 0.45)));
        assert!(!params_clearly_better(&cand(0.75, 0.47), &cand(0.8, 0.45)));
        // ... but not where the effect leaves no more than clean runs show.
        assert!(!params_clearly_better(&cand(0.28, 0.47), &cand(0.45, 0.45)));
    }

    #[test]
    fn a_general_family_refines_only_where_the_check_runs_tell() {
        // Clearly lower on check runs that still show a gap.
        assert!(general_refines(&cand(1.5, 2.0), 0.5, 1.5));
        // Not clearly lower there.
        assert!(!general_refines(&cand(1.5, 2.0), 0.5, 1.7));
        // Lower on the check runs but not on the fit runs.
        assert!(!general_refines(&cand(0.5, 2.0), 0.6, 1.0));
        // The named form leaves the check runs within the noise.
        assert!(!general_refines(&cand(1.5, 0.9), 0.5, 0.3));
    }
}
