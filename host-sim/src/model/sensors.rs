//! Sensor models (docs/model.md section 5): ideal, or realistic with 12-bit ADCs,
//! seeded Gaussian noise and encoder counts.
//!
//! | sensor | signal | range | LSB | noise (1 sigma) |
//! |--------|--------|-------|-----|-----------------|
//! | LVDT | Xo | -10 .. 110 mm | 29.3 um | 10 um |
//! | pressure x2 | P1, P2 | 0 .. 10 MPa | 2.44 kPa | 5 kPa |
//! | force | Ft | -2000 .. 2000 N | 0.98 N | 2 N |
//! | encoder | Xi | - | 0.2 um/count | none |
//!
//! ADC: `code = clamp(floor((v + noise - lo) / (hi - lo) * 4096), 0, 4095)`,
//! reading `lo + (code + 0.5) (hi - lo) / 4096`. Encoder: `floor(Xi / 0.2e-6) * 0.2e-6`.
//! Noise comes from a ChaCha8 generator seeded by the run's seed, so a seed
//! gives the same run on every machine (the statistics, not the samples, of
//! docs/model.md's numpy generator).

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use crate::model::effects::{
    CalChannel, Effects, SensorCalibration, SensorDelay, SensorFilter, SensorMap, FILTER_DELAYS_S,
    FILTER_TAPS,
};

/// How sensors report the plant state.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SensorMode {
    /// The exact state at the sampling instant.
    Ideal,
    /// Quantised, noisy readings as on the board.
    Realistic,
}

impl SensorMode {
    /// `ideal` or `realistic`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Ideal => "ideal",
            Self::Realistic => "realistic",
        }
    }

    /// Parse a name given by [`Self::name`].
    pub fn by_name(s: &str) -> Option<Self> {
        match s {
            "ideal" => Some(Self::Ideal),
            "realistic" => Some(Self::Realistic),
            _ => None,
        }
    }
}

/// A 12-bit ADC channel with Gaussian noise before quantisation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AdcChannel {
    /// Lower end of the range, SI.
    pub lo: f64,
    /// Upper end of the range, SI.
    pub hi: f64,
    /// Noise standard deviation before quantisation, SI.
    pub noise_sigma: f64,
}

impl AdcChannel {
    /// LVDT: -10 .. 110 mm, 10 um noise.
    pub const LVDT: Self = Self {
        lo: -0.010,
        hi: 0.110,
        noise_sigma: 10e-6,
    };
    /// Pressure: 0 .. 10 MPa gauge, 5 kPa noise.
    pub const PRESSURE: Self = Self {
        lo: 0.0,
        hi: 10.0e6,
        noise_sigma: 5.0e3,
    };
    /// Force: -2000 .. 2000 N, 2 N noise.
    pub const FORCE: Self = Self {
        lo: -2000.0,
        hi: 2000.0,
        noise_sigma: 2.0,
    };

    /// One LSB, SI.
    pub fn lsb(&self) -> f64 {
        (self.hi - self.lo) / 4096.0
    }

    /// The ADC code of `v + noise`.
    pub fn code(&self, v: f64, noise: f64) -> u16 {
        let c = ((v + noise - self.lo) / (self.hi - self.lo) * 4096.0).floor();
        c.clamp(0.0, 4095.0) as u16
    }

    /// The calibrated reading of a code (centre of its bin).
    pub fn reading(&self, code: u16) -> f64 {
        self.lo + (code as f64 + 0.5) * self.lsb()
    }
}

/// Encoder resolution: 10 000 counts/rev on a 2 mm lead, m per count.
pub const ENCODER_M_PER_COUNT: f64 = 0.2e-6;

/// Encoder reading of a power-piston position.
pub fn encoder_reading_m(xi_m: f64) -> f64 {
    (xi_m / ENCODER_M_PER_COUNT).floor() * ENCODER_M_PER_COUNT
}

