//! `host-sim hose`: the hose-model studies as one Markdown report.
//!
//! Always GRNN, RBF and BP side by side on the quasi-static data (the paper's
//! Fig. 9, with its figure); on request the GRNN with memory held out run by
//! run on the dynamic data ([`super::memory`]) and the closed-loop comparison
//! of the hoses ([`super::closed_loop`]).

use std::path::PathBuf;

use super::{closed_loop, memory, paper};
use crate::io::files::{self, PathError};
use crate::io::plot::PlotError;
use crate::model::hose::data::{DataError, DynamicData, QuasiStaticData};
use crate::model::hose::net::FitError;
use crate::sim::SimError;

/// What to study and where the report goes.
#[derive(Clone, Debug)]
pub struct HoseOptions {
    /// Quasi-static hose data (default: the shipped sample data).
    pub quasistatic: Option<PathBuf>,
    /// Dynamic hose data (default: the shipped sample data).
    pub dynamic: Option<PathBuf>,
    /// Report directory (created).
    pub out_dir: PathBuf,
    /// Also the leave-one-run-out comparison of the static and memory GRNNs.
    pub memory: bool,
    /// Also the closed-loop comparison of the hose models.
    pub closed_loop: bool,
}

/// Why the study failed.
#[derive(Debug, thiserror::Error)]
pub enum HoseError {
    /// The report directory or file.
    #[error(transparent)]
    File(#[from] PathError),
    /// A hose data file.
    #[error(transparent)]
    Data(#[from] DataError),
    /// A network could not be fitted.
    #[error(transparent)]
    Fit(#[from] FitError),
    /// The figure.
    #[error(transparent)]
    Plot(#[from] PlotError),
    /// A closed-loop run.
    #[error(transparent)]
    Sim(#[from] SimError),
}

/// Run the studies, hand each table to `table` as soon as it is ready, and
/// write `report.md` (with its figure) into the report directory; returns the
/// report's path. Says on standard error when the long study starts.
pub fn hose_report(opts: &HoseOptions, mut table: impl FnMut(&str)) -> Result<PathBuf, HoseError> {
    let out = &opts.out_dir;
    files::create_dir_all(out)?;
    let qs = match &opts.quasistatic {
        Some(p) => QuasiStaticData::load(p)?,
        None => QuasiStaticData::shipped(),
    };
    let mut md = String::from("# Hose models (docs/model.md section 9)\n\n## GRNN, RBF and BP (80/20 split per section, the paper's Fig. 9)\n\n");
    let cmp = paper::compare_models(&qs, &paper::CompareOptions::default())?;
    let t = cmp.table();
    table(&t);
    md.push_str(&t);
    cmp.plot(&out.join("fig9_models.png"))?;
    md.push_str("\n![measured against predicted](fig9_models.png)\n");
    if opts.memory {
        let dy = match &opts.dynamic {
            Some(p) => DynamicData::load(p)?,
            None => DynamicData::shipped(),
        };
        eprintln!("leave-one-run-out on the dynamic data ...");
        let rows = memory::leave_one_run_out(&dy, &qs, 4)?;
        let t = memory::loro_table(&rows);
        table(&t);
        md.push_str("\n## GRNN with memory, held-out dynamic runs\n\n");
        md.push_str(&t);
    }
    if opts.closed_loop {
        let rows = closed_loop::stepload_comparison()?;
        let t = closed_loop::comparison_table(&rows);
        table(&t);
        md.push_str("\n## Closed loop: MPC-ESO, 800 N step\n\n");
        md.push_str(&t);
    }
    let report = out.join("report.md");
    files::write(&report, md)?;
    Ok(report)
}
