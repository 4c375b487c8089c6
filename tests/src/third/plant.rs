//! The third family's own plant: the equations of docs/model.md section 4
//! (nominal hose), written anew from the text, with the effect forms of
//! [`super::effects`] composed in. Classical RK4 at 1e-4 s with the inputs held
//! over the step (section 4.2); the drive ripple alone is evaluated at the stage
//! times.

use super::effects::Effects;

/// Number of states: the 11 of docs/model.md section 2 plus the effects' own.
pub const N_STATES: usize = 26;

/// State indices beyond the nominal 11.
pub mod ix {
    /// Power piston position behind the coupling play, m.
    pub const XP: usize = 11;
    /// Power piston velocity behind the play, m/s.
    pub const VP: usize = 12;
    /// LuGre bristle deflection, m.
    pub const Z: usize = 13;
    /// Accumulator gas temperature, K.
    pub const T_GAS: usize = 14;
    /// First Prandtl-Ishlinskii operator of line 1 (four per line, Pa).
    pub const PI1: usize = 15;
    /// First Prandtl-Ishlinskii operator of line 2, Pa.
    pub const PI2: usize = 19;
    /// Pressure at the power cylinder's port behind the line-1 orifice, Pa.
    pub const P1A: usize = 23;
    /// LVDT conditioner output (Butterworth), m.
    pub const XF: usize = 24;
    /// Its derivative, m/s.
    pub const XF_DOT: usize = 25;
}

/// Plant step, s (docs/model.md section 3.1).
pub const DT_S: f64 = 1.0e-4;

/// Ambient (and initial gas) temperature, K.
pub const T_AMBIENT_K: f64 = 293.15;

/// The physical parameters of docs/model.md sections 3.1 and 3.2, as this
/// family's own copy.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigParams {
    /// Moving mass of the actuating side, kg.
    pub m_kg: f64,
    /// Power cylinder annulus (line 1), m^2.
    pub ap1_m2: f64,
    /// Power cylinder full bore (line 2), m^2.
    pub ap2_m2: f64,
    /// Actuating cylinder full bore (line 1), m^2.
    pub aa1_m2: f64,
    /// Actuating cylinder annulus (line 2), m^2.
    pub aa2_m2: f64,
    /// Viscous friction of the actuating piston, N s/m.
    pub c_visc_nspm: f64,
    /// Hose bore radius, m.
    pub hose_radius_m: f64,
    /// Hose length, m.
    pub hose_length_m: f64,
    /// Oil bulk modulus, Pa.
    pub beta_e_pa: f64,
    /// Lower stroke end, m.
    pub x_min_m: f64,
    /// Upper stroke end, m.
    pub x_max_m: f64,
    /// Dead volume per chamber end, m^3.
    pub v_dead_m3: f64,
    /// Fittings volume per line, m^3.
    pub v_fit_m3: f64,
    /// Servo speed limit, m/s.
    pub v_max_mps: f64,
    /// Servo speed-loop time constant, s.
    pub tau_m_s: f64,
    /// Accumulator gauge pressure at t = 0, Pa.
    pub p_acc0_pa: f64,
    /// Accumulator gas volume at t = 0, m^3.
    pub v_gas0_m3: f64,
    /// Polytropic index, -.
    pub n_poly: f64,
    /// Atmospheric pressure, Pa.
    pub p_atm_pa: f64,
    /// Accumulator restrictor conductance, m^3/(s Pa).
    pub g_acc_m3pspa: f64,
    /// End-stop stiffness, N/m.
    pub k_stop_npm: f64,
    /// End-stop damping, N s/m.
    pub c_stop_nspm: f64,
    /// Instantaneous wall compliance at P = 0, m^3/Pa.
    pub ce0_m3pp: f64,
    /// Fast relaxation compliance at P = 0, m^3/Pa.
    pub cf0_m3pp: f64,
    /// Fast relaxation time constant, s.
    pub tau_f_s: f64,
    /// Creep compliance at P = 0, m^3/Pa.
    pub cs0_m3pp: f64,
    /// Creep time constant, s.
    pub tau_s_s: f64,
    /// Stiffening pressure, Pa.
    pub ps_pa: f64,
}

