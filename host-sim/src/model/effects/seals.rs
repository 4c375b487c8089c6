//! Seals: internal leakage across the pistons and seal friction on the actuating
//! piston, each as its named form and its general family.

use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, GeneralFamily, NamedEffect, ParamSpec};
use super::terms::RigTerms;

use super::common::{interp, one};

/// Internal leakage across the pistons.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Leakage {
    /// Conductance from line 1 to line 2 at a 1 MPa difference, m^3/(s Pa).
    pub g_m3pspa: f64,
    /// Flow exponent: 1 laminar (Q proportional to dP), 0.5 orifice-like.
    #[serde(default = "one")]
    pub exponent: f64,
}

/// Reference pressure difference of the leakage conductance, Pa.
pub const LEAK_P_REF_PA: f64 = 1e6;
/// Pressure difference below which the leakage stays laminar, Pa.
pub const LEAK_P_SMOOTH_PA: f64 = 1e4;

/// Pressure differences of the knots of a [`LeakageMap`], Pa.
pub const LEAK_DP_PA: [f64; 6] = [0.0, 0.25e6, 0.5e6, 1e6, 2e6, 4e6];

/// The general family of `leakage` (internal leakage of any shape over the
/// pressure difference and the pressure level): the flow from line 1 to
/// line 2 is `sign(dP) L(abs(dP)) + g dP (P1 + P2) / (2 MPa)`, dP = P1 - P2,
/// `L` piecewise linear between the knots [`LEAK_DP_PA`] (0 at 0, extended
/// along its last segment). A straight `L` is laminar flow, a bent one an
/// orifice or a seal lip that opens; `g` is a gap that widens with the
/// pressure.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LeakageMap {
    /// Flow at the knots 0.25, 0.5, 1, 2, 4 MPa, m^3/s (non-negative).
    pub q_m3ps: [f64; 5],
    /// Conductance per MPa of mean line pressure, m^3/(s Pa) (non-negative).
    #[serde(default)]
    pub g_m3pspa: f64,
}

impl LeakageMap {
    /// The leakage flow from line 1 to line 2, m^3/s.
    pub fn flow(&self, p1_pa: f64, p2_pa: f64) -> f64 {
        let dp = p1_pa - p2_pa;
        let mut q = [0.0; 6];
        q[1..].copy_from_slice(&self.q_m3ps);
        let mean = (0.5 * (p1_pa + p2_pa) / SEAL_P_REF_PA).max(0.0);
        interp(&LEAK_DP_PA, &q, dp.abs(), false).copysign(dp) + self.g_m3pspa * dp * mean
    }

    /// Whether the map is usable: every value finite and non-negative.
    pub fn is_valid(&self) -> bool {
        self.q_m3ps
            .iter()
            .chain([&self.g_m3pspa])
            .all(|q| q.is_finite() && *q >= 0.0)
    }
}

/// Leakage flow from line 1 to line 2, m^3/s.
pub fn leak_flow_m3ps(l: &Leakage, p1_pa: f64, p2_pa: f64) -> f64 {
    let dp = p1_pa - p2_pa;
    if l.exponent == 1.0 {
        return l.g_m3pspa * dp;
    }
    let r = (dp.abs() + LEAK_P_SMOOTH_PA) / LEAK_P_REF_PA;
    l.g_m3pspa * dp * libm::pow(r, l.exponent - 1.0)
}

/// Seal friction on the actuating piston beyond the viscous term.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
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

/// Speeds of the knots of a [`FrictionMap`], m/s: dense where Stribeck
/// curves bend, up to the servo's 0.1 m/s times the area ratio.
pub const FRICTION_SPEEDS_MPS: [f64; 6] = [0.0, 0.5e-3, 2e-3, 8e-3, 30e-3, 100e-3];

/// Pressure that scales the pressure-dependent parts of the seal maps, Pa.
pub const SEAL_P_REF_PA: f64 = 1e6;

