//! Realistic sensors of plant.md section 5 with this family's own random
//! numbers, plus the sensor-side effects (calibration maps, filter and
//! transport delay, membranes, drift).

use std::collections::VecDeque;

use super::effects::Effect;
use super::plant::ix::*;
use super::rig::State;

/// A small seeded generator: SplitMix64 for the bits, Box-Muller for the
/// Gaussian samples.
#[derive(Clone, Debug)]
pub struct Rng {
    s: u64,
    spare: Option<f64>,
}

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self {
            s: seed ^ 0x5DEE_CE66_D1CE_4E5B,
            spare: None,
        }
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.s = self.s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in (0, 1).
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// Standard normal.
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        let u1 = self.uniform();
        let u2 = self.uniform();
        let r = (-2.0 * u1.ln()).sqrt();
        let a = 2.0 * std::f64::consts::PI * u2;
        self.spare = Some(r * a.sin());
        r * a.cos()
    }
}

/// What the sensors report at one instant (SI units, gauge pressures).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// Encoder, m.
    pub xi: f64,
    /// LVDT, m.
    pub xo: f64,
    /// Line-1 pressure, Pa.
    pub p1: f64,
    /// Line-2 pressure, Pa.
    pub p2: f64,
    /// Force sensor, N.
    pub ft: f64,
}

/// The sensor set of one run.
#[derive(Clone, Debug)]
pub struct Sensors {
    rng: Rng,
    noisy: bool,
    effects: Vec<Effect>,
    /// LVDT signal history at the plant step (transport delay), oldest first.
    history: VecDeque<f64>,
    delay_steps: usize,
    /// Plant step, s.
    plant_dt: f64,
    /// Xo at the plant steps for a sample-and-hold module, oldest first,
    /// and the number of plant steps before its first entry.
    held: VecDeque<f64>,
    held_start: usize,
    /// Steps the sample-and-hold line keeps.
    held_len: usize,
    /// Position of a sticky LVDT core, m.
    core: Option<f64>,
}

/// 12-bit ADC of plant.md section 5: code = clamp(floor((v - lo)/(hi - lo)
/// 4096), 0, 4095), reading lo + (code + 0.5) (hi - lo)/4096.
pub fn adc(v: f64, lo: f64, hi: f64) -> f64 {
    let code = ((v - lo) / (hi - lo) * 4096.0).floor().clamp(0.0, 4095.0);
    lo + (code + 0.5) * (hi - lo) / 4096.0
}

/// Encoder: 0.2 um counts, floor(Xi/0.2e-6) 0.2e-6.
pub fn encoder(xi: f64) -> f64 {
    (xi / 0.2e-6).floor() * 0.2e-6
}

impl Sensors {
    /// Realistic sensors (noise and quantisation) when `noisy`, otherwise
    /// the exact values through the same sensor-side effects.
    pub fn new(seed: u64, noisy: bool, effects: &[Effect], plant_dt: f64) -> Self {
        let mut delay_steps = 0;
        for e in effects {
            if let Effect::LvdtFilterDelay { delay_s, .. } = e {
                delay_steps = (delay_s / plant_dt).round() as usize;
            }
        }
        let mut held_len = 0;
        for e in effects {
            if let Effect::LvdtSampleHold {
                period, transport, ..
            } = e
            {
                held_len = ((period + transport) / plant_dt).ceil() as usize + 4;
            }
        }
        Self {
            rng: Rng::new(seed),
            noisy,
            effects: effects.to_vec(),
            history: VecDeque::with_capacity(delay_steps + 2),
            delay_steps,
            plant_dt,
            held: VecDeque::with_capacity(held_len + 1),
            held_start: 0,
            held_len,
            core: None,
        }
    }

    fn filtered(&self) -> bool {
        self.effects
            .iter()
            .any(|e| matches!(e, Effect::LvdtFilterDelay { .. }))
    }

    /// Record the state after each plant step (the transport delay's line).
    pub fn record(&mut self, x: &State) {
        if self.filtered() {
            self.history.push_back(x[LV1]);
            while self.history.len() > self.delay_steps + 1 {
                self.history.pop_front();
            }
        }
        if self.held_len > 0 {
            self.held.push_back(x[XO]);
            while self.held.len() > self.held_len {
                self.held.pop_front();
                self.held_start += 1;
            }
        }
        for e in &self.effects {
            if let Effect::StickyLvdtCore { half_play } = *e {
                let xo = x[XO];
                let c = self.core.unwrap_or(xo);
                self.core = Some(c.clamp(xo - half_play, xo + half_play));
            }
        }
    }

    /// Xo as a sample-and-hold module reports it at time `t`.
    fn sample_held(&self, t: f64, period: f64, phase: f64, transport: f64) -> f64 {
        let n = ((t - transport - phase) / period).floor();
        let ts = phase + n * period;
        let k = if ts <= 0.0 {
            0
        } else {
            (ts / self.plant_dt).round() as usize
        };
        let i = k.saturating_sub(self.held_start).min(self.held.len() - 1);
        self.held[i]
    }

    /// Read every sensor at time `t` in state `x` with load `ft`.
    pub fn read(&mut self, t: f64, x: &State, ft: f64) -> Reading {
        let mut xo = x[XO];
        if self.filtered() {
            // The oldest entry is delay_steps plant steps old (or the
            // initial value before the line has filled).
            xo = self.history.front().copied().unwrap_or(x[LV1]);
        }
        let mut ft = ft;
        let (mut p1, mut p2) = (x[P1], x[P2]);
        for e in &self.effects {
            match *e {
                Effect::PressureMembrane { .. } => {
                    p1 = x[PM1];
                    p2 = x[PM2];
                }
                Effect::LvdtNonlinear {
                    gain_err,
                    cubic,
                    center,
                    half_span,
                } => {
                    let u = (xo - center) / half_span;
                    xo = xo * (1.0 + gain_err) - cubic * u * u * u;
                }
                Effect::P1Saturating { p_sat, offset } => {
                    p1 = p_sat * (p1 / p_sat).tanh() + offset;
                }
                Effect::LvdtDrift { rate } => xo += rate * t,
                Effect::LvdtSampleHold {
                    period,
                    phase,
                    transport,
                } => xo = self.sample_held(t, period, phase, transport),
                Effect::StickyLvdtCore { .. } => xo = self.core.unwrap_or(xo),
                Effect::LoadCellError {
                    gain_err,
                    offset,
                    cubic,
                    f_ref,
                } => ft = ft * (1.0 + gain_err) + offset + cubic * (ft / f_ref).powi(3),
                Effect::MainsHum {
                    amp,
                    freq_hz,
                    amp3,
                    phase,
                } => {
                    let w = 2.0 * std::f64::consts::PI * freq_hz;
                    p1 += amp * (w * t + phase).sin() + amp3 * (3.0 * (w * t + phase)).sin();
                }
                _ => {}
            }
        }
        let mut r = Reading {
            xi: x[XI],
            xo,
            p1,
            p2,
            ft,
        };
        if self.noisy {
            r.xi = encoder(r.xi);
            r.xo = adc(r.xo + 10e-6 * self.rng.normal(), -0.010, 0.110);
            r.p1 = adc(r.p1 + 5e3 * self.rng.normal(), 0.0, 10e6);
            r.p2 = adc(r.p2 + 5e3 * self.rng.normal(), 0.0, 10e6);
            r.ft = adc(r.ft + 2.0 * self.rng.normal(), -2000.0, 2000.0);
        }
        r
    }
}
