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
/// with `wide`, its parameters instead. `none` and `unexplained` without
/// `wide` identify the nominal rig.
pub fn rig(details: &Details, wide: Option<&WideFit>) -> RigFile {
    let mut effects = details.effects;
    let ratios = effects.parameters.take();
    let params = match (wide, ratios) {
        (Some(w), _) => w.params,
        (None, Some(r)) => r.apply(details.base.params()),
        (None, None) => *details.base.params(),
    };
    RigFile { params, effects }
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
    let w = wide::fit(&details.fit, &details.check, &details.base, &effects, dt_s)?;
    wide::confirmed(&w, d.check.after, d.check.before).then_some(w)
}

/// What the rig file's header says of a wide fit `w` that replaced the
/// verdict's rig.
fn wide_trust(details: &Details, w: &WideFit) -> String {
    let with_effect = details
        .effects
        .active()
        .iter()
        .any(|k| *k != EffectKind::Parameters);
    format!(
        "{}the rig's parameters fitted widely for tuning (the verdict's model alone left more \
         on the check runs); gap with them: fit runs {}, check runs {}",
        if with_effect {
            "the verdict's effect with its fitted parameters, and "
        } else {
            ""
        },
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
