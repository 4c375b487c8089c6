//! The diagnosis's reasons in English: one sentence (and its additions) per
//! outcome of the policy ([`super::policy`]).

use super::diagnosis::Candidate;
use super::equations::Residual;
use super::isolate::Isolation;
use super::policy::{MOST, NONE_GAP, PARAMS_MARGIN};
use crate::model::effects::EffectKind;

/// The verdict `none`.
pub fn within_noise(pooled: f64) -> String {
    format!(
        "the nominal model agrees with the runs within their noise (pooled gap {pooled:.2} < {NONE_GAP})"
    )
}

/// An effect as the verdict, against the best other candidate on the check
/// runs; with `check_within_noise`, why the check runs cannot confirm it
/// (they stay at the nominal gap `before_check`).
pub fn explained(
    chosen: &Candidate,
    runner_up: Option<&Candidate>,
    check_within_noise: bool,
    before_check: f64,
) -> String {
    let mut reason = format!(
        "{} shrinks the gap by {:.0} % on the fit runs and {:.0} % on the held-out check runs",
        chosen.effect,
        chosen.fit_shrink * 100.0,
        chosen.check_shrink * 100.0,
    );
    if let Some(x) = runner_up {
        reason.push_str(&format!(
            "; of the other candidates, {} does best on the check runs ({:.0} % / {:.0} %)",
            x.effect,
            x.fit_shrink * 100.0,
            x.check_shrink * 100.0
        ));
    }
    if check_within_noise {
        reason.push_str(&format!(
            "; the check runs agree with the nominal model within the noise (gap {before_check:.2}) and stay so with the effect ({:.2}): they do not excite it, so they cannot confirm it, only not refute it",
            chosen.check_after
        ));
    }
    reason
}

/// The addition when a second effect shrinks the remaining gap significantly.
pub fn second_added(other: EffectKind, fit_extra: f64, check_extra: f64) -> String {
    format!(
        "; adding {} shrinks the remaining gap by a further {:.0} % / {:.0} %",
        other.name(),
        fit_extra * 100.0,
        check_extra * 100.0
    )
}

/// The addition when the verdict is a named effect although the
/// `parameters` re-estimate `p` shrinks the fit runs' gap at least as much:
/// why it was set aside (implausible ratios, or the effect holds as well on
/// the check runs).
pub fn parameters_set_aside(p: &Candidate, plausible: bool) -> String {
    if plausible {
        format!(
            "; re-estimating the parameters ({}) shrinks the gap by {:.0} % / {:.0} %, but not clearly more than the named effect (it must leave at most {:.0} % of the effect's gap on the check runs, or on the fit runs where both keep the check runs within the noise), so the effect is preferred",
            p.form,
            p.fit_shrink * 100.0,
            p.check_shrink * 100.0,
            (1.0 - PARAMS_MARGIN) * 100.0
        )
    } else {
        format!(
            "; the parameter re-estimate ({}) shrinks the gap by {:.0} % / {:.0} % but is implausible (a ratio at its bound or beyond 0.5-2 times nominal), so it is set aside",
            p.form,
            p.fit_shrink * 100.0,
            p.check_shrink * 100.0
        )
    }
}

/// Where first: the violated equation, its evidence and the name the table
/// gives it, as the verdict's opening.
pub fn located(iso: &Isolation) -> String {
    let Some(best) = iso.best() else {
        return String::new();
    };
    let violated: Vec<String> = iso
        .residuals
        .iter()
        .filter(|r| r.violated)
        .map(|r| format!("{} ({:.1} / {:.1})", r.residual, r.fit, r.check))
        .collect();
    let other = iso
        .closures
        .iter()
        .find(|c| c.closure.site != best.closure.site)
        .map(|c| {
            format!(
                "; the best closure of another equation ({}) leaves {:.2}",
                c.label,
                iso.left(c)
            )
        })
        .unwrap_or_default();
    format!(
        "residuals beyond the noise (fit / check runs, noise units per block): {}; violated: {}, depending on {} (a closure of it leaves {:.2} per block of the fit and check runs{other}); the table of docs/gap.md names this {}. ",
        if violated.is_empty() { "none".to_string() } else { violated.join(", ") },
        iso.equation,
        iso.dependence,
        iso.left(best),
        iso.names,
    )
}

/// The addition when the best closure scales the parameters of the
/// residual `r` alone, their re-estimate does not hold, and the verdict
/// names an effect another closure of that residual names.
pub fn one_equation(r: usize) -> String {
    format!(
        "That closure's gain lies in the {} residual alone and the parameters' re-estimate does not hold there, so the effects the other closures of that equation name were weighed by their replayed models. ",
        Residual::ALL[r].name()
    )
}

/// The verdict `unexplained` after isolation: where the violation is, what
/// the closures say, and the best partial candidate among the effects they
/// allow (or the best candidate overall) against what was needed.
pub fn unexplained_located(
    pooled: f64,
    iso: &Isolation,
    partial: Option<&Candidate>,
    best: Option<&Candidate>,
) -> String {
    let mut r = format!("gap {pooled:.2} beyond the noise; ");
    r.push_str(&located(iso));
    if iso.outside_best() {
        r.push_str(
            "The best closure lies outside the catalogue, so no effect of the catalogue is named. ",
        );
    }
    match partial {
        Some(c) => r.push_str(&format!(
            "The best model of {} shrinks the gap by {:.0} % on the fit runs and {:.0} % on the check runs; a verdict needs {:.0} % on the check runs (or, where they show no gap, on the fit runs with the check runs kept within the noise)",
            c.effect,
            c.fit_shrink * 100.0,
            c.check_shrink * 100.0,
            MOST * 100.0
        )),
        None => r.push_str(&match best {
            Some(b) => format!(
                "no effect of the catalogue matches; the best candidate fitted ({}) shrinks the gap by {:.0} % / {:.0} %",
                b.effect,
                b.fit_shrink * 100.0,
                b.check_shrink * 100.0
            ),
            None => "no effect of the catalogue matches".to_string(),
        }),
    }
    r
}

/// `form` of an `unexplained` verdict: the violated equation, what it
/// depends on, and the best partial candidate.
pub fn partial_form(iso: &Isolation, partial: Option<&Candidate>) -> String {
    let mut f = format!(
        "violated: {}, depending on {}",
        iso.equation, iso.dependence
    );
    if let Some(c) = partial {
        f.push_str(&format!(
            "; best partial candidate: {} ({}), fit shrink {:.0} %, check shrink {:.0} %",
            c.effect,
            c.form,
            c.fit_shrink * 100.0,
            c.check_shrink * 100.0
        ));
    }
    f
}
