//! `host-sim sweep --report DIR`: a Markdown report of a batch (a Monte Carlo
//! over the rig, typically) with histograms of the main metrics over the
//! runs and the count of failed, diverged and unstable runs.
//!
//! A run is
//! * *diverged* when the simulated plant's state stopped being finite;
//! * *failed* when it was refused otherwise (a design refused, a drawn rig
//!   that is not physical, a log that could not be written);
//! * *unstable* when it finished but its error after 2 s exceeds
//!   [`UNSTABLE_ERR_MM`] somewhere, or a metric is not finite: a loop that
//!   settles keeps its error within a few millimetres under the 800 N load
//!   step (2.0 mm nominal), one that oscillates or drifts does not.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::io::files::{self, PathError};
use crate::io::plot::{self, Panel, PlotError, Series};
use crate::sim::batch::{BatchRow, SweepError};
use crate::sim::metrics::Metrics;
use crate::sim::SimError;

/// The largest |error| after t = 2 s of a run that counts as stable, mm
/// (20 % of the 50 mm step).
pub const UNSTABLE_ERR_MM: f64 = 10.0;

/// Why the report could not be written.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// The directory or the Markdown file.
    #[error(transparent)]
    File(#[from] PathError),
    /// A histogram.
    #[error(transparent)]
    Plot(#[from] PlotError),
}

/// How the runs of a batch ended.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Outcome {
    /// Runs in the batch.
    pub runs: usize,
    /// Finished and stable.
    pub stable: usize,
    /// Finished, but the error after 2 s exceeds [`UNSTABLE_ERR_MM`] or a
    /// metric is not finite.
    pub unstable: usize,
    /// The plant's state stopped being finite.
    pub diverged: usize,
    /// Refused for another reason.
    pub failed: usize,
}

/// Whether a finished run is unstable (see the module doc).
pub fn is_unstable(m: &Metrics) -> bool {
    let finite = |v: Option<f64>| v.is_none_or(f64::is_finite);
    m.max_err_after_2_mm.is_some_and(|e| e > UNSTABLE_ERR_MM)
        || !m.ise_mm2s.is_finite()
        || !finite(m.rmse_after_4_mm)
        || !finite(m.rmse_after_2_mm)
        || m.load.iter().any(|l| !l.deviation_mm.is_finite())
}

/// Count the outcomes of `rows`.
pub fn outcome(rows: &[BatchRow]) -> Outcome {
    let mut o = Outcome {
        runs: rows.len(),
        ..Outcome::default()
    };
    for r in rows {
        match &r.result {
            Ok(m) if is_unstable(m) => o.unstable += 1,
            Ok(_) => o.stable += 1,
            Err(SweepError::Sim(SimError::Diverged { .. })) => o.diverged += 1,
            Err(_) => o.failed += 1,
        }
    }
    o
}

/// One metric of the report: name, unit, file stem, how to read it.
struct MetricSpec {
    label: &'static str,
    unit: &'static str,
    stem: &'static str,
    get: fn(&Metrics) -> Option<f64>,
}

const METRICS: [MetricSpec; 5] = [
    MetricSpec {
        label: "load deviation at the first load step (800 N in stepload)",
        unit: "mm",
        stem: "hist-load-dev",
        get: |m| m.load.first().map(|l| l.deviation_mm),
    },
    MetricSpec {
        label: "RMSE t >= 4 s",
        unit: "mm",
        stem: "hist-rmse-4",
        get: |m| m.rmse_after_4_mm,
    },
    MetricSpec {
        label: "RMSE t >= 2 s",
        unit: "mm",
        stem: "hist-rmse-2",
        get: |m| m.rmse_after_2_mm,
    },
    MetricSpec {
        label: "rise time 10-90 %",
        unit: "s",
        stem: "hist-rise",
        get: |m| m.rise_time_s,
    },
    MetricSpec {
        label: "largest error t >= 2 s",
        unit: "mm",
        stem: "hist-max-err",
        get: |m| m.max_err_after_2_mm,
    },
];

/// The `q` quantile (0..=1) of sorted values, linearly interpolated.
pub fn quantile(sorted: &[f64], q: f64) -> Option<f64> {
    if sorted.is_empty() {
        return None;
    }
    let x = q.clamp(0.0, 1.0) * (sorted.len() - 1) as f64;
    let (i, f) = (x.floor() as usize, x.fract());
    let next = sorted.get(i + 1).copied().unwrap_or(sorted[i]);
    Some(sorted[i] + f * (next - sorted[i]))
}