impl RigParams {
    /// The nominal values of docs/model.md section 3.
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
        k_stop_npm: 1.0e7,
        c_stop_nspm: 2.0e4,
        ce0_m3pp: 1.2e-13,
        cf0_m3pp: 1.2e-13,
        tau_f_s: 0.010,
        cs0_m3pp: 4.8e-13,
        tau_s_s: 0.30,
        ps_pa: 1.0e6,
    };

    /// Oil volume of one hose, m^3.
    pub fn v_hose_m3(&self) -> f64 {
        std::f64::consts::PI * self.hose_radius_m * self.hose_radius_m * self.hose_length_m
    }

    /// Stiffening factor f(P).
    pub fn stiff(&self, p_pa: f64) -> f64 {
        1.0 / (1.0 + p_pa.max(-0.9 * self.ps_pa) / self.ps_pa)
    }

    /// Integral of the stiffening factor, L(P), Pa.
    pub fn stiff_integral_pa(&self, p_pa: f64) -> f64 {
        self.ps_pa * (p_pa.max(-0.9 * self.ps_pa) / self.ps_pa).ln_1p()
    }

    /// Line volumes (V1, V2) at power piston xi and actuating piston xo, m^3.
    pub fn volumes_m3(&self, xi_m: f64, xo_m: f64) -> (f64, f64) {
        let common = 2.0 * self.v_dead_m3 + self.v_hose_m3() + self.v_fit_m3;
        (
            common + self.ap1_m2 * (self.x_max_m - xi_m) + self.aa1_m2 * (xo_m - self.x_min_m),
            common + self.ap2_m2 * (xi_m - self.x_min_m) + self.aa2_m2 * (self.x_max_m - xo_m),
        )
    }

    /// Nominal (adiabatic) accumulator gauge pressure at gas volume vg, Pa.
    pub fn p_acc_pa(&self, vg_m3: f64) -> f64 {
        (self.p_acc0_pa + self.p_atm_pa) * (self.v_gas0_m3 / vg_m3).powf(self.n_poly)
            - self.p_atm_pa
    }
}

/// A rig of this family: parameters and effects.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rig {
    /// Physical parameters (nominal unless a `parameters` case changes them).
    pub params: RigParams,
    /// Departures from the nominal model.
    pub effects: Effects,
}

/// One state vector.
pub type State = [f64; N_STATES];

impl Rig {
    /// The nominal rig.
    pub fn nominal() -> Self {
        Self {
            params: RigParams::NOMINAL,
            effects: Effects::default(),
        }
    }

    /// Rest state with load `ft0_n` (docs/model.md section 4.1, extended to the
    /// effects' states).
    pub fn rest(&self, ft0_n: f64) -> State {
        let p = &self.params;
        let mut x = [0.0; N_STATES];
        let p2 = p.p_acc0_pa;
        let p1 = (p.aa2_m2 * p2 + ft0_n) / p.aa1_m2;
        x[4] = p1;
        x[5] = p2;
        x[6] = p.cf0_m3pp * p.stiff_integral_pa(p1);
        x[7] = p.cs0_m3pp * p.stiff_integral_pa(p1);
        x[8] = p.cf0_m3pp * p.stiff_integral_pa(p2);
        x[9] = p.cs0_m3pp * p.stiff_integral_pa(p2);
        x[10] = p.v_gas0_m3;
        x[ix::T_GAS] = T_AMBIENT_K;
        x[ix::P1A] = p1;
        if let Some(b) = self.effects.backlash {
            let f_oil = p.ap2_m2 * p2 - p.ap1_m2 * p1;
            x[ix::XP] = 0.5 * b.play_m * f_oil.signum() + f_oil / b.stiffness_npm;
        }
        if let Some(h) = self.effects.hysteresis {
            for i in 0..4 {
                x[ix::PI1 + i] = p1 - h.thresholds_pa[i];
                x[ix::PI2 + i] = p2 - h.thresholds_pa[i];
            }
        }
        x
    }