/// The general family of `friction` (seal friction of any shape over speed
/// and pressure): the friction on the actuating piston has the magnitude
/// `S(abs(v)) + k (P1 + P2) / 1 MPa`, `S` piecewise linear between the
/// knots [`FRICTION_SPEEDS_MPS`] (flat beyond), and opposes the velocity
/// (smoothed as the named form is, over 0.1 mm/s). A falling `S` is a
/// Stribeck curve, a rising one adds viscous-like drag, `k` is the load
/// of seals that the line pressures press against the rod and bore.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FrictionMap {
    /// Friction at the knot speeds with both lines at 0 Pa, N (non-negative).
    pub force_n: [f64; 6],
    /// Friction added per MPa of P1 + P2, N/MPa (non-negative).
    #[serde(default)]
    pub n_per_mpa: f64,
}

impl FrictionMap {
    /// The friction's magnitude at the speed `v_mps` (its magnitude) and
    /// the line pressures, N.
    pub fn magnitude_n(&self, v_mps: f64, p1_pa: f64, p2_pa: f64) -> f64 {
        let s = interp(&FRICTION_SPEEDS_MPS, &self.force_n, v_mps.abs(), true);
        let p = ((p1_pa + p2_pa) / SEAL_P_REF_PA).max(0.0);
        s + self.n_per_mpa * p
    }

    /// The friction force on the actuating piston (sign of -v), N.
    pub fn force(&self, v_mps: f64, p1_pa: f64, p2_pa: f64) -> f64 {
        -self.magnitude_n(v_mps, p1_pa, p2_pa) * libm::tanh(v_mps / FRICTION_SMOOTH_MPS)
    }

    /// Whether the map is usable: every value finite and non-negative.
    pub fn is_valid(&self) -> bool {
        self.force_n
            .iter()
            .chain([&self.n_per_mpa])
            .all(|f| f.is_finite() && *f >= 0.0)
    }
}

/// Friction force opposing the actuating piston's velocity, N (sign of -v).
pub fn friction_force_n(f: &Friction, v_mps: f64) -> f64 {
    let r = v_mps / f.stribeck_mps;
    let mag = f.coulomb_n + (f.static_n - f.coulomb_n) * libm::exp(-r * r);
    -mag * libm::tanh(v_mps / FRICTION_SMOOTH_MPS)
}

impl NamedEffect for Leakage {
    const SUBSYSTEM: &'static str = "seals";
    const PARAMS: &'static [ParamSpec] = &[
        p("g_m3pspa", 1e-13, 1e-16, 1e-11),
        p("exponent", 1.0, 0.5, 1.0),
    ];
    fn values(&self) -> Vec<f64> {
        vec![self.g_m3pspa, self.exponent]
    }
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        Self {
            g_m3pspa: at(0),
            exponent: at(1),
        }
    }
    fn check_relations(&self) -> Result<(), Broken> {
        if !(self.exponent > 0.0 && self.exponent <= 2.0) {
            return Err(Broken::Requirement("exponent must be in (0, 2]"));
        }
        Ok(())
    }
}

impl GeneralFamily for LeakageMap {
    const FORM: &'static str =
        "general: internal leakage of any shape over the pressure difference, plus a share growing with the pressure level";
    const BOTH: &'static str = "the named form and the leakage map exclude each other";
    const REQUIREMENT: &'static str = "leakage_map: q_m3ps and g_m3pspa must be finite and >= 0";
    fn family_valid(&self) -> bool {
        self.is_valid()
    }
    fn param_map(&self) -> Vec<(String, f64)> {
        let mut m = vec![("g_m3pspa".to_string(), self.g_m3pspa)];
        for (dp, q) in LEAK_DP_PA[1..].iter().zip(self.q_m3ps) {
            m.push((format!("q_m3ps_at_{:.2}_mpa", dp * 1e-6), q));
        }
        m
    }
    /// The flow at the knots in units of 1e-7 m^3/s (1e-13 m^3/(s Pa) at
    /// 1 MPa), then the level conductance in units of 1e-13 m^3/(s Pa).
    const LEARNED: usize = 6;
    fn from_learned(x: &[f64]) -> Option<Self> {
        Some(Self {
            q_m3ps: std::array::from_fn(|i| x[i].max(0.0) * 1e-7),
            g_m3pspa: x[5].max(0.0) * 1e-13,
        })
    }
    fn to_learned(&self) -> Option<Vec<f64>> {
        let mut x: Vec<f64> = self.q_m3ps.iter().map(|q| q.max(0.0) / 1e-7).collect();
        x.push(self.g_m3pspa.max(0.0) / 1e-13);
        Some(x)
    }
}

