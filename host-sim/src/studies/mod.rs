//! Layer `studies` (beside [`crate::gap`] and [`crate::hil`]): the experiments
//! and printouts built on the simulator.
//!
//! * [`paper`]: the paper's simulation experiments, the table against docs/model.md
//!   section 10 and the paper's Tables 3-4, and the report with figures;
//! * [`gains`]: the MPC design of docs/model.md section 6.3 as JSON;
//! * [`grnn`]: the hose-model studies (GRNN, RBF and BP on the hose data, the
//!   memory GRNN held out run by run, the closed-loop hose comparison);
//! * [`montecarlo`]: the report of a sweep (Monte Carlo over the rig): histograms,
//!   unstable and diverged runs;
//! * [`mod@bench`]: speed of the simulator and of the diagnosis.
//!
//! May import from [`crate::io`], [`crate::model`], [`crate::sim`], its own
//! layer ([`crate::gap`]'s validation runs for the bench) and `studies` itself.

pub mod bench;
pub mod commission;
pub mod gains;
pub mod grnn;
pub mod montecarlo;
pub mod paper;
pub mod tune;
