//! The memory GRNN hose chosen from data (beyond the paper): the filter time
//! constants and sigma picked by time-blocked cross-validation ([`select`]):
//! each fold is one contiguous fifth of every training run, so a fold's test
//! samples are not interleaved with its training samples.
//!
//! [`leave_one_run_out`] fits on all runs but one and tests on the held-out run,
//! side by side with the static (P, dP/dt) GRNN (the paper's model trained on the
//! quasi-static data, and the same inputs trained on the dynamic runs).
//!
//! The network itself is [`crate::model::hose::memory`].

use rayon::prelude::*;

use crate::model::hose::data::{DynamicData, DynamicRun, QuasiStaticData};
use crate::model::hose::grnn::PAPER_SIGMA;
use crate::model::hose::memory::{
    features, stack, static_features, MemoryGrnn, MEMORY_DIM, N_FILTERS,
};
use crate::model::hose::net::{score, vacc_relative_pct, FitError, Grnn, Scores, DEFAULT_SIGMAS};

/// Filter time constants searched by [`select`], s.
pub const TAU_GRID_S: [f64; 6] = [0.003, 0.01, 0.03, 0.1, 0.3, 1.0];
/// Spreads searched by [`select`] (z-score units).
pub const SIGMA_GRID: [f64; 4] = [0.05, 0.1, 0.2, 0.4];

/// Default training subsampling of the 1 kHz dynamic data (every n-th sample).
pub const DEFAULT_STRIDE: usize = 2;

/// Result of [`select`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Selection {
    /// Chosen filter time constants, s.
    pub taus_s: [f64; N_FILTERS],
    /// Chosen spread.
    pub sigma: f64,
    /// Cross-validated mean VAcc (relative) of the choice, %.
    pub cv_vacc_pct: f64,
    /// Every candidate: (taus, sigma, CV VAcc %).
    pub table: Vec<([f64; N_FILTERS], f64, f64)>,
}

/// Pick the filter time constants (pairs tau_1 < tau_2 from [`TAU_GRID_S`]) and
/// sigma ([`SIGMA_GRID`]) by 5-fold time-blocked cross-validation on `runs`
/// (every `stride`-th sample), maximising the mean fold VAcc (relative).
pub fn select(runs: &[&DynamicRun], stride: usize) -> Result<Selection, FitError> {
    let mut pairs = Vec::new();
    for (i, &a) in TAU_GRID_S.iter().enumerate() {
        for &b in &TAU_GRID_S[i + 1..] {
            pairs.push([a, b]);
        }
    }
    let rows: Vec<Vec<([f64; N_FILTERS], f64, f64)>> = pairs
        .par_iter()
        .map(|&taus| {
            let s = blocked_cv(runs, |r| features(r, taus), MEMORY_DIM, &SIGMA_GRID, stride)?;
            Ok(s.into_iter().map(|(sig, v)| (taus, sig, v)).collect())
        })
        .collect::<Result<_, FitError>>()?;
    let table: Vec<([f64; N_FILTERS], f64, f64)> = rows.into_iter().flatten().collect();
    let best = table
        .iter()
        .copied()
        .max_by(|a, b| a.2.total_cmp(&b.2))
        .expect("non-empty grid");
    Ok(Selection {
        taus_s: best.0,
        sigma: best.1,
        cv_vacc_pct: best.2,
        table,
    })
}

/// 5-fold time-blocked CV of a GRNN on `runs` for each sigma: (sigma, mean fold
/// VAcc relative %).
pub fn blocked_cv(
    runs: &[&DynamicRun],
    feat: impl Fn(&DynamicRun) -> Vec<f64> + Sync,
    dim: usize,
    sigmas: &[f64],
    stride: usize,
) -> Result<Vec<(f64, f64)>, FitError> {
    const K: usize = 5;
    let stride = stride.max(1);
    let feats: Vec<Vec<f64>> = runs.iter().map(|r| feat(r)).collect();
    let mut acc = vec![0.0; sigmas.len()];
    for fold in 0..K {
        let (mut xt, mut yt, mut xv, mut yv) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (r, f) in runs.iter().zip(&feats) {
            let n = r.len();
            let (a, b) = (fold * n / K, (fold + 1) * n / K);
            for i in (0..n).step_by(stride) {
                let row = &f[i * dim..(i + 1) * dim];
                if i >= a && i < b {
                    xv.extend_from_slice(row);
                    yv.push(r.dvdt_mm3_s[i]);
                } else {
                    xt.extend_from_slice(row);
                    yt.push(r.dvdt_mm3_s[i]);
                }
            }
        }
        let net = Grnn::fit(&xt, dim, &yt, sigmas[0])?;
        for (s, a) in sigmas.iter().zip(acc.iter_mut()) {
            let n = net.with_sigma(*s)?;
            let p = n.predict_many(&xv);
            *a += vacc_relative_pct(&yv, &p) / K as f64;
        }
    }
    Ok(sigmas.iter().copied().zip(acc).collect())
}

