//! host-sim: the DCA plant and tools around the control core.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod gains;
pub mod metrics;
pub mod plant;
pub mod scenario;
pub mod sensors;
pub mod sim;
