//! Physical parameters of the nominal plant (docs/model.md section 3).
//!
//! One parameter set serves the controller design (the prediction model of
//! section 6.2 needs the mass, the areas and the hose) and the host simulator's
//! plant, so both always agree on the numbers. All values are SI.

/// Hose wall parameters of one line (docs/model.md section 3.2).
///
/// Generalised standard linear solid with an instantaneous compliance `ce0_m3pp`,
/// a fast relaxation element (`cf0_m3pp`, `tau_f_s`) and a slow creep element
/// (`cs0_m3pp`, `tau_s_s`); every compliance stiffens as `1 / (1 + P / ps_pa)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HoseParams {
    /// Instantaneous wall compliance at P = 0, m^3/Pa.
    pub ce0_m3pp: f64,
    /// Fast relaxation compliance at P = 0, m^3/Pa.
    pub cf0_m3pp: f64,
    /// Fast relaxation time constant, s.
    pub tau_f_s: f64,
    /// Slow creep compliance at P = 0, m^3/Pa.
    pub cs0_m3pp: f64,
    /// Creep time constant (the paper's T1 = Be/k2), s.
    pub tau_s_s: f64,
    /// Stiffening pressure: compliance halves at P = ps_pa, Pa.
    pub ps_pa: f64,
}

impl HoseParams {
    /// The nominal hose of docs/model.md section 3.2.
    pub const NOMINAL: Self = Self {
        ce0_m3pp: 1.2e-13,
        cf0_m3pp: 1.2e-13,
        tau_f_s: 0.010,
        cs0_m3pp: 4.8e-13,
        tau_s_s: 0.30,
        ps_pa: 1.0e6,
    };

    /// Stiffening factor f(P) = 1 / (1 + max(P, -0.9 Ps) / Ps) (docs/model.md section 4).
    pub fn stiffening(&self, p_pa: f64) -> f64 {
        1.0 / (1.0 + guard_pressure(p_pa, self.ps_pa) / self.ps_pa)
    }

    /// L(P) = Ps ln(1 + max(P, -0.9 Ps) / Ps), the integral of f (docs/model.md section 4), Pa.
    pub fn log_pressure(&self, p_pa: f64) -> f64 {
        self.ps_pa * libm::log1p(guard_pressure(p_pa, self.ps_pa) / self.ps_pa)
    }
}

fn guard_pressure(p_pa: f64, ps_pa: f64) -> f64 {
    let floor = -0.9 * ps_pa;
    if p_pa > floor {
        p_pa
    } else {
        floor
    }
}

/// Nominal plant parameters (docs/model.md section 3.1), SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlantParams {
    /// Equivalent moving mass, kg.
    pub m_kg: f64,
    /// Power cylinder annulus area (line 1 side), m^2.
    pub ap1_m2: f64,
    /// Power cylinder full bore area (line 2 side), m^2.
    pub ap2_m2: f64,
    /// Actuating cylinder full bore area (line 1 side), m^2.
    pub aa1_m2: f64,
    /// Actuating cylinder annulus area (line 2 side), m^2.
    pub aa2_m2: f64,
    /// Viscous friction of the actuating piston, N s/m.
    pub c_visc_nspm: f64,
    /// Hose mean radius a, m.
    pub hose_radius_m: f64,
    /// Hose length l (each line), m.
    pub hose_length_m: f64,
    /// Effective oil bulk modulus, Pa.
    pub beta_e_pa: f64,
    /// Lower mechanical stroke limit of both cylinders, m.
    pub x_min_m: f64,
    /// Upper mechanical stroke limit of both cylinders, m.
    pub x_max_m: f64,
    /// Dead volume at each chamber end, m^3.
    pub v_dead_m3: f64,
    /// Fittings and sensor port volume per line, m^3.
    pub v_fit_m3: f64,
    /// Ball-screw speed limit of the servo, m/s.
    pub v_max_mps: f64,
    /// Servo speed-loop time constant, s.
    pub tau_m_s: f64,
    /// Accumulator pressure (= P2) at t = 0, gauge, Pa.
    pub p_acc0_pa: f64,
    /// Accumulator gas volume at t = 0, m^3.
    pub v_gas0_m3: f64,
    /// Polytropic index of the accumulator gas.
    pub n_poly: f64,
    /// Atmospheric pressure, Pa.
    pub p_atm_pa: f64,
    /// Laminar conductance of the accumulator restrictor, m^3/(s Pa).
    pub g_acc_m3pspa: f64,
    /// End-stop stiffness of the actuating cylinder, N/m.
    pub k_stop_npm: f64,
    /// End-stop damping of the actuating cylinder, N s/m.
    pub c_stop_nspm: f64,
    /// Hose wall of each line.
    pub hose: HoseParams,
    /// Pressure at which the prediction model linearises the hose, Pa.
    pub p_nom_pa: f64,
}

