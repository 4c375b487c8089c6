//! The accumulator: the gas temperature relaxing (`accumulator_thermal`) and
//! its general family, the gas relaxation spectrum.

use dca_core::params::PlantParams;
use serde::{Deserialize, Serialize};

use super::catalogue::{p, Broken, GeneralFamily, NamedEffect, ParamSpec};
use super::terms::{Gas, Rest, RigTerms};

/// Accumulator gas temperature relaxation.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AccumulatorThermal {
    /// Thermal time constant of the gas, s.
    pub tau_s: f64,
}

/// Ambient (and initial) gas temperature, K.
pub const T_AMBIENT_K: f64 = 293.15;

/// Time constants of the elements of a [`GasRelaxation`], s: half a decade
/// apart from 0.1 s to 30 s.
pub const GAS_TAUS_S: [f64; 6] = [0.1, 0.3, 1.0, 3.0, 10.0, 30.0];

/// Largest sum of a [`GasRelaxation`]'s weights: the gas keeps a long-run
/// polytropic index of at least `n_poly - 1` (0.4 on the nominal rig), so
/// the accumulator never turns into a negative spring.
pub const GAS_WEIGHT_SUM_MAX: f64 = 1.0;

/// The general family of the accumulator (`accumulator_thermal` in any
/// shape): the gas spring's stiffness relaxing over a spectrum of time
/// constants (a Prony series of the gas). With `u = ln(V_gas0 / Vg)` the
/// gas's log compression, element `k` carries a relaxed share `s_k` of the
/// log pressure, `ds_k/dt = (w_k u - s_k) / tau_k` ([`GAS_TAUS_S`]), and the
/// gas's absolute pressure is `P0_abs exp(n_poly u - sum_k s_k)`. A fast
/// compression meets the nominal (adiabatic) index; held, the index falls by
/// the weights of the elements that have relaxed ([`Self::index_after`]).
/// One element of weight `n_poly - 1` is the named form's thermal
/// relaxation to first order in the temperature; several are heat paths of
/// different speeds (gas to a foam filling, to the shell, to the mount); a
/// total above `n_poly - 1` is a bladder or membrane that creeps.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GasRelaxation {
    /// Weight of each element, dimensionless (non-negative, sum at most
    /// [`GAS_WEIGHT_SUM_MAX`]).
    pub weights: [f64; 6],
}

impl GasRelaxation {
    /// The gas's effective polytropic index a time `t_s` after a step
    /// compression from rest, on a rig whose nominal index is `n_poly`:
    /// `n_poly - sum_k w_k (1 - exp(-t / tau_k))`.
    pub fn index_after(&self, n_poly: f64, t_s: f64) -> f64 {
        n_poly
            - self
                .weights
                .iter()
                .zip(GAS_TAUS_S)
                .map(|(w, tau)| w * (1.0 - (-t_s / tau).exp()))
                .sum::<f64>()
    }

    /// Whether the family is usable: every weight finite and non-negative,
    /// their sum at most [`GAS_WEIGHT_SUM_MAX`] (to rounding: a fit scales
    /// its weights back onto the bound).
    pub fn is_valid(&self) -> bool {
        self.weights.iter().all(|w| w.is_finite() && *w >= 0.0)
            && self.weights.iter().sum::<f64>() <= GAS_WEIGHT_SUM_MAX * (1.0 + 1e-9)
    }
}

impl NamedEffect for AccumulatorThermal {
    const SUBSYSTEM: &'static str = "accumulator";
    const PARAMS: &'static [ParamSpec] = &[p("tau_s", 5.0, 0.05, 1000.0)];
    fn values(&self) -> Vec<f64> {
        vec![self.tau_s]
    }
    fn from_values(at: &dyn Fn(usize) -> f64) -> Self {
        Self { tau_s: at(0) }
    }
    fn check_relations(&self) -> Result<(), Broken> {
        if self.tau_s <= 0.0 {
            return Err(Broken::Requirement("tau_s must be > 0"));
        }
        Ok(())
    }
}

