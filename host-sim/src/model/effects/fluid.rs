//! The oil: entrained air (`air`).

use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, NamedEffect, ParamSpec, KAPPA_MAX};
use super::terms::{Line, RigTerms};

/// Entrained air.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Air {
    /// Air volume fraction at atmospheric pressure.
    pub fraction: f64,
    /// Polytropic index of the air bubbles.
    #[serde(default = "default_kappa")]
    pub kappa: f64,
}

pub(super) fn default_kappa() -> f64 {
    1.4
}

/// Effective bulk modulus of oil with entrained air at gauge pressure `p_pa`,
/// returned as its inverse (the compressibility), 1/Pa.
pub fn compressibility_ppa(a: &Air, beta_e_pa: f64, p_pa: f64, p_atm_pa: f64) -> f64 {
    // The absolute pressure is kept above 5 % of atmospheric (no vacuum).
    let p_abs = (p_pa + p_atm_pa).max(0.05 * p_atm_pa);
    1.0 / beta_e_pa + a.fraction / (a.kappa * p_abs) * libm::pow(p_atm_pa / p_abs, 1.0 / a.kappa)
}

impl NamedEffect for Air {
    const SUBSYSTEM: &'static str = "oil";
    const PARAMS: &'static [ParamSpec] = &[p("fraction", 0.005, 0.0, 0.1)];
    fn values(&self) -> Vec<f64> {
        vec![self.fraction]
    }
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        Self {
            fraction: at(0),
            kappa: default_kappa(),
        }
    }
    fn check_bounds(&self) -> Result<(), Broken> {
        if !(1.0..=KAPPA_MAX).contains(&self.kappa) {
            return Err(Broken::Kappa(self.kappa));
        }
        Ok(())
    }
}

/// The oil's compressibility V / beta_e of each line becomes V / beta_eff(P).
impl RigTerms for Air {
    const ON_LINES: bool = true;
    fn add_line_compliance(&self, line: &mut Line<'_>, _own: &[f64], _rates: &mut [f64]) {
        let p = line.params;
        let c = compressibility_ppa(self, p.beta_e_pa, line.p_pa, p.p_atm_pa);
        line.add_compliance([line.v_m3 * (c - 1.0 / p.beta_e_pa)]);
    }
}
