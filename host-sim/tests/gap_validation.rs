//! The validation suite of the gap diagnosis (issue targets): right verdict
//! for at least 90 % of the single-effect cases and `none` for clean runs;
//! at least 50 % shrink of the gap on the held-out check runs wherever the
//! verdict is right and the check runs show a gap beyond the noise. The
//! re-estimate of the nominal parameters must not absorb a named effect
//! (entrained air depends on pressure, a wrong bulk modulus does not): no
//! case with a named effect comes out `parameters`, every `air` case comes
//! out `air`, and where the rig's parameters are off the re-estimate finds
//! the parameter that is off. The table is written to
//! target/gap-validation.md.
//!
//! The suite takes minutes, so `cargo test` skips it (`#[ignore]`); CI runs
//! it as its own stage, `.ci/validation.sh`.

use host_sim::gap::diagnose::Options;
use host_sim::gap::validation::{cases, publish, run_suite, score, suite_logs};
use host_sim::model::effects::{EffectKind, RATIO_KEYS};

#[test]
#[ignore = "validation suite, minutes: CI's validation stage runs it (bash .ci/validation.sh)"]
fn gap_validation_suite() {
    let out = run_suite(&cases(), &Options::default(), false);
    let s = publish(&out, "gap-validation.md");
    assert_eq!(s.clean.0, s.clean.1, "clean runs must give `none`");
    assert!(
        s.single.0 as f64 >= 0.9 * s.single.1 as f64,
        "single effects right: {}/{}",
        s.single.0,
        s.single.1
    );
    // The shrink target applies where the check runs show a gap at all.
    for o in out
        .iter()
        .filter(|o| o.right() && o.case.truth.len() == 1 && o.check_excited())
    {
        let c = &o.diagnosis.check;
        assert!(
            c.shrink >= 0.5,
            "{}: check {:.2} -> {:.2} ({:.0} %)",
            o.case.name,
            c.before,
            c.after,
            c.shrink * 100.0
        );
    }
    // The general families' path: shapes their named forms cannot take come
    // out right in the general family of their part of the rig (where the
    // named form fails, or holds but leaves clearly more on the check runs).
    for name in [
        "leakage (seal lip",
        "sensor_delay (encoder",
        "sensor_calibration (LVDT wavy",
        "accumulator_thermal (yielding",
        "sensor_calibration (force sensor",
    ] {
        let o = out
            .iter()
            .find(|o| o.case.name.starts_with(name))
            .expect("a case of the suite");
        let form = o.diagnosis.form.as_deref().unwrap_or("-");
        assert!(
            o.right() && form.starts_with("general:"),
            "{}: `{}` in the form {form}",
            o.case.name,
            o.diagnosis.verdict
        );
    }
    // The load cell's case is learned on the force sensor (channel 4), not
    // on the pressures its error shows in first.
    let o = out
        .iter()
        .find(|o| o.case.name.starts_with("sensor_calibration (force sensor"))
        .expect("a case of the suite");
    let chosen = o
        .diagnosis
        .candidates
        .iter()
        .find(|c| c.effect == "sensor_calibration")
        .expect("a sensor_calibration candidate");
    assert_eq!(
        chosen.params.get("channel"),
        Some(&4.0),
        "{:?}",
        chosen.params
    );
    // `parameters` does not absorb a named effect.
    for o in out
        .iter()
        .filter(|o| !o.case.truth.is_empty() && !o.case.truth.contains(&EffectKind::Parameters))
    {
        assert!(
            o.diagnosis.verdict != EffectKind::Parameters.name(),
            "{}: came out `parameters`",
            o.case.name
        );
    }
    for o in out.iter().filter(|o| o.case.truth == [EffectKind::Air]) {
        assert!(
            o.diagnosis.verdict == "air",
            "{}: came out `{}`, not `air`",
            o.case.name,
            o.diagnosis.verdict
        );
    }
    // Where the parameters are off, the re-estimate finds the one that is
    // (within 5 % of its true ratio).
    for o in out
        .iter()
        .filter(|o| o.case.truth == [EffectKind::Parameters])
    {
        let truth = o
            .case
            .effects
            .parameters
            .expect("a parameters case")
            .to_array();
        for (i, r) in truth.iter().enumerate().filter(|(_, r)| **r != 1.0) {
            let key = RATIO_KEYS[i][0];
            let e = o.diagnosis.parameters.iter().find(|e| e.key == key);
            assert!(
                e.is_some_and(|e| (e.ratio / r - 1.0).abs() <= 0.05),
                "{}: {key} (ratio {r}) re-estimated as {:?}",
                o.case.name,
                e.map(|e| (e.ratio, e.ci95))
            );
        }
    }
}

/// The same suite on logs as the board's console records them: every tenth
/// row (10 ms). A measurement (`--ignored`, about as long as the suite): it
/// publishes target/gap-validation-10ms.md and checks `none` on the clean runs
/// and finite gaps everywhere; docs/gap.md gives its table.
#[test]
#[ignore = "measurement; run with --ignored --nocapture"]
fn gap_validation_suite_at_10_ms() {
    let out = score(
        &cases(),
        |i, c| {
            let (fit, check) = suite_logs(i, c);
            (fit.decimate(10), check.decimate(10))
        },
        &Options::default(),
        false,
    );
    let s = publish(&out, "gap-validation-10ms.md");
    // (`publish` prints the table and its summary line.) The nominal model
    // holds on 10 ms rows: clean runs give `none` (they did not while the
    // load's median spanned 11 rows; docs/gap.md, "Logs at 10 ms"). Every
    // case diagnosed with finite gaps; the other verdicts are what the table
    // reports.
    assert_eq!(s.clean.0, s.clean.1, "clean runs must give `none`");
    for o in &out {
        assert!(o.gaps_finite(), "{}: {:?}", o.case.name, o.diagnosis.fit);
    }
}
