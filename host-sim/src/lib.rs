//! host-sim: the DCA plant and tools around the control core.
//!
//! The crate is built in layers, each a folder, bottom to top:
//!
//! * [`io`]: file formats and output helpers (run logs, plots, files named in errors);
//! * [`model`]: the plant, its hose models (the GRNN hose included), the unmodelled
//!   effects, the rig, the sensors and the scenarios;
//! * [`sim`]: the one closed loop (shared by the software runs and the HIL lockstep),
//!   metrics, run requests, configuration files and sweeps;
//! * [`gap`], [`hil`], [`studies`]: siblings on top of the loop: the sim-to-real gap
//!   diagnosis; hardware- and processor-in-the-loop runs with the board's host side;
//!   the paper's experiments and the hose-model studies;
//! * the command line (`src/cli/`, part of the binary, not of this library).
//!
//! The rule: a module imports only from its own layer or below, and modules do not
//! import each other in a cycle. `tests/layers.rs` checks both in `cargo test`.
#![forbid(unsafe_code)]

pub mod gap;
pub mod hil;
pub mod io;
pub mod model;
pub mod sim;
pub mod studies;