impl Default for PlantParams {
    fn default() -> Self {
        Self::NOMINAL
    }
}

/// The hose linearised at one pressure (docs/model.md section 4, relation to eq. 1-4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HoseLinearisation {
    /// Series (instantaneous plus fast) wall stiffness k1, Pa/m.
    pub k1_papm: f64,
    /// Kelvin (creep) stiffness k2, Pa/m.
    pub k2_papm: f64,
    /// Oil in the hose seen as a radial spring, Pa/m.
    pub kh_papm: f64,
    /// Total stiffness k (1/k = 1/k1 + 1/k2 + 1/kh), Pa/m.
    pub k_papm: f64,
    /// Kelvin damper Be = k2 tau_s, Pa s/m.
    pub be_paspm: f64,
    /// Creep time constant T1 = Be/k2, s.
    pub t1_s: f64,
    /// Lead time constant T2 = Be / (k2 + k1 kh / (k1 + kh)), s.
    pub t2_s: f64,
}

impl PlantParams {
    /// The nominal parameter set of docs/model.md section 3.
    pub const NOMINAL: Self = Self {
        m_kg: 50.0,
        ap1_m2: 3.77e-4,
        ap2_m2: 4.91e-4,
        aa1_m2: 3.14e-4,
        aa2_m2: 2.01e-4,
        c_visc_nspm: 200.0,
        hose_radius_m: 0.003,
        hose_length_m: 1.0,
        beta_e_pa: 1.2e9,
        x_min_m: -0.010,
        x_max_m: 0.110,
        v_dead_m3: 1.0e-6,
        v_fit_m3: 1.0e-6,
        v_max_mps: 0.10,
        tau_m_s: 0.010,
        p_acc0_pa: 1.0e6,
        v_gas0_m3: 1.0e-4,
        n_poly: 1.4,
        p_atm_pa: 101_325.0,
        g_acc_m3pspa: 5.0e-10,
        k_stop_npm: 1e7,
        c_stop_nspm: 2e4,
        hose: HoseParams::NOMINAL,
        p_nom_pa: 1.0e6,
    };

    /// Oil volume of one hose, pi a^2 l, m^3.
    pub fn v_hose_m3(&self) -> f64 {
        core::f64::consts::PI * self.hose_radius_m * self.hose_radius_m * self.hose_length_m
    }

    /// The hose linearised at `p_pa` (docs/model.md section 4).
    pub fn hose_linearisation(&self, p_pa: f64) -> HoseLinearisation {
        let h = &self.hose;
        let g = 2.0 * core::f64::consts::PI * self.hose_radius_m * self.hose_length_m;
        let f = h.stiffening(p_pa);
        let k1 = g / ((h.ce0_m3pp + h.cf0_m3pp) * f);
        let k2 = g / (h.cs0_m3pp * f);
        let kh = 2.0 * self.beta_e_pa / self.hose_radius_m;
        let k = 1.0 / (1.0 / k1 + 1.0 / k2 + 1.0 / kh);
        let be = k2 * h.tau_s_s;
        HoseLinearisation {
            k1_papm: k1,
            k2_papm: k2,
            kh_papm: kh,
            k_papm: k,
            be_paspm: be,
            t1_s: be / k2,
            t2_s: be / (k2 + k1 * kh / (k1 + kh)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rel(a: f64, b: f64) -> f64 {
        ((a - b) / b).abs()
    }

    #[test]
    fn hose_linearisation_matches_plant_md_section_4() {
        let lin = PlantParams::NOMINAL.hose_linearisation(1.0e6);
        assert!(rel(lin.k1_papm, 1.5708e11) < 1e-4);
        assert!(rel(lin.k2_papm, 7.8540e10) < 1e-4);
        assert!(rel(lin.kh_papm, 8.0e11) < 1e-12);
        assert!(rel(lin.k_papm, 4.9143e10) < 1e-4);
        assert!(rel(lin.be_paspm, 2.3562e10) < 1e-4);
        assert!(rel(lin.t1_s, 0.3) < 1e-12);
        assert!(rel(lin.t2_s, 0.112286) < 1e-5);
    }

    #[test]
    fn stiffening_guard_and_log() {
        let h = HoseParams::NOMINAL;
        assert_eq!(h.stiffening(0.0), 1.0);
        assert!((h.stiffening(1.0e6) - 0.5).abs() < 1e-15);
        // Guard: below -0.9 Ps the factor saturates at 10.
        assert!((h.stiffening(-5.0e6) - 10.0).abs() < 1e-9);
        assert!((h.log_pressure(1.0e6) - 1.0e6 * core::f64::consts::LN_2).abs() < 1e-6);
    }

    #[test]
    fn hose_volume() {
        assert!(rel(PlantParams::NOMINAL.v_hose_m3(), 2.827433e-5) < 1e-6);
    }
}
