//! The paper's hose-model study on the quasi-static data (docs/model.md section 9,
//! the paper's Fig. 9): GRNN per pressure section on an 80/20 split, the pooled
//! GRNN, cross-validated sigma, and GRNN / RBF / BP side by side.

use std::path::Path;

use rayon::prelude::*;

use super::bp::{Mlp, MlpOptions};
use super::rbf::{Rbf, RbfOptions};
use crate::io::plot::{self, Panel, PlotError, Series};
use crate::model::hose::data::QuasiStaticData;
use crate::model::hose::grnn::PAPER_SIGMA;
use crate::model::hose::net::{cv_sigma, score, CvResult, FitError, Grnn, Scores, DEFAULT_SIGMAS};
use crate::model::hose::split::{split_80_20, Shuffle};

/// The split of docs/model.md section 9: seed 7, first 20 % of the permutation tested.
pub const PAPER_SEED: u32 = 7;

/// Train and test indices (into `data.samples`) of one section, or of all samples
/// (`section = None`), split 80/20 by `shuffle` with `seed`.
pub fn split_indices(
    data: &QuasiStaticData,
    section: Option<u32>,
    shuffle: Shuffle,
    seed: u32,
) -> (Vec<usize>, Vec<usize>) {
    let idx: Vec<usize> = match section {
        Some(s) => data.section_indices(s),
        None => (0..data.samples.len()).collect(),
    };
    let (tr, te) = split_80_20(shuffle, seed, idx.len());
    (
        tr.iter().map(|&i| idx[i]).collect(),
        te.iter().map(|&i| idx[i]).collect(),
    )
}

fn flat(x: &[[f64; 2]]) -> Vec<f64> {
    x.iter().flatten().copied().collect()
}

/// GRNN test scores per section at `sigma` on the 80/20 split.
pub fn section_scores(
    data: &QuasiStaticData,
    shuffle: Shuffle,
    seed: u32,
    sigma: f64,
) -> Result<Vec<(u32, Scores)>, FitError> {
    data.sections()
        .into_iter()
        .map(|s| {
            let (tr, te) = split_indices(data, Some(s), shuffle, seed);
            let (xt, yt) = data.xy(&tr);
            let (xv, yv) = data.xy(&te);
            let net = Grnn::fit2(&xt, &yt, sigma)?;
            let p: Vec<f64> = xv.iter().map(|x| net.predict(x)).collect();
            Ok((s, score(&yv, &p)))
        })
        .collect()
}

/// Test scores of one GRNN on all samples (80/20 split) for each sigma.
pub fn pooled_scores(
    data: &QuasiStaticData,
    shuffle: Shuffle,
    seed: u32,
    sigmas: &[f64],
) -> Result<Vec<(f64, Scores)>, FitError> {
    let (tr, te) = split_indices(data, None, shuffle, seed);
    let (xt, yt) = data.xy(&tr);
    let (xv, yv) = data.xy(&te);
    let net = Grnn::fit2(&xt, &yt, sigmas.first().copied().unwrap_or(PAPER_SIGMA))?;
    sigmas
        .par_iter()
        .map(|&s| {
            let n = net.with_sigma(s)?;
            let p: Vec<f64> = xv.iter().map(|x| n.predict(x)).collect();
            Ok((s, score(&yv, &p)))
        })
        .collect()
}

/// 5-fold cross-validated sigma (criterion: mean fold VAcc, relative) per section
/// on the training part of the 80/20 split, and for all samples pooled
/// (`None`), over [`DEFAULT_SIGMAS`].
pub fn cv_sigmas(
    data: &QuasiStaticData,
    shuffle: Shuffle,
    seed: u32,
) -> Result<Vec<(Option<u32>, CvResult)>, FitError> {
    let mut groups: Vec<Option<u32>> = data.sections().into_iter().map(Some).collect();
    groups.push(None);
    groups
        .into_iter()
        .map(|g| {
            let (tr, _) = split_indices(data, g, shuffle, seed);
            let (xt, yt) = data.xy(&tr);
            Ok((
                g,
                cv_sigma(&flat(&xt), 2, &yt, &DEFAULT_SIGMAS, 5, shuffle, seed)?,
            ))
        })
        .collect()
}

/// Options of [`compare_models`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CompareOptions {
    /// Which shuffle defines the 80/20 split.
    pub shuffle: Shuffle,
    /// Split seed.
    pub seed: u32,
    /// GRNN spread.
    pub sigma: f64,
    /// RBF hyper-parameters.
    pub rbf: RbfOptions,
    /// BP hyper-parameters.
    pub mlp: MlpOptions,
}

