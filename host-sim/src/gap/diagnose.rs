//! The diagnosis: gap of the nominal model, where it lies, which effect
//! removes it (fitted on the fit runs), and how much on the check runs.
//!
//! [`diagnose`] puts the parts together: the measure ([`super::measure`]),
//! the localisation ([`super::localise`]), the fits ([`super::candidates`]),
//! the verdict's policy ([`super::policy`]) and its reasons
//! ([`super::reasons`]), with a progress bar ([`super::progress`]).

use std::time::Instant;

use super::candidates::{CandidateFit, Fitter, LearnedStarts, PairFit};
use super::closures::{Dependence, Site, LEAK_LEVEL_PA};
use super::diagnosis::{Combined, Details, Diagnosis, Second, Verdict};
use super::grey_box;
use super::isolate::{self, Isolation};
use super::localise::{channel_reports, where_list};
use super::measure::{channel_excess, gap_of, pooled, replays, Shrink, GAP_METRIC};
use super::policy::{self, Decision};
use super::prefit;
use super::progress::Progress;
use super::reasons;
use super::replay::Replay;
use super::run::Run;
use super::stats::BANDS_HZ;
use crate::model::effects::{
    EffectKind, Effects, GeneralFamily, LeakageMap, ScrewMap, LEAK_DP_PA, SCREW_FORCES_N,
};
use crate::model::plant::Plant;

/// Options of a diagnosis.
#[derive(Clone, Debug)]
pub struct Options {
    /// Largest plant step of the replays, s. 5e-4 s keeps RK4 stable (the
    /// fastest eigenvalue of the plant, about -4700 1/s, gives |lambda h| = 2.3
    /// < 2.78) and changes the gaps of the validation suite by less than 0.01
    /// against 2e-4 s, at 2.5 times less cost.
    pub dt_s: f64,
    /// Objective evaluations per candidate fit.
    pub max_evals: usize,
    /// Show a progress bar.
    pub progress: bool,
    /// Try a second effect on top of the best one.
    pub second_effect: bool,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            dt_s: 5e-4,
            max_evals: 36,
            progress: false,
            second_effect: true,
        }
    }
}

/// The nominal model on the runs.
struct Nominal {
    /// Gap of the fit runs.
    fit: f64,
    /// Gap of the check runs.
    check: f64,
    /// Gap pooled over all runs.
    pooled: f64,
    /// Replays, fit runs then check runs.
    replays: Vec<Replay>,
}

fn nominal(fit: &[Run], check: &[Run], base: &Plant, dt_s: f64) -> Nominal {
    let nominal_fit = replays(fit, base, &Effects::NONE, dt_s);
    let nominal_check = replays(check, base, &Effects::NONE, dt_s);
    let before_fit = gap_of(fit, &nominal_fit);
    let before_check = gap_of(check, &nominal_check);
    let all: Vec<&Run> = fit.iter().chain(check.iter()).collect();
    let replays: Vec<Replay> = nominal_fit.into_iter().chain(nominal_check).collect();
    let lens: Vec<usize> = all.iter().map(|r| r.log.len()).collect();
    let excess: Vec<[f64; 4]> = all
        .iter()
        .zip(&replays)
        .map(|(r, s)| channel_excess(r, s))
        .collect();
    Nominal {
        fit: before_fit,
        check: before_check,
        pooled: pooled(&excess, &lens),
        replays,
    }
}

/// What the verdict sets: the gaps with its effect, the effects the report
/// replays, the reason, the second effect and the pair.
struct Conclusion {
    fit: Shrink,
    check: Shrink,
    effects: Effects,
    reason: String,
    second_effect: Option<Second>,
    combined: Option<Combined>,
}

