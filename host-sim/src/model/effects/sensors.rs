//! The sensors: `sensor_delay` and `sensor_calibration`, each as its named form
//! and its general family (the sensor filter, the sensor map).

use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, GeneralFamily, NamedEffect, ParamSpec};
use super::terms::RigTerms;

use super::common::{interp, one};

/// Delay and lag of the measurements.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SensorDelay {
    /// Transport delay of the LVDT reading, s.
    #[serde(default)]
    pub xo_delay_s: f64,
    /// First-order time constant of the LVDT reading, s.
    #[serde(default)]
    pub xo_tau_s: f64,
    /// First-order time constant of the pressure readings, s.
    #[serde(default)]
    pub p_tau_s: f64,
}

/// Taps of a [`SensorFilter`].
pub const FILTER_TAPS: usize = 11;

/// Delays of the taps of a [`SensorFilter`], s: its impulse response on a
/// grid of 1 ms up to 4 ms, coarser up to 32 ms.
pub const FILTER_DELAYS_S: [f64; FILTER_TAPS] = [
    0.0, 1e-3, 2e-3, 3e-3, 4e-3, 6e-3, 8e-3, 12e-3, 16e-3, 24e-3, 32e-3,
];

/// The general family of `sensor_delay` (a lag of any shape on any one of
/// the LVDT, the encoder and the pressures): a causal, non-negative impulse
/// response with unit gain at rest. The channel records
/// `sum_j w_j v(t - d_j) / sum_j w_j` of its true value `v`, `d_j` the
/// delays [`FILTER_DELAYS_S`] (between samples `v` is interpolated
/// linearly). One weight is a pure delay, weights falling off with the
/// delay a first-order lag, equal weights a moving average.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SensorFilter {
    /// The sensor (not the force sensor, whose reading drives the load).
    pub channel: CalChannel,
    /// Weight of each tap (non-negative, not all zero; normalised on use).
    pub weights: [f64; FILTER_TAPS],
}

impl SensorFilter {
    /// The weights normalised to a sum of 1.
    pub fn normalised(&self) -> [f64; FILTER_TAPS] {
        let sum: f64 = self.weights.iter().sum();
        self.weights.map(|w| w / sum)
    }

    /// Mean delay of the impulse response (its centre of mass), s.
    pub fn mean_delay_s(&self) -> f64 {
        self.normalised()
            .iter()
            .zip(FILTER_DELAYS_S)
            .map(|(w, d)| w * d)
            .sum()
    }

    /// Whether the filter is usable: a channel other than the force
    /// sensor, weights finite, non-negative, not all zero.
    pub fn is_valid(&self) -> bool {
        self.channel != CalChannel::Ft
            && self.weights.iter().all(|w| w.is_finite() && *w >= 0.0)
            && self.weights.iter().sum::<f64>() > 0.0
    }
}

/// The channel a [`SensorCalibration`] acts on.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
pub enum CalChannel {
    /// The LVDT, Xo.
    #[serde(rename = "xo_m")]
    Xo,
    /// The encoder, Xi.
    #[serde(rename = "xi_m")]
    Xi,
    /// Line-1 pressure.
    #[serde(rename = "p1_pa")]
    P1,
    /// Line-2 pressure.
    #[serde(rename = "p2_pa")]
    P2,
    /// The load force sensor.
    #[serde(rename = "ft_n")]
    Ft,
}

impl CalChannel {
    /// Every channel, in index order.
    pub const ALL: [Self; 5] = [Self::Xo, Self::Xi, Self::P1, Self::P2, Self::Ft];

    /// The run-log column (`xo_m`, `xi_m`, `p1_pa`, `p2_pa`, `ft_n`).
    pub fn name(self) -> &'static str {
        match self {
            Self::Xo => "xo_m",
            Self::Xi => "xi_m",
            Self::P1 => "p1_pa",
            Self::P2 => "p2_pa",
            Self::Ft => "ft_n",
        }
    }

    /// The SI unit suffix of the channel's values (`m`, `pa`, `n`).
    pub fn unit(self) -> &'static str {
        match self {
            Self::Xo | Self::Xi => "m",
            Self::P1 | Self::P2 => "pa",
            Self::Ft => "n",
        }
    }

    /// Index (0 to 4, [`Self::ALL`] order).
    pub fn index(self) -> usize {
        self as usize
    }

    /// The channel of an index, if any.
    pub fn from_index(i: usize) -> Option<Self> {
        Self::ALL.get(i).copied()
    }

    /// Full scale of the sensor, SI: the LVDT's and the stroke's 0.12 m,
    /// the pressure sensors' 10 MPa, the force sensor's 4000 N
    /// (docs/model.md section 5).
    pub fn span(self) -> f64 {
        match self {
            Self::Xo | Self::Xi => 0.12,
            Self::P1 | Self::P2 => 10.0e6,
            Self::Ft => 4000.0,
        }
    }
}