impl Default for CompareOptions {
    fn default() -> Self {
        Self {
            shuffle: Shuffle::Numpy,
            seed: PAPER_SEED,
            sigma: PAPER_SIGMA,
            rbf: RbfOptions::default(),
            mlp: MlpOptions::default(),
        }
    }
}

/// GRNN, RBF and BP side by side (the paper's Fig. 9): each model fitted per
/// section on the training part and scored on the test part.
#[derive(Clone, Debug, PartialEq)]
pub struct ModelComparison {
    /// Model names, in row order: `GRNN`, `RBF`, `BP`.
    pub models: Vec<String>,
    /// Section indices, in column order.
    pub sections: Vec<u32>,
    /// Scores `[model][section]`.
    pub scores: Vec<Vec<Scores>>,
    /// Test points (measured, predicted) of every section, per model, mm^3/s.
    pub predictions: Vec<Vec<(f64, f64)>>,
}

/// Scores and (measured, predicted) test pairs of one model in one section.
type ModelResult = (Scores, Vec<(f64, f64)>);

/// Fit and score the three models of Fig. 9 per section.
pub fn compare_models(
    data: &QuasiStaticData,
    o: &CompareOptions,
) -> Result<ModelComparison, FitError> {
    let sections = data.sections();
    let models = vec!["GRNN".to_string(), "RBF".to_string(), "BP".to_string()];
    // Per section: [model] -> (scores, test pairs).
    let per: Vec<Vec<ModelResult>> = sections
        .par_iter()
        .map(|&s| {
            let (tr, te) = split_indices(data, Some(s), o.shuffle, o.seed);
            let (xt, yt) = data.xy(&tr);
            let (xv, yv) = data.xy(&te);
            let xtf = flat(&xt);
            let grnn = Grnn::fit(&xtf, 2, &yt, o.sigma)?;
            let rbf = Rbf::fit(&xtf, 2, &yt, &o.rbf)?;
            let mlp = Mlp::fit(&xtf, 2, &yt, &o.mlp)?;
            let preds: [Vec<f64>; 3] = [
                xv.iter().map(|x| grnn.predict(x)).collect(),
                xv.iter().map(|x| rbf.predict(x)).collect(),
                xv.iter().map(|x| mlp.predict(x)).collect(),
            ];
            Ok(preds
                .iter()
                .map(|p| {
                    (
                        score(&yv, p),
                        yv.iter().copied().zip(p.iter().copied()).collect(),
                    )
                })
                .collect())
        })
        .collect::<Result<_, FitError>>()?;
    let scores = (0..models.len())
        .map(|m| per.iter().map(|s| s[m].0).collect())
        .collect();
    let predictions = (0..models.len())
        .map(|m| per.iter().flat_map(|s| s[m].1.iter().copied()).collect())
        .collect();
    Ok(ModelComparison {
        models,
        sections,
        scores,
        predictions,
    })
}

impl ModelComparison {
    /// A Markdown table: one row per model, VAcc relative / mean-normalised (%)
    /// and RMSE (mm^3/s) per section.
    pub fn table(&self) -> String {
        let mut s = String::from("| model |");
        for sec in &self.sections {
            s += &format!(" section {sec}: VAcc rel / mean [%], RMSE [mm^3/s] |");
        }
        s += "\n|---|";
        s += &"---|".repeat(self.sections.len());
        s += "\n";
        for (m, row) in self.models.iter().zip(&self.scores) {
            s += &format!("| {m} |");
            for sc in row {
                s += &format!(
                    " {:.1} / {:.1}, {:.1} |",
                    sc.vacc_rel_pct, sc.vacc_mean_pct, sc.rmse
                );
            }
            s += "\n";
        }
        s
    }

    /// PNG of measured vs predicted dV/dt on the test sets, one panel per model,
    /// with the identity line.
    pub fn plot(&self, path: &Path) -> Result<(), PlotError> {
        let (lo, hi) = self
            .predictions
            .iter()
            .flatten()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
                (a.min(p.0), b.max(p.0))
            });
        let panels: Vec<Panel> = self
            .models
            .iter()
            .zip(&self.predictions)
            .zip(&self.scores)
            .map(|((m, pts), sc)| {
                let acc: Vec<String> = sc
                    .iter()
                    .map(|s| format!("{:.1}", s.vacc_rel_pct))
                    .collect();
                Panel::new(
                    format!("{m}: test VAcc per section {} %", acc.join(" / ")),
                    "measured dV/dt [mm^3/s]",
                    "predicted dV/dt [mm^3/s]",
                )
                .with(Series::points("test samples", pts.clone()))
                .with(Series::dashed(
                    "measured = predicted",
                    vec![(lo, lo), (hi, hi)],
                ))
            })
            .collect();
        plot::save(path, &panels, 800, 420)
    }
}
