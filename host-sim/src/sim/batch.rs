//! Scenario batches on every core: parameter sweeps and Monte Carlo seeds.
//!
//! A sweep is the Cartesian product of parameter values (`path=v1,v2,...`,
//! where `path` is a controller parameter of the board's settings table, as
//! in a configuration file and the console's `set`, e.g.
//! `mpc_eso.rw=10,33,100` or `eso.beta1=20,30`) and noise seeds. Every
//! combination is one run of the same scenario; the runs go to a rayon pool
//! and each yields one row of metrics.

use std::fmt::Write as _;
use std::path::Path;

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::io::files::{self, PathError};
use crate::sim::config::{check_value, controller_param, set_param, ParamError};
use crate::sim::metrics::Metrics;
use crate::sim::request::{resolve, trace_metrics, RequestError, RunRequest};
use crate::sim::{run, SimError};

/// Why a sweep parameter, the sweep or one of its runs failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum SweepError {
    /// Not `path=v1,v2,...`.
    #[error("'{0}': expected path=v1,v2,...")]
    Syntax(String),
    /// The path is not `table.key`.
    #[error("'{0}': expected table.key, e.g. mpc_eso.rw")]
    Path(String),
    /// A value is not a finite number.
    #[error("'{path}': '{value}' is not a finite number")]
    Value {
        /// The parameter's path.
        path: String,
        /// The value as given.
        value: String,
    },
    /// The path is not a controller parameter, or a value is refused.
    #[error(transparent)]
    Param(#[from] ParamError),
    /// The base request (or a run's) does not resolve.
    #[error(transparent)]
    Request(#[from] RequestError),
    /// A run was refused or diverged.
    #[error(transparent)]
    Sim(#[from] SimError),
}

/// One swept parameter: a configuration path and its values.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepParam {
    /// Dotted path into the configuration format, e.g. `mpc_eso.rw`.
    pub path: String,
    /// Values to try.
    pub values: Vec<f64>,
}

impl SweepParam {
    /// Parse `path=v1,v2,...`.
    pub fn parse(s: &str) -> Result<Self, SweepError> {
        let (path, vals) = s
            .split_once('=')
            .ok_or_else(|| SweepError::Syntax(s.to_string()))?;
        let parts: Vec<&str> = path.split('.').collect();
        if parts.len() != 2 || parts.iter().any(|p| p.is_empty()) {
            return Err(SweepError::Path(path.to_string()));
        }
        let values = vals
            .split(',')
            .map(|v| {
                v.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| SweepError::Value {
                        path: path.to_string(),
                        value: v.to_string(),
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        // Check the path and every value now (each run applies one value),
        // against the table the configuration files and the console use.
        let p = controller_param(path)?;
        for v in &values {
            check_value(p, *v)?;
        }
        Ok(Self {
            path: p.name.to_string(),
            values,
        })
    }
}

/// One finished run of a batch.
#[derive(Clone, Debug)]
pub struct BatchRow {
    /// Parameter values of this run, in sweep order.
    pub params: Vec<(String, f64)>,
    /// Noise seed.
    pub seed: u64,
    /// Metrics, or why the run failed (e.g. a design refused).
    pub result: Result<Metrics, SweepError>,
}

/// Run every combination of `params` and `seeds` on `base` (in parallel).
pub fn sweep(
    base: &RunRequest,
    params: &[SweepParam],
    seeds: &[u64],
    progress: bool,
) -> Result<Vec<BatchRow>, SweepError> {
    // The base request must resolve on its own.
    resolve(base)?;
    let mut combos: Vec<Vec<(String, f64)>> = vec![Vec::new()];
    for p in params {
        combos = combos
            .into_iter()
            .flat_map(|c| {
                p.values.iter().map(move |v| {
                    let mut c = c.clone();
                    c.push((p.path.clone(), *v));
                    c
                })
            })
            .collect();
    }
    let jobs: Vec<(Vec<(String, f64)>, u64)> = combos
        .into_iter()
        .flat_map(|c| seeds.iter().map(move |s| (c.clone(), *s)))
        .collect();
    let bar = if progress {
        ProgressBar::new(jobs.len() as u64)
    } else {
        ProgressBar::hidden()
    };
    bar.set_style(
        ProgressStyle::with_template("[{elapsed_precise}] {bar:40} {pos}/{len} runs, eta {eta}")
            .expect("valid template"),
    );
    let rows = jobs
        .into_par_iter()
        .map(|(assign, seed)| {
            let result = (|| {
                let mut spec = resolve(&RunRequest {
                    seed: Some(seed),
                    ..base.clone()
                })?;
                for (path, v) in &assign {
                    set_param(&mut spec.controller, path, *v)?;
                }
                let trace = run(&spec)?;
                Ok(trace_metrics(&trace, &spec.scenario))
            })();
            bar.inc(1);
            BatchRow {
                params: assign,
                seed,
                result,
            }
        })
        .collect();
    bar.finish_and_clear();
    Ok(rows)
}

fn opt(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.6}")).unwrap_or_default()
}

/// Write the batch as CSV: parameters, seed, the main metrics, error.
pub fn write_csv(rows: &[BatchRow], path: &Path) -> Result<(), PathError> {
    let mut s = String::new();
    let names: Vec<String> = rows
        .first()
        .map(|r| r.params.iter().map(|p| p.0.clone()).collect())
        .unwrap_or_default();
    let mut header = names.clone();
    header.extend(
        [
            "seed",
            "rise_time_s",
            "overshoot_pct",
            "sse_mm",
            "ise_mm2s",
            "load_dev_pct",
            "load_settling_s",
            "rmse_after_4_mm",
            "rmse_after_2_mm",
            "error",
        ]
        .map(String::from),
    );
    let _ = writeln!(s, "{}", header.join(","));
    for r in rows {
        let mut f: Vec<String> = r.params.iter().map(|p| format!("{}", p.1)).collect();
        f.push(r.seed.to_string());
        match &r.result {
            Ok(m) => {
                let l = m.load.first();
                f.extend([
                    opt(m.rise_time_s),
                    opt(m.overshoot_pct),
                    opt(m.sse_mm),
                    opt(Some(m.ise_mm2s)),
                    opt(l.map(|l| l.deviation_pct)),
                    opt(l.map(|l| l.settling_s)),
                    opt(m.rmse_after_4_mm),
                    opt(m.rmse_after_2_mm),
                    String::new(),
                ]);
            }
            Err(e) => {
                f.extend(std::iter::repeat_n(String::new(), 8));
                f.push(format!("\"{}\"", e.to_string().replace('"', "'")));
            }
        }
        let _ = writeln!(s, "{}", f.join(","));
    }
    files::write(path, s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_params() {
        let p = SweepParam::parse("mpc_eso.rw=10, 33,100").unwrap();
        assert_eq!(p.values, vec![10.0, 33.0, 100.0]);
        assert!(SweepParam::parse("rw=10").is_err());
        assert!(SweepParam::parse("mpc_eso.rw").is_err());
        assert!(SweepParam::parse("mpc_eso.rw=ten").is_err());
        let e = SweepParam::parse("eso.beta9=1").unwrap_err().to_string();
        assert!(e.contains("beta9"), "{e}");
        assert!(SweepParam::parse("mpc.np=6.5").is_err());
        // Found by fuzzing: only the first value was checked, so a sweep
        // started and then refused its later runs.
        let e = SweepParam::parse("mpc.nc=2,4.5").unwrap_err().to_string();
        assert!(e.contains("whole number"), "{e}");
        // The ranges are the console's: refused before any run.
        let e = SweepParam::parse("mpc.nc=2,40").unwrap_err().to_string();
        assert!(e.contains("out of range") && e.contains("1 to 8"), "{e}");
        let e = SweepParam::parse("eso.beta9=1").unwrap_err().to_string();
        assert!(e.contains("beta1"), "the keys of [eso] are listed: {e}");
        let e = SweepParam::parse("drive.invert=1").unwrap_err().to_string();
        assert!(e.contains("board"), "{e}");
        // Every controller parameter of the table is a sweep path.
        for p in dca_app::settings::PARAMS
            .iter()
            .filter(|p| p.is_controller())
        {
            let v = p.min.value();
            let q = SweepParam::parse(&format!("{}={v:?}", p.name)).unwrap();
            assert_eq!(q.path, p.name);
        }
    }

    #[test]
    fn sweep_runs_every_combination_and_reports_refused_designs() {
        let base = RunRequest {
            scenario: "step".into(),
            controller: Some("mpc".into()),
            ..RunRequest::default()
        };
        let params = [
            SweepParam::parse("mpc.rw=10,33").unwrap(),
            SweepParam::parse("mpc.nc=2,8").unwrap(),
        ];
        let rows = sweep(&base, &params, &[0, 1], false).unwrap();
        assert_eq!(rows.len(), 8);
        // nc = 8 is a valid setting but exceeds the preset's np = 6: the
        // design is refused, not a crash.
        for r in &rows {
            let nc = r.params[1].1;
            assert_eq!(r.result.is_ok(), nc == 2.0, "{:?}", r.params);
        }
        // A larger input weight moves more gently: a longer rise time.
        let rise = |rw: f64| {
            rows.iter()
                .find(|r| r.params[0].1 == rw && r.params[1].1 == 2.0)
                .and_then(|r| r.result.as_ref().ok()?.rise_time_s)
                .unwrap()
        };
        assert!(rise(33.0) > rise(10.0), "{} vs {}", rise(33.0), rise(10.0));
    }
}
