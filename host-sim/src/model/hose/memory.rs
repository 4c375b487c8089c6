//! A GRNN hose with memory, fitted on the dynamic hose test (beyond the paper).
//!
//! A static map g(P, dP/dt) cannot represent the hose's relaxation and creep:
//! the wall keeps moving after the pressure stops changing. The memory GRNN adds
//! inputs that carry the pressure history: the deviations of the pressure from
//! its first-order low-pass filtered versions,
//!
//! x = [P, dP/dt, P - lowpass(P, tau_1), P - lowpass(P, tau_2)]   (MPa, MPa/s),
//!
//! z-scored like the static GRNN. The filter time constants and sigma are picked
//! from data by time-blocked cross-validation
//! ([`studies::grnn::memory::select`](crate::studies::grnn::memory::select)).
//! On the data a filter is integrated exactly for a pressure linear between
//! samples (starting at equilibrium, lowpass = P at the first sample); in the
//! plant the filter states are plant states (see
//! [`HoseModel::GrnnMemory`](crate::model::plant::HoseModel::GrnnMemory)).

use super::data::DynamicRun;
use super::net::{FitError, Grnn};

/// Number of memory (filter) inputs.
pub const N_FILTERS: usize = 2;
/// Input dimension of the memory GRNN.
pub const MEMORY_DIM: usize = 2 + N_FILTERS;

/// Low-pass filtered pressure lowpass(P, tau) of a run, MPa: exact for a pressure
/// linear between samples, starting at equilibrium.
pub fn lowpass(t_s: &[f64], p: &[f64], tau_s: f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(p.len());
    let Some(&p0) = p.first() else {
        return out;
    };
    let mut f = p0;
    out.push(f);
    for i in 1..p.len() {
        let dt = t_s[i] - t_s[i - 1];
        let s = (p[i] - p[i - 1]) / dt;
        let a = (-dt / tau_s).exp();
        // Pf(t) = P(t) - s tau + (Pf0 - P0 + s tau) e^{-t/tau}.
        f = p[i] - s * tau_s + (f - p[i - 1] + s * tau_s) * a;
        out.push(f);
    }
    out
}

/// Memory GRNN inputs of a run (row-major, [`MEMORY_DIM`] per sample) for the
/// filter time constants `taus_s`.
pub fn features(run: &DynamicRun, taus_s: [f64; N_FILTERS]) -> Vec<f64> {
    let lp: Vec<Vec<f64>> = taus_s
        .iter()
        .map(|&tau| lowpass(&run.t_s, &run.p_mpa, tau))
        .collect();
    let mut x = Vec::with_capacity(run.len() * MEMORY_DIM);
    for i in 0..run.len() {
        x.push(run.p_mpa[i]);
        x.push(run.dpdt_mpa_s[i]);
        for f in &lp {
            x.push(run.p_mpa[i] - f[i]);
        }
    }
    x
}

/// Static inputs [P, dP/dt] of a run (row-major).
pub fn static_features(run: &DynamicRun) -> Vec<f64> {
    run.p_mpa
        .iter()
        .zip(&run.dpdt_mpa_s)
        .flat_map(|(p, d)| [*p, *d])
        .collect()
}

/// A memory GRNN: the network and its filter time constants.
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryGrnn {
    /// The network on [`features`] inputs.
    pub net: Grnn,
    /// Filter time constants, s.
    pub taus_s: [f64; N_FILTERS],
}

impl MemoryGrnn {
    /// Fit on the given runs (every `stride`-th sample).
    pub fn fit(
        runs: &[&DynamicRun],
        taus_s: [f64; N_FILTERS],
        sigma: f64,
        stride: usize,
    ) -> Result<Self, FitError> {
        let (x, y) = stack(runs, |r| features(r, taus_s), MEMORY_DIM, stride.max(1));
        Ok(Self {
            net: Grnn::fit(&x, MEMORY_DIM, &y, sigma)?,
            taus_s,
        })
    }

    /// Fit like [`MemoryGrnn::fit`], merging consecutive samples within `delta`
    /// (z units) of each other ([`Grnn::fit_merged`]).
    pub fn fit_merged(
        runs: &[&DynamicRun],
        taus_s: [f64; N_FILTERS],
        sigma: f64,
        stride: usize,
        delta: f64,
    ) -> Result<Self, FitError> {
        let (x, y) = stack(runs, |r| features(r, taus_s), MEMORY_DIM, stride.max(1));
        Ok(Self {
            net: Grnn::fit_merged(&x, MEMORY_DIM, &y, sigma, delta)?,
            taus_s,
        })
    }

    /// Predictions along a run (filters started at equilibrium).
    pub fn predict_run(&self, run: &DynamicRun) -> Vec<f64> {
        self.net.predict_many(&features(run, self.taus_s))
    }
}

/// Inputs (from `feat`, `dim` per sample) and outputs of several runs, every
/// `stride`-th sample.
pub fn stack(
    runs: &[&DynamicRun],
    feat: impl Fn(&DynamicRun) -> Vec<f64>,
    dim: usize,
    stride: usize,
) -> (Vec<f64>, Vec<f64>) {
    let mut x = Vec::new();
    let mut y = Vec::new();
    for r in runs {
        let f = feat(r);
        for i in (0..r.len()).step_by(stride) {
            x.extend_from_slice(&f[i * dim..(i + 1) * dim]);
            y.push(r.dvdt_mm3_s[i]);
        }
    }
    (x, y)
}
