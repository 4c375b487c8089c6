//! `parameters`: a grey-box re-estimate of the rig's nominal parameters
//! (docs/model.md section 12) on the fit runs.
//!
//! The candidate parameters are the ratios of
//! [`crate::model::effects::ParameterRatios`] (mass, bulk modulus, hose wall
//! compliance, viscous damping, servo time constant, accumulator precharge,
//! actuating-piston areas), fitted as theta = ln(ratio) within
//! [`RATIO_BOUNDS`]:
//!
//! 1. **Scans**: each ratio alone on a grid of 8 values from 1/3 to 3 (the
//!    residual of oscillatory responses is far from linear in them).
//! 2. **Subset** (forward selection): the three most promising ratios (by
//!    the scans first, then by the Jacobian of the block-mean residuals
//!    ([`super::lsq::residuals`]) at the current estimate) are each fitted
//!    together with those already chosen (Levenberg-Marquardt); the best is
//!    kept while it lowers the residual's excess over the noise floor by at
//!    least [`MIN_GAIN`] of what is left, at most [`MAX_FREE`] ratios (a
//!    small, identifiable subset; the others stay 1), and only while the
//!    residual left implies a gap of at least
//!    [`super::measure::CLEAN_GAP`] (what clean runs show).
//! 3. **Fit**: Levenberg-Marquardt on the subset to convergence.
//! 4. **Intervals**: cov(theta) = s^2 (J^T J)^-1 at the estimate, with
//!    s^2 = RSS / (N - p) and inflated by (1 + rho) / (1 - rho), rho the
//!    residuals' lag-1 autocorrelation (an AR(1) effective sample size:
//!    block means next to each other are not independent); the 95 %
//!    interval is exp(theta +- 1.96 sd) times the nominal value.

use rayon::prelude::*;
use serde::Serialize;

use super::lsq::{self, levenberg_marquardt, noise_floor, normal_step};
use super::measure::{gap, CLEAN_GAP};
use super::run::Run;
use crate::model::effects::{Effects, ParameterRatios, RATIO_BOUNDS, RATIO_KEYS};
use crate::model::params;
use crate::model::plant::Plant;

/// Most ratios fitted at once.
pub const MAX_FREE: usize = 3;
/// Smallest share of the remaining excess sum of squares (over the noise
/// floor) a further ratio must remove, on the linearised problem.
pub const MIN_GAIN: f64 = 0.1;
/// A re-estimate is plausible within these ratios of the nominal value.
pub const PLAUSIBLE: (f64, f64) = (0.5, 2.0);
/// Step of the finite differences, in ln(ratio).
const H_LN: f64 = 0.05;
/// Levenberg-Marquardt iterations (Jacobians) of the final fit at most.
const ITERS: usize = 10;
/// A ratio within this of its bound (in ln) sits at the bound.
const AT_BOUND_LN: f64 = 0.02;

/// One re-estimated parameter.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Estimate {
    /// Its key in [`crate::model::params::KEYS`] (`beta_e_pa`, `hose.ce0_m3pp`).
    pub key: String,
    /// The nominal value, SI.
    pub nominal: f64,
    /// The re-estimate, SI.
    pub value: f64,
    /// 95 % confidence interval of the re-estimate, SI.
    pub ci95: [f64; 2],
    /// value / nominal.
    pub ratio: f64,
    /// Whether the fit ended at a bound of [`RATIO_BOUNDS`].
    pub at_bound: bool,
}

/// The grey-box fit.
#[derive(Clone, Debug, PartialEq)]
pub struct GreyBox {
    /// The re-estimated parameters as the `parameters` effect.
    pub effects: Effects,
    /// The fitted parameters (empty when none lowers the residual).
    pub estimates: Vec<Estimate>,
    /// Every ratio within [`PLAUSIBLE`] and none at a bound.
    pub plausible: bool,
    /// Replays of the fit runs used.
    pub evals: usize,
}

