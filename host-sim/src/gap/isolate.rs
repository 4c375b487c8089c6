//! Isolation: which equation of the model the runs violate and what the
//! violation depends on, found before any effect is named.
//!
//! The structural residuals ([`super::equations`]) say which equations are
//! out of balance; the closures ([`super::closures`]), each a form-free term
//! added to one equation, say which single equation's correction explains
//! them and over which of its variables. The best closure is judged on the
//! held-out check runs where they show the violation, else on the fit runs
//! with a penalty for its number of weights. Closures that leave about as
//! much ([`comparable`]) cannot be told apart by the residuals: the verdict
//! is then decided between the effects they name by the replayed models
//! ([`super::policy`]), and only between those.

use rayon::prelude::*;
use serde::Serialize;

use super::closures::{fit_closure, library, residual_excess, Closure, Fitted, Knots, RunData};
use super::equations::Residual;
use super::run::Run;
use crate::model::effects::EffectKind;
use crate::model::plant::Plant;

/// A residual's excess over its noise (mean over the 10 ms blocks of the
/// squared block mean in units of its noise, less one): 0 within the noise.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ResidualExcess {
    /// `servo`, `line1`, `line2` or `force`.
    pub residual: String,
    /// The equations it checks.
    pub checks: String,
    /// On the fit runs.
    pub fit: f64,
    /// On the check runs.
    pub check: f64,
    /// Beyond [`VIOLATED`] on either.
    pub violated: bool,
}

/// Excess above which a residual is reported as violated (its block means
/// scatter 1.7 times as widely as the noise alone makes them).
pub const VIOLATED: f64 = 2.0;

/// Total check-run excess (summed over the residuals) from which the
/// closures are judged on the check runs: below it the check runs do not
/// show the violation, and the fit runs judge (penalised).
pub const CHECK_SHOWS: f64 = 2.0;

/// A closure leaves about as much as the best when it leaves at most this
/// much more excess per block (in units of the noise's power)...
pub const COMPARABLE_ABS: f64 = 0.5;
/// ... or at most this share more than the best leaves.
pub const COMPARABLE_REL: f64 = 0.25;

/// Whether a closure that leaves `left` is comparable to the best, which
/// leaves `best`.
pub fn comparable(left: f64, best: f64) -> bool {
    left - best <= COMPARABLE_ABS.max(COMPARABLE_REL * best.max(0.0))
}

/// What the isolation found.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Isolation {
    /// Each residual's excess on the fit and check runs.
    pub residuals: Vec<ResidualExcess>,
    /// `check` or `fit`: the runs the closures were judged on.
    pub judged_on: String,
    /// Every closure tried, best first.
    pub closures: Vec<Fitted>,
    /// The violated equation: where the best closure adds its term.
    pub equation: String,
    /// What its term depends on.
    pub dependence: String,
    /// The identifier the table of docs/gap.md gives the two
    /// (`unexplained` outside the catalogue).
    pub names: String,
    /// The identifiers of the closures that explain about as much as the
    /// best ([`comparable`]), the best's first; `unexplained` for a closure
    /// outside the catalogue.
    pub comparable: Vec<String>,
}

impl Isolation {
    /// The best closure.
    pub fn best(&self) -> Option<&Fitted> {
        self.closures.first()
    }

    /// The closures comparable to the best (the best first).
    pub fn comparable_closures(&self) -> impl Iterator<Item = &Fitted> {
        let best = self.best().map(|b| self.left(b));
        self.closures
            .iter()
            .filter(move |c| best.is_some_and(|b| comparable(self.left(c), b)))
    }

    /// What a closure leaves on the runs it is judged on.
    pub fn left(&self, c: &Fitted) -> f64 {
        if self.judged_on == "check" {
            c.check_left
        } else {
            c.fit_left
        }
    }

    /// Whether the effect `k` is among those the comparable closures name.
    pub fn allows(&self, k: EffectKind) -> bool {
        self.comparable_closures()
            .any(|c| c.closure.names() == Some(k))
    }

    /// Whether a closure outside the catalogue explains about as much as
    /// the best.
    pub fn outside_comparable(&self) -> bool {
        self.comparable_closures()
            .any(|c| c.closure.names().is_none())
    }

    /// The best closure's closure, if any.
    pub fn best_closure(&self) -> Option<Closure> {
        self.best().map(|b| b.closure)
    }
}

