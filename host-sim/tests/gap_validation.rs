//! The validation suite of the gap diagnosis (issue targets): right verdict
//! for at least 90 % of the single-effect cases and `none` for clean runs;
//! at least 50 % shrink of the gap on the held-out check runs wherever the
//! verdict is right and the check runs show a gap beyond the noise. The
//! table is written to target/gap-validation.md.

use host_sim::gap::diagnose::Options;
use host_sim::gap::validation::{cases, publish, run_suite};

#[test]
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
}
