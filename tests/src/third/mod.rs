//! A third, independently written family of simulated rigs for validating the gap
//! diagnosis (`host-sim gap`, docs/gap.md; issue 11, deliverable 4).
//!
//! Everything here was written from docs/model.md sections 1-5 and 12 and
//! docs/interfaces.md sections 1-2 alone, without reading host-sim's plant,
//! effects or gap code or the second ("foreign") family: its own plant and RK4
//! ([`plant`]), its own effect forms ([`effects`]), sensors and random numbers
//! ([`sensors`], [`rng`]), scenarios that differ from the other suites'
//! ([`scenario`]) and the case list with the expected verdicts ([`cases`]). Only
//! the control laws come from `dca_core`. docs/gap-validation.md describes it and
//! publishes its confusion tables.

pub mod cases;
pub mod effects;
pub mod plant;
pub mod rng;
pub mod scenario;
pub mod sensors;
