//! The servo drive: the named `motor_limit` and its general family, the force
//! envelope over speed.

use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, GeneralFamily, NamedEffect, ParamSpec, VALID_SPAN};
use super::terms::RigTerms;

/// Servo torque and acceleration limits.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MotorLimit {
    /// Largest axial force of the drive on the screw, N.
    pub force_max_n: f64,
    /// Motor and screw inertia reflected to the screw axis, kg.
    pub mass_eq_kg: f64,
    /// Highest speed the drive reaches, m/s.
    #[serde(default = "default_speed_max")]
    pub speed_max_mps: f64,
}

fn default_speed_max() -> f64 {
    dca_core::params::PlantParams::NOMINAL.v_max_mps
}

/// Servo acceleration under the motor limit: the speed loop asks for
/// `a_mps2` towards its target against the hydraulic force `f_load_n` on the
/// power piston (positive opposing extension); the drive's force is clamped.
pub fn motor_accel(m: &MotorLimit, a_mps2: f64, f_load_n: f64) -> f64 {
    let f = (m.mass_eq_kg * a_mps2 + f_load_n).clamp(-m.force_max_n, m.force_max_n);
    (f - f_load_n) / m.mass_eq_kg
}

/// Speeds of the knots of a [`ServoEnvelope`], m/s: 0 to the nominal
/// command limit (0.1 m/s) in steps of 20 mm/s.
pub const ENVELOPE_SPEEDS_MPS: [f64; 6] = [0.0, 0.02, 0.04, 0.06, 0.08, 0.10];

/// The general family of the servo (`motor_limit` in any shape): the
/// drive's force envelope over speed. The speed loop asks for the force
/// `m a + F` (a = (v_target - v) / tau, F the hydraulic force on the power
/// piston); while motoring (force and speed of one sign) it gets at most
/// the available force `A(abs(v))`, piecewise linear between the knots and
/// flat beyond the last; while braking at most `A(0)`. A constant `A` is
/// the named form's force limit, `A` falling to zero at some speed its speed
/// cap, and any torque-speed curve lies in between. A drive may also ramp
/// its speed target (`accel_max_mps2`): the asked acceleration is then
/// clamped to +-that before the force is, whatever the load.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ServoEnvelope {
    /// Motor and screw inertia reflected to the screw axis, kg.
    pub mass_eq_kg: f64,
    /// Available force at [`ENVELOPE_SPEEDS_MPS`], N (non-increasing).
    pub force_n: [f64; 6],
    /// The drive's ramp: largest acceleration it asks for, m/s^2 (none
    /// where absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub accel_max_mps2: Option<f64>,
}

impl ServoEnvelope {
    /// Available (motoring) force at `speed_mps` (its magnitude), N.
    pub fn available_n(&self, speed_mps: f64) -> f64 {
        let s = speed_mps.abs();
        let dv = ENVELOPE_SPEEDS_MPS[1];
        let last = self.force_n.len() - 1;
        let x = s / dv;
        if x.is_nan() || x >= last as f64 {
            return self.force_n[last];
        }
        let i = x as usize;
        let w = x - i as f64;
        self.force_n[i] + w * (self.force_n[i + 1] - self.force_n[i])
    }

    /// Servo acceleration when the speed loop asks for `a_mps2` at the
    /// speed `v_mps` against the hydraulic force `f_load_n` (positive
    /// opposing extension).
    pub fn accel(&self, a_mps2: f64, v_mps: f64, f_load_n: f64) -> f64 {
        let a_mps2 = match self.accel_max_mps2 {
            Some(ramp) => a_mps2.clamp(-ramp, ramp),
            None => a_mps2,
        };
        let f = self.mass_eq_kg * a_mps2 + f_load_n;
        let cap = if f * v_mps >= 0.0 {
            self.available_n(v_mps)
        } else {
            self.force_n[0]
        };
        (f.clamp(-cap, cap) - f_load_n) / self.mass_eq_kg
    }

    /// Whether the envelope is usable: finite, a positive mass and force at
    /// rest, forces non-negative and non-increasing with speed, a ramp (if
    /// any) positive.
    pub fn is_valid(&self) -> bool {
        self.accel_max_mps2.is_none_or(|a| a.is_finite() && a > 0.0)
            && self.mass_eq_kg.is_finite()
            && self.mass_eq_kg > 0.0
            && self.force_n[0].is_finite()
            && self.force_n[0] > 0.0
            && self.force_n.iter().all(|f| f.is_finite() && *f >= 0.0)
            && self.force_n.windows(2).all(|w| w[1] <= w[0])
    }
}