/// Isolate on the fit and check runs against `plant`.
pub fn isolate(fit: &[Run], check: &[Run], plant: &Plant) -> Isolation {
    let prep = |runs: &[Run]| -> Vec<RunData> {
        runs.par_iter()
            .map(|r| RunData::new(&r.log, plant))
            .collect()
    };
    let (fit_d, check_d) = (prep(fit), prep(check));
    let sigs: Vec<_> = fit_d.iter().map(|r| &r.sig).collect();
    let knots = Knots::of(&sigs);
    let ef = residual_excess(&fit_d);
    let ec = residual_excess(&check_d);
    let residuals = Residual::ALL
        .iter()
        .map(|r| ResidualExcess {
            residual: r.name().to_string(),
            checks: r.checks().to_string(),
            fit: ef[r.index()],
            check: ec[r.index()],
            violated: ef[r.index()].max(ec[r.index()]) > VIOLATED,
        })
        .collect();
    let on_check = ec.iter().sum::<f64>() >= CHECK_SHOWS;
    let mut closures: Vec<Fitted> = library()
        .par_iter()
        .map(|c| fit_closure(*c, &fit_d, &check_d, plant, &knots))
        .collect();
    let left = |c: &Fitted| if on_check { c.check_left } else { c.fit_left };
    closures.sort_by(|a, b| left(a).total_cmp(&left(b)));
    let mut iso = Isolation {
        residuals,
        judged_on: if on_check { "check" } else { "fit" }.into(),
        equation: String::new(),
        dependence: String::new(),
        names: String::new(),
        comparable: Vec::new(),
        closures,
    };
    if let Some(b) = iso.best().map(|b| b.closure) {
        iso.equation = b.site.name();
        iso.dependence = b.dep.name().to_string();
        iso.names = name_of(b).to_string();
    }
    let mut names: Vec<String> = Vec::new();
    for c in iso.comparable_closures() {
        let n = name_of(c.closure).to_string();
        if !names.contains(&n) {
            names.push(n);
        }
    }
    iso.comparable = names;
    iso
}

/// The identifier a closure names, `unexplained` outside the catalogue.
fn name_of(c: Closure) -> &'static str {
    c.names().map_or("unexplained", EffectKind::name)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::closures::{Dependence, Site};
    use crate::gap::validation::{cases, suite_logs};

    /// The own suite's case named `name`, isolated.
    fn isolated(name: &str) -> Isolation {
        let all = cases();
        let i = all
            .iter()
            .position(|c| c.name == name)
            .expect("a suite case");
        let (f, k) = suite_logs(i, &all[i]);
        isolate(
            &[Run::new("fit".into(), f)],
            &[Run::new("check".into(), k)],
            &Plant::nominal(),
        )
    }

    /// Each effect's own equation and dependence come out best, from the
    /// residuals alone.
    #[test]
    fn the_violated_equation_is_found_before_any_effect_is_fitted() {
        for (name, site, dep, residual) in [
            ("friction (small)", Site::Force, Dependence::Speed, "force"),
            (
                "leakage (small)",
                Site::Between,
                Dependence::PressureDifference,
                "line1",
            ),
            (
                "motor_limit (small)",
                Site::Servo,
                Dependence::Drive,
                "servo",
            ),
            (
                "accumulator_thermal (large)",
                Site::Line2,
                Dependence::Relaxation,
                "line2",
            ),
        ] {
            let iso = isolated(name);
            let best = iso.best_closure().expect("closures");
            assert_eq!(
                (best.site, best.dep),
                (site, dep),
                "{name}: {}",
                iso.equation
            );
            let violated: Vec<&str> = iso
                .residuals
                .iter()
                .filter(|r| r.violated)
                .map(|r| r.residual.as_str())
                .collect();
            assert_eq!(violated, [residual], "{name}");
        }
    }

    /// A clean rig violates no equation.
    #[test]
    fn a_clean_rig_violates_nothing() {
        let iso = isolated("clean (seed a)");
        assert!(
            iso.residuals.iter().all(|r| !r.violated),
            "{:?}",
            iso.residuals
        );
    }

    #[test]
    fn comparable_is_absolute_near_the_noise_and_relative_beyond() {
        assert!(comparable(0.4, -0.05));
        assert!(!comparable(0.6, 0.0));
        assert!(comparable(124.0, 100.0));
        assert!(!comparable(126.0, 100.0));
    }
}
