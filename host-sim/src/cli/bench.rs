//! `host-sim bench`: speed of the simulator and of the diagnosis.

use host_sim::studies::bench::{bench, table};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Repetitions of each measurement (the best is kept).
    #[arg(long, default_value_t = 5)]
    reps: usize,
}

/// The bench cannot fail.
pub fn run(a: Args) {
    print!("{}", table(&bench(a.reps)));
}