/// The decision turned into the diagnosis's numbers and prose; `partial`:
/// for `unexplained`, the best candidate among the effects the isolation
/// allows.
fn conclude(
    n: &Nominal,
    ranked: &[CandidateFit],
    pair: Option<&PairFit>,
    decision: &Decision,
    iso: &Isolation,
    partial: Option<usize>,
) -> Conclusion {
    let mut c = Conclusion {
        fit: Shrink::new(n.fit, n.fit),
        check: Shrink::new(n.check, n.check),
        effects: Effects::NONE,
        reason: String::new(),
        second_effect: None,
        combined: None,
    };
    c.reason = match decision.chosen {
        None if decision.verdict == Verdict::None => reasons::within_noise(n.pooled),
        None => reasons::unexplained_located(
            n.pooled,
            iso,
            partial.map(|i| &ranked[i].candidate),
            ranked.first().map(|c| &c.candidate),
        ),
        Some(i) => {
            let chosen = &ranked[i];
            c.fit = Shrink::new(n.fit, chosen.candidate.fit_after);
            c.check = Shrink::new(n.check, chosen.candidate.check_after);
            c.effects = chosen.effects;
            let runner_up = ranked
                .iter()
                .filter(|x| x.kind != chosen.kind)
                .max_by(|a, b| {
                    a.candidate
                        .check_shrink
                        .total_cmp(&b.candidate.check_shrink)
                });
            let mut r = reasons::located(iso);
            if let Some(res) = iso.parameters_in_one_equation() {
                if !iso.allows(chosen.kind) {
                    r.push_str(&reasons::one_equation(res));
                }
            }
            r.push_str(&reasons::explained(
                &chosen.candidate,
                runner_up.map(|x| &x.candidate),
                policy::check_within_noise(n.check),
                n.check,
            ));
            if let Some(p) = ranked.iter().find(|x| {
                x.kind == EffectKind::Parameters
                    && x.kind != chosen.kind
                    && x.candidate.fit_shrink >= chosen.candidate.fit_shrink
            }) {
                r.push_str(&reasons::parameters_set_aside(&p.candidate, p.plausible));
            }
            r
        }
    };
    if let (Some(p), Some(s)) = (pair, decision.second) {
        let mut params = p.effects.param_map(p.first);
        params.extend(p.effects.param_map(p.second));
        c.second_effect = Some(Second {
            effect: s.other.name().to_string(),
            params: p.effects.param_map(s.other),
            fit_extra_shrink: s.fit_extra,
            check_extra_shrink: s.check_extra,
            significant: s.significant,
        });
        c.combined = Some(Combined {
            effects: vec![p.first.name().to_string(), p.second.name().to_string()],
            params,
            fit: Shrink::new(n.fit, p.fit_after),
            check: Shrink::new(n.check, p.check_after),
        });
        if s.significant && decision.verdict != Verdict::Unexplained {
            c.effects = p.effects;
            c.reason
                .push_str(&reasons::second_added(s.other, s.fit_extra, s.check_extra));
        }
    }
    c
}

/// The learned general families' starting points from the closures of
/// their equations, as their learned values: the coupling's deflection at
/// the screw map's knots (the closure's odd tents over the same forces,
/// each weight the deflection at its knot), and the leakage map from the
/// closure of the flow between the lines (the same knots and level
/// column).
fn learned_starts(iso: &Isolation) -> LearnedStarts {
    let mut starts = LearnedStarts::default();
    let screw = iso
        .weights(Site::CouplingIn, Dependence::Force)
        .filter(|w| w.len() == SCREW_FORCES_N.len())
        .and_then(|w| {
            let map = ScrewMap {
                deflection_m: std::array::from_fn(|i| w[i + 1]),
            };
            map.to_learned()
        });
    if let Some(x) = screw {
        starts.0.insert(EffectKind::Backlash, x);
    }
    // The leakage map from the closure of the flow between the lines: its
    // odd tents over the pressure difference at the map's knots (each
    // weight the flow there; the tent at 0, a step through dP = 0, has no
    // place in a map that flows nothing at 0) and its level column, cut to
    // the map's non-negative values.
    let leak = iso
        .weights(Site::Between, Dependence::PressureDifference)
        .filter(|w| w.len() == LEAK_DP_PA.len() + 1)
        .and_then(|w| {
            let map = LeakageMap {
                q_m3ps: std::array::from_fn(|i| w[i + 1].max(0.0)),
                g_m3pspa: (w[LEAK_DP_PA.len()] / LEAK_LEVEL_PA).max(0.0),
            };
            map.to_learned()
        });
    if let Some(x) = leak {
        starts.0.insert(EffectKind::Leakage, x);
    }
    starts
}