/// One set of readings, SI.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Readings {
    /// Power piston position (encoder), m.
    pub xi_m: f64,
    /// Actuating piston position (LVDT), m.
    pub xo_m: f64,
    /// Line-1 pressure, Pa.
    pub p1_pa: f64,
    /// Line-2 pressure, Pa.
    pub p2_pa: f64,
    /// Load force, N.
    pub ft_n: f64,
}

/// Transport delay and first-order lag of the readings (the `sensor_delay`
/// effect), applied to the true values before the ADC.
#[derive(Clone, Debug)]
struct DelayLine {
    /// Past true Xo values, oldest first (length = delay in samples).
    xo_past: std::collections::VecDeque<f64>,
    /// Filter gains 1 - exp(-dt / tau) (1 = no filter).
    xo_gain: f64,
    p_gain: f64,
    /// Filter states (None until the first sample).
    xo_f: Option<f64>,
    p_f: Option<(f64, f64)>,
}

impl DelayLine {
    fn new(d: &SensorDelay, dt_s: f64) -> Self {
        let n = (d.xo_delay_s / dt_s).round().max(0.0) as usize;
        let gain = |tau: f64| {
            if tau > 0.0 {
                1.0 - (-dt_s / tau).exp()
            } else {
                1.0
            }
        };
        Self {
            xo_past: std::collections::VecDeque::with_capacity(n + 1),
            xo_gain: gain(d.xo_tau_s),
            p_gain: gain(d.p_tau_s),
            xo_f: None,
            p_f: None,
        }
        .with_len(n)
    }

    fn with_len(mut self, n: usize) -> Self {
        // Marks the length with NaN until filled with the first sample.
        self.xo_past.extend(std::iter::repeat_n(f64::NAN, n));
        self
    }

    fn apply(&mut self, truth: &Readings) -> Readings {
        // Transport delay: a run starts at rest, so the first sample fills the past.
        if self.xo_past.front().is_some_and(|v| v.is_nan()) {
            for v in self.xo_past.iter_mut() {
                *v = truth.xo_m;
            }
        }
        self.xo_past.push_back(truth.xo_m);
        let xo_delayed = self.xo_past.pop_front().unwrap_or(truth.xo_m);
        let xo = match self.xo_f {
            None => xo_delayed,
            Some(f) => f + self.xo_gain * (xo_delayed - f),
        };
        self.xo_f = Some(xo);
        let (p1, p2) = match self.p_f {
            None => (truth.p1_pa, truth.p2_pa),
            Some((f1, f2)) => (
                f1 + self.p_gain * (truth.p1_pa - f1),
                f2 + self.p_gain * (truth.p2_pa - f2),
            ),
        };
        self.p_f = Some((p1, p2));
        Readings {
            xo_m: xo,
            p1_pa: p1,
            p2_pa: p2,
            ..*truth
        }
    }
}

/// The general `sensor_delay` ([`SensorFilter`]) at readings taken every
/// `dt_s`: the channel's past true values, newest first.
#[derive(Clone, Debug)]
struct FilterLine {
    filter: SensorFilter,
    weights: [f64; FILTER_TAPS],
    dt_s: f64,
    /// Samples kept: enough for the longest delay and its interpolation.
    len: usize,
    past: std::collections::VecDeque<f64>,
}

impl FilterLine {
    fn new(f: &SensorFilter, dt_s: f64) -> Self {
        // Without a sample period (a one-row log) every tap reads now.
        let dt_s = if dt_s > 0.0 { dt_s } else { f64::INFINITY };
        let last = FILTER_DELAYS_S[FILTER_DELAYS_S.len() - 1];
        let n = (last / dt_s).ceil() as usize + 2;
        Self {
            filter: *f,
            weights: f.normalised(),
            dt_s,
            len: n,
            past: std::collections::VecDeque::with_capacity(n),
        }
    }

