//! The GRNN hose models at run time (docs/model.md sections 4 and 9).
//!
//! * [`data`]: the two hose-test formats (quasi-static, dynamic), loaders with
//!   file:line:column errors, and the shipped sample data (compiled in);
//! * [`net`]: the GRNN of the paper's eq. 19-24 with z-score inputs, VAcc (eq. 26
//!   as reconstructed, relative and mean-normalised), RMSE, k-fold CV of sigma;
//! * [`split`]: seeded splits, including numpy's `default_rng(seed).permutation`
//!   bit for bit (the reference implementation's split);
//! * [`memory`]: the GRNN with memory (filtered pressures as inputs);
//! * [`fast`]: evaluation much faster than the direct sum, within stated bounds;
//! * [`local`]: the memory GRNN in the integrator, from a cached local list of
//!   samples, within a provable bound;
//! * [`grnn`]: the GRNN hoses of the plant
//!   ([`HoseModel::Grnn`](super::plant::HoseModel::Grnn),
//!   [`HoseModel::GrnnMemory`](super::plant::HoseModel::GrnnMemory)) and the
//!   implicit pressure-rate solve.
//!
//! The studies of these models (the paper's Fig. 9, the choice of the memory
//! hose's filters, the closed-loop comparison) are in [`crate::studies::grnn`].

pub mod data;
pub mod fast;
pub mod grnn;
pub mod local;
pub mod memory;
pub mod net;
pub mod split;
