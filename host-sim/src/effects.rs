//! Unmodelled effects of plant.md section 12: composable, off by default.
//!
//! Users switch them on to emulate their own rig; the gap diagnosis adds them
//! one at a time to the nominal model as candidate explanations. Each effect
//! has documented parameters (SI, units in the names), a typical magnitude,
//! and bounds the diagnosis fits within.
//!
//! | identifier | model | parameters |
//! |---|---|---|
//! | `leakage` | internal leakage line 1 -> line 2 across the pistons, Q = G (P1 - P2) | `g_m3pspa` (typ. 1e-13: 0.2 cm^3/s at 2 MPa) |
//! | `friction` | seal friction on the actuating piston, Coulomb + Stribeck, smoothed: F = (Fc + (Fs - Fc) exp(-(v/vs)^2)) tanh(v/v_eps) | `coulomb_n` (typ. 30), `static_n` (typ. 45), `stribeck_mps` (typ. 2e-3); v_eps = 1e-4 m/s |
//! | `backlash` | play between the motor (encoder, Xi) and the power piston: the piston follows only when the play is taken up | `play_m` (typ. 50e-6) |
//! | `air` | entrained air: 1/beta_eff = 1/beta_e + x_a / (kappa P_abs) (P_atm / P_abs)^(1/kappa) | `fraction` (air volume fraction at P_atm, typ. 0.005), kappa = 1.4 |
//! | `sensor_delay` | the LVDT reading delayed and low-pass filtered; pressure readings low-pass filtered | `xo_delay_s` (typ. 3e-3), `xo_tau_s` (typ. 2e-3), `p_tau_s` |
//! | `motor_limit` | servo acceleration limit and a linear torque-speed line: v <= v_max (1 - F_load / F_stall) when the hydraulic force on the power piston opposes the motion | `accel_max_mps2` (typ. 2), `force_stall_n` (typ. 1500) |
//! | `hose_hysteresis` | rate-independent wall hysteresis: a play operator of half-width r on each line pressure adds the compliance c while engaged | `c_m3pp` (typ. 2e-13), `half_width_pa` (typ. 1e5) |
//! | `accumulator_thermal` | gas temperature T relaxing to ambient: dT/dt = -(n - 1) T dVg/dt / Vg + (T0 - T)/tau, P_abs = P0_abs (V0/Vg)(T/T0) | `tau_s` (typ. 5) |
//!
//! With every effect off the plant is exactly the nominal model of plant.md.

use serde::Deserialize;

/// Internal leakage across the pistons.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Leakage {
    /// Conductance from line 1 to line 2, m^3/(s Pa).
    pub g_m3pspa: f64,
}

/// Seal friction on the actuating piston beyond the viscous term.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Friction {
    /// Coulomb (sliding) friction, N.
    pub coulomb_n: f64,
    /// Static (breakaway) friction, N (>= coulomb_n).
    pub static_n: f64,
    /// Stribeck velocity, m/s.
    #[serde(default = "default_stribeck")]
    pub stribeck_mps: f64,
}

fn default_stribeck() -> f64 {
    2e-3
}

/// Velocity below which friction is smoothed to zero (tanh), m/s.
pub const FRICTION_SMOOTH_MPS: f64 = 1e-4;

/// Play between motor and power piston.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Backlash {
    /// Total play, m.
    pub play_m: f64,
}

/// Entrained air.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Air {
    /// Air volume fraction at atmospheric pressure.
    pub fraction: f64,
    /// Polytropic index of the air bubbles.
    #[serde(default = "default_kappa")]
    pub kappa: f64,
}

fn default_kappa() -> f64 {
    1.4
}

/// Delay and lag of the measurements.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
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

/// Servo torque and acceleration limits.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MotorLimit {
    /// Largest acceleration of the ball screw, m/s^2.
    pub accel_max_mps2: f64,
    /// Axial force at which the speed falls to zero, N.
    pub force_stall_n: f64,
}

/// Rate-independent hose-wall hysteresis.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HoseHysteresis {
    /// Compliance of the hysteretic element, m^3/Pa.
    pub c_m3pp: f64,
    /// Half width of the play in pressure, Pa.
    pub half_width_pa: f64,
}

/// Accumulator gas temperature relaxation.
#[derive(Clone, Copy, Debug, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AccumulatorThermal {
    /// Thermal time constant of the gas, s.
    pub tau_s: f64,
}

/// Ambient (and initial) gas temperature, K.
pub const T_AMBIENT_K: f64 = 293.15;