/// A static calibration error of one sensor: it records
/// `offset_si + gain_1 v + quad_1 v^2 / span` for the true value `v`.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SensorCalibration {
    /// The sensor.
    pub channel: CalChannel,
    /// Gain (1: right).
    #[serde(default = "one")]
    pub gain_1: f64,
    /// Offset, in the channel's SI unit (m, Pa or N).
    #[serde(default)]
    pub offset_si: f64,
    /// Quadratic nonlinearity: the deviation at full scale as a share of it.
    #[serde(default)]
    pub quad_1: f64,
}

impl SensorCalibration {
    /// The recorded value of the true value `v`.
    pub fn map(&self, v: f64) -> f64 {
        self.offset_si + self.gain_1 * v + self.quad_1 * v * v / self.channel.span()
    }

    /// The true value of the recorded value `y` (the root of [`Self::map`]
    /// next to the affine inverse; Newton steps).
    pub fn invert(&self, y: f64) -> f64 {
        let mut v = (y - self.offset_si) / self.gain_1;
        let span = self.channel.span();
        for _ in 0..4 {
            let slope = self.gain_1 + 2.0 * self.quad_1 * v / span;
            if slope.abs() < 1e-9 {
                break;
            }
            v -= (self.map(v) - y) / slope;
        }
        v
    }
}

/// Knots of a [`SensorMap`].
pub const MAP_KNOTS: usize = 6;

/// The general family of `sensor_calibration` (a static map of any
/// monotone shape on one of the sensors): the
/// channel records the piecewise-linear interpolation of `(knots_si,
/// readings_si)` at its true value, extended linearly beyond the end knots.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SensorMap {
    /// The sensor.
    pub channel: CalChannel,
    /// True values at the knots, SI (strictly increasing).
    pub knots_si: [f64; MAP_KNOTS],
    /// Recorded values at the knots, SI (strictly increasing).
    pub readings_si: [f64; MAP_KNOTS],
}

impl SensorMap {
    /// The recorded value of the true value `v`.
    pub fn map(&self, v: f64) -> f64 {
        interp(&self.knots_si, &self.readings_si, v, false)
    }

    /// The true value of the recorded value `y` (exact: the map is
    /// monotone and piecewise linear).
    pub fn invert(&self, y: f64) -> f64 {
        interp(&self.readings_si, &self.knots_si, y, false)
    }

    /// Whether the map is usable: knots and readings finite and strictly
    /// increasing (a monotone map, so that a reading names one true value),
    /// every reading within one span of its knot. On the force sensor the
    /// replay applies the true load the map's inverse gives of the reading.
    pub fn is_valid(&self) -> bool {
        let rising = |v: &[f64; MAP_KNOTS]| {
            v.iter().all(|x| x.is_finite()) && v.windows(2).all(|w| w[1] > w[0])
        };
        let span = self.channel.span();
        rising(&self.knots_si)
            && rising(&self.readings_si)
            && self
                .knots_si
                .iter()
                .zip(&self.readings_si)
                .all(|(k, r)| (r - k).abs() <= span)
    }
}

impl NamedEffect for SensorDelay {
    const SUBSYSTEM: &'static str = "sensors";
    const PARAMS: &'static [ParamSpec] = &[
        p("xo_delay_s", 3e-3, 0.0, 0.1),
        p("xo_tau_s", 2e-3, 0.0, 0.1),
        p("p_tau_s", 1e-3, 0.0, 0.1),
    ];
    fn values(&self) -> Vec<f64> {
        vec![self.xo_delay_s, self.xo_tau_s, self.p_tau_s]
    }
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        Self {
            xo_delay_s: at(0),
            xo_tau_s: at(1),
            p_tau_s: at(2),
        }
    }
}

