//! The rig as the diagnosis identified it (`gap --rig-out RIG.toml`): the
//! nominal parameters with the accepted re-estimate (`parameters`) applied,
//! and the verdict's effects with their fitted parameters, as a rig file
//! that `--plant RIG.toml` runs (docs/interfaces.md sections 6 and 8).
//!
//! Where a gap remains beyond the noise, the rig's parameters are also
//! fitted widely ([`super::wide`]); that fit replaces the verdict's rig
//! where the held-out check runs confirm it ([`super::wide::confirmed`]),
//! so that a rig off its model in many parameters at once is tuned for
//! what it is, not for the nominal model. The verdict stays what it is.

use super::diagnosis::{Details, Diagnosis, Verdict};
use super::policy::NONE_GAP;
use super::wide::{self, WideFit};
use crate::io::num::Num;
use crate::model::effects::{EffectKind, Effects};
use crate::sim::config::{rig_file_text, RigFile};

/// The identified rig: `base`'s parameters, scaled by the verdict's
/// `parameters` ratios when it has them, with the verdict's other effects;
/// with `wide`, its parameters instead, and its alternatives. `none` and
/// `unexplained` without `wide` identify the nominal rig.
pub fn rig(details: &Details, wide: Option<&WideFit>) -> RigFile {
    let mut effects = details.effects;
    let ratios = effects.parameters.take();
    let params = match (wide, ratios) {
        (Some(w), _) => {
            effects = w.effects;
            w.params
        }
        (None, Some(r)) => r.apply(details.base.params()),
        (None, None) => *details.base.params(),
    };
    RigFile {
        params,
        effects,
        alternatives: wide.map(|w| w.alternatives.clone()).unwrap_or_default(),
    }
}

/// The wide fit of the rig's parameters, around the verdict's effect (not
/// its `parameters` ratios, which it replaces), where the verdict leaves a
/// gap beyond the noise on the fit or the check runs (not `none`) and the
/// check runs confirm it.
pub fn wide_fit(d: &Diagnosis, details: &Details, dt_s: f64) -> Option<WideFit> {
    let within_noise = d.fit.after < NONE_GAP && d.check.after < NONE_GAP;
    if d.verdict == Verdict::None || within_noise {
        return None;
    }
    let effects = Effects {
        parameters: None,
        ..details.effects
    };
    let start = wide::structural(&details.fit, &details.base);
    let fit = |e: &Effects| {
        wide::fit(
            &details.fit,
            &details.check,
            &details.base,
            e,
            dt_s,
            start.as_deref(),
        )
    };
    let around = fit(&effects);
    // A rig off in many parameters at once can lend a named effect part of
    // its gap: the parameters are also fitted alone, and the held-out
    // check runs decide.
    let alone = (effects != Effects::NONE)
        .then(|| fit(&Effects::NONE))
        .flatten();
    let w = match (around, alone) {
        (Some(a), Some(b)) => Some(if b.check_gap < a.check_gap { b } else { a }),
        (a, b) => a.or(b),
    }?;
    wide::confirmed(&w, d.check.after, d.check.before).then_some(w)
}

/// What the rig file's header says of a wide fit `w` that replaced the
/// verdict's rig.
fn wide_trust(details: &Details, w: &WideFit) -> String {
    let named = |e: &Effects| e.active().iter().any(|k| *k != EffectKind::Parameters);
    let what = match (named(&w.effects), named(&details.effects)) {
        (true, _) => {
            "the verdict's effect with its fitted parameters, and the rig's parameters fitted \
             widely for tuning (the verdict's model alone left more on the check runs)"
        }
        (false, true) => {
            "the rig's parameters fitted widely for tuning, without the verdict's effect (with \
             it, and with the verdict's model alone, the check runs kept more of the gap)"
        }
        (false, false) => {
            "the rig's parameters fitted widely for tuning (the verdict's model alone left more \
             on the check runs)"
        }
    };
    format!(
        "{what}; gap with them: fit runs {}, check runs {}",
        Num(w.fit_gap),
        Num(w.check_gap)
    )
}

/// The rig file's text: [`rig`] under a header that says where it comes
/// from and how far it is to be trusted.
pub fn rig_text(d: &Diagnosis, details: &Details, wide: Option<&WideFit>, runs: &str) -> String {
    let trust = match (d.verdict, wide) {
        (Verdict::None, _) => {
            "the runs agree with the nominal model within their noise: the nominal rig".into()
        }
        (_, Some(w)) => wide_trust(details, w),
        (Verdict::Unexplained, None) => {
            "no effect explained the gap: the nominal rig (the gap remains; see the report)".into()
        }
        (Verdict::Effect(EffectKind::Parameters), None) => "the re-estimated parameters".into(),
        (Verdict::Effect(_), None) => "the verdict's effect with its fitted parameters".into(),
    };
    let header = format!(
        "The rig as `host-sim gap` identified it ({runs}).\n\
         Verdict: {} - {trust}.\n\
         Gap with the verdict's model (fit runs): {} -> {}; (check runs, held out): {} -> {}.\n\
         Run it with `--plant` (host-sim run, sweep, hil), tune for it with `host-sim tune --plant`.",
        d.verdict,
        Num(d.fit.before),
        Num(d.fit.after),
        Num(d.check.before),
        Num(d.check.after),
    );
    rig_file_text(&rig(details, wide), &header)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::Friction;
    use crate::model::plant::Plant;

    /// The rig file carries the effects the wide fit was made around: the
    /// verdict's where they were kept, none where the parameters alone left
    /// less on the check runs; without a wide fit, the verdict's.
    #[test]
    fn the_rig_file_carries_the_effects_of_the_fit_it_holds() {
        let base = Plant::nominal();
        let effects = Effects {
            friction: Some(Friction {
                coulomb_n: 40.0,
                static_n: 60.0,
                stribeck_mps: 2e-3,
            }),
            ..Effects::NONE
        };
        let details = Details {
            fit: Vec::new(),
            check: Vec::new(),
            before: Vec::new(),
            after: Vec::new(),
            effects,
            base: base.clone(),
        };
        let mut params = *base.params();
        params.m_kg *= 1.2;
        let wide = |effects| WideFit {
            params,
            ratios: Vec::new(),
            fit_gap: 1.0,
            check_gap: 1.0,
            effects,
            alternatives: Vec::new(),
            evals: 0,
        };
        let alone = rig(&details, Some(&wide(Effects::NONE)));
        assert_eq!((alone.params, alone.effects), (params, Effects::NONE));
        let around = rig(&details, Some(&wide(effects)));
        assert_eq!((around.params, around.effects), (params, effects));
        let verdict = rig(&details, None);
        assert_eq!((verdict.params, verdict.effects), (*base.params(), effects));
    }
}
