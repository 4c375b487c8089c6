//! `host-sim gap-suite`: the gap diagnosis's validation suite.

use std::path::PathBuf;

use anyhow::Context as _;
use host_sim::gap::validation::{cases, markdown, run_suite};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Also write the table to this Markdown file.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Only the cases whose name contains this text (repeatable: any of them).
    #[arg(long, value_name = "TEXT")]
    only: Vec<String>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let t0 = std::time::Instant::now();
    let chosen: Vec<_> = cases()
        .into_iter()
        .filter(|c| a.only.is_empty() || a.only.iter().any(|o| c.name.contains(o.as_str())))
        .collect();
    anyhow::ensure!(
        !chosen.is_empty(),
        "no case of the suite matches --only {:?}; the cases are listed in docs/gap.md",
        a.only
    );
    let res = run_suite(&chosen, &Default::default(), true);
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
