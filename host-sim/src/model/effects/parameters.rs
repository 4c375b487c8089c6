//! The rig's nominal parameters off by ratios (`parameters`).

use dca_core::params::PlantParams;
use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, NamedEffect, ParamSpec};
use super::terms::RigTerms;

use super::common::one;

/// The rig's nominal parameters off by ratios (1: nominal): the diagnosis's
/// grey-box re-estimate (`parameters`). To set a simulated rig's parameters
/// directly, `[plant.params]` is the way; this is that same change as an
/// effect, so that a candidate is one [`Effects`](super::Effects).
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ParameterRatios {
    /// Actuating piston and load mass, `m_kg`.
    #[serde(default = "one")]
    pub m_kg_ratio: f64,
    /// Oil bulk modulus, `beta_e_pa`.
    #[serde(default = "one")]
    pub beta_e_pa_ratio: f64,
    /// The hose wall's compliances `hose.ce0_m3pp`, `hose.cf0_m3pp`,
    /// `hose.cs0_m3pp` (the inverse of its stiffness).
    #[serde(default = "one")]
    pub hose_c_ratio: f64,
    /// Viscous damping, `c_visc_nspm`.
    #[serde(default = "one")]
    pub c_visc_ratio: f64,
    /// Servo time constant, `tau_m_s`.
    #[serde(default = "one")]
    pub tau_m_ratio: f64,
    /// Accumulator precharge (gauge), `p_acc0_pa`.
    #[serde(default = "one")]
    pub p_acc0_ratio: f64,
    /// Actuating-piston areas `aa1_m2` and `aa2_m2`.
    #[serde(default = "one")]
    pub aa_ratio: f64,
}

/// The plant parameter keys ([`crate::model::params::KEYS`]) each ratio of
/// [`ParameterRatios`] scales, in its order.
pub const RATIO_KEYS: [&[&str]; 7] = [
    &["m_kg"],
    &["beta_e_pa"],
    &["hose.ce0_m3pp", "hose.cf0_m3pp", "hose.cs0_m3pp"],
    &["c_visc_nspm"],
    &["tau_m_s"],
    &["p_acc0_pa"],
    &["aa1_m2", "aa2_m2"],
];

impl ParameterRatios {
    /// All ratios 1.
    pub const NOMINAL: Self = Self {
        m_kg_ratio: 1.0,
        beta_e_pa_ratio: 1.0,
        hose_c_ratio: 1.0,
        c_visc_ratio: 1.0,
        tau_m_ratio: 1.0,
        p_acc0_ratio: 1.0,
        aa_ratio: 1.0,
    };

    /// The ratios in [`RATIO_KEYS`] order.
    pub fn to_array(&self) -> [f64; 7] {
        [
            self.m_kg_ratio,
            self.beta_e_pa_ratio,
            self.hose_c_ratio,
            self.c_visc_ratio,
            self.tau_m_ratio,
            self.p_acc0_ratio,
            self.aa_ratio,
        ]
    }

    /// Ratios from an array in [`RATIO_KEYS`] order.
    pub fn from_array(a: [f64; 7]) -> Self {
        Self {
            m_kg_ratio: a[0],
            beta_e_pa_ratio: a[1],
            hose_c_ratio: a[2],
            c_visc_ratio: a[3],
            tau_m_ratio: a[4],
            p_acc0_ratio: a[5],
            aa_ratio: a[6],
        }
    }

    /// `p` with every key of [`RATIO_KEYS`] scaled by its ratio.
    pub fn apply(&self, p: &PlantParams) -> PlantParams {
        let mut out = *p;
        for (keys, r) in RATIO_KEYS.iter().zip(self.to_array()) {
            for name in keys.iter() {
                if let Some(k) = crate::model::params::find(name) {
                    k.set(&mut out, k.get(p) * r);
                }
            }
        }
        out
    }
}

/// Smallest and largest ratio of a re-estimated parameter.
pub const RATIO_BOUNDS: (f64, f64) = (1.0 / 3.0, 3.0);

impl NamedEffect for ParameterRatios {
    const SUBSYSTEM: &'static str = "plant";
    const PARAMS: &'static [ParamSpec] = &[
        p("m_kg_ratio", 1.0, RATIO_BOUNDS.0, RATIO_BOUNDS.1),
        p("beta_e_pa_ratio", 1.0, RATIO_BOUNDS.0, RATIO_BOUNDS.1),
        p("hose_c_ratio", 1.0, RATIO_BOUNDS.0, RATIO_BOUNDS.1),
        p("c_visc_ratio", 1.0, RATIO_BOUNDS.0, RATIO_BOUNDS.1),
        p("tau_m_ratio", 1.0, RATIO_BOUNDS.0, RATIO_BOUNDS.1),
        p("p_acc0_ratio", 1.0, RATIO_BOUNDS.0, RATIO_BOUNDS.1),
        p("aa_ratio", 1.0, RATIO_BOUNDS.0, RATIO_BOUNDS.1),
    ];
    const SEARCHED: bool = false;
    fn values(&self) -> Vec<f64> {
        self.to_array().to_vec()
    }
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        let a: [f64; 7] = std::array::from_fn(at);
        Self::from_array(a)
    }
    fn check_relations(&self) -> Result<(), Broken> {
        if self.to_array().iter().any(|x| *x <= 0.0) {
            return Err(Broken::Requirement("every ratio must be > 0"));
        }
        Ok(())
    }
}

/// The plant built with its parameters scaled: the equations are the
/// plant's.
impl RigTerms for ParameterRatios {
    const ON_EQUATIONS: bool = false;
    fn plant_params(&self, p: &PlantParams) -> Option<PlantParams> {
        Some(self.apply(p))
    }
}