/// Scores of the models on one held-out run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HeldOutRun {
    /// Run index.
    pub run: u32,
    /// Run kind.
    pub kind: String,
    /// The paper's static GRNN (P, dP/dt), trained on all quasi-static samples at
    /// sigma 0.1 (the plant's `grnn` hose).
    pub static_quasistatic: Scores,
    /// Static GRNN (P, dP/dt) trained on the other dynamic runs (sigma by blocked CV).
    pub static_dynamic: Scores,
    /// Spread of `static_dynamic`.
    pub static_sigma: f64,
    /// Memory GRNN trained on the other dynamic runs (taus and sigma by blocked CV
    /// on those runs).
    pub memory: Scores,
    /// Filter time constants of `memory`, s.
    pub memory_taus_s: [f64; N_FILTERS],
    /// Spread of `memory`.
    pub memory_sigma: f64,
}

/// Leave-one-run-out evaluation of the static and memory GRNNs on the dynamic
/// data: every hyper-parameter is chosen on the training runs only.
/// Training uses every `stride`-th sample; the held-out run is scored on all of
/// its samples.
pub fn leave_one_run_out(
    dynamic: &DynamicData,
    quasistatic: &QuasiStaticData,
    stride: usize,
) -> Result<Vec<HeldOutRun>, FitError> {
    let (xq, yq) = quasistatic.xy(&(0..quasistatic.samples.len()).collect::<Vec<_>>());
    let qs = Grnn::fit2(&xq, &yq, PAPER_SIGMA)?;
    let sigmas = DEFAULT_SIGMAS;
    dynamic
        .runs
        .iter()
        .enumerate()
        .map(|(h, held)| {
            let train: Vec<&DynamicRun> = dynamic
                .runs
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != h)
                .map(|(_, r)| r)
                .collect();
            let truth = &held.dvdt_mm3_s;
            // The paper's map.
            let p_qs = qs.predict_many(&static_features(held));
            // Static inputs, dynamic training.
            let cv = blocked_cv(&train, static_features, 2, &sigmas, stride)?;
            let s_sigma = cv
                .iter()
                .copied()
                .max_by(|a, b| a.1.total_cmp(&b.1))
                .expect("grid")
                .0;
            let (xs, ys) = stack(&train, static_features, 2, stride.max(1));
            let s_net = Grnn::fit(&xs, 2, &ys, s_sigma)?;
            let p_s = s_net.predict_many(&static_features(held));
            // Memory inputs.
            let sel = select(&train, stride)?;
            let m = MemoryGrnn::fit(&train, sel.taus_s, sel.sigma, stride)?;
            let p_m = m.predict_run(held);
            Ok(HeldOutRun {
                run: held.run,
                kind: held.kind.clone(),
                static_quasistatic: score(truth, &p_qs),
                static_dynamic: score(truth, &p_s),
                static_sigma: s_sigma,
                memory: score(truth, &p_m),
                memory_taus_s: sel.taus_s,
                memory_sigma: sel.sigma,
            })
        })
        .collect()
}

/// A Markdown table of a leave-one-run-out evaluation.
pub fn loro_table(rows: &[HeldOutRun]) -> String {
    let mut s = String::from(
        "| held-out run | model | VAcc rel [%] | VAcc mean [%] | RMSE dV/dt [mm^3/s] |\n|---|---|---|---|---|\n",
    );
    for r in rows {
        let name = format!("{} ({})", r.run, r.kind);
        for (m, sc) in [
            (
                "static GRNN, quasi-static data, sigma 0.1".to_string(),
                r.static_quasistatic,
            ),
            (
                format!("static GRNN, dynamic runs, sigma {}", r.static_sigma),
                r.static_dynamic,
            ),
            (
                format!(
                    "memory GRNN, taus {:?} s, sigma {}",
                    r.memory_taus_s, r.memory_sigma
                ),
                r.memory,
            ),
        ] {
            s += &format!(
                "| {name} | {m} | {:.1} | {:.1} | {:.0} |\n",
                sc.vacc_rel_pct, sc.vacc_mean_pct, sc.rmse
            );
        }
    }
    s
}
