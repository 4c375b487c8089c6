//! Isolation: which equation of the model the runs violate and what the
//! violation depends on, found before any effect is named.
//!
//! The structural residuals ([`super::equations`]) say which equations are
//! out of balance; the closures ([`super::closures`]), each a form-free term
//! added to one equation, say which single equation's correction explains
//! them and over which of its variables. Closures are judged on what they
//! leave of the fit runs' excess (with a penalty for their number of
//! weights) and of the held-out check runs' together. Closures that leave about as
//! much ([`comparable`]) cannot be told apart by the residuals: the verdict
//! is then decided between the effects they name by the replayed models
//! ([`super::policy`]), and only between those.

use rayon::prelude::*;
use serde::Serialize;

use super::closures::{
    fit_closure, library, residual_excess, Closure, Dependence, Fitted, Knots, RunData, Site,
};
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

/// A closure leaves about as much as the best when it leaves at most this
/// much more excess per block (in units of the noise's power)...
pub const COMPARABLE_ABS: f64 = 0.5;
/// ... or at most this share more than the best leaves.
pub const COMPARABLE_REL: f64 = 0.25;
/// A closure of the best's own equation keeps its name in play when it
/// leaves at most this many times what the best leaves (plus
/// [`COMPARABLE_ABS`]): within one equation the dependences nest (the
/// pressure-history closure holds the static pressure closure, the coupling
/// loop holds the plain relative displacement), so the richer one wins by
/// its extra freedom as well as by being right, and the replayed models
/// decide between them.
pub const SAME_EQUATION_FACTOR: f64 = 1.5;