/// The set of active effects (all `None`: the nominal plant).
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    /// `leakage`.
    pub leakage: Option<Leakage>,
    /// `friction`.
    pub friction: Option<Friction>,
    /// `backlash`.
    pub backlash: Option<Backlash>,
    /// `air`.
    pub air: Option<Air>,
    /// `sensor_delay`.
    pub sensor_delay: Option<SensorDelay>,
    /// `motor_limit`.
    pub motor_limit: Option<MotorLimit>,
    /// `hose_hysteresis`.
    pub hose_hysteresis: Option<HoseHysteresis>,
    /// `accumulator_thermal`.
    pub accumulator_thermal: Option<AccumulatorThermal>,
}

/// The effect identifiers of plant.md section 12.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum EffectKind {
    /// Internal leakage.
    Leakage,
    /// Seal friction.
    Friction,
    /// Ball-screw play.
    Backlash,
    /// Entrained air.
    Air,
    /// Measurement delay.
    SensorDelay,
    /// Servo limits.
    MotorLimit,
    /// Hose hysteresis.
    HoseHysteresis,
    /// Accumulator thermal drift.
    AccumulatorThermal,
}

/// One parameter of an effect: name (with unit), typical value, fit bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParamSpec {
    /// Name with unit suffix, as in the configuration files.
    pub name: &'static str,
    /// A typical magnitude on a rig of this size.
    pub typical: f64,
    /// Smallest value a fit may take.
    pub min: f64,
    /// Largest value a fit may take.
    pub max: f64,
}

const fn p(name: &'static str, typical: f64, min: f64, max: f64) -> ParamSpec {
    ParamSpec {
        name,
        typical,
        min,
        max,
    }
}

impl EffectKind {
    /// All effects, in the order of plant.md section 12.
    pub const ALL: [Self; 8] = [
        Self::Leakage,
        Self::Friction,
        Self::Backlash,
        Self::Air,
        Self::SensorDelay,
        Self::MotorLimit,
        Self::HoseHysteresis,
        Self::AccumulatorThermal,
    ];

    /// The identifier of plant.md section 12.
    pub fn name(self) -> &'static str {
        match self {
            Self::Leakage => "leakage",
            Self::Friction => "friction",
            Self::Backlash => "backlash",
            Self::Air => "air",
            Self::SensorDelay => "sensor_delay",
            Self::MotorLimit => "motor_limit",
            Self::HoseHysteresis => "hose_hysteresis",
            Self::AccumulatorThermal => "accumulator_thermal",
        }
    }

    /// Parse an identifier.
    pub fn by_name(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == s)
    }

    /// The parameters, in the order [`Effects::set`] takes them.
    pub fn params(self) -> &'static [ParamSpec] {
        match self {
            Self::Leakage => LEAKAGE_PARAMS,
            Self::Friction => FRICTION_PARAMS,
            Self::Backlash => BACKLASH_PARAMS,
            Self::Air => AIR_PARAMS,
            Self::SensorDelay => SENSOR_DELAY_PARAMS,
            Self::MotorLimit => MOTOR_LIMIT_PARAMS,
            Self::HoseHysteresis => HOSE_HYSTERESIS_PARAMS,
            Self::AccumulatorThermal => ACCUMULATOR_THERMAL_PARAMS,
        }
    }
}

const LEAKAGE_PARAMS: &[ParamSpec] = &[p("g_m3pspa", 1e-13, 1e-16, 1e-11)];
const FRICTION_PARAMS: &[ParamSpec] = &[
    p("coulomb_n", 30.0, 0.0, 500.0),
    p("static_n", 45.0, 0.0, 800.0),
    p("stribeck_mps", 2e-3, 1e-4, 5e-2),
];
const BACKLASH_PARAMS: &[ParamSpec] = &[p("play_m", 50e-6, 0.0, 2e-3)];
const AIR_PARAMS: &[ParamSpec] = &[p("fraction", 0.005, 0.0, 0.1)];
const SENSOR_DELAY_PARAMS: &[ParamSpec] = &[
    p("xo_delay_s", 3e-3, 0.0, 0.1),
    p("xo_tau_s", 2e-3, 0.0, 0.1),
];
const MOTOR_LIMIT_PARAMS: &[ParamSpec] = &[
    p("accel_max_mps2", 2.0, 0.05, 100.0),
    p("force_stall_n", 1500.0, 100.0, 50_000.0),
];
const HOSE_HYSTERESIS_PARAMS: &[ParamSpec] = &[
    p("c_m3pp", 2e-13, 0.0, 5e-12),
    p("half_width_pa", 1e5, 1e3, 2e6),
];
const ACCUMULATOR_THERMAL_PARAMS: &[ParamSpec] = &[p("tau_s", 5.0, 0.05, 1000.0)];

