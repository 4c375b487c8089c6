//! `host-sim sweep`: parameter sweeps and Monte Carlo seeds.

use std::path::PathBuf;

use host_sim::sim::batch::{sweep, write_csv, SweepParam};

use super::args::RunOpts;

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
    /// Where to write the CSV.
    #[arg(long)]
    out: PathBuf,
}

/// `A..B` (B excluded, at most 100 000 seeds) or `a,b,c`.
fn parse_seeds(s: &str) -> anyhow::Result<Vec<u64>> {
    let bad = || anyhow::anyhow!("--seeds '{s}': expected A..B or a,b,c");
    if let Some((a, b)) = s.split_once("..") {
        let (a, b): (u64, u64) = (
            a.trim().parse().map_err(|_| bad())?,
            b.trim().parse().map_err(|_| bad())?,
        );
        if b <= a || b - a > 100_000 {
            return Err(bad());
        }
        Ok((a..b).collect())
    } else {
        s.split(',')
            .map(|x| x.trim().parse().map_err(|_| bad()))
            .collect()
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let params = a
        .params
        .iter()
        .map(|p| SweepParam::parse(p))
        .collect::<Result<Vec<_>, _>>()?;
    let seeds = parse_seeds(&a.seeds)?;
    let base = a.what.request(None, None);
    let t0 = std::time::Instant::now();
    let rows = sweep(&base, &params, &seeds, true)?;
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
    Ok(())
}
