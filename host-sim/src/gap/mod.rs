//! Layer `gap` (beside [`crate::hil`] and [`crate::studies`]): `host-sim gap`,
//! where a recorded run departs from the nominal model, which unmodelled
//! effect causes it, and how far the gap shrinks once that effect is added,
//! checked on held-out runs (docs/interfaces.md section 2).
//!
//! May import from [`crate::io`], [`crate::model`], [`crate::sim`] and `gap`
//! itself.
//!
//! 1. **Replay** ([`replay`]): the nominal model driven open loop by each log's
//!    recorded drive command (through the servo model) and load, for each run
//!    prepared with its noise levels ([`run`]).
//! 2. **Localise** ([`measure`], [`localise`], [`segment`], [`stats`]): the
//!    residual per channel, per automatically found segment (moves, holds, load
//!    steps, reversals) and per frequency band; whiteness and residual-input
//!    tests at 99 %.
//! 3. **Attribute** ([`candidates`]): every effect of docs/model.md section 12 is
//!    added in turn, its parameters fitted on the fit runs only ([`fit`],
//!    starting points from [`prefit`]); the effects are ranked by the shrink of
//!    the gap, and a second effect is tried on top of the best;
//!    `sensor_calibration` is fitted by least squares ([`calibrate`]) and
//!    `parameters` by a grey-box re-estimate with intervals ([`grey_box`],
//!    [`lsq`]).
//! 4. **Validate** ([`policy`], [`reasons`]): the chosen effect with its fitted
//!    parameters on the check runs: before, after, shrink; `none` within the
//!    noise, `unexplained` when no effect shrinks the gap on both.
//! 5. **Report** ([`diagnosis`], [`report`]): the JSON of the contract, and a
//!    Markdown report.
//!
//! [`diagnose`] runs the steps; [`validation`] is its suite of synthetic runs
//! with hidden effects.

pub mod calibrate;
pub mod candidates;
pub mod closures;
pub mod diagnose;
pub mod diagnosis;
pub mod equations;
pub mod fit;
pub mod grey_box;
pub mod identified;
pub mod isolate;
pub mod localise;
pub mod lsq;
pub mod measure;
pub mod policy;
pub mod prefit;
pub mod progress;
pub mod reasons;
pub mod replay;
pub mod report;
pub mod run;
pub mod segment;
pub mod sensor_family;
pub mod stats;
#[cfg(test)]
pub(crate) mod testing;
pub mod validation;
pub mod wide;

use std::path::{Path, PathBuf};

use crate::io::files::{self, PathError};
use crate::io::runlog::{LogError, RunLog};
use crate::model::plant::Plant;
use diagnose::Options;
use diagnosis::Diagnosis;
use report::ReportError;
use run::Run;

/// Why `host-sim gap` failed.
#[derive(Debug, thiserror::Error)]
pub enum GapError {
    /// No fit or no check run.
    #[error("give at least one --fit and one --check run log")]
    NoRuns,
    /// A run log could not be read.
    #[error(transparent)]
    Log(#[from] LogError),
    /// A run log too short to diagnose.
    #[error("{}: {rows} rows; a diagnosis needs at least 200", path.display())]
    TooShort {
        /// The log.
        path: PathBuf,
        /// Its rows.
        rows: usize,
    },
    /// The JSON could not be made.
    #[error("{0}")]
    Json(serde_json::Error),
    /// The JSON could not be written.
    #[error(transparent)]
    File(#[from] PathError),
    /// The Markdown report could not be written.
    #[error(transparent)]
    Report(#[from] ReportError),
}

fn load(paths: &[PathBuf]) -> Result<Vec<Run>, GapError> {
    paths
        .iter()
        .map(|p| {
            let log = RunLog::read_with(p, &replay::LOG_STEPS)?;
            if log.len() < 200 {
                return Err(GapError::TooShort {
                    path: p.clone(),
                    rows: log.len(),
                });
            }
            let name = p
                .file_name()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_else(|| p.display().to_string());
            Ok(Run::new(name, log))
        })
        .collect()
}

/// What `run_gap` writes besides returning the diagnosis.
#[derive(Clone, Copy, Debug, Default)]
pub struct Outputs<'a> {
    /// The JSON report (docs/interfaces.md section 2).
    pub json: Option<&'a Path>,
    /// The directory of the Markdown report with plots.
    pub report: Option<&'a Path>,
    /// The identified rig as a rig file ([`identified`]).
    pub rig_out: Option<&'a Path>,
}

/// Diagnose the logs and write what `out` asks for.
pub fn run_gap(
    fit: &[PathBuf],
    check: &[PathBuf],
    out: Outputs<'_>,
    opts: &Options,
) -> Result<Diagnosis, GapError> {
    if fit.is_empty() || check.is_empty() {
        return Err(GapError::NoRuns);
    }
    let names = |ps: &[PathBuf]| {
        ps.iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    let runs = format!("fit runs {}; check runs {}", names(fit), names(check));
    let (fit, check) = (load(fit)?, load(check)?);
    let (d, details) = diagnose::diagnose(fit, check, &Plant::nominal(), opts);
    if let Some(json) = out.json {
        let text = serde_json::to_string_pretty(&d).map_err(GapError::Json)?;
        files::write(json, text)?;
    }
    if let Some(dir) = out.report {
        report::write(dir, &d, &details)?;
    }
    if let Some(path) = out.rig_out {
        let bar = progress::Progress::step(
            opts.progress,
            "fitting the rig's parameters for --rig-out (16 groups)",
        );
        let wide = identified::wide_fit(&d, &details, opts.dt_s);
        bar.finish();
        files::write(
            path,
            identified::rig_text(&d, &details, wide.as_ref(), &runs),
        )?;
    }
    Ok(d)
}
