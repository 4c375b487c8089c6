//! `host-sim sweep`: parameter sweeps and Monte Carlo seeds.

use std::path::PathBuf;

use std::sync::Arc;

use host_sim::sim::batch::{sweep_with, write_csv, BatchOptions, Perturb, Retune, SweepParam};
use host_sim::sim::request::resolve;
use host_sim::sim::tolerance::read_spec;
use host_sim::studies::commission::{commission, Commissioning};
use host_sim::studies::montecarlo::{outcome, quantile, write_report};
use host_sim::studies::tune::{self, Robust};

use super::args::{RunOpts, CONTROL_TICK_HELP};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// What to simulate.
    #[command(flatten)]
    what: RunOpts,
    /// A swept parameter, `table.key=v1,v2,...` (repeatable), e.g. mpc_eso.rw=10,33,100.
    #[arg(long = "param")]
    params: Vec<String>,
    /// Noise seeds: `A..B` (B excluded) or `a,b,c` (default 0).
    #[arg(long, default_value = "0")]
    seeds: String,
    /// Monte Carlo over the rig: draw the plant parameters per seed uniformly
    /// within +-F of their value (F a fraction in [0, 1), e.g. 0.1).
    #[arg(long, value_name = "F")]
    perturb: Option<f64>,
    /// The plant parameters drawn by --perturb, `k1,k2,...` (`hose.<key>` for
    /// the hose wall; default: every physical one).
    // Clap counts a requirement met when a given option conflicts with it:
    // the conflict with --perturb-spec is said explicitly.
    #[arg(
        long,
        value_name = "KEYS",
        requires = "perturb",
        conflicts_with = "perturb_spec"
    )]
    perturb_keys: Option<String>,
    /// Monte Carlo over the rig from a tolerance spec (TOML: per plant parameter
    /// a distribution, uniform, normal or lognormal, and its reason), e.g.
    /// host-sim/data/tolerances/dca-rig.toml; keys not listed are not drawn.
    #[arg(long, value_name = "FILE", conflicts_with = "perturb")]
    perturb_spec: Option<PathBuf>,
    /// Commission every rig before its run (docs/control.md "Commissioning"): the
    /// identification runs on it (realistic sensors), `gap --rig-out`, `tune`; the
    /// run then uses the tuned settings. CSV columns `tuned.<path>`.
    #[arg(long)]
    commission: bool,
    /// Objective evaluations of each tune (--commission).
    #[arg(long, value_name = "N", default_value_t = 40, requires = "commission")]
    commission_evals: u64,
    /// Also write each run's log as DIR/run-<index>.csv (with --commission also
    /// DIR/commission-<index>/: identification logs, identified rig, tuned settings).
    #[arg(long, value_name = "DIR")]
    logs: Option<PathBuf>,
    /// Also run each rig's floor (docs/control.md's floor.toml on the same
    /// drawn rig, ideal sensors) and write `floor_mm` and `excess_mm` (the
    /// first load deviation minus the floor) columns.
    #[arg(long)]
    floor: bool,
    /// Write a Markdown report with histograms of the metrics to DIR/report.md.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
    #[arg(long, value_name = "S", help = CONTROL_TICK_HELP)]
    control_tick: Option<f64>,
    /// Where to write the CSV.
    #[arg(long)]
    out: PathBuf,
}

/// The most seeds one `--seeds A..B` runs.
const MAX_SEEDS: u64 = 100_000;

