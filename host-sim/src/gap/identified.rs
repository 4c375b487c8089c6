//! The rig as the diagnosis identified it (`gap --rig-out RIG.toml`): the
//! nominal parameters with the accepted re-estimate (`parameters`) applied,
//! and the verdict's effects with their fitted parameters, as a rig file
//! that `--plant RIG.toml` runs (docs/interfaces.md sections 6 and 8).

use super::diagnosis::{Details, Diagnosis, Verdict};
use crate::io::num::Num;
use crate::model::effects::EffectKind;
use crate::sim::config::{rig_file_text, RigFile};

/// The identified rig: `base`'s parameters, scaled by the verdict's
/// `parameters` ratios when it has them, with the verdict's other effects.
/// `none` and `unexplained` identify the nominal rig.
pub fn rig(details: &Details) -> RigFile {
    let mut effects = details.effects;
    let params = match effects.parameters.take() {
        Some(r) => r.apply(details.base.params()),
        None => *details.base.params(),
    };
    RigFile { params, effects }
}

/// The rig file's text: [`rig`] under a header that says where it comes
/// from and how far it is to be trusted.
pub fn rig_text(d: &Diagnosis, details: &Details, runs: &str) -> String {
    let trust = match d.verdict {
        Verdict::None => {
            "the runs agree with the nominal model within their noise: the nominal rig"
        }
        Verdict::Unexplained => {
            "no effect explained the gap: the nominal rig (the gap remains; see the report)"
        }
        Verdict::Effect(EffectKind::Parameters) => "the re-estimated parameters",
        Verdict::Effect(_) => "the verdict's effect with its fitted parameters",
    };
    let header = format!(
        "The rig as `host-sim gap` identified it ({runs}).\n\
         Verdict: {} - {trust}.\n\
         Gap (fit runs): {} -> {}; (check runs, held out): {} -> {}.\n\
         Run it with `--plant` (host-sim run, sweep, hil), tune for it with `host-sim tune --plant`.",
        d.verdict,
        Num(d.fit.before),
        Num(d.fit.after),
        Num(d.check.before),
        Num(d.check.after),
    );
    rig_file_text(&rig(details), &header)
}
