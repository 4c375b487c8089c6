//! One run log prepared for the diagnosis: its noise levels, channel scales,
//! segment labels and the load the replays are driven with (shared by the
//! gap measure, the prefit and the diagnosis).

use super::replay::{filtered_load, measured};
use super::segment::{labels, Label};
use super::stats::noise_sigma;
use crate::io::runlog::RunLog;

/// Lowest channel scales (noise floors) in SI: Xo 5 um, Xi 1 um, P 1 kPa.
pub const SCALE_FLOOR: [f64; 4] = [5e-6, 1e-6, 1e3, 1e3];

/// One run prepared for the diagnosis: the log, its noise scales and labels.
pub struct Run {
    /// Display name.
    pub name: String,
    /// The log.
    pub log: RunLog,
    /// Noise level per channel.
    pub noise: [f64; 4],
    /// Scale per channel (noise with floor).
    pub scale: [f64; 4],
    /// Segment label per sample.
    pub labels: Vec<Label>,
    /// The recorded load with its noise reduced (the replay's input).
    pub load: Vec<f64>,
}

impl Run {
    /// Prepare a log.
    pub fn new(name: String, log: RunLog) -> Self {
        let m = measured(&log);
        let noise: [f64; 4] = std::array::from_fn(|c| noise_sigma(m[c]));
        let scale = std::array::from_fn(|c| noise[c].max(SCALE_FLOOR[c]));
        let labels = labels(&log);
        let load = filtered_load(&log);
        Self {
            name,
            log,
            noise,
            scale,
            labels,
            load,
        }
    }
}