fn ratios_effects(theta: &[f64; 7]) -> Effects {
    let mut e = Effects::NONE;
    e.parameters = Some(ParameterRatios::from_array(theta.map(f64::exp)));
    e
}

/// Candidate ratios of the one-parameter scans, ln(ratio) (0 is the nominal model).
const SCAN: [f64; 8] = [
    -LN_3,
    -std::f64::consts::LN_2,
    -LN_1_4,
    -LN_1_15,
    LN_1_15,
    LN_1_4,
    std::f64::consts::LN_2,
    LN_3,
];
/// ln 3, ln 1.4, ln 1.15.
const LN_3: f64 = 1.098_612_288_668_109_8;
const LN_1_4: f64 = 0.336_472_236_621_212_9;
const LN_1_15: f64 = 0.139_761_942_375_158_8;
/// Candidates refitted per step of the forward selection.
const TRIES: usize = 3;
/// Levenberg-Marquardt iterations of a trial; of the final fit.
const TRIAL_ITERS: usize = 5;

/// A fit of the ratios `free` (indices into [`RATIO_KEYS`]) with the others at 1.
struct SubFit {
    free: Vec<usize>,
    fit: lsq::LsqFit,
}

/// Re-estimate the parameters on `runs`; `None` when the nominal model
/// cannot be replayed.
pub fn fit(runs: &[Run], base: &Plant, dt_s: f64) -> Option<GreyBox> {
    let mut g = GreyFit::new(runs, base, dt_s)?;
    // 1. One-parameter scans: where each ratio alone lowers the residual most.
    let scans = g.scans();
    // 2. Forward selection of a small subset.
    let chosen = g.select(&scans);
    // 3. The final fit and its intervals.
    let (theta, estimates) = match chosen {
        Some(s) => g.final_fit(s)?,
        None => ([0.0; 7], Vec::new()),
    };
    let plausible = !estimates.is_empty()
        && estimates
            .iter()
            .all(|e| !e.at_bound && (PLAUSIBLE.0..=PLAUSIBLE.1).contains(&e.ratio));
    Some(GreyBox {
        effects: ratios_effects(&theta),
        estimates,
        plausible,
        evals: g.evals,
    })
}

/// The steps of [`fit`] on the fit runs, and the replays they took.
struct GreyFit<'a> {
    /// The fit runs.
    runs: &'a [Run],
    /// The nominal plant.
    base: &'a Plant,
    /// The replay's step, s.
    dt_s: f64,
    /// [`RATIO_BOUNDS`] in ln(ratio).
    lo: f64,
    /// See `lo`.
    hi: f64,
    /// The nominal model's residuals.
    r0: Vec<f64>,
    /// The residuals' noise floor (sum of squares).
    floor: f64,
    /// Replays of the fit runs so far.
    evals: usize,
}

impl<'a> GreyFit<'a> {
    /// The nominal model replayed once; `None` where it cannot be.
    fn new(runs: &'a [Run], base: &'a Plant, dt_s: f64) -> Option<Self> {
        let mut g = Self {
            runs,
            base,
            dt_s,
            lo: RATIO_BOUNDS.0.ln(),
            hi: RATIO_BOUNDS.1.ln(),
            r0: Vec::new(),
            floor: 0.0,
            evals: 1,
        };
        g.r0 = g.full(&[0.0; 7])?;
        g.floor = noise_floor(runs);
        Some(g)
    }

    /// The residuals with the ratios exp(`theta`).
    fn full(&self, theta: &[f64]) -> Option<Vec<f64>> {
        let t: [f64; 7] = std::array::from_fn(|i| theta[i]);
        lsq::residuals(self.runs, self.base, &ratios_effects(&t), self.dt_s)
    }

    /// A sum of squares' excess over the noise floor.
    fn excess(&self, rss: f64) -> f64 {
        (rss - self.floor).max(0.0)
    }

