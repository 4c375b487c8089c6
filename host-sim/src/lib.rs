//! host-sim: the DCA plant and tools around the control core.
#![forbid(unsafe_code)]

pub mod batch;
pub mod bench;
pub mod board;
pub mod config;
pub mod effects;
pub mod gains;
pub mod gap;
pub mod grnn;
pub mod hil;
pub mod metrics;
pub mod paper;
pub mod plant;
pub mod plot;
pub mod rig;
pub mod run;
pub mod runlog;
pub mod scenario;
pub mod sensors;
pub mod sim;