/// A histogram of `values` as a step outline over `bins` equal bins.
fn histogram(values: &[f64], bins: usize) -> Vec<(f64, f64)> {
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(*v), b.max(*v))
        });
    let width = if hi > lo {
        (hi - lo) / bins as f64
    } else {
        (lo.abs() * 1e-3).max(1e-9)
    };
    let mut counts = vec![0usize; bins];
    for v in values {
        let i = (((v - lo) / width) as usize).min(bins - 1);
        counts[i] += 1;
    }
    let mut pts = vec![(lo, 0.0)];
    for (i, c) in counts.iter().enumerate() {
        let x0 = lo + i as f64 * width;
        pts.push((x0, *c as f64));
        pts.push((x0 + width, *c as f64));
    }
    pts.push((lo + bins as f64 * width, 0.0));
    pts
}

/// Write `dir/report.md` with a histogram per metric (`dir/hist-*.png`);
/// `title` heads the report, `setup` (Markdown) says what was run.
pub fn write_report(
    rows: &[BatchRow],
    dir: &Path,
    title: &str,
    setup: &str,
) -> Result<PathBuf, ReportError> {
    files::create_dir_all(dir)?;
    let o = outcome(rows);
    let mut md = String::new();
    let _ = writeln!(md, "# {title}\n\n{setup}\n");
    let _ = writeln!(md, "## Outcome\n");
    let _ = writeln!(md, "| runs | stable | unstable | diverged | failed |");
    let _ = writeln!(md, "|---|---|---|---|---|");
    let _ = writeln!(
        md,
        "| {} | {} | {} | {} | {} |\n",
        o.runs, o.stable, o.unstable, o.diverged, o.failed
    );
    let _ = writeln!(
        md,
        "Unstable: finished, but the error exceeds {UNSTABLE_ERR_MM} mm somewhere after t = 2 s, or a \
         metric not finite. Diverged: the plant's state stopped being finite. Failed: refused \
         (see the CSV's `error` column).\n"
    );
    let _ = writeln!(md, "## Metrics over the finished runs\n");
    let _ = writeln!(
        md,
        "| metric | unit | runs | min | median | 95th percentile | max |"
    );
    let _ = writeln!(md, "|---|---|---|---|---|---|---|");
    let mut figs = Vec::new();
    for spec in &METRICS {
        let mut v: Vec<f64> = rows
            .iter()
            .filter_map(|r| r.result.as_ref().ok().and_then(spec.get))
            .filter(|x| x.is_finite())
            .collect();
        if v.is_empty() {
            continue;
        }
        v.sort_by(f64::total_cmp);
        let q = |p: f64| quantile(&v, p).map_or("-".into(), |x| format!("{x:.4}"));
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} |",
            spec.label,
            spec.unit,
            v.len(),
            q(0.0),
            q(0.5),
            q(0.95),
            q(1.0)
        );
        let bins = (v.len() as f64).sqrt().ceil().clamp(5.0, 40.0) as usize;
        let file = format!("{}.png", spec.stem);
        let panel = Panel::new(
            format!("{} over {} runs", spec.label, v.len()),
            format!("{} [{}]", spec.label, spec.unit),
            "runs",
        )
        .with(Series::line("", histogram(&v, bins)));
        plot::save(&dir.join(&file), &[panel], 800, 360)?;
        figs.push((file, spec.label));
    }
    let _ = writeln!(md, "\n## Histograms\n");
    for (file, label) in figs {
        let _ = writeln!(md, "![{label}]({file})\n");
    }
    let report = dir.join("report.md");
    files::write(&report, md)?;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_and_histogram() {
        let v = [1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(quantile(&v, 0.5), Some(3.0));
        assert_eq!(quantile(&v, 0.95), Some(4.8));
        assert_eq!(quantile(&[], 0.5), None);
        let h = histogram(&v, 5);
        let total: f64 = h.iter().skip(1).step_by(2).map(|p| p.1).sum();
        assert_eq!(total, 5.0);
        assert_eq!(histogram(&[2.0, 2.0], 5).len(), 12);
    }
}
