//! `host-sim gap-suite`: the gap diagnosis's validation suite.

use std::path::PathBuf;

use anyhow::Context as _;
use host_sim::gap::validation::{cases, markdown, score, suite_logs};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Also write the table to this Markdown file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Only the cases whose name contains this text (repeatable: any of them).
    #[arg(long, value_name = "TEXT")]
    only: Vec<String>,
    /// Draw every case's noise as if it stood this many places later in the
    /// suite (0: the suite's own seeds). A check of how much the table hangs
    /// on the noise of its runs.
    #[arg(long, value_name = "K", default_value_t = 0)]
    seed_shift: u32,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    // Each case keeps its place in the whole suite: its logs' noise seeds
    // follow from it, so a case run alone gives the suite's result.
    let (index, chosen): (Vec<usize>, Vec<_>) = cases()
        .into_iter()
        .enumerate()
        .filter(|(_, c)| a.only.is_empty() || a.only.iter().any(|o| c.name.contains(o.as_str())))
        .unzip();
    if chosen.is_empty() {
        let names: Vec<String> = cases().into_iter().map(|c| c.name).collect();
        anyhow::bail!(
            "no case of the suite matches --only {:?}; the cases are: {}",
            a.only,
            names.join(", ")
        );
    }
    let logs = |i: usize, c: &_| suite_logs(index[i] + a.seed_shift as usize, c);
    let res = score(&chosen, logs, &Default::default(), true);
    let table = markdown(&res);
    println!("{table}");
    eprintln!(
        "{} cases in {:.1} s on {} threads",
        res.len(),
        t0.elapsed().as_secs_f64(),
        rayon::current_num_threads()
    );
    if let Some(p) = a.out {
        std::fs::write(&p, table).with_context(|| p.display().to_string())?;
    }
    Ok(())
}
