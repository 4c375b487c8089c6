//! The servo drive: the named `motor_limit` and its general family, the force
//! envelope over speed.

use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, GeneralFamily, NamedEffect, ParamSpec, VALID_SPAN};
use super::terms::{Rest, RigTerms};

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
/// clamped to +-that before the force is, whatever the load. Its command
/// path may differ from the ideal one ([`CommandMap`]: a dead band, a gain).
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
    /// The drive's own speed loop ([`SpeedLoop`]) in place of the nominal
    /// servo's ideal one (none where absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub speed_loop: Option<SpeedLoop>,
    /// The drive's command path ([`CommandMap`]) in place of the ideal one
    /// (none where absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub command_map: Option<CommandMap>,
}

/// Command speeds of the knots of a [`CommandMap`], m/s: dense below
/// 3 mm/s, where a drive's dead band and the steps of a quantised command
/// act, then on to the command limit.
pub const COMMAND_SPEEDS_MPS: [f64; 12] = [
    0.0, 0.25e-3, 0.5e-3, 1.0e-3, 1.5e-3, 2.0e-3, 3.0e-3, 5.0e-3, 10e-3, 20e-3, 50e-3, 0.1,
];

/// The drive's command path: the speed target it makes of a speed command,
/// the same either way (odd), piecewise linear between the knots
/// [`COMMAND_SPEEDS_MPS`] (0 at 0, non-decreasing), the last segment's
/// slope beyond them. A dead band is a map at 0 up to its width, a gain
/// error a slope other than 1, a finely quantised command its average.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CommandMap {
    /// Speed target at the command speeds `COMMAND_SPEEDS_MPS[1..]`, m/s.
    pub target_mps: [f64; 11],
}

impl CommandMap {
    /// The speed target of the command `vc_mps`, m/s.
    pub fn target_of(&self, vc_mps: f64) -> f64 {
        let s = vc_mps.abs();
        let k = &COMMAND_SPEEDS_MPS;
        let y = |i: usize| if i == 0 { 0.0 } else { self.target_mps[i - 1] };
        // The segment [k[i], k[i + 1]] holding s (the last one beyond).
        let i = k[1..].iter().position(|x| s < *x).unwrap_or(k.len() - 2);
        let w = (s - k[i]) / (k[i + 1] - k[i]);
        (y(i) + w * (y(i + 1) - y(i))).copysign(vc_mps)
    }

    /// Whether the map is usable: finite, non-negative, non-decreasing.
    pub fn is_valid(&self) -> bool {
        self.target_mps.iter().all(|t| t.is_finite() && *t >= 0.0)
            && self.target_mps.windows(2).all(|w| w[1] >= w[0])
    }
}

/// The drive's own speed loop, a PI loop on the reflected mass `m` under the
/// envelope: the drive shapes its speed reference `v_ref` from the command as
/// the nominal servo does (first order, time constant tau, within the ramp if
/// any) and asks for the force `m dv_ref/dt + kp (v_ref - v) + I`, with
/// `kp = m bandwidth` and `dI/dt = ki (v_ref - v)`, `ki = kp integral`; the
/// load is not fed forward (the integrator takes it up, and the screw's
/// viscous loss `c v`). The envelope clamps the force; under `windup` the
/// integrator keeps integrating meanwhile, otherwise it holds (conditional
/// integration). Unsaturated and with a high bandwidth it is the nominal
/// servo; after a saturation the speed catches up on the lost position
/// (windup) or not.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SpeedLoop {
    /// The proportional gain over the reflected mass: the loop's bandwidth,
    /// rad/s (at most [`SpeedLoop::BANDWIDTH_MAX_RADPS`]).
    pub bandwidth_radps: f64,
    /// The integral gain over the proportional gain: the integrator's
    /// corner, rad/s (at most the bandwidth).
    pub integral_radps: f64,
    /// Whether the integrator keeps integrating while the force is clamped.
    pub windup: bool,
    /// Viscous loss of the screw and its bearings, N s/m: it takes `c v`
    /// from the drive's force, which the loop makes up for while it can.
    #[serde(default)]
    pub damping_nspm: f64,
}