    /// Extra line compliance of entrained air at gauge pressure p in a line of
    /// volume v, m^3/Pa.
    fn air_compliance(&self, p_pa: f64, v_m3: f64) -> f64 {
        match self.effects.air {
            None => 0.0,
            Some(a) => {
                let pat = self.params.p_atm_pa;
                let pabs = (p_pa + pat).max(0.2 * pat);
                let va = a.fraction * v_m3 * (pat / pabs) * (-(pabs - pat) / a.dissolve_pa).exp();
                va * (1.0 / pabs + 1.0 / a.dissolve_pa)
            }
        }
    }

    /// Prandtl-Ishlinskii compliance of the operators that the pressure drags in
    /// the direction `dir` (sign of dP/dt), m^3/Pa, and their engagement.
    fn hyst_compliance(&self, x: &State, first: usize, p_pa: f64, dir: f64) -> (f64, [f64; 4]) {
        let mut e = [0.0; 4];
        let Some(h) = self.effects.hysteresis else {
            return (0.0, e);
        };
        let mut c = 0.0;
        for i in 0..4 {
            let gap = dir * (p_pa - x[first + i]);
            e[i] = (1.0 + (gap - h.thresholds_pa[i]) / 2.0e3).clamp(0.0, 1.0);
            c += e[i] * h.weights_m3pp[i];
        }
        (c, e)
    }

    /// Right-hand side dx/dt at time t (s) with drive command `v_cmd_mps` and load
    /// `ft_n` (docs/model.md section 4 plus the effects).
    pub fn rhs(&self, t_s: f64, x: &State, v_cmd_mps: f64, ft_n: f64) -> State {
        let p = &self.params;
        let ef = &self.effects;
        let mut d = [0.0; N_STATES];
        let (xi, vi, xo, p1, p2) = (x[0], x[1], x[2], x[4], x[5]);

        // Power piston behind the coupling (the encoder reads xi).
        let (xpp, vpp) = if ef.backlash.is_some() {
            (x[ix::XP], x[ix::VP])
        } else {
            (xi, vi)
        };
        // Line-1 pressure at the power cylinder's port.
        let p1_port = if ef.restriction.is_some() {
            x[ix::P1A]
        } else {
            p1
        };
        let f_oil = p.ap2_m2 * p2 - p.ap1_m2 * p1_port; // on the power piston, +x

        self.servo_and_screw(t_s, x, v_cmd_mps, f_oil, (xpp, vpp), &mut d);
        self.actuating_piston(x, ft_n, &mut d);
        let qa = self.accumulator(x, &mut d);
        self.lines(x, (xpp, vpp), p1_port, qa, &mut d);
        // LVDT conditioner (second-order Butterworth on the true Xo).
        if let Some(l) = ef.lag {
            if l.lvdt_corner_hz > 0.0 {
                let w = 2.0 * std::f64::consts::PI * l.lvdt_corner_hz;
                d[ix::XF] = x[ix::XF_DOT];
                d[ix::XF_DOT] =
                    w * w * (xo - x[ix::XF]) - std::f64::consts::SQRT_2 * w * x[ix::XF_DOT];
            }
        }
        d
    }