impl GeneralFamily for GasRelaxation {
    const FORM: &'static str =
        "general: the accumulator gas relaxing over six time constants (0.1 to 30 s)";
    const BOTH: &'static str = "the named form and the gas relaxation exclude each other";
    const REQUIREMENT: &'static str =
        "gas_relaxation: weights finite, >= 0 and summing to at most 1";
    fn family_valid(&self) -> bool {
        self.is_valid()
    }
    fn param_map(&self) -> Vec<(String, f64)> {
        GAS_TAUS_S
            .iter()
            .zip(self.weights)
            .map(|(tau, w)| (format!("weight_at_tau_{tau}_s"), w))
            .collect()
    }
    /// The weights in units of 0.02 (a total beyond
    /// [`GAS_WEIGHT_SUM_MAX`] is scaled back onto it).
    const LEARNED: usize = GAS_TAUS_S.len();
    fn from_learned(x: &[f64]) -> Option<Self> {
        const UNIT: f64 = 0.02;
        let w: [f64; 6] = std::array::from_fn(|i| x[i].max(0.0) * UNIT);
        let sum: f64 = w.iter().sum();
        let scale = if sum > GAS_WEIGHT_SUM_MAX {
            GAS_WEIGHT_SUM_MAX / sum
        } else {
            1.0
        };
        Some(Self {
            weights: w.map(|v| v * scale),
        })
    }
}

/// The gas temperature T (the one state) relaxing to ambient:
/// P_acc,abs = P0_abs (V0/Vg) (T/T0).
impl RigTerms for AccumulatorThermal {
    const STATES: usize = 1;
    fn rest_states(&self, _rest: &Rest, own: &mut [f64]) {
        own[0] = T_AMBIENT_K;
    }
    fn accumulator_flow_m3ps(&self, gas: &Gas<'_>, own: &[f64], rates: &mut [f64]) -> Option<f64> {
        let p = gas.params;
        let t_gas_k = own[0];
        // Gas law with temperature: P_abs = P0_abs (V0 / Vg) (T / T0).
        let p_abs0 = p.p_acc0_pa + p.p_atm_pa;
        let pacc = p_abs0 * (p.v_gas0_m3 / gas.vg_m3) * (t_gas_k / T_AMBIENT_K) - p.p_atm_pa;
        let qa = p.g_acc_m3pspa * (pacc - gas.p2_pa);
        // Adiabatic compression heats the gas (dVg = qa), exchange relaxes it.
        rates[0] =
            -(p.n_poly - 1.0) * t_gas_k * qa / gas.vg_m3 + (T_AMBIENT_K - t_gas_k) / self.tau_s;
        Some(qa)
    }
}

/// The relaxed shares s_k of the gas's log pressure (the six states):
/// P_acc,abs = P0_abs exp(n ln(V0/Vg) - sum s_k).
impl RigTerms for GasRelaxation {
    const STATES: usize = GAS_TAUS_S.len();
    /// The weights must leave the gas some stiffness: their sum below the
    /// plant's polytropic index.
    fn check_plant(&self, p: &PlantParams) -> Result<(), String> {
        let sum: f64 = self.weights.iter().sum();
        let n_poly = p.n_poly;
        if sum >= n_poly {
            return Err(format!(
                "accumulator_thermal's relaxation weights sum to {sum}, not below the rig's \
                 polytropic index n_poly = {n_poly}: the relaxed gas would have no stiffness"
            ));
        }
        Ok(())
    }
    fn accumulator_flow_m3ps(&self, gas: &Gas<'_>, own: &[f64], rates: &mut [f64]) -> Option<f64> {
        let p = gas.params;
        // The nominal law with the relaxed shares taken off the log
        // pressure: exactly the plant's with every share at zero.
        let u = libm::log(p.v_gas0_m3 / gas.vg_m3);
        let relaxed: f64 = own.iter().sum();
        let p_abs0 = p.p_acc0_pa + p.p_atm_pa;
        let pacc = p_abs0 * libm::exp(p.n_poly * u - relaxed) - p.p_atm_pa;
        let qa = p.g_acc_m3pspa * (pacc - gas.p2_pa);
        for (k, d) in rates.iter_mut().enumerate() {
            *d = (self.weights[k] * u - own[k]) / GAS_TAUS_S[k];
        }
        Some(qa)
    }
}