impl Effects {
    /// No effect: the nominal plant.
    pub const NONE: Self = Self {
        leakage: None,
        friction: None,
        backlash: None,
        air: None,
        sensor_delay: None,
        motor_limit: None,
        hose_hysteresis: None,
        accumulator_thermal: None,
    };

    /// True when no effect is active.
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// The active effects.
    pub fn active(&self) -> Vec<EffectKind> {
        EffectKind::ALL
            .into_iter()
            .filter(|k| self.get(*k).is_some())
            .collect()
    }

    /// The parameters of effect `k` if active, in [`EffectKind::params`] order.
    pub fn get(&self, k: EffectKind) -> Option<Vec<f64>> {
        Some(match k {
            EffectKind::Leakage => vec![self.leakage?.g_m3pspa],
            EffectKind::Friction => {
                let f = self.friction?;
                vec![f.coulomb_n, f.static_n, f.stribeck_mps]
            }
            EffectKind::Backlash => vec![self.backlash?.play_m],
            EffectKind::Air => vec![self.air?.fraction],
            EffectKind::SensorDelay => {
                let s = self.sensor_delay?;
                vec![s.xo_delay_s, s.xo_tau_s]
            }
            EffectKind::MotorLimit => {
                let m = self.motor_limit?;
                vec![m.accel_max_mps2, m.force_stall_n]
            }
            EffectKind::HoseHysteresis => {
                let h = self.hose_hysteresis?;
                vec![h.c_m3pp, h.half_width_pa]
            }
            EffectKind::AccumulatorThermal => vec![self.accumulator_thermal?.tau_s],
        })
    }

    /// Switch effect `k` on with `v` (in [`EffectKind::params`] order; missing
    /// entries take the typical value), or off with `None`.
    pub fn set(&mut self, k: EffectKind, v: Option<&[f64]>) {
        let Some(v) = v else {
            match k {
                EffectKind::Leakage => self.leakage = None,
                EffectKind::Friction => self.friction = None,
                EffectKind::Backlash => self.backlash = None,
                EffectKind::Air => self.air = None,
                EffectKind::SensorDelay => self.sensor_delay = None,
                EffectKind::MotorLimit => self.motor_limit = None,
                EffectKind::HoseHysteresis => self.hose_hysteresis = None,
                EffectKind::AccumulatorThermal => self.accumulator_thermal = None,
            }
            return;
        };
        let specs = k.params();
        let at = |i: usize| v.get(i).copied().unwrap_or(specs[i].typical);
        match k {
            EffectKind::Leakage => self.leakage = Some(Leakage { g_m3pspa: at(0) }),
            EffectKind::Friction => {
                self.friction = Some(Friction {
                    coulomb_n: at(0),
                    static_n: at(1),
                    stribeck_mps: at(2),
                })
            }
            EffectKind::Backlash => self.backlash = Some(Backlash { play_m: at(0) }),
            EffectKind::Air => {
                self.air = Some(Air {
                    fraction: at(0),
                    kappa: default_kappa(),
                })
            }
            EffectKind::SensorDelay => {
                let p_tau_s = self.sensor_delay.map(|s| s.p_tau_s).unwrap_or(0.0);
                self.sensor_delay = Some(SensorDelay {
                    xo_delay_s: at(0),
                    xo_tau_s: at(1),
                    p_tau_s,
                })
            }
            EffectKind::MotorLimit => {
                self.motor_limit = Some(MotorLimit {
                    accel_max_mps2: at(0),
                    force_stall_n: at(1),
                })
            }
            EffectKind::HoseHysteresis => {
                self.hose_hysteresis = Some(HoseHysteresis {
                    c_m3pp: at(0),
                    half_width_pa: at(1),
                })
            }
            EffectKind::AccumulatorThermal => {
                self.accumulator_thermal = Some(AccumulatorThermal { tau_s: at(0) })
            }
        }
    }