    /// Levenberg-Marquardt on the ratios `free` from `x0`, the others at 1.
    fn refit(&self, free: Vec<usize>, x0: Vec<f64>, iters: usize) -> Option<SubFit> {
        let sub = |x: &[f64]| self.full(&theta_of(&free, x));
        let p = free.len();
        let fit = levenberg_marquardt(
            &sub,
            &x0,
            None,
            &vec![H_LN; p],
            &vec![self.lo; p],
            &vec![self.hi; p],
            iters,
        )?;
        Some(SubFit { free, fit })
    }

    /// Each ratio alone on [`SCAN`]: (ratio, best ln(ratio), its sum of
    /// squares).
    fn scans(&mut self) -> Vec<(usize, f64, f64)> {
        let scans = (0..7)
            .into_par_iter()
            .map(|j| {
                let mut best = (0.0, lsq::ss(&self.r0));
                for &g in &SCAN {
                    let mut t = [0.0; 7];
                    t[j] = g;
                    if let Some(r) = self.full(&t) {
                        let v = lsq::ss(&r);
                        if v < best.1 {
                            best = (g, v);
                        }
                    }
                }
                (j, best.0, best.1)
            })
            .collect();
        self.evals += 7 * SCAN.len();
        scans
    }

    /// Forward selection: the most promising ratios refitted with those
    /// already chosen; the best kept while it lowers the excess by
    /// [`MIN_GAIN`], at most [`MAX_FREE`], while the gap left is beyond a
    /// clean run's.
    fn select(&mut self, scans: &[(usize, f64, f64)]) -> Option<SubFit> {
        let mut now: Option<SubFit> = None;
        let mut now_excess = self.excess(lsq::ss(&self.r0));
        // The gap the excess implies: its mean per block and channel, rooted.
        let blocks = self.r0.len().max(1) as f64;
        let implied_gap = |e: f64| (e / blocks).sqrt();
        while now.as_ref().map_or(0, |s| s.free.len()) < MAX_FREE
            && now_excess > 0.0
            && (now.is_none() || implied_gap(now_excess) >= CLEAN_GAP)
        {
            let (free, x) = match &now {
                Some(s) => (s.free.clone(), s.fit.x.clone()),
                None => (Vec::new(), Vec::new()),
            };
            let proposals = self.proposals(scans, now.as_ref(), &free, &x);
            let trials: Vec<SubFit> = proposals
                .par_iter()
                .filter_map(|&(j, start)| {
                    let mut f = free.clone();
                    f.push(j);
                    let mut x0 = x.clone();
                    x0.push(start);
                    self.refit(f, x0, TRIAL_ITERS)
                })
                .collect();
            self.evals += trials.iter().map(|t| t.fit.evals).sum::<usize>();
            let Some(best) = trials
                .into_iter()
                .min_by(|a, b| a.fit.rss.total_cmp(&b.fit.rss))
            else {
                break;
            };
            let e = self.excess(best.fit.rss);
            if now_excess - e < MIN_GAIN * now_excess {
                break;
            }
            now_excess = e;
            now = Some(best);
        }
        now
    }

    /// The ratios to try next with their starts: the best [`TRIES`] of the
    /// scans first, then of the problem linearised at the current estimate
    /// `now` (ratios `free` at `x`).
    fn proposals(
        &mut self,
        scans: &[(usize, f64, f64)],
        now: Option<&SubFit>,
        free: &[usize],
        x: &[f64],
    ) -> Vec<(usize, f64)> {
        if free.is_empty() {
            let mut by_scan = scans.to_vec();
            by_scan.sort_by(|a, b| a.2.total_cmp(&b.2));
            return by_scan.iter().take(TRIES).map(|s| (s.0, s.1)).collect();
        }
        let t = theta_of(free, x);
        let r = now.map(|s| s.fit.r.clone()).unwrap_or_default();
        let full = |theta: &[f64]| self.full(theta);
        let jac = lsq::jacobian(&full, &t, &r, &[H_LN; 7], &[self.hi; 7]);
        self.evals += 7;
        let mut lin = linear_gains(&jac, &r, free);
        lin.sort_by(|a, b| a.1.total_cmp(&b.1));
        lin.iter().take(TRIES).map(|l| (l.0, 0.0)).collect()
    }