/// `A..B` (B excluded, at most [`MAX_SEEDS`] seeds) or `a,b,c`.
fn parse_seeds(s: &str) -> anyhow::Result<Vec<u64>> {
    let bad = || anyhow::anyhow!("--seeds '{s}': expected A..B or a,b,c");
    if let Some((a, b)) = s.split_once("..") {
        let (a, b): (u64, u64) = (
            a.trim().parse().map_err(|_| bad())?,
            b.trim().parse().map_err(|_| bad())?,
        );
        if b <= a {
            anyhow::bail!(
                "--seeds '{s}': empty range (A..B runs the seeds A to B - 1: B must be above A)"
            );
        }
        if b - a > MAX_SEEDS {
            anyhow::bail!("--seeds '{s}': {} seeds, at most {MAX_SEEDS}", b - a);
        }
        Ok((a..b).collect())
    } else {
        s.split(',')
            .map(|x| x.trim().parse().map_err(|_| bad()))
            .collect()
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    a.what.check_files()?;
    let params = a
        .params
        .iter()
        .map(|p| SweepParam::parse(p))
        .collect::<Result<Vec<_>, _>>()?;
    let seeds = parse_seeds(&a.seeds)?;
    let perturb = match (&a.perturb_spec, a.perturb) {
        (Some(file), _) => Some(Perturb::from_spec(&read_spec(file)?)),
        (None, f) => f
            .map(|f| Perturb::new(f, a.perturb_keys.as_deref()))
            .transpose()?,
    };
    let setup = setup_text(&a, perturb.as_ref(), seeds.len());
    let base = a.what.request(None, None, a.control_tick);
    let t0 = std::time::Instant::now();
    let retune = if a.commission {
        Some(retune(a.commission_evals, a.logs.clone(), &base)?)
    } else {
        None
    };
    let opts = BatchOptions {
        retune,
        perturb,
        logs: a.logs.clone(),
        progress: true,
        floor: a.floor,
    };
    let rows = sweep_with(&base, &params, &seeds, &opts)?;
    write_csv(&rows, &a.out)?;
    let failed = rows.iter().filter(|r| r.result.is_err()).count();
    eprintln!(
        "{} runs ({} failed) in {:.1} s on {} threads -> {}",
        rows.len(),
        failed,
        t0.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        a.out.display()
    );
    if a.floor {
        eprintln!("{}", floor_summary(&rows));
    }
    if let Some(dir) = &a.report {
        let o = outcome(&rows);
        let path = write_report(&rows, dir, "DCA: sweep report", &setup)?;
        eprintln!(
            "{} stable, {} unstable, {} diverged, {} failed -> {}",
            o.stable,
            o.unstable,
            o.diverged,
            o.failed,
            path.display()
        );
    }
    Ok(())
}

/// The commissioning step of `--commission`: the base request's controller,
/// hose and effects; the tuned settings' columns.
fn retune(
    evals: u64,
    keep: Option<PathBuf>,
    base: &host_sim::sim::request::RunRequest,
) -> anyhow::Result<Retune> {
    let spec = resolve(base)?;
    let c = Commissioning {
        base: spec.controller,
        preset: tune::preset_of(base.config.as_deref())?,
        hose: spec.plant.hose_model(),
        effects: spec.effects,
        max_evals: evals,
        robust: Robust {
            draws: 4,
            fraction: 0.1,
        },
        keep,
    };
    tune::Knob::of(spec.controller.kind)?;
    Ok(Retune(Arc::new(move |rig, seed, index| {
        let done = commission(&c, rig, seed, index)?;
        let mut columns = vec![("verdict".to_string(), done.verdict)];
        columns.extend(
            done.changed
                .iter()
                .map(|(p, v)| (p.to_string(), format!("{v:e}"))),
        );
        Ok((done.config, columns))
    })))
}

/// The floor and the excess over it: median, 95th percentile, largest.
fn floor_summary(rows: &[host_sim::sim::batch::BatchRow]) -> String {
    let stats = |mut v: Vec<f64>| {
        v.retain(|x| x.is_finite());
        v.sort_by(f64::total_cmp);
        let q = |p| quantile(&v, p).map_or("-".into(), |x| format!("{x:.3}"));
        format!(
            "median {}, 95th percentile {}, max {} mm ({} runs)",
            q(0.5),
            q(0.95),
            q(1.0),
            v.len()
        )
    };
    let floors = rows
        .iter()
        .filter_map(|r| r.floor_mm.as_ref()?.as_ref().ok().copied())
        .collect();
    let excess = rows.iter().filter_map(|r| r.excess_mm()).collect();
    format!(
        "floor: {}\nexcess over the floor: {}",
        stats(floors),
        stats(excess)
    )
}

/// What the sweep ran, for the report (Markdown).
fn setup_text(a: &Args, perturb: Option<&Perturb>, seeds: usize) -> String {
    let mut s = format!("`host-sim sweep`, {seeds} seed(s) `{}`", a.seeds);
    if !a.params.is_empty() {
        s += &format!(", parameters `{}`", a.params.join("`, `"));
    }
    if let Some(p) = perturb {
        s += &format!(". {} (the controller keeps its design model)", p.describe());
    }
    s + ". Options: `" + &a.what.describe() + "`."
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_ranges_and_lists() {
        assert_eq!(parse_seeds("3..6").unwrap(), [3, 4, 5]);
        assert_eq!(parse_seeds("7, 2,9").unwrap(), [7, 2, 9]);
        for (s, want) in [
            ("5..1", "--seeds '5..1': empty range"),
            ("5..5", "--seeds '5..5': empty range"),
            ("0..200000", "200000 seeds, at most 100000"),
            ("a..3", "expected A..B or a,b,c"),
            ("1,x", "expected A..B or a,b,c"),
        ] {
            let e = parse_seeds(s).unwrap_err().to_string();
            assert!(e.contains(want), "{s}: {e}");
        }
    }

    /// `--perturb` and `--perturb-spec` exclude each other; `--perturb-keys`
    /// goes with `--perturb` only; the report says which spec drew the rigs.
    #[test]
    fn perturb_options_exclude_each_other() {
        use clap::Parser as _;
        let parse = |extra: &[&str]| {
            let argv = ["host-sim", "sweep", "--scenario", "step", "--out", "x.csv"];
            super::super::Cli::try_parse_from(argv.iter().chain(extra))
        };
        assert!(parse(&["--perturb", "0.3"]).is_ok());
        assert!(parse(&["--perturb-spec", "t.toml"]).is_ok());
        let e = parse(&["--perturb", "0.3", "--perturb-spec", "t.toml"]).unwrap_err();
        assert_eq!(e.kind(), clap::error::ErrorKind::ArgumentConflict, "{e}");
        assert!(parse(&["--perturb-spec", "t.toml", "--perturb-keys", "m_kg"]).is_err());
        assert!(parse(&["--perturb-keys", "m_kg"]).is_err());
        let spec = host_sim::sim::tolerance::spec_str(
            "[m_kg]\ndist = \"normal\"\nsigma = 0.05\nreason = \"weighed\"\n",
            "my-rig.toml",
        )
        .unwrap();
        let super::super::Command::Sweep(a) = parse(&[]).unwrap().command else {
            panic!("not sweep");
        };
        let text = setup_text(&a, Some(&Perturb::from_spec(&spec)), 2);
        assert!(
            text.contains("from the tolerance spec `my-rig.toml`")
                && text.contains("`m_kg` normal sigma 0.05"),
            "{text}"
        );
        let text = setup_text(&a, Some(&Perturb::new(0.3, Some("m_kg")).unwrap()), 2);
        assert!(
            text.contains("uniformly within +-0.3 of its value: m_kg"),
            "{text}"
        );
    }
}