/// Diagnose: fit runs, check runs, the nominal plant.
pub fn diagnose(
    fit: Vec<Run>,
    check: Vec<Run>,
    base: &Plant,
    opts: &Options,
) -> (Diagnosis, Details) {
    let t0 = Instant::now();
    let n = nominal(&fit, &check, base, opts.dt_s);
    let all: Vec<&Run> = fit.iter().chain(check.iter()).collect();
    let where_ = where_list(&all, &n.replays);
    let channels = channel_reports(&all, &n.replays);
    // Where first: which equation the runs violate and on what.
    let iso = isolate::isolate(&fit, &check, base);
    // The models worth fitting: the effects the isolation points at (none
    // where the runs agree with the nominal model within the noise).
    let kinds = if n.pooled < policy::NONE_GAP {
        Vec::new()
    } else {
        iso.to_fit()
    };
    let fitter = Fitter {
        fit: &fit,
        check: &check,
        nominal_fit: n.replays.get(..fit.len()).unwrap_or_default(),
        base,
        seeds: seeds(&kinds, &fit, base),
        dt_s: opts.dt_s,
        max_evals: opts.max_evals,
        learned: learned_starts(&iso),
    };
    // Candidates: those effects, fitted on the fit runs, evaluated on the
    // check runs.
    let progress = Progress::candidates(opts.progress, kinds.len());
    let explains =
        |fit_after: f64, check_after: f64| policy::explains(n.fit, n.check, fit_after, check_after);
    let mut ranked = fitter.rank(&kinds, n.fit, n.check, &explains, &progress);
    progress.finish();
    // The effects a verdict may name: those the closures comparable to the
    // best name, none where the best lies outside the catalogue;
    // `parameters` only where its re-estimate on the check runs agrees.
    let outside = iso.outside_best();
    let params_agree = !outside && parameters_agree(&n, &iso, &ranked, &check, base, opts.dt_s);
    // Where the best closure scales the parameters of one equation alone
    // and their re-estimate does not hold, the equation is located but not
    // the form: the effects its other closures name may be named, the
    // replayed models deciding.
    let allowed = |k: EffectKind| {
        !outside
            && (iso.allows(k) || !params_agree && iso.in_one_equation(k))
            && (k != EffectKind::Parameters || params_agree)
    };
    let (decision, pair, partial) = verdict(&fitter, &n, &mut ranked, &allowed, opts);
    let c = conclude(&n, &ranked, pair.as_ref(), &decision, &iso, partial);
    // The report's replays with the verdict's effects.
    let after = if c.effects.is_none() {
        Vec::new()
    } else {
        replays(&fit, base, &c.effects, opts.dt_s)
            .into_iter()
            .chain(replays(&check, base, &c.effects, opts.dt_s))
            .collect()
    };
    let elapsed_s = t0.elapsed().as_secs_f64();
    let (form, subsystem) = form_and_subsystem(&decision, &ranked, &iso, partial);
    let diag = Diagnosis {
        verdict: decision.verdict,
        form,
        subsystem,
        isolation: iso,
        parameters: ranked
            .iter()
            .find(|c| c.kind == EffectKind::Parameters)
            .and_then(|c| c.candidate.parameters.clone())
            .unwrap_or_default(),
        gap_metric: GAP_METRIC.into(),
        fit: c.fit,
        check: c.check,
        candidates: ranked.iter().map(|r| r.candidate.clone()).collect(),
        where_,
        second_effect: c.second_effect,
        combined: c.combined,
        channels,
        bands_hz: BANDS_HZ
            .iter()
            .map(|(a, b)| [*a, if b.is_finite() { *b } else { 0.5 / 1e-3 }])
            .collect(),
        reason: c.reason,
        elapsed_s,
    };
    let details = Details {
        before: n.replays,
        after,
        effects: c.effects,
        fit,
        check,
        base: base.clone(),
    };
    (diag, details)
}

/// Starting points where the gap is a narrow valley (see [`prefit`]): the
/// motor limit's, when it is among `kinds`.
fn seeds(kinds: &[EffectKind], fit: &[Run], base: &Plant) -> Effects {
    let mut seeds = Effects::NONE;
    if kinds.contains(&EffectKind::MotorLimit) {
        if let Some(x) = prefit::motor_limit(fit, base) {
            seeds.set(EffectKind::MotorLimit, Some(&x));
        }
    }
    seeds
}

/// Whether `parameters` may be named: the isolation allows it, and its
/// re-estimate is plausible, explains the gap and agrees on the check runs.
fn parameters_agree(
    n: &Nominal,
    iso: &Isolation,
    ranked: &[CandidateFit],
    check: &[Run],
    base: &Plant,
    dt_s: f64,
) -> bool {
    iso.allows(EffectKind::Parameters)
        && ranked
            .iter()
            .find(|c| c.kind == EffectKind::Parameters)
            .is_some_and(|p| {
                p.plausible
                    && policy::explains(
                        n.fit,
                        n.check,
                        p.candidate.fit_after,
                        p.candidate.check_after,
                    )
                    && grey_box::agrees(
                        p.candidate.parameters.as_deref().unwrap_or_default(),
                        p.candidate.check_after,
                        check,
                        base,
                        dt_s,
                    )
            })
}