impl SpeedLoop {
    /// Largest bandwidth: the replay's 0.5 ms RK4 step stays well inside
    /// its stability limit (h lambda = 1.5 against 2.78).
    pub const BANDWIDTH_MAX_RADPS: f64 = 3000.0;

    /// Whether the loop is usable: finite, a positive bandwidth up to
    /// [`Self::BANDWIDTH_MAX_RADPS`], an integral corner from 0 to it.
    pub fn is_valid(&self) -> bool {
        self.bandwidth_radps.is_finite()
            && self.bandwidth_radps > 0.0
            && self.bandwidth_radps <= Self::BANDWIDTH_MAX_RADPS
            && self.integral_radps.is_finite()
            && self.integral_radps >= 0.0
            && self.integral_radps <= self.bandwidth_radps
            && self.damping_nspm.is_finite()
            && self.damping_nspm >= 0.0
    }
}

impl ServoEnvelope {
    /// Available (motoring) force at `speed_mps` (its magnitude), N.
    #[inline]
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

    /// The asked acceleration `a_mps2` within the drive's ramp, if any.
    #[inline]
    fn ramped(&self, a_mps2: f64) -> f64 {
        match self.accel_max_mps2 {
            Some(ramp) => a_mps2.clamp(-ramp, ramp),
            None => a_mps2,
        }
    }

    /// The force `f_n` the drive asks for at the speed `v_mps`, clamped to
    /// the envelope: the available force while motoring, the force at rest
    /// while braking.
    #[inline]
    fn clamped_n(&self, f_n: f64, v_mps: f64) -> f64 {
        let cap = if f_n * v_mps >= 0.0 {
            self.available_n(v_mps)
        } else {
            self.force_n[0]
        };
        f_n.clamp(-cap, cap)
    }

    /// Servo acceleration when the speed loop asks for `a_mps2` at the
    /// speed `v_mps` against the hydraulic force `f_load_n` (positive
    /// opposing extension), the nominal loop's load fed forward.
    #[inline]
    pub fn accel(&self, a_mps2: f64, v_mps: f64, f_load_n: f64) -> f64 {
        let f = self.mass_eq_kg * self.ramped(a_mps2) + f_load_n;
        (self.clamped_n(f, v_mps) - f_load_n) / self.mass_eq_kg
    }

    /// Under the drive's own speed loop `lp`, from its states `own` (the
    /// speed reference, m/s, and the integrator's force, N): the servo's
    /// acceleration and the states' rates, towards the command `vc_mps`
    /// with the nominal time constant `tau_s`, at the speed `v_mps` against
    /// the hydraulic force `f_load_n`.
    #[inline]
    pub fn loop_rates(
        &self,
        lp: &SpeedLoop,
        (vc_mps, tau_s): (f64, f64),
        v_mps: f64,
        f_load_n: f64,
        own: [f64; 2],
    ) -> (f64, [f64; 2]) {
        let [v_ref, integral_n] = own;
        let m = self.mass_eq_kg;
        let dv_ref = self.ramped((vc_mps - v_ref) / tau_s);
        let kp = m * lp.bandwidth_radps;
        let asked = m * dv_ref + kp * (v_ref - v_mps) + integral_n;
        let f = self.clamped_n(asked, v_mps);
        let di = if lp.windup || f == asked {
            kp * lp.integral_radps * (v_ref - v_mps)
        } else {
            0.0
        };
        ((f - lp.damping_nspm * v_mps - f_load_n) / m, [dv_ref, di])
    }

