//! Realistic sensors of docs/model.md section 5 (Gaussian noise, then a 12-bit
//! ADC; the encoder counts 0.2 um), with this family's sensor-side effects: a
//! wrong calibration, an LVDT transport delay or conditioner filter, and LVDT
//! dropouts. Noise comes from this family's own generator.

use std::collections::VecDeque;

use super::effects::{Channel, Effects};
use super::plant::{ix, State};
use super::rng::SplitMix;

/// One reading of every channel, SI.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Reading {
    /// LVDT, m.
    pub xo_m: f64,
    /// Encoder, m.
    pub xi_m: f64,
    /// Line-1 pressure, Pa.
    pub p1_pa: f64,
    /// Line-2 pressure, Pa.
    pub p2_pa: f64,
    /// Load force, N.
    pub ft_n: f64,
}

/// A 12-bit ADC channel over [lo, hi] with Gaussian noise of `sigma` before it.
pub fn adc(value: f64, lo: f64, hi: f64, sigma: f64, rng: &mut SplitMix) -> f64 {
    let v = value + sigma * rng.gaussian();
    let code = ((v - lo) / (hi - lo) * 4096.0).floor().clamp(0.0, 4095.0);
    lo + (code + 0.5) * (hi - lo) / 4096.0
}

/// Encoder reading of the power piston, m.
pub fn encoder(xi_m: f64) -> f64 {
    (xi_m / 0.2e-6).floor() * 0.2e-6
}

/// The sensor chain of one run, sampled once per 1 ms tick.
#[derive(Clone, Debug)]
pub struct Sensors {
    effects: Effects,
    rng: SplitMix,
    history: VecDeque<f64>,
    delay_ticks: usize,
    hold_until_s: f64,
    next_drop_s: f64,
    last_xo_m: f64,
}

impl Sensors {
    /// A sensor chain for `effects`, with noise seed `seed`.
    pub fn new(effects: Effects, seed: u64) -> Self {
        let delay_ticks = effects
            .lag
            .map(|l| (l.lvdt_delay_s / 1e-3).round() as usize)
            .unwrap_or(0);
        let mut s = Self {
            effects,
            rng: SplitMix::new(seed),
            history: VecDeque::new(),
            delay_ticks,
            hold_until_s: -1.0,
            next_drop_s: f64::INFINITY,
            last_xo_m: 0.0,
        };
        s.next_drop_s = s.draw_next_drop(0.0);
        s
    }

    fn draw_next_drop(&mut self, after_s: f64) -> f64 {
        match self.effects.dropout {
            Some(d) => after_s - (1.0 - self.rng.uniform()).ln() / d.rate_hz,
            None => f64::INFINITY,
        }
    }

    fn calibrated(&self, ch: Channel, v: f64) -> f64 {
        match self.effects.calibration {
            Some(c) if c.channel == ch => c.offset + c.gain * v + c.quad * v * v,
            _ => v,
        }
    }

    /// Read every channel at time `t_s` from the true state `x` and load `ft_n`.
    pub fn read(&mut self, t_s: f64, x: &State, ft_n: f64) -> Reading {
        // The LVDT's analogue value: through the conditioner, then the delay.
        let mut xo = match self.effects.lag {
            Some(l) if l.lvdt_corner_hz > 0.0 => x[ix::XF],
            _ => x[2],
        };
        if self.delay_ticks > 0 {
            self.history.push_back(xo);
            xo = if self.history.len() > self.delay_ticks {
                self.history.pop_front().unwrap_or(xo)
            } else {
                self.history[0]
            };
        }
        let xo = self.calibrated(Channel::Lvdt, xo);
        // With the line-1 orifice the sensor sits at the power cylinder's port.
        let p1_true = if self.effects.restriction.is_some() {
            x[ix::P1A]
        } else {
            x[4]
        };
        let p1 = self.calibrated(Channel::P1, p1_true);
        let p2 = self.calibrated(Channel::P2, x[5]);
        // Noise is drawn in a fixed order: Xo, P1, P2, Ft.
        let mut xo_r = adc(xo, -0.010, 0.110, 10e-6, &mut self.rng);
        let p1_r = adc(p1, 0.0, 10.0e6, 5.0e3, &mut self.rng);
        let p2_r = adc(p2, 0.0, 10.0e6, 5.0e3, &mut self.rng);
        let ft_r = adc(ft_n, -2000.0, 2000.0, 2.0, &mut self.rng);
        if let Some(d) = self.effects.dropout {
            if t_s >= self.next_drop_s {
                let len = d.min_s + (d.max_s - d.min_s) * self.rng.uniform();
                self.hold_until_s = self.next_drop_s + len;
                self.next_drop_s = self.draw_next_drop(self.hold_until_s);
            }
            if t_s < self.hold_until_s {
                xo_r = self.last_xo_m;
            }
        }
        self.last_xo_m = xo_r;
        Reading {
            xo_m: xo_r,
            xi_m: encoder(x[0]),
            p1_pa: p1_r,
            p2_pa: p2_r,
            ft_n: ft_r,
        }
    }
}
