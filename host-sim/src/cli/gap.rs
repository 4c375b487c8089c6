//! `host-sim gap`: the sim-to-real gap diagnosis of recorded run logs.

use std::path::{Path, PathBuf};

use host_sim::gap::diagnose::Options;
use host_sim::gap::diagnosis::Diagnosis;
use host_sim::gap::{run_gap, Outputs};
use host_sim::io::num::Num;

use super::args::input_file;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// A run log used to localise the gap and fit the candidate effects (repeatable).
    #[arg(long = "fit", required = true)]
    fit: Vec<PathBuf>,
    /// A held-out run log, only used to evaluate what was fitted (repeatable).
    #[arg(long = "check", required = true)]
    check: Vec<PathBuf>,
    /// Where to write the JSON report (optional).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Directory for the Markdown report with plots (optional). Without
    /// --json, --report and --rig-out the verdict and its key numbers go to stdout.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Write the rig as the diagnosis identified it (re-estimated parameters,
    /// the verdict's effect with its fitted parameters) as a rig file that
    /// `--plant RIG.toml` runs and `host-sim tune --plant` tunes for.
    #[arg(long, value_name = "RIG.toml")]
    rig_out: Option<PathBuf>,
}

/// The runs' files exist, and no file is given twice: a run given as a fit
/// and as a check run would leave nothing held out.
fn check_runs(fit: &[PathBuf], check: &[PathBuf]) -> anyhow::Result<()> {
    let mut seen: Vec<(PathBuf, &str, &Path)> = Vec::new();
    for (option, paths) in [("--fit", fit), ("--check", check)] {
        for p in paths {
            let canonical = input_file(option, p)?;
            if let Some((_, first, q)) = seen.iter().find(|(c, _, _)| *c == canonical) {
                anyhow::bail!(
                    "{option} {} is the same file as {first} {}: {}",
                    p.display(),
                    q.display(),
                    if *first == option {
                        "give each run once"
                    } else {
                        "a check run must be held out from the fit (give another recorded run)"
                    }
                );
            }
            seen.push((canonical, option, p));
        }
    }
    Ok(())
}

pub fn run(a: Args) -> anyhow::Result<()> {
    check_runs(&a.fit, &a.check)?;
    let opts = Options {
        progress: true,
        ..Default::default()
    };
    let out = Outputs {
        json: a.json.as_deref(),
        report: a.report.as_deref(),
        rig_out: a.rig_out.as_deref(),
    };
    let d = run_gap(&a.fit, &a.check, out, &opts)?;
    let written: Vec<String> = [a.json.as_deref(), a.report.as_deref(), a.rig_out.as_deref()]
        .into_iter()
        .flatten()
        .map(|p| p.display().to_string())
        .collect();
    if written.is_empty() {
        print!("{}", summary(&d));
    } else {
        eprintln!(
            "verdict: {} (fit {:.2} -> {:.2}, check {:.2} -> {:.2}, {:.1} s) -> {}",
            d.verdict,
            d.fit.before,
            d.fit.after,
            d.check.before,
            d.check.after,
            d.elapsed_s,
            written.join(", ")
        );
    }
    Ok(())
}

/// The verdict and the key numbers, as text for the terminal: the gap
/// before and after on the fit and check runs, the best candidates and
/// where the gap is.
fn summary(d: &Diagnosis) -> String {
    let mut s = format!("verdict: {}", d.verdict);
    if let (Some(form), Some(part)) = (&d.form, &d.subsystem) {
        s += &format!(" ({form} form, {part})");
    }
    s += "\n";
    for (name, g) in [("fit", &d.fit), ("check", &d.check)] {
        s += &format!(
            "{name:<5} runs: gap {:.2} -> {:.2} (shrink {:.0} %)\n",
            g.before,
            g.after,
            100.0 * g.shrink
        );
    }
    s += &format!("reason: {}\n", d.reason);
    s += "best candidates (shrink on fit / check runs):\n";
    for c in d.candidates.iter().take(3) {
        let params: Vec<String> = c
            .params
            .iter()
            .map(|(k, v)| format!("{k}={}", Num(*v)))
            .collect();
        s += &format!(
            "  {:<20} {:>5.0} % / {:>5.0} %  {}\n",
            c.effect,
            100.0 * c.fit_shrink,
            100.0 * c.check_shrink,
            params.join(" ")
        );
    }
    if !d.where_.is_empty() {
        s += "where the gap is (share of the run's gap):\n";
        for w in d.where_.iter().take(3) {
            s += &format!(
                "  {:>3.0} %  {} {} {:.3}-{:.3} s ({})\n",
                100.0 * w.share,
                w.run,
                w.channel,
                w.t0_s,
                w.t1_s,
                w.label
            );
        }
    }
    s += &format!(
        "gap: {}\n({:.1} s; --json FILE for every number, --report DIR for plots)\n",
        d.gap_metric, d.elapsed_s
    );
    s
}