/// Share of the best closure's gain on the fit runs that one residual must
/// hold for a `parameters` closure to be read as that equation's violation
/// ([`Isolation::parameters_in_one_equation`]).
pub const ONE_EQUATION_SHARE: f64 = 0.9;
/// Share of a residual's excess on the fit runs a closure must explain to
/// count among that residual's closures.
pub const IN_RESIDUAL_SHARE: f64 = 0.1;

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
    /// Every closure tried, best first.
    pub closures: Vec<Fitted>,
    /// The violated equation: where the best closure adds its term.
    pub equation: String,
    /// What its term depends on.
    pub dependence: String,
    /// The identifier the table of docs/gap.md gives the two
    /// (`unexplained` outside the catalogue).
    pub names: String,
    /// The identifiers a verdict may name ([`Isolation::allows`]): those of
    /// the closures comparable to the best ([`comparable`]) and of the
    /// best's own equation ([`Isolation::same_equation`]), the best's first;
    /// `unexplained` for a closure outside the catalogue.
    pub may_name: Vec<String>,
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

    /// What a closure leaves of the runs' excess, per block ([`Fitted::left`]).
    pub fn left(&self, c: &Fitted) -> f64 {
        c.left
    }

    /// The closures of the best's own equation (the same dominant residual)
    /// that leave at most [`SAME_EQUATION_FACTOR`] times what the best
    /// leaves: other dependences of the same equation's violation, told
    /// apart less surely than equations are.
    pub fn same_equation(&self) -> impl Iterator<Item = &Fitted> {
        let best = self.best().map(|b| (b.dominant(), b.left));
        self.closures.iter().filter(move |c| {
            best.is_some_and(|(d, l)| {
                c.dominant() == d && c.left <= SAME_EQUATION_FACTOR * l.max(0.0) + COMPARABLE_ABS
            })
        })
    }

    /// Whether the effect `k` is among those the comparable closures, or
    /// the closures of the same equation, name.
    pub fn allows(&self, k: EffectKind) -> bool {
        self.comparable_closures()
            .chain(self.same_equation())
            .any(|c| c.closure.names() == Some(k))
    }

    /// Where the best closure re-scales the nominal parameters but holds
    /// its gain (at least [`ONE_EQUATION_SHARE`] of it, on the fit runs) in
    /// one residual: that residual's index. Scaling one equation's own terms
    /// then says where, not which form: an effect with memory (a speed
    /// loop's integrator winding up) is no function of the closures'
    /// variables, and its linear closure may fit the check runs worse than a
    /// rescaled time constant while its replayed model explains them.
    pub fn parameters_in_one_equation(&self) -> Option<usize> {
        let b = self.best()?;
        if b.closure.site != Site::Parameters {
            return None;
        }
        let total: f64 = b.fit_per_residual.iter().map(|x| x.max(0.0)).sum();
        let d = b.dominant();
        (total > 0.0 && b.fit_per_residual[d] >= ONE_EQUATION_SHARE * total).then_some(d)
    }

    /// The effects other than `parameters` that closures of residual `r`
    /// name (each explaining at least [`IN_RESIDUAL_SHARE`] of its excess on
    /// the fit runs, and most in it).
    pub fn named_in_residual(&self, r: usize) -> impl Iterator<Item = EffectKind> + '_ {
        self.closures
            .iter()
            .filter(move |c| c.dominant() == r && c.fit_per_residual[r] >= IN_RESIDUAL_SHARE)
            .filter_map(|c| c.closure.names())
            .filter(|k| *k != EffectKind::Parameters)
    }

    /// Whether a `parameters` closure holds its gain in one residual
    /// ([`Isolation::parameters_in_one_equation`]) and a closure of that
    /// residual names `k` ([`Isolation::named_in_residual`]).
    pub fn in_one_equation(&self, k: EffectKind) -> bool {
        self.parameters_in_one_equation()
            .is_some_and(|r| self.named_in_residual(r).any(|x| x == k))
    }

    /// Whether the best closure lies outside the catalogue (a force over
    /// the load's position, a drift): no effect of the catalogue is then
    /// named, whatever the others explain.
    pub fn outside_best(&self) -> bool {
        self.best().is_some_and(|c| c.closure.names().is_none())
    }

    /// The effects worth fitting as models: those a verdict may name
    /// ([`Isolation::allows`]), the first three effects the best closures
    /// name (the best partial candidates of an `unexplained`), and where a
    /// `parameters` closure holds its gain in one residual, the effects
    /// that residual's closures name; in [`EffectKind::ALL`] order.
    pub fn to_fit(&self) -> Vec<EffectKind> {
        let mut best3: Vec<EffectKind> = Vec::new();
        for k in self.closures.iter().filter_map(|c| c.closure.names()) {
            if best3.len() == 3 {
                break;
            }
            if !best3.contains(&k) {
                best3.push(k);
            }
        }
        EffectKind::ALL
            .into_iter()
            .filter(|k| best3.contains(k) || self.allows(*k) || self.in_one_equation(*k))
            .collect()
    }

    /// The fitted weights of the closure at `site` depending on `dep`.
    pub fn weights(&self, site: Site, dep: Dependence) -> Option<&[f64]> {
        self.closures
            .iter()
            .find(|c| c.closure.site == site && c.closure.dep == dep)
            .map(|c| c.w.as_slice())
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
    let mut closures: Vec<Fitted> = library()
        .par_iter()
        .map(|c| fit_closure(*c, &fit_d, &check_d, plant, &knots))
        .collect();
    closures.sort_by(|a, b| a.left.total_cmp(&b.left));
    let mut iso = Isolation {
        residuals,
        equation: String::new(),
        dependence: String::new(),
        names: String::new(),
        may_name: Vec::new(),
        closures,
    };
    if let Some(b) = iso.best().map(|b| b.closure) {
        iso.equation = b.site.name();
        iso.dependence = b.dep.name().to_string();
        iso.names = name_of(b).to_string();
    }
    let mut names: Vec<String> = Vec::new();
    for c in iso.comparable_closures().chain(iso.same_equation()) {
        let n = name_of(c.closure).to_string();
        if !names.contains(&n) {
            names.push(n);
        }
    }
    iso.may_name = names;
    iso
}

/// The identifier a closure names, `unexplained` outside the catalogue.
fn name_of(c: Closure) -> &'static str {
    c.names().map_or("unexplained", EffectKind::name)
}

#[cfg(test)]
mod tests {
    use super::*;
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