    /// Whether the envelope is usable: finite, a positive mass and force at
    /// rest, forces non-negative and non-increasing with speed, a ramp (if
    /// any) positive, a speed loop and a command map (if any) valid.
    pub fn is_valid(&self) -> bool {
        self.accel_max_mps2.is_none_or(|a| a.is_finite() && a > 0.0)
            && self.speed_loop.is_none_or(|l| l.is_valid())
            && self.command_map.is_none_or(|m| m.is_valid())
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
/// the nominal +-v_max) from the speed `v_mps`, and the rates of the servo's
/// states `own` (those of the envelope's speed loop; zero otherwise): the
/// nominal first-order servo with time constant `tau_s`, or under the named
/// limit its speed cap and force limit, or under the envelope its force over
/// speed (with its own speed loop if any), against the hydraulic force
/// `f_load_n`.
#[inline]
pub fn servo_rates(
    servo: Servo<'_>,
    (vc_mps, tau_s): (f64, f64),
    v_mps: f64,
    f_load_n: f64,
    own: [f64; 2],
) -> (f64, [f64; 2]) {
    match servo {
        Servo::Limit(m) => {
            let target = vc_mps.clamp(-m.speed_max_mps, m.speed_max_mps);
            (motor_accel(m, (target - v_mps) / tau_s, f_load_n), [0.0; 2])
        }
        Servo::Envelope(s) => {
            let vc_mps = s.command_map.map_or(vc_mps, |m| m.target_of(vc_mps));
            match &s.speed_loop {
                Some(lp) => s.loop_rates(lp, (vc_mps, tau_s), v_mps, f_load_n, own),
                None => (s.accel((vc_mps - v_mps) / tau_s, v_mps, f_load_n), [0.0; 2]),
            }
        }
        Servo::Nominal => ((vc_mps - v_mps) / tau_s, [0.0; 2]),
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
        "general: the servo's force envelope over speed and its command path, learned from the encoder";
    const BOTH: &'static str = "the named form and the servo envelope exclude each other";
    const REQUIREMENT: &'static str =
        "servo_envelope: mass_eq_kg and force_n[0] must be > 0, force_n non-negative \
         and non-increasing with speed, accel_max_mps2 (if given) > 0, \
         command_map.target_mps (if given) non-negative and non-decreasing";
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
        if let Some(l) = self.speed_loop {
            m.push(("loop_bandwidth_radps".to_string(), l.bandwidth_radps));
            m.push(("loop_integral_radps".to_string(), l.integral_radps));
            m.push(("loop_windup".to_string(), f64::from(u8::from(l.windup))));
            m.push(("loop_damping_nspm".to_string(), l.damping_nspm));
        }
        if let Some(c) = self.command_map {
            for (v, t) in COMMAND_SPEEDS_MPS[1..].iter().zip(c.target_mps) {
                m.push((format!("command_target_mps_at_{v:.5}_mps"), t));
            }
        }
        m
    }
}

/// The speed cap and the force limit on the servo.
impl RigTerms for MotorLimit {
    fn servo_accel_mps2(
        &self,
        (vc_mps, tau_s): (f64, f64),
        v_mps: f64,
        f_load_n: f64,
        _own: &[f64],
        _rates: &mut [f64],
    ) -> Option<f64> {
        Some(
            servo_rates(
                Servo::Limit(self),
                (vc_mps, tau_s),
                v_mps,
                f_load_n,
                [0.0; 2],
            )
            .0,
        )
    }
}

/// The force envelope over speed on the servo; the states of its speed loop
/// (the speed reference and the integrator's force), carried whether or not
/// it has one.
impl RigTerms for ServoEnvelope {
    const STATES: usize = 2;
    /// The reference at rest, the integrator holding the load.
    fn rest_states(&self, rest: &Rest, own: &mut [f64]) {
        own[1] = rest.piston_force_n;
    }
    fn servo_accel_mps2(
        &self,
        (vc_mps, tau_s): (f64, f64),
        v_mps: f64,
        f_load_n: f64,
        own: &[f64],
        rates: &mut [f64],
    ) -> Option<f64> {
        let (a, d) = servo_rates(
            Servo::Envelope(self),
            (vc_mps, tau_s),
            v_mps,
            f_load_n,
            [own[0], own[1]],
        );
        rates[..2].copy_from_slice(&d);
        Some(a)
    }
}
