//! Studies of the hose models (docs/model.md section 9, section 11 item 18).
//!
//! * [`paper`]: the paper's study: VAcc per pressure section, the pooled GRNN,
//!   CV sigma, and GRNN / RBF ([`rbf`]) / BP ([`bp`]) side by side (Fig. 9) with
//!   a table and a PNG;
//! * [`memory`]: the choice of the memory GRNN's filters and spread by blocked
//!   cross-validation, and leave-one-run-out against the static map;
//! * [`closed_loop`]: MPC-ESO on `stepload` with the true, rigid, GRNN and
//!   memory-GRNN hoses (the load-step deviation of section 11, item 18);
//! * [`report`]: `host-sim hose`: the above as one Markdown report.
//!
//! The networks themselves are in [`crate::model::hose`].

pub mod bp;
pub mod closed_loop;
pub mod memory;
pub mod paper;
pub mod rbf;
pub mod report;
