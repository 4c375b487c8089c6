//! `host-sim bench`: speed of the simulator and of the diagnosis.

use host_sim::studies::bench::{bench, gap_suite_rows, table};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Repetitions of each measurement (the best is kept).
    #[arg(long, default_value_t = 5)]
    reps: usize,
    /// Instead: one whole gap diagnosis on one core for every case of the
    /// validation suite (minutes long; a row per case, the median and the
    /// longest). Run it on a quiet machine.
    #[arg(long)]
    gap_suite: bool,
}

/// The bench cannot fail.
pub fn run(a: Args) {
    let rows = if a.gap_suite {
        gap_suite_rows()
    } else {
        bench(a.reps)
    };
    print!("{}", table(&rows));
}