    /// The subset `s` fitted to convergence (kept where that is no better),
    /// as the full theta and the estimates with their 95 % intervals.
    fn final_fit(&mut self, s: SubFit) -> Option<([f64; 7], Vec<Estimate>)> {
        let last = self.refit(s.free.clone(), s.fit.x.clone(), ITERS)?;
        let last = if last.fit.rss <= s.fit.rss { last } else { s };
        self.evals += last.fit.evals;
        let f = &last.fit;
        let sd = standard_errors(f);
        let mut theta = [0.0; 7];
        let mut estimates = Vec::new();
        for (k, &i) in last.free.iter().enumerate() {
            theta[i] = f.x[k];
            let at_bound = f.x[k] <= self.lo + AT_BOUND_LN || f.x[k] >= self.hi - AT_BOUND_LN;
            let ratio = f.x[k].exp();
            let band = [(f.x[k] - 1.96 * sd[k]).exp(), (f.x[k] + 1.96 * sd[k]).exp()];
            for name in RATIO_KEYS[i] {
                let Some(key) = params::find(name) else {
                    continue;
                };
                let nominal = key.get(self.base.params());
                estimates.push(Estimate {
                    key: key.name.to_string(),
                    nominal,
                    value: nominal * ratio,
                    ci95: [nominal * band[0], nominal * band[1]],
                    ratio,
                    at_bound,
                });
            }
        }
        Some((theta, estimates))
    }
}

/// Ratios `free` at `x` (others 1) as the full theta.
fn theta_of(free: &[usize], x: &[f64]) -> [f64; 7] {
    let mut t = [0.0; 7];
    for (i, v) in free.iter().zip(x) {
        t[*i] = *v;
    }
    t
}

/// For each ratio not in `free`: the sum of squares the linearised problem
/// r + J d leaves with it and `free` fitted.
fn linear_gains(jac: &[Vec<f64>], r: &[f64], free: &[usize]) -> Vec<(usize, f64)> {
    (0..jac.len())
        .filter(|j| !free.contains(j))
        .filter_map(|j| {
            let mut cols = free.to_vec();
            cols.push(j);
            let d = normal_step(jac, &cols, r, 0.0)?;
            let rss: f64 = (0..r.len())
                .map(|k| {
                    let v = r[k]
                        + cols
                            .iter()
                            .zip(&d)
                            .map(|(c, x)| jac[*c][k] * x)
                            .sum::<f64>();
                    v * v
                })
                .sum();
            Some((j, rss))
        })
        .collect()
}

