//! Velocity-output PID with conditional-integration anti-windup
//! (docs/model.md section 6.7), f32.
//!
//! ```text
//! e = r - Xo;  v = Kp e + Ki I + Kd d/dt(-Xo);  v_cmd = clamp(v, +-v_max)
//! I += e Ts   only if v was not clamped or sign(v) != sign(e)   (after the output)
//! ```
//! Units: Kp [1/s], Ki [1/s^2], Kd [-]. The derivative acts on the
//! measurement, not on the error, so a reference step gives no derivative
//! kick (with the paper's Kd = 0 the two are the same).
//!
//! Stroke saturation: the controller integrates its own command into a
//! power-piston position u and clamps it to the stroke; a command that would
//! leave the stroke is cut to reach the end and counts as clamped.

use crate::mpc::{clamp, Limits};

/// PID gains and sample time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PidParams {
    /// Proportional gain, 1/s.
    pub kp: f32,
    /// Integral gain, 1/s^2.
    pub ki: f32,
    /// Derivative gain (on the measurement), dimensionless.
    pub kd: f32,
    /// Sample time, s.
    pub ts_s: f32,
}

impl PidParams {
    /// Table 2 of the paper: P = 2.7, I = 0.05, Ts = 0.1 s.
    pub const PAPER: Self = Self {
        kp: 2.7,
        ki: 0.05,
        kd: 0.0,
        ts_s: 0.1,
    };

    /// True when the gains are finite and non-negative and Ts is positive.
    pub fn is_valid(&self) -> bool {
        [self.kp, self.ki, self.kd]
            .iter()
            .all(|v| v.is_finite() && *v >= 0.0)
            && self.ts_s.is_finite()
            && self.ts_s > 0.0
    }
}

/// PID state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Pid {
    /// Integral of the error, m s.
    pub integral_ms: f32,
    /// Measurement at the previous tick, m.
    pub y_prev_m: f32,
    /// Integrated command (power-piston position), m.
    pub u_m: f32,
    /// True until the first tick has run.
    pub started: bool,
}

/// Result of one PID tick.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PidOutput {
    /// Drive speed command, m/s.
    pub v_cmd_mps: f32,
    /// True when the speed or stroke clamp was active.
    pub saturated: bool,
}

impl Pid {
    /// Start from rest with the power piston at `u0_m`.
    pub fn new(u0_m: f32) -> Self {
        Self {
            u_m: u0_m,
            ..Self::default()
        }
    }

    /// One PID tick with gains `g` (which a fuzzy scheduler may have adapted).
    pub fn tick(&mut self, g: &PidParams, lim: &Limits, y_m: f32, r_m: f32) -> PidOutput {
        let e = r_m - y_m;
        let dy = if self.started {
            (y_m - self.y_prev_m) / g.ts_s
        } else {
            0.0
        };
        let v = g.kp * e + g.ki * self.integral_ms - g.kd * dy;
        let v_sat = clamp(v, -lim.v_max_mps, lim.v_max_mps);
        let u_free = self.u_m + v_sat * g.ts_s;
        let u_new = clamp(u_free, lim.x_min_m, lim.x_max_m);
        // Decide saturation from the clamps themselves: re-deriving the
        // command from u would differ from v by rounding and look clamped.
        let stroke_hit = u_new != u_free;
        let saturated = v_sat != v || stroke_hit;
        let v_cmd = if stroke_hit {
            (u_new - self.u_m) / g.ts_s
        } else {
            v_sat
        };
        if !saturated || (v > 0.0) != (e > 0.0) {
            self.integral_ms += e * g.ts_s;
        }
        self.u_m = u_new;
        self.y_prev_m = y_m;
        self.started = true;
        PidOutput {
            v_cmd_mps: v_cmd,
            saturated,
        }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
    use crate::params::PlantParams;

    fn lim() -> Limits {
        Limits::from_plant(&PlantParams::NOMINAL)
    }

    #[test]
    fn proportional_then_integral() {
        let mut pid = Pid::new(0.0);
        let out = pid.tick(&PidParams::PAPER, &lim(), 0.0, 0.01);
        assert!((out.v_cmd_mps - 0.027).abs() < 1e-6);
        // I = 0.001 m s after the first tick.
        let out = pid.tick(&PidParams::PAPER, &lim(), 0.0, 0.01);
        assert!((out.v_cmd_mps - (0.027 + 0.05 * 0.001)).abs() < 1e-6);
    }

    #[test]
    fn integrates_away_from_the_origin_without_false_clamps() {
        // Regression: re-deriving the command from the integrated position
        // differs from v by f32 rounding away from u = 0 and once looked like
        // a clamp, which blocked the integral.
        let mut pid = Pid::new(0.041_549);
        let mut want = 0.0f32;
        for i in 0..50 {
            let e = 1e-4 * (1.0 + i as f32 * 0.01);
            let out = pid.tick(&PidParams::PAPER, &lim(), 0.03, 0.03 + e);
            assert!(!out.saturated, "tick {i}");
            want += e * 0.1;
        }
        assert!(
            (pid.integral_ms - want).abs() < 1e-9,
            "{} vs {want}",
            pid.integral_ms
        );
    }

    #[test]
    fn conditional_integration_stops_windup() {
        let mut pid = Pid::new(0.0);
        // Ten ticks at v_max reach 0.1 m, inside the stroke.
        for _ in 0..10 {
            let out = pid.tick(&PidParams::PAPER, &lim(), 0.0, 0.05);
            assert!(out.saturated);
            assert!((out.v_cmd_mps - 0.1).abs() < 1e-6);
        }
        assert_eq!(pid.integral_ms, 0.0, "no integration while clamped");
    }

    #[test]
    fn integrates_when_clamped_against_the_error() {
        // Clamped negative output, positive error: integrating helps unwind.
        let g = PidParams {
            kp: 0.0,
            ki: 1.0,
            kd: 0.0,
            ts_s: 0.1,
        };
        let mut pid = Pid::new(0.0);
        pid.integral_ms = -1.0;
        let out = pid.tick(&g, &lim(), 0.0, 0.01);
        assert!(out.saturated);
        assert!((pid.integral_ms + 1.0 - 0.001).abs() < 1e-6);
    }

    #[test]
    fn stroke_limit_cuts_the_command() {
        let mut pid = Pid::new(0.109);
        let out = pid.tick(&PidParams::PAPER, &lim(), 0.0, 0.05);
        assert!((out.v_cmd_mps - 0.01).abs() < 1e-4, "{}", out.v_cmd_mps);
        assert!(out.saturated);
        let out = pid.tick(&PidParams::PAPER, &lim(), 0.0, 0.05);
        assert_eq!(out.v_cmd_mps, 0.0);
    }

    #[test]
    fn derivative_on_measurement() {
        let g = PidParams {
            kp: 0.0,
            ki: 0.0,
            kd: 0.5,
            ts_s: 0.1,
        };
        let mut pid = Pid::new(0.0);
        assert_eq!(pid.tick(&g, &lim(), 0.0, 0.05).v_cmd_mps, 0.0);
        // y rose by 1 mm in 0.1 s: -Kd * 0.01 m/s.
        let out = pid.tick(&g, &lim(), 0.001, 0.05);
        assert!((out.v_cmd_mps + 0.005).abs() < 1e-6);
    }
}