    /// Parse a command-line effect: `name` (typical parameters) or
    /// `name:param=value,param=value`.
    pub fn parse_arg(&mut self, s: &str) -> Result<(), String> {
        let (name, rest) = s.split_once(':').unwrap_or((s, ""));
        let k = EffectKind::by_name(name.trim()).ok_or_else(|| {
            let all: Vec<&str> = EffectKind::ALL.iter().map(|k| k.name()).collect();
            format!(
                "unknown effect '{name}': expected one of {}",
                all.join(", ")
            )
        })?;
        let specs = k.params();
        let mut v: Vec<f64> = specs.iter().map(|p| p.typical).collect();
        for kv in rest.split(',').filter(|s| !s.trim().is_empty()) {
            let (pn, pv) = kv
                .split_once('=')
                .ok_or_else(|| format!("effect {name}: '{kv}' is not param=value"))?;
            let i = specs
                .iter()
                .position(|p| p.name == pn.trim())
                .ok_or_else(|| {
                    let all: Vec<&str> = specs.iter().map(|p| p.name).collect();
                    format!(
                        "effect {name}: unknown parameter '{pn}' (expected {})",
                        all.join(", ")
                    )
                })?;
            v[i] = pv
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("effect {name}: '{pv}' is not a finite number"))?;
        }
        self.set(k, Some(&v));
        self.validate()
    }

    /// Check every active effect's parameters.
    pub fn validate(&self) -> Result<(), String> {
        for k in self.active() {
            let v = self.get(k).unwrap_or_default();
            for (x, s) in v.iter().zip(k.params()) {
                if !x.is_finite() || *x < 0.0 {
                    return Err(format!(
                        "effect {}: {} = {x} must be finite and >= 0",
                        k.name(),
                        s.name
                    ));
                }
            }
        }
        if let Some(f) = self.friction {
            if f.stribeck_mps <= 0.0 {
                return Err("effect friction: stribeck_mps must be > 0".into());
            }
        }
        if let Some(m) = self.motor_limit {
            if m.accel_max_mps2 <= 0.0 || m.force_stall_n <= 0.0 {
                return Err(
                    "effect motor_limit: accel_max_mps2 and force_stall_n must be > 0".into(),
                );
            }
        }
        if let Some(t) = self.accumulator_thermal {
            if t.tau_s <= 0.0 {
                return Err("effect accumulator_thermal: tau_s must be > 0".into());
            }
        }
        Ok(())
    }
}

/// Leakage flow from line 1 to line 2, m^3/s.
pub fn leak_flow_m3ps(l: &Leakage, p1_pa: f64, p2_pa: f64) -> f64 {
    l.g_m3pspa * (p1_pa - p2_pa)
}

/// Friction force opposing the actuating piston's velocity, N (sign of -v).
pub fn friction_force_n(f: &Friction, v_mps: f64) -> f64 {
    let r = v_mps / f.stribeck_mps;
    let mag = f.coulomb_n + (f.static_n - f.coulomb_n) * libm::exp(-r * r);
    -mag * libm::tanh(v_mps / FRICTION_SMOOTH_MPS)
}

/// Effective bulk modulus of oil with entrained air at gauge pressure `p_pa`,
/// returned as its inverse (the compressibility), 1/Pa.
pub fn compressibility_ppa(a: &Air, beta_e_pa: f64, p_pa: f64, p_atm_pa: f64) -> f64 {
    // The absolute pressure is kept above 5 % of atmospheric (no vacuum).
    let p_abs = (p_pa + p_atm_pa).max(0.05 * p_atm_pa);
    1.0 / beta_e_pa + a.fraction / (a.kappa * p_abs) * libm::pow(p_atm_pa / p_abs, 1.0 / a.kappa)
}

/// Rate of a play (backlash) operator's output `y` driven by `x` moving at
/// `dx`: it follows when the play of total width `width` is taken up in the
/// direction of motion, and stays otherwise.
pub fn play_rate(x: f64, y: f64, dx: f64, width: f64) -> f64 {
    let half = 0.5 * width;
    if (x - y >= half && dx > 0.0) || (x - y <= -half && dx < 0.0) {
        dx
    } else {
        0.0
    }
}

/// Servo speed target under the motor limit: the commanded speed `vc`, cut
/// along the torque-speed line when the hydraulic force `f_load_n` (positive
/// opposing extension) opposes the motion.
pub fn motor_speed_target(m: &MotorLimit, vc_mps: f64, f_load_n: f64) -> f64 {
    let opposing = if vc_mps > 0.0 { f_load_n } else { -f_load_n };
    let scale = (1.0 - opposing.max(0.0) / m.force_stall_n).max(0.0);
    vc_mps * scale
}