impl GeneralFamily for SensorFilter {
    const FORM: &'static str =
        "general: a sensor's lag of any shape (a non-negative impulse response over 0 to 32 ms)";
    const BOTH: &'static str = "the named form and the sensor filter exclude each other";
    const REQUIREMENT: &'static str =
        "sensor_filter: channel xo_m, xi_m, p1_pa or p2_pa, weights non-negative \
         and not all zero";
    fn family_valid(&self) -> bool {
        self.is_valid()
    }
    fn param_map(&self) -> Vec<(String, f64)> {
        let mut m = vec![
            ("channel".to_string(), self.channel.index() as f64),
            ("mean_delay_s".to_string(), self.mean_delay_s()),
        ];
        for (d, w) in FILTER_DELAYS_S.iter().zip(self.normalised()) {
            m.push((format!("weight_at_{:.0}_ms", d * 1e3), w));
        }
        m
    }
}

/// The offset and the nonlinearity are signed: [`NamedEffect::check_relations`]
/// checks them against the channel's span, not these bounds.
impl NamedEffect for SensorCalibration {
    const SUBSYSTEM: &'static str = "sensors";
    const PARAMS: &'static [ParamSpec] = &[
        p("channel", 0.0, 0.0, 4.0),
        p("gain_1", 1.0, 0.5, 2.0),
        p("offset_si", 0.0, 0.0, 0.0),
        p("quad_1", 0.0, 0.0, 0.0),
    ];
    const SEARCHED: bool = false;
    const RANGE_CHECKED: bool = false;
    fn values(&self) -> Vec<f64> {
        vec![
            self.channel.index() as f64,
            self.gain_1,
            self.offset_si,
            self.quad_1,
        ]
    }
    /// A channel index off the list is kept out of range as a NaN gain,
    /// which the checks refuse.
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        let ch = at(0);
        let channel = CalChannel::from_index(ch.round().max(0.0) as usize);
        Self {
            channel: channel.unwrap_or(CalChannel::Xo),
            gain_1: if channel.is_some() && ch.fract() == 0.0 {
                at(1)
            } else {
                f64::NAN
            },
            offset_si: at(2),
            quad_1: at(3),
        }
    }
    fn check_relations(&self) -> Result<(), Broken> {
        let span = self.channel.span();
        let ok = (0.1..=10.0).contains(&self.gain_1)
            && self.offset_si.abs() <= span
            && self.quad_1.abs() <= 1.0;
        if !ok {
            return Err(Broken::Requirement(
                "channel must be 0 to 4, gain_1 in [0.1, 10], abs(offset_si) at most the \
                 channel's span, abs(quad_1) at most 1",
            ));
        }
        Ok(())
    }
    /// The offset carries its channel's unit: `offset_m`, `offset_pa`,
    /// `offset_n`.
    fn param_map(&self) -> Option<Vec<(String, f64)>> {
        Some(vec![
            ("channel".to_string(), self.channel.index() as f64),
            ("gain_1".to_string(), self.gain_1),
            (format!("offset_{}", self.channel.unit()), self.offset_si),
            ("quad_1".to_string(), self.quad_1),
        ])
    }
}

impl GeneralFamily for SensorMap {
    const FORM: &'static str =
        "general: a sensor's monotone static map of any shape (piecewise linear, six knots)";
    const BOTH: &'static str = "the named form and the sensor map exclude each other";
    const REQUIREMENT: &'static str = "sensor_map: knots_si and readings_si \
                 strictly increasing, each reading within the channel's span of its knot";
    fn family_valid(&self) -> bool {
        self.is_valid()
    }
    fn param_map(&self) -> Vec<(String, f64)> {
        let mut m = vec![("channel".to_string(), self.channel.index() as f64)];
        let unit = self.channel.unit();
        for (i, (k, r)) in self.knots_si.iter().zip(self.readings_si).enumerate() {
            m.push((format!("knot{i}_{unit}"), *k));
            m.push((format!("reading{i}_{unit}"), r));
        }
        m
    }
}

/// On the readings only ([`crate::model::sensors`]).
impl RigTerms for SensorDelay {
    const ON_EQUATIONS: bool = false;
}

/// On the readings only ([`crate::model::sensors`]).
impl RigTerms for SensorFilter {
    const ON_EQUATIONS: bool = false;
}

/// On the readings only ([`crate::model::sensors`]).
impl RigTerms for SensorCalibration {
    const ON_EQUATIONS: bool = false;
}

/// On the readings only ([`crate::model::sensors`]).
impl RigTerms for SensorMap {
    const ON_EQUATIONS: bool = false;
}