    /// The filtered reading of the true value `v` now.
    fn apply(&mut self, v: f64) -> f64 {
        // A run starts at rest: the first value fills the past.
        if self.past.is_empty() {
            self.past.extend(std::iter::repeat_n(v, self.len));
        }
        self.past.pop_back();
        self.past.push_front(v);
        let at = |k: usize| self.past[k.min(self.past.len() - 1)];
        self.weights
            .iter()
            .zip(FILTER_DELAYS_S)
            .map(|(w, d)| {
                let x = d / self.dt_s;
                let k = x.floor();
                let frac = x - k;
                let k = k as usize;
                w * (at(k) + frac * (at(k + 1) - at(k)))
            })
            .sum()
    }
}

/// The readings of a signal `v` (one value per reading, every `dt_s`)
/// through the filter `f` (its channel aside): what [`Sensors`] reports.
pub fn filtered(f: &SensorFilter, v: &[f64], dt_s: f64) -> Vec<f64> {
    let mut line = FilterLine::new(f, dt_s);
    v.iter().map(|x| line.apply(*x)).collect()
}

/// The value of `ch` in `r`, mutable.
fn channel_mut(r: &mut Readings, ch: CalChannel) -> &mut f64 {
    match ch {
        CalChannel::Xo => &mut r.xo_m,
        CalChannel::Xi => &mut r.xi_m,
        CalChannel::P1 => &mut r.p1_pa,
        CalChannel::P2 => &mut r.p2_pa,
        CalChannel::Ft => &mut r.ft_n,
    }
}

impl Readings {
    /// The readings as the control core's sample (f32, as the board has them).
    pub fn to_sample(&self) -> dca_core::controller::Sample {
        dca_core::controller::Sample {
            xo_m: self.xo_m as f32,
            xi_m: self.xi_m as f32,
            p1_pa: self.p1_pa as f32,
            p2_pa: self.p2_pa as f32,
            ft_n: self.ft_n as f32,
        }
    }
}

/// `r` with the channel of `c` mapped by its calibration.
fn calibrate(c: &SensorCalibration, r: &Readings) -> Readings {
    let mut out = *r;
    let v = channel_mut(&mut out, c.channel);
    *v = c.map(*v);
    out
}

/// The sensor set of a run.
#[derive(Clone, Debug)]
pub struct Sensors {
    mode: SensorMode,
    rng: ChaCha8Rng,
    delay: Option<DelayLine>,
    filter: Option<FilterLine>,
    calibration: Option<SensorCalibration>,
    map: Option<SensorMap>,
}

impl Sensors {
    /// Sensors in `mode`, noise seeded with `seed`.
    pub fn new(mode: SensorMode, seed: u64) -> Self {
        Self {
            mode,
            rng: ChaCha8Rng::seed_from_u64(seed),
            delay: None,
            filter: None,
            calibration: None,
            map: None,
        }
    }

    /// Add the sensor effects of `effects` for readings taken every `dt_s`:
    /// `sensor_delay` (named, or its general family) and then
    /// `sensor_calibration` (named, or its general family).
    pub fn with_effects(mut self, effects: &Effects, dt_s: f64) -> Self {
        if let Some(d) = &effects.sensor_delay {
            self = self.with_delay(d, dt_s);
        }
        if let Some(f) = &effects.sensor_filter {
            self.filter = Some(FilterLine::new(f, dt_s));
        }
        if let Some(c) = &effects.sensor_calibration {
            self = self.with_calibration(c);
        }
        self.map = effects.sensor_map;
        self
    }

    /// Add the `sensor_calibration` effect: its channel records its map of
    /// the true (delayed, for the LVDT and the pressures) value, before the ADC.
    pub fn with_calibration(mut self, c: &SensorCalibration) -> Self {
        self.calibration = Some(*c);
        self
    }

    /// Add the `sensor_delay` effect for readings taken every `dt_s`.
    pub fn with_delay(mut self, d: &SensorDelay, dt_s: f64) -> Self {
        self.delay = Some(DelayLine::new(d, dt_s));
        self
    }

    /// The mode.
    pub fn mode(&self) -> SensorMode {
        self.mode
    }