    /// The servo and the screw, with the power piston behind the coupling:
    /// their derivatives into `d`.
    fn servo_and_screw(
        &self,
        t_s: f64,
        x: &State,
        v_cmd_mps: f64,
        f_oil: f64,
        (xpp, vpp): (f64, f64),
        d: &mut State,
    ) {
        let p = &self.params;
        let ef = &self.effects;
        let (xi, vi) = (x[0], x[1]);
        let mut v_in = v_cmd_mps;
        if let Some(r) = ef.ripple {
            v_in += r.amplitude_mps * (2.0 * std::f64::consts::PI * r.freq_hz * t_s).sin();
        }
        let vc = v_in.clamp(-p.v_max_mps, p.v_max_mps);
        let a_dem = (vc - vi) / p.tau_m_s;
        d[0] = vi;
        d[1] = match ef.motor {
            None => a_dem,
            Some(m) => {
                // Force the screw takes from the piston side, +x.
                let f_load = match ef.backlash {
                    Some(b) => -contact_force(b, xi - xpp, vi - vpp),
                    None => f_oil,
                };
                let f_req = m.mass_eq_kg * a_dem - f_load;
                let motoring = f_req * vi >= 0.0;
                let speed = vi.abs();
                let f_av = if !motoring || speed <= m.corner_mps {
                    m.peak_n
                } else {
                    (m.peak_n * (m.no_load_mps - speed) / (m.no_load_mps - m.corner_mps)).max(0.0)
                };
                (f_req.clamp(-f_av, f_av) + f_load) / m.mass_eq_kg
            }
        };
        if let Some(b) = ef.backlash {
            let fc = contact_force(b, xi - xpp, vi - vpp);
            d[ix::XP] = vpp;
            d[ix::VP] =
                (fc + f_oil - b.seal_nspm * vpp - b.seal_n * (vpp / 2.0e-3).tanh()) / b.piston_kg;
        }
    }

    /// The actuating piston's derivatives (end stops, load, friction) into `d`.
    fn actuating_piston(&self, x: &State, ft_n: f64, d: &mut State) {
        let p = &self.params;
        let ef = &self.effects;
        let (xo, vo, p1, p2) = (x[2], x[3], x[4], x[5]);
        let mut fs = 0.0;
        if xo > p.x_max_m {
            fs = -p.k_stop_npm * (xo - p.x_max_m) - if vo > 0.0 { p.c_stop_nspm * vo } else { 0.0 };
        } else if xo < p.x_min_m {
            fs = -p.k_stop_npm * (xo - p.x_min_m) - if vo < 0.0 { p.c_stop_nspm * vo } else { 0.0 };
        }
        let mut f_fric = 0.0;
        if let Some(f) = ef.friction {
            let fc = f.coulomb_n + f.per_pa_n * (p1 + p2).max(0.0);
            let g = (fc + (f.static_ratio - 1.0) * fc * (-(vo / f.stribeck_mps).powi(2)).exp())
                .max(1e-3);
            let z = x[ix::Z];
            let dz = vo - f.sigma0_npm * vo.abs() * z / g;
            d[ix::Z] = dz;
            f_fric = f.sigma0_npm * z + f.sigma1_nspm * dz;
        }
        d[2] = vo;
        d[3] = (p.aa1_m2 * p1 - p.aa2_m2 * p2 - ft_n - p.c_visc_nspm * vo + fs - f_fric) / p.m_kg;
    }

    /// The accumulator's derivatives into `d`; its flow into line 2, m^3/s.
    fn accumulator(&self, x: &State, d: &mut State) -> f64 {
        let p = &self.params;
        let ef = &self.effects;
        let p2 = x[5];
        let vg = x[10];
        let p_acc = match ef.thermal {
            None => p.p_acc_pa(vg),
            Some(_) => {
                (p.p_acc0_pa + p.p_atm_pa) * (p.v_gas0_m3 / vg) * (x[ix::T_GAS] / T_AMBIENT_K)
                    - p.p_atm_pa
            }
        };
        let qa = p.g_acc_m3pspa * (p_acc - p2);
        d[10] = qa;
        if let Some(th) = ef.thermal {
            let t = x[ix::T_GAS];
            d[ix::T_GAS] = -(th.gamma - 1.0) * t * qa / vg + (T_AMBIENT_K - t) / th.tau_s;
        }
        qa
    }

