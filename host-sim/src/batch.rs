//! Scenario batches on every core: parameter sweeps and Monte Carlo seeds.
//!
//! A sweep is the Cartesian product of parameter values (`path=v1,v2,...`,
//! where `path` is a key of the configuration file format, e.g.
//! `mpc_eso.rw=10,33,100` or `eso.beta1=20,30`) and noise seeds. Every
//! combination is one run of the same scenario; the runs go to a rayon pool
//! and each yields one row of metrics.

use std::fmt::Write as _;
use std::path::Path;

use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use crate::config::ConfigFile;
use crate::metrics::Metrics;
use crate::run::{resolve, trace_metrics, RunRequest};
use crate::sim::run;

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
    pub fn parse(s: &str) -> Result<Self, String> {
        let (path, vals) = s
            .split_once('=')
            .ok_or_else(|| format!("'{s}': expected path=v1,v2,..."))?;
        let parts: Vec<&str> = path.split('.').collect();
        if parts.len() != 2 || parts.iter().any(|p| p.is_empty()) {
            return Err(format!("'{path}': expected table.key, e.g. mpc_eso.rw"));
        }
        let values = vals
            .split(',')
            .map(|v| {
                v.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| format!("'{path}': '{v}' is not a finite number"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        // Check the path and every value now (each run applies one value;
        // e.g. a horizon must be a whole number).
        for v in &values {
            overrides(&[(path.to_string(), *v)])?;
        }
        Ok(Self {
            path: path.to_string(),
            values,
        })
    }
}

/// The configuration overrides for one combination, through the TOML format
/// (so a sweep accepts exactly the keys a configuration file accepts).
fn overrides(assign: &[(String, f64)]) -> Result<ConfigFile, String> {
    // Group the keys by table: a TOML table may appear only once.
    let mut tables: std::collections::BTreeMap<&str, String> = Default::default();
    for (path, v) in assign {
        let (table, key) = path.split_once('.').unwrap_or(("", path));
        // Integers for the horizons, floats elsewhere.
        let value = if matches!(key, "np" | "nc") {
            if v.fract() != 0.0 || *v < 0.0 {
                return Err(format!("'{path}' must be a whole number, got {v}"));
            }
            format!("{}", *v as u64)
        } else {
            format!("{v:?}")
        };
        let _ = writeln!(tables.entry(table).or_default(), "{key} = {value}");
    }
    let text: String = tables
        .iter()
        .map(|(t, body)| format!("[{t}]\n{body}"))
        .collect();
    toml::from_str(&text).map_err(|e: toml::de::Error| format!("sweep parameter: {}", e.message()))
}

/// One finished run of a batch.
#[derive(Clone, Debug)]
pub struct BatchRow {
    /// Parameter values of this run, in sweep order.
    pub params: Vec<(String, f64)>,
    /// Noise seed.
    pub seed: u64,
    /// Metrics, or why the run failed (e.g. a design refused).
    pub result: Result<Metrics, String>,
}

/// Run every combination of `params` and `seeds` on `base` (in parallel).
pub fn sweep(
    base: &RunRequest,
    params: &[SweepParam],
    seeds: &[u64],
    progress: bool,
) -> Result<Vec<BatchRow>, String> {
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
                overrides(&assign)?.apply(&mut spec.controller);
                let trace = run(&spec).map_err(|e| e.to_string())?;
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
pub fn write_csv(rows: &[BatchRow], path: &Path) -> Result<(), String> {
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
                f.push(format!("\"{}\"", e.replace('"', "'")));
            }
        }
        let _ = writeln!(s, "{}", f.join(","));
    }
    std::fs::write(path, s).map_err(|e| format!("{}: {e}", path.display()))
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
        let e = SweepParam::parse("eso.beta9=1").unwrap_err();
        assert!(e.contains("beta9"), "{e}");
        assert!(SweepParam::parse("mpc.np=6.5").is_err());
        // Found by fuzzing: only the first value was checked, so a sweep
        // started and then refused its later runs.
        let e = SweepParam::parse("mpc.nc=2,4.5").unwrap_err();
        assert!(e.contains("whole number"), "{e}");
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
            SweepParam::parse("mpc.nc=2,40").unwrap(),
        ];
        let rows = sweep(&base, &params, &[0, 1], false).unwrap();
        assert_eq!(rows.len(), 8);
        // nc = 40 exceeds the design's bound: refused, not a crash.
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
