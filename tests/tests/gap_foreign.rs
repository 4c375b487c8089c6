//! The gap diagnosis on rig logs from an independent simulator whose effect
//! models have forms the diagnosis does not know (`dca_tests::foreign`):
//! orifice leakage, LuGre friction, Hertz-contact backlash, an exponential
//! air law, a second-order LVDT filter with delayed pressures, a servo force
//! limit, Bouc-Wen hose hysteresis and a gas-wall thermal model. Different
//! scenarios from the project's own suite, too. The table is written to
//! target/gap-foreign.md.
//!
//! The suite takes minutes, so `cargo test` skips it (`#[ignore]`); CI runs
//! it as its own stage, `.ci/validation.sh`.

use dca_tests::foreign::{cases, log_csv, ForeignCase, ForeignScenario};
use host_sim::gap::diagnose::Options;
use host_sim::gap::policy::NONE_GAP;
use host_sim::gap::validation::{publish, score, Case};
use host_sim::io::runlog::RunLog;
use host_sim::model::effects::{EffectKind, Effects};

fn as_case(c: &ForeignCase) -> Case {
    Case {
        name: c.name.clone(),
        truth: c
            .truth
            .iter()
            .filter(|t| **t != "none")
            .map(|t| EffectKind::by_name(t).expect("an identifier of docs/model.md section 12"))
            .collect(),
        // The foreign effects have no counterpart here: the truth is the name.
        effects: Effects::NONE,
    }
}

fn read(case: &ForeignCase, s: ForeignScenario, seed: u64) -> RunLog {
    RunLog::parse(&log_csv(case, s, seed), s.name()).expect("foreign log reads")
}

/// The fit and check logs of the `i`-th case (1 ms rows).
fn logs(case: &ForeignCase, i: usize) -> (RunLog, RunLog) {
    let seed = 500 + 2 * i as u64;
    (
        read(case, ForeignScenario::Fit, seed),
        read(case, ForeignScenario::Check, seed + 1),
    )
}

#[test]
#[ignore = "validation suite, minutes: CI's validation stage runs it (bash .ci/validation.sh)"]
fn gap_diagnosis_on_foreign_effect_forms() {
    let foreign = cases();
    let ours: Vec<Case> = foreign.iter().map(as_case).collect();
    let out = score(
        &ours,
        |i, _| logs(&foreign[i], i),
        &Options::default(),
        false,
    );
    let s = publish(&out, "gap-foreign.md");
    // The targets, on effects of forms the diagnosis never saw.
    assert_eq!(s.clean.0, s.clean.1, "clean runs must give `none`");
    assert!(
        s.single.0 as f64 >= 0.9 * s.single.1 as f64,
        "single effects right: {}/{}",
        s.single.0,
        s.single.1
    );
    assert!(s.pairs.0 >= 1, "pairs naming one of the two: {:?}", s.pairs);
    // Held out: where the check runs show a gap, the chosen effect shrinks it
    // by at least 30 % (the verdict's own criterion) or brings it within the
    // noise. The forms differ, so 50 % is not asserted here; docs/gap.md
    // gives the measured shrinks.
    for o in out
        .iter()
        .filter(|o| o.right() && o.case.truth.len() == 1 && o.check_excited())
    {
        let c = &o.diagnosis.check;
        assert!(
            c.shrink >= 0.3 || c.after < NONE_GAP,
            "{}: check {:.2} -> {:.2}",
            o.case.name,
            c.before,
            c.after
        );
    }
}

/// The foreign logs as the board's console records them: every tenth row
/// (10 ms). A measurement (`--ignored`): it publishes
/// target/gap-foreign-10ms.md and checks `none` on the clean runs and finite
/// gaps everywhere; docs/gap.md gives its table.
#[test]
#[ignore = "measurement; run with --ignored --nocapture"]
fn gap_diagnosis_on_foreign_effect_forms_at_10_ms() {
    let foreign = cases();
    let ours: Vec<Case> = foreign.iter().map(as_case).collect();
    let out = score(
        &ours,
        |i, _| {
            let (fit, check) = logs(&foreign[i], i);
            (fit.decimate(10), check.decimate(10))
        },
        &Options::default(),
        false,
    );
    let s = publish(&out, "gap-foreign-10ms.md");
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
