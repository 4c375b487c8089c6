//! Layer `model`: what is simulated, without any loop around it.
//!
//! * [`plant`]: the nominal 11-state plant of docs/model.md sections 2-4;
//! * [`params`]: its physical parameters by key: from TOML, checked, drawn for Monte Carlo;
//! * [`hose`]: the GRNN hose models the plant runs (networks, data, fast
//!   evaluation, the implicit pressure-rate solve);
//! * [`effects`]: the unmodelled effects of docs/model.md section 12;
//! * [`rig`]: the plant with effects switched on;
//! * [`sensors`]: ideal and realistic sensors;
//! * [`scenario`]: the scenarios of docs/model.md section 7.
//!
//! May import from [`crate::io`] and from `model` itself.

pub mod effects;
pub mod hose;
pub mod params;
pub mod plant;
pub mod rig;
pub mod scenario;
pub mod sensors;