    fn noise(&mut self, sigma: f64) -> f64 {
        let n: f64 = StandardNormal.sample(&mut self.rng);
        n * sigma
    }

    fn adc(&mut self, ch: AdcChannel, v: f64) -> f64 {
        let n = self.noise(ch.noise_sigma);
        ch.reading(ch.code(v, n))
    }

    /// Read the true values (one sample instant; call once per sample period).
    pub fn read(&mut self, truth: &Readings) -> Readings {
        let delayed;
        let truth = match &mut self.delay {
            Some(d) => {
                delayed = d.apply(truth);
                &delayed
            }
            None => truth,
        };
        let mut shaped = *truth;
        if let Some(f) = &mut self.filter {
            let v = channel_mut(&mut shaped, f.filter.channel);
            *v = f.apply(*v);
        }
        if let Some(m) = &self.map {
            let v = channel_mut(&mut shaped, m.channel);
            *v = m.map(*v);
        }
        let truth = &shaped;
        let calibrated;
        let truth = match &self.calibration {
            Some(c) => {
                calibrated = calibrate(c, truth);
                &calibrated
            }
            None => truth,
        };
        match self.mode {
            SensorMode::Ideal => *truth,
            SensorMode::Realistic => Readings {
                xi_m: encoder_reading_m(truth.xi_m),
                xo_m: self.adc(AdcChannel::LVDT, truth.xo_m),
                p1_pa: self.adc(AdcChannel::PRESSURE, truth.p1_pa),
                p2_pa: self.adc(AdcChannel::PRESSURE, truth.p2_pa),
                ft_n: self.adc(AdcChannel::FORCE, truth.ft_n),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_filter_delays_averages_and_starts_at_rest() {
        let ramp: Vec<f64> = (0..40).map(|k| k as f64).collect();
        let mut w = [0.0; FILTER_TAPS];
        // A pure 3 ms delay at 1 ms: the ramp three samples late (the past
        // before the first sample is the first sample).
        w[3] = 2.0;
        let f = SensorFilter {
            channel: CalChannel::Xi,
            weights: w,
        };
        let y = filtered(&f, &ramp, 1e-3);
        assert_eq!(&y[..5], &[0.0, 0.0, 0.0, 0.0, 1.0]);
        assert_eq!(y[39], 36.0);
        // At 2 ms rows the 3 ms tap falls between rows: interpolated.
        assert_eq!(filtered(&f, &ramp, 2e-3)[10], 8.5);
        // A moving average over taps 0 to 4 ms: two samples late on a ramp.
        let avg = SensorFilter {
            weights: [1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ..f
        };
        assert!((avg.mean_delay_s() - 2e-3).abs() < 1e-15);
        assert_eq!(filtered(&avg, &ramp, 1e-3)[20], 18.0);
        // Without a sample period every tap reads the present value.
        assert_eq!(filtered(&f, &ramp, 0.0), ramp);
        // Through the sensor set, only the filter's channel is filtered.
        let mut s = Sensors::new(SensorMode::Ideal, 0).with_effects(
            &Effects {
                sensor_filter: Some(f),
                ..Effects::NONE
            },
            1e-3,
        );
        let mut last = Readings::default();
        for k in 0..10 {
            let v = k as f64;
            last = s.read(&Readings {
                xi_m: v,
                xo_m: v,
                p1_pa: v,
                p2_pa: v,
                ft_n: v,
            });
        }
        assert_eq!((last.xi_m, last.xo_m, last.p1_pa), (6.0, 9.0, 9.0));
    }

    #[test]
    fn delay_shifts_and_lag_smooths_the_position() {
        let d = SensorDelay {
            xo_delay_s: 3e-3,
            xo_tau_s: 0.0,
            p_tau_s: 0.0,
        };
        let mut s = Sensors::new(SensorMode::Ideal, 0).with_delay(&d, 1e-3);
        let r = |x: f64| Readings {
            xo_m: x,
            ..Readings::default()
        };
        let out: Vec<f64> = (0..6).map(|i| s.read(&r(i as f64)).xo_m).collect();
        assert_eq!(out, vec![0.0, 0.0, 0.0, 0.0, 1.0, 2.0]);
        let lag = SensorDelay {
            xo_delay_s: 0.0,
            xo_tau_s: 1e-3,
            p_tau_s: 1e-3,
        };
        let mut s = Sensors::new(SensorMode::Ideal, 0).with_delay(&lag, 1e-3);
        s.read(&r(0.0));
        let y = s.read(&r(1.0)).xo_m;
        assert!((y - (1.0 - (-1.0f64).exp())).abs() < 1e-12, "{y}");
    }

    #[test]
    fn calibration_maps_one_channel_and_inverts() {
        let c = SensorCalibration {
            channel: CalChannel::P1,
            gain_1: 1.1,
            offset_si: -2e4,
            quad_1: 0.05,
        };
        let truth = Readings {
            xi_m: 0.01,
            xo_m: 0.02,
            p1_pa: 2e6,
            p2_pa: 1e6,
            ft_n: 100.0,
        };
        let r = Sensors::new(SensorMode::Ideal, 0)
            .with_calibration(&c)
            .read(&truth);
        let want = -2e4 + 1.1 * 2e6 + 0.05 * 4e12 / 10e6;
        assert!((r.p1_pa - want).abs() < 1e-6, "{}", r.p1_pa);
        assert_eq!(Readings { p1_pa: 2e6, ..r }, truth);
        assert!((c.invert(r.p1_pa) - 2e6).abs() < 1e-3);
    }

    #[test]
    fn lsb_values_of_section_5() {
        assert!((AdcChannel::LVDT.lsb() - 29.3e-6).abs() < 0.05e-6);
        assert!((AdcChannel::PRESSURE.lsb() - 2.44e3).abs() < 5.0);
        assert!((AdcChannel::FORCE.lsb() - 0.98).abs() < 0.005);
    }

    #[test]
    fn adc_clamps_and_centres() {
        let ch = AdcChannel::PRESSURE;
        assert_eq!(ch.code(-1.0e6, 0.0), 0);
        assert_eq!(ch.code(20.0e6, 0.0), 4095);
        assert_eq!(ch.reading(0), ch.lsb() / 2.0);
        let v = 1.234e6;
        assert!((ch.reading(ch.code(v, 0.0)) - v).abs() <= ch.lsb() / 2.0);
    }

    #[test]
    fn encoder_floors_to_counts() {
        assert_eq!(encoder_reading_m(0.0), 0.0);
        assert!((encoder_reading_m(1.0e-6 + 1e-9) - 1.0e-6).abs() < 1e-15);
        assert!((encoder_reading_m(-0.1e-6) + 0.2e-6).abs() < 1e-15);
    }

    #[test]
    fn ideal_is_exact_and_realistic_is_noisy_but_unbiased() {
        let truth = Readings {
            xi_m: 0.02,
            xo_m: 0.025,
            p1_pa: 1.5e6,
            p2_pa: 0.9e6,
            ft_n: 300.0,
        };
        assert_eq!(Sensors::new(SensorMode::Ideal, 0).read(&truth), truth);
        let mut s = Sensors::new(SensorMode::Realistic, 1);
        let n = 20_000;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let r = s.read(&truth);
            let d = r.xo_m - truth.xo_m;
            sum += d;
            sum2 += d * d;
        }
        let mean = sum / n as f64;
        let sd = (sum2 / n as f64 - mean * mean).sqrt();
        // 10 um noise plus uniform quantisation (29.3 um / sqrt 12 = 8.5 um).
        assert!(mean.abs() < 1.0e-6, "bias {mean:e}");
        assert!((sd - 13.1e-6).abs() < 1.0e-6, "sd {sd:e}");
        // Same seed, same stream.
        let a = Sensors::new(SensorMode::Realistic, 7).read(&truth);
        let b = Sensors::new(SensorMode::Realistic, 7).read(&truth);
        assert_eq!(a, b);
    }
}