impl NamedEffect for Friction {
    const SUBSYSTEM: &'static str = "seals";
    const PARAMS: &'static [ParamSpec] = &[
        p("coulomb_n", 30.0, 0.0, 500.0),
        p("static_n", 45.0, 0.0, 800.0),
        p("stribeck_mps", 2e-3, 1e-4, 5e-2),
    ];
    fn values(&self) -> Vec<f64> {
        vec![self.coulomb_n, self.static_n, self.stribeck_mps]
    }
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        Self {
            coulomb_n: at(0),
            static_n: at(1),
            stribeck_mps: at(2),
        }
    }
    fn check_bounds(&self) -> Result<(), Broken> {
        if self.stribeck_mps <= 0.0 {
            return Err(Broken::Requirement("stribeck_mps must be > 0"));
        }
        Ok(())
    }
}

impl GeneralFamily for FrictionMap {
    const FORM: &'static str =
        "general: seal friction of any shape over speed, plus a share growing with the line pressures";
    const BOTH: &'static str = "the named form and the friction map exclude each other";
    const REQUIREMENT: &'static str = "friction_map: force_n and n_per_mpa must be finite and >= 0";
    fn family_valid(&self) -> bool {
        self.is_valid()
    }
    fn param_map(&self) -> Vec<(String, f64)> {
        let mut m = vec![("n_per_mpa".to_string(), self.n_per_mpa)];
        for (v, x) in FRICTION_SPEEDS_MPS.iter().zip(self.force_n) {
            m.push((format!("force_n_at_{:.1}_mmps", v * 1e3), x));
        }
        m
    }
    /// The friction at the speed knots, then per MPa, in units of 10 N.
    const LEARNED: usize = 7;
    fn from_learned(x: &[f64]) -> Option<Self> {
        const UNIT_N: f64 = 10.0;
        Some(Self {
            force_n: std::array::from_fn(|i| x[i].max(0.0) * UNIT_N),
            n_per_mpa: x[6].max(0.0) * UNIT_N,
        })
    }
}

/// A flow from line 1 to line 2.
impl RigTerms for Leakage {
    fn leak_flow_m3ps(&self, p1_pa: f64, p2_pa: f64) -> Option<f64> {
        Some(leak_flow_m3ps(self, p1_pa, p2_pa))
    }
}

/// A flow from line 1 to line 2.
impl RigTerms for LeakageMap {
    fn leak_flow_m3ps(&self, p1_pa: f64, p2_pa: f64) -> Option<f64> {
        Some(self.flow(p1_pa, p2_pa))
    }
}

/// A force on the actuating piston.
impl RigTerms for Friction {
    fn piston_force_n(&self, vo_mps: f64, _p1_pa: f64, _p2_pa: f64) -> Option<f64> {
        Some(friction_force_n(self, vo_mps))
    }
}

/// A force on the actuating piston.
impl RigTerms for FrictionMap {
    fn piston_force_n(&self, vo_mps: f64, p1_pa: f64, p2_pa: f64) -> Option<f64> {
        Some(self.force(vo_mps, p1_pa, p2_pa))
    }
}