/// The servo model a rig runs: nominal, the named `motor_limit` form, or
/// its general family.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Servo<'a> {
    /// The nominal first-order servo.
    Nominal,
    /// The named force limit and speed cap.
    Limit(&'a MotorLimit),
    /// The learned force envelope.
    Envelope(&'a ServoEnvelope),
}

/// Servo acceleration towards the speed command `vc_mps` (already within
/// the nominal +-v_max) from the speed `v_mps`: the nominal first-order
/// servo with time constant `tau_s`, or under the named limit its speed cap
/// and force limit, or under the envelope its force over speed, against the
/// hydraulic force `f_load_n`.
pub fn servo_accel(servo: Servo<'_>, vc_mps: f64, v_mps: f64, tau_s: f64, f_load_n: f64) -> f64 {
    match servo {
        Servo::Limit(m) => {
            let target = vc_mps.clamp(-m.speed_max_mps, m.speed_max_mps);
            motor_accel(m, (target - v_mps) / tau_s, f_load_n)
        }
        Servo::Envelope(s) => s.accel((vc_mps - v_mps) / tau_s, v_mps, f_load_n),
        Servo::Nominal => (vc_mps - v_mps) / tau_s,
    }
}

impl NamedEffect for MotorLimit {
    const SUBSYSTEM: &'static str = "servo";
    const PARAMS: &'static [ParamSpec] = &[
        p("force_max_n", 2000.0, 50.0, 1e5),
        p("mass_eq_kg", 200.0, 5.0, 1e5),
        p("speed_max_mps", 0.1, 0.005, 0.1),
    ];
    fn values(&self) -> Vec<f64> {
        vec![self.force_max_n, self.mass_eq_kg, self.speed_max_mps]
    }
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        Self {
            force_max_n: at(0),
            mass_eq_kg: at(1),
            speed_max_mps: at(2),
        }
    }
    fn check_bounds(&self) -> Result<(), Broken> {
        if self.force_max_n <= 0.0 || self.mass_eq_kg <= 0.0 || self.speed_max_mps <= 0.0 {
            return Err(Broken::Requirement(
                "force_max_n, mass_eq_kg and speed_max_mps must be > 0",
            ));
        }
        Ok(())
    }
}

impl GeneralFamily for ServoEnvelope {
    const FORM: &'static str =
        "general: the servo's force envelope over speed, learned from the encoder";
    const BOTH: &'static str = "the named form and the servo envelope exclude each other";
    const REQUIREMENT: &'static str =
        "servo_envelope: mass_eq_kg and force_n[0] must be > 0, force_n non-negative \
         and non-increasing with speed, accel_max_mps2 (if given) > 0";
    /// Valid, and its force at rest and mass within VALID_SPAN times the
    /// named form's largest.
    fn family_valid(&self) -> bool {
        self.is_valid()
            && self.force_n[0] <= VALID_SPAN * MotorLimit::PARAMS[0].max
            && self.mass_eq_kg <= VALID_SPAN * MotorLimit::PARAMS[1].max
    }
    fn param_map(&self) -> Vec<(String, f64)> {
        let mut m = vec![("mass_eq_kg".to_string(), self.mass_eq_kg)];
        for (v, f) in ENVELOPE_SPEEDS_MPS.iter().zip(self.force_n) {
            m.push((format!("force_n_at_{v:.2}_mps"), f));
        }
        if let Some(a) = self.accel_max_mps2 {
            m.push(("accel_max_mps2".to_string(), a));
        }
        m
    }
}

/// The speed cap and the force limit on the servo.
impl RigTerms for MotorLimit {
    fn servo_accel_mps2(&self, vc_mps: f64, v_mps: f64, tau_s: f64, f_load_n: f64) -> Option<f64> {
        Some(servo_accel(
            Servo::Limit(self),
            vc_mps,
            v_mps,
            tau_s,
            f_load_n,
        ))
    }
}

/// The force envelope over speed on the servo.
impl RigTerms for ServoEnvelope {
    fn servo_accel_mps2(&self, vc_mps: f64, v_mps: f64, tau_s: f64, f_load_n: f64) -> Option<f64> {
        Some(servo_accel(
            Servo::Envelope(self),
            vc_mps,
            v_mps,
            tau_s,
            f_load_n,
        ))
    }
}
