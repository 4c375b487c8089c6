//! `host-sim gap`: where a recorded run departs from the nominal model, which
//! unmodelled effect causes it, and how far the gap shrinks once that effect
//! is added, checked on held-out runs (interfaces.md section 2).
//!
//! 1. **Replay** ([`replay`]): the nominal model driven open loop by each log's
//!    recorded drive command (through the servo model) and load.
//! 2. **Localise** ([`diagnose`], [`segment`], [`stats`]): the residual per
//!    channel, per automatically found segment (moves, holds, load steps,
//!    reversals) and per frequency band; whiteness and residual-input tests
//!    at 99 %.
//! 3. **Attribute**: every effect of plant.md section 12 is added in turn, its
//!    parameters fitted on the fit runs only ([`fit`]); the effects are ranked by
//!    the shrink of the gap, and a second effect is tried on top of the best.
//! 4. **Validate**: the chosen effect with its fitted parameters on the check
//!    runs: before, after, shrink; `none` within the noise, `unexplained` when
//!    no effect shrinks the gap on both.
//! 5. **Report** ([`report`]): the JSON of the contract, and a Markdown report.

pub mod diagnose;
pub mod fit;
pub mod prefit;
pub mod replay;
pub mod report;
pub mod segment;
pub mod stats;
pub mod validation;

use std::path::{Path, PathBuf};

use crate::plant::Plant;
use crate::runlog::RunLog;
use diagnose::{Diagnosis, Options, Run};

fn load(paths: &[PathBuf]) -> Result<Vec<Run>, String> {
    paths
        .iter()
        .map(|p| {
            let log = RunLog::read(p).map_err(|e| e.to_string())?;
            if log.len() < 200 {
                return Err(format!(
                    "{}: {} rows; a diagnosis needs at least 200",
                    p.display(),
                    log.len()
                ));
            }
            let name = p
                .file_name()
                .map(|s| s.to_string_lossy().to_string())
                .unwrap_or_else(|| p.display().to_string());
            Ok(Run::new(name, log))
        })
        .collect()
}

/// Diagnose the logs; write the JSON to `json` and, with `report`, the
/// Markdown report into that directory.
pub fn run_gap(
    fit: &[PathBuf],
    check: &[PathBuf],
    json: &Path,
    report: Option<&Path>,
    opts: &Options,
) -> Result<Diagnosis, String> {
    if fit.is_empty() || check.is_empty() {
        return Err("give at least one --fit and one --check run log".into());
    }
    let (fit, check) = (load(fit)?, load(check)?);
    let (d, details) = diagnose::diagnose(fit, check, &Plant::nominal(), opts);
    let text = serde_json::to_string_pretty(&d).map_err(|e| e.to_string())?;
    std::fs::write(json, text).map_err(|e| format!("{}: {e}", json.display()))?;
    if let Some(dir) = report {
        report::write(dir, &d, &details)?;
    }
    Ok(d)
}