    /// Flows, hose walls and pressures of both lines (and the restriction's
    /// port node): their derivatives into `d`.
    fn lines(&self, x: &State, (xpp, vpp): (f64, f64), p1_port: f64, qa: f64, d: &mut State) {
        let p = &self.params;
        let ef = &self.effects;
        let (xo, vo, p1, p2) = (x[2], x[3], x[4], x[5]);
        let q_leak = match ef.leakage {
            None => 0.0,
            Some(l) => {
                let dp = p1 - p2;
                l.g_m3pspa * (1.0 + dp.abs() / l.widen_pa) * dp
            }
        };
        let (v1, v2) = p.volumes_m3(xpp, xo);
        let q1 = if let Some(r) = ef.restriction {
            // Port node: the power cylinder's annulus, its dead volume and half the fittings.
            let va = p.v_dead_m3 + 0.5 * p.v_fit_m3 + p.ap1_m2 * (p.x_max_m - xpp);
            let dp = p1_port - p1;
            let k = r.cd_area_m2 * (2.0 / r.rho_kgpm3).sqrt();
            let qr = k * dp / (dp.abs() + r.transition_pa).sqrt();
            d[ix::P1A] = (p.ap1_m2 * vpp - qr) * p.beta_e_pa / va;
            qr - p.aa1_m2 * vo - q_leak
        } else {
            p.ap1_m2 * vpp - p.aa1_m2 * vo - q_leak
        };
        let v1 = if ef.restriction.is_some() {
            v1 - p.v_dead_m3 - 0.5 * p.v_fit_m3 - p.ap1_m2 * (p.x_max_m - xpp)
        } else {
            v1
        };
        let q2 = p.aa2_m2 * vo - p.ap2_m2 * vpp + qa + q_leak;

        // Hose walls and pressures.
        for (line, (pj, q, vj)) in [(p1, q1, v1), (p2, q2, v2)].into_iter().enumerate() {
            let (ixf, ixs, ipi, ip) = if line == 0 {
                (6, 7, ix::PI1, 4)
            } else {
                (8, 9, ix::PI2, 5)
            };
            let dvf = (p.cf0_m3pp * p.stiff_integral_pa(pj) - x[ixf]) / p.tau_f_s;
            let dvs = (p.cs0_m3pp * p.stiff_integral_pa(pj) - x[ixs]) / p.tau_s_s;
            d[ixf] = dvf;
            d[ixs] = dvs;
            let num = q - dvf - dvs;
            let c_base = vj / p.beta_e_pa + p.ce0_m3pp * p.stiff(pj) + self.air_compliance(pj, vj);
            let (c_h, e) = self.hyst_compliance(x, ipi, pj, num.signum());
            let dp = num / (c_base + c_h);
            d[ip] = dp;
            for i in 0..4 {
                d[ipi + i] = e[i] * dp;
            }
        }
    }

    /// One classical RK4 step of `dt_s` from time `t_s`, inputs held, with the
    /// ball-screw software limit of docs/model.md section 4.2.
    pub fn step(&self, t_s: f64, x: &mut State, v_cmd_mps: f64, ft_n: f64, dt_s: f64) {
        let p = &self.params;
        let v = if (x[0] >= p.x_max_m && v_cmd_mps > 0.0) || (x[0] <= p.x_min_m && v_cmd_mps < 0.0)
        {
            0.0
        } else {
            v_cmd_mps
        };
        let k1 = self.rhs(t_s, x, v, ft_n);
        let k2 = self.rhs(t_s + 0.5 * dt_s, &axpy(x, 0.5 * dt_s, &k1), v, ft_n);
        let k3 = self.rhs(t_s + 0.5 * dt_s, &axpy(x, 0.5 * dt_s, &k2), v, ft_n);
        let k4 = self.rhs(t_s + dt_s, &axpy(x, dt_s, &k3), v, ft_n);
        for i in 0..N_STATES {
            x[i] += dt_s / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
}

/// Contact force of the coupling on the power piston, +x, at relative position
/// d = xi - xp and relative speed dv (unilateral: it only pushes).
fn contact_force(b: super::effects::Backlash, d_m: f64, dv_mps: f64) -> f64 {
    let h = 0.5 * b.play_m;
    if d_m > h {
        (b.stiffness_npm * (d_m - h) + b.damping_nspm * dv_mps).max(0.0)
    } else if d_m < -h {
        (b.stiffness_npm * (d_m + h) + b.damping_nspm * dv_mps).min(0.0)
    } else {
        0.0
    }
}

fn axpy(x: &State, a: f64, k: &State) -> State {
    let mut y = *x;
    for i in 0..N_STATES {
        y[i] += a * k[i];
    }
    y
}