/// Standard deviations of the fitted parameters (see the module
/// documentation); infinite where J^T J is singular.
pub fn standard_errors(f: &lsq::LsqFit) -> Vec<f64> {
    let p = f.x.len();
    let dof = f.n.saturating_sub(p).max(1) as f64;
    let rho = lsq::lag1(&f.r).clamp(0.0, 0.95);
    let s2 = f.rss / dof * (1.0 + rho) / (1.0 - rho);
    match lsq::inverse_normal(&f.jac) {
        Some(inv) => (0..p).map(|i| (s2 * inv[i][i]).max(0.0).sqrt()).collect(),
        None => vec![f64::INFINITY; p],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::validation::{fit_scenario, rig_log};
    use crate::model::effects::EffectKind;
    use dca_core::controller::ControllerKind;

    #[test]
    fn re_estimates_a_lowered_bulk_modulus_within_its_interval() {
        let mut truth = Effects::NONE;
        truth.set(EffectKind::Parameters, Some(&[1.0, 0.6]));
        let runs = vec![Run::new(
            "f".into(),
            rig_log(fit_scenario(), ControllerKind::MpcEso, &truth, 11),
        )];
        let g = fit(&runs, &Plant::nominal(), 5e-4).unwrap();
        let beta = g
            .estimates
            .iter()
            .find(|e| e.key == "beta_e_pa")
            .unwrap_or_else(|| panic!("beta_e_pa not re-estimated: {g:?}"));
        assert!((beta.ratio - 0.6).abs() < 0.05, "{g:?}");
        assert!(beta.ci95[0] < beta.value && beta.value < beta.ci95[1]);
        assert!(g.plausible, "{g:?}");
    }
}

#[cfg(test)]
mod explore {
    use super::*;
    use crate::gap::measure::gap;
    use crate::gap::validation::{check_scenario, fit_scenario, rig_log};
    use crate::model::effects::EffectKind;
    use dca_core::controller::ControllerKind;

    #[test]
    #[ignore]
    fn explore() {
        for truth_v in [vec![1.0, 0.6], vec![1.6], vec![1.0, 1.0, 1.7]] {
            let mut truth = Effects::NONE;
            truth.set(EffectKind::Parameters, Some(&truth_v));
            let runs = vec![Run::new(
                "f".into(),
                rig_log(fit_scenario(), ControllerKind::MpcEso, &truth, 11),
            )];
            let check = vec![Run::new(
                "c".into(),
                rig_log(check_scenario(), ControllerKind::Pid, &truth, 12),
            )];
            let base = Plant::nominal();
            let t0 = std::time::Instant::now();
            let g = fit(&runs, &base, 5e-4).unwrap();
            let el = t0.elapsed().as_secs_f64();
            eprintln!("truth {truth_v:?}: nominal fit {:.2} check {:.2}; truth fit {:.2}; est fit {:.2} check {:.2}; {:?} evals {} in {el:.1}s",
                gap(&runs, &base, &Effects::NONE, 5e-4), gap(&check, &base, &Effects::NONE, 5e-4),
                gap(&runs, &base, &truth, 5e-4),
                gap(&runs, &base, &g.effects, 5e-4), gap(&check, &base, &g.effects, 5e-4),
                g.estimates.iter().map(|e| (e.key.clone(), e.ratio, e.ci95[0]/e.nominal, e.ci95[1]/e.nominal)).collect::<Vec<_>>(), g.evals);
        }
    }
}

/// Largest difference of a parameter's log ratio between the fit runs' and
/// the check runs' re-estimates for the two to agree (about 10 %).
pub const AGREE_LN: f64 = 0.1;

/// The fit runs' re-estimate predicts the check runs as well as their own
/// when it leaves them at most this factor (plus [`AGREE_GAP`]) of the gap
/// their own re-estimate leaves.
pub const AGREE_FACTOR: f64 = 1.2;
/// ... plus this much gap (a tenth of the noise's level).
pub const AGREE_GAP: f64 = 0.1;

/// Whether the re-estimate `on_fit` (from the fit runs), which leaves the
/// check runs at the gap `on_fit_check_gap`, agrees with one made on the
/// check runs alone: either every ratio the check runs re-estimate is
/// within [`AGREE_LN`] of the fit runs' (1 where the fit runs left it
/// nominal; ratios only the fit runs re-estimate are not contradicted), or
/// the fit runs' re-estimate predicts the check runs about as well as their
/// own ([`AGREE_FACTOR`]): a parameter group the check runs add to match
/// details the fit runs did not need (a bulk modulus beside a softer hose
/// wall on 10 ms rows) does not contradict it. A re-estimate that stands in
/// for an effect which is not a parameter (hysteresis taken for a softer
/// wall) moves with the runs' scenario and fails both.
pub fn agrees(
    on_fit: &[Estimate],
    on_fit_check_gap: f64,
    check: &[Run],
    base: &Plant,
    dt_s: f64,
) -> bool {
    let Some(on_check) = fit(check, base, dt_s) else {
        return false;
    };
    let same_ratios = on_check.estimates.iter().all(|c| {
        let f = on_fit
            .iter()
            .find(|e| e.key == c.key)
            .map_or(1.0, |e| e.ratio);
        (c.ratio.ln() - f.ln()).abs() <= AGREE_LN
    });
    same_ratios || {
        let own = gap(check, base, &on_check.effects, dt_s);
        on_fit_check_gap <= AGREE_FACTOR * own + AGREE_GAP
    }
}