/// Servo acceleration under the motor limit.
pub fn motor_accel(m: &MotorLimit, a_mps2: f64) -> f64 {
    a_mps2.clamp(-m.accel_max_mps2, m.accel_max_mps2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_and_set_round_trip() {
        let mut e = Effects::NONE;
        assert!(e.is_none());
        e.parse_arg("leakage:g_m3pspa=2e-13").unwrap();
        e.parse_arg("friction").unwrap();
        assert_eq!(e.get(EffectKind::Leakage), Some(vec![2e-13]));
        assert_eq!(e.get(EffectKind::Friction).unwrap()[0], 30.0);
        assert_eq!(e.active(), vec![EffectKind::Leakage, EffectKind::Friction]);
        e.set(EffectKind::Leakage, None);
        assert_eq!(e.active(), vec![EffectKind::Friction]);
        for bad in [
            "magic",
            "leakage:g=1",
            "leakage:g_m3pspa=x",
            "air:fraction=-1",
            "motor_limit:force_stall_n=0",
        ] {
            let mut e = Effects::NONE;
            assert!(e.parse_arg(bad).is_err(), "{bad}");
        }
        let toml: Effects =
            toml::from_str("[air]\nfraction = 0.01\n[backlash]\nplay_m = 1e-4\n").unwrap();
        assert_eq!(toml.air.unwrap().kappa, 1.4);
        assert_eq!(toml.backlash.unwrap().play_m, 1e-4);
        assert!(toml::from_str::<Effects>("[air]\nfractoin = 0.01\n").is_err());
    }

    #[test]
    fn every_effect_has_params_within_bounds() {
        for k in EffectKind::ALL {
            assert_eq!(EffectKind::by_name(k.name()), Some(k));
            for s in k.params() {
                assert!(
                    s.min <= s.typical && s.typical <= s.max,
                    "{} {}",
                    k.name(),
                    s.name
                );
            }
            let mut e = Effects::NONE;
            e.set(k, Some(&[]));
            assert_eq!(e.active(), vec![k]);
            assert_eq!(
                e.get(k).unwrap(),
                k.params().iter().map(|p| p.typical).collect::<Vec<_>>()
            );
            e.validate().unwrap();
        }
    }

    #[test]
    fn friction_opposes_motion_with_breakaway_peak() {
        let f = Friction {
            coulomb_n: 30.0,
            static_n: 45.0,
            stribeck_mps: 2e-3,
        };
        assert_eq!(friction_force_n(&f, 0.0), 0.0);
        assert!(friction_force_n(&f, 1e-3) < -40.0);
        assert!((friction_force_n(&f, 0.05) + 30.0).abs() < 1e-6);
        assert!((friction_force_n(&f, -0.05) - 30.0).abs() < 1e-6);
    }

    #[test]
    fn air_softens_most_at_low_pressure() {
        let a = Air {
            fraction: 0.005,
            kappa: 1.4,
        };
        let beta = |p: f64| 1.0 / compressibility_ppa(&a, 1.2e9, p, 101_325.0);
        assert!(beta(0.5e6) < 0.6e9, "{}", beta(0.5e6));
        assert!(beta(3.0e6) > beta(0.5e6) * 2.0);
        assert!(beta(3.0e6) < 1.2e9);
        let none = Air {
            fraction: 0.0,
            kappa: 1.4,
        };
        assert_eq!(
            compressibility_ppa(&none, 1.2e9, 1e6, 101_325.0),
            1.0 / 1.2e9
        );
    }

    #[test]
    fn play_operator_follows_only_beyond_the_play() {
        assert_eq!(play_rate(0.0, 0.0, 1.0, 1e-4), 0.0);
        assert_eq!(play_rate(5e-5, 0.0, 1.0, 1e-4), 1.0);
        assert_eq!(play_rate(5e-5, 0.0, -1.0, 1e-4), 0.0);
        assert_eq!(play_rate(-5e-5, 0.0, -1.0, 1e-4), -1.0);
    }

    #[test]
    fn motor_limit_cuts_speed_against_load_only() {
        let m = MotorLimit {
            accel_max_mps2: 2.0,
            force_stall_n: 1000.0,
        };
        assert_eq!(motor_speed_target(&m, 0.1, 500.0), 0.05);
        assert_eq!(motor_speed_target(&m, -0.1, 500.0), -0.1);
        assert_eq!(motor_speed_target(&m, 0.1, 2000.0), 0.0);
        assert_eq!(motor_accel(&m, 10.0), 2.0);
    }
}