/// The verdict on the ranked candidates: a second effect where the best one
/// leaves a gap beyond the noise, the best named candidate refined by its
/// general family, the decision, and an effect named only where its model
/// explains most of the gap. Returns the decision, the pair and the
/// partial candidate (for `unexplained`).
fn verdict(
    fitter: &Fitter<'_>,
    n: &Nominal,
    ranked: &mut [CandidateFit],
    allowed: &dyn Fn(EffectKind) -> bool,
    opts: &Options,
) -> (Decision, Option<PairFit>, Option<usize>) {
    let explains =
        |fit_after: f64, check_after: f64| policy::explains(n.fit, n.check, fit_after, check_after);
    // A second effect where the best single one leaves a gap beyond the noise.
    let pair = if ranked
        .first()
        .is_some_and(|b| policy::wants_pair(n.pooled, b, opts.second_effect))
    {
        fitter.best_pair(ranked)
    } else {
        None
    };
    // The best named candidate that holds, refined by its part's general
    // family where that holds clearly better on the check runs, before the
    // verdict is decided: `parameters` is weighed against the effect's best
    // model, and the effect named stays the same (not within the noise,
    // where the verdict is `none` whatever the candidates).
    let best = policy::best_named_holding(n.fit, n.check, ranked, allowed);
    let mut named = None;
    if let Some(i) = best
        .filter(|_| n.pooled >= policy::NONE_GAP)
        .filter(|&i| policy::may_be_refined(&ranked[i].candidate))
    {
        let r = fitter.refine(
            &ranked[i],
            n.fit,
            n.check,
            &explains,
            &policy::general_refines,
        );
        if let Some(r) = r {
            named = Some((i, std::mem::replace(&mut ranked[i], r)));
        }
    }
    let mut decision = policy::decide(n.pooled, n.fit, n.check, ranked, pair.as_ref(), allowed);
    // A second effect was fitted beside the named form: where it adds
    // significantly, the verdict is decided on the named forms.
    if let Some((i, c)) = named.filter(|_| decision.second.is_some_and(|s| s.significant)) {
        ranked[i] = c;
        decision = policy::decide(n.pooled, n.fit, n.check, ranked, pair.as_ref(), allowed);
    }
    // An effect is named only where its model explains most of the gap
    // (alone, or with the second effect of the pair it leads).
    let mut partial = (0..ranked.len()).find(|&i| allowed(ranked[i].kind));
    if let (Verdict::Effect(k), Some(i)) = (decision.verdict, decision.chosen) {
        let c = &ranked[i].candidate;
        let alone = policy::explains_most(n.fit, n.check, c.fit_after, c.check_after);
        let with_pair = pair.as_ref().is_some_and(|p| {
            (p.first == k || p.second == k)
                && policy::explains_most(n.fit, n.check, p.fit_after, p.check_after)
        });
        if !(alone || with_pair) {
            partial = Some(i);
            decision.verdict = Verdict::Unexplained;
            decision.chosen = None;
        }
    }
    (decision, pair, partial)
}

/// The verdict's form and subsystem: its candidate's, or for `unexplained`
/// the isolation's best closure's with the partial candidate.
fn form_and_subsystem(
    decision: &Decision,
    ranked: &[CandidateFit],
    iso: &Isolation,
    partial: Option<usize>,
) -> (Option<String>, Option<String>) {
    let verdict_candidate = decision.chosen.map(|i| &ranked[i].candidate);
    match (decision.verdict, verdict_candidate) {
        (Verdict::None, _) => (None, None),
        (_, Some(c)) => (Some(c.form.clone()), Some(c.subsystem.clone())),
        (_, None) => (
            Some(reasons::partial_form(
                iso,
                partial.map(|i| &ranked[i].candidate),
            )),
            iso.best().map(|b| b.closure.site.subsystem().to_string()),
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::validation::{check_scenario, fit_scenario, rig_log};
    use dca_core::controller::ControllerKind;

    /// The leakage map's start read from the closure of the flow between
    /// the lines, on runs of a rig whose map is known (laminar, 1e-13
    /// m^3/(s Pa), plus a level share): at the pressures the runs reach the
    /// start's flow is within 30 % of the truth's (a unit slip between the
    /// closure's columns and the map's values would be a factor 10 or more).
    #[test]
    fn the_leakage_start_reads_the_flow_closure_in_the_maps_units() {
        let truth = LeakageMap {
            q_m3ps: std::array::from_fn(|i| 1e-13 * LEAK_DP_PA[i + 1]),
            g_m3pspa: 0.5e-13,
        };
        let e = Effects {
            leakage_map: Some(truth),
            ..Effects::NONE
        };
        let run = |s, seed| Run::new("r".into(), rig_log(s, ControllerKind::MpcEso, &e, seed));
        let (fit, check) = ([run(fit_scenario(), 1)], [run(check_scenario(), 2)]);
        let iso = isolate::isolate(&fit, &check, &Plant::nominal());
        let x = learned_starts(&iso)
            .0
            .remove(&EffectKind::Leakage)
            .expect("a start");
        let start = LeakageMap::from_learned(&x).expect("a map");
        for (p1, p2) in [(1.5e6, 0.8e6), (2.5e6, 0.9e6), (0.9e6, 0.7e6)] {
            let (a, b) = (start.flow(p1, p2), truth.flow(p1, p2));
            assert!(
                (a / b - 1.0).abs() < 0.3,
                "{p1} {p2}: {a:e} vs {b:e}: {start:?}"
            );
        }
    }
}
