//! GRNN hose models (plant.md sections 4 and 9, section 11 item 18).
//!
//! * [`data`]: the two hose-test formats (quasi-static, dynamic), loaders with
//!   file:line:column errors, and the shipped sample data (compiled in);
//! * [`net`]: the GRNN of the paper's eq. 19-24 with z-score inputs, VAcc (eq. 26
//!   as reconstructed, relative and mean-normalised), RMSE, k-fold CV of sigma;
//! * [`split`]: seeded splits, including numpy's `default_rng(seed).permutation`
//!   bit for bit (the reference implementation's split);
//! * [`paper`]: the paper's study: VAcc per pressure section, the pooled GRNN,
//!   CV sigma, and GRNN / RBF ([`rbf`]) / BP ([`bp`]) side by side (Fig. 9) with
//!   a table and a PNG;
//! * [`memory`]: a GRNN hose with memory (filtered pressures as inputs) fitted on
//!   the dynamic data, leave-one-run-out against the static map;
//! * [`fast`]: evaluation much faster than the direct sum, within stated bounds;
//! * [`hose`]: the GRNN hoses of the plant (`plant::HoseModel::Grnn`,
//!   `plant::HoseModel::GrnnMemory`) and the implicit pressure-rate solve;
//! * [`closed_loop`]: MPC-ESO on `stepload` with the true, rigid, GRNN and
//!   memory-GRNN hoses (the load-step deviation of section 11, item 18).

pub mod bp;
pub mod closed_loop;
pub mod data;
pub mod fast;
pub mod hose;
pub mod memory;
pub mod net;
pub mod paper;
pub mod rbf;
pub mod split;
