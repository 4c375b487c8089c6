//! The nominal plant of plant.md sections 1-4, written for this family: the
//! parameters of section 3, the helper functions and volumes of section 4 and
//! the state layout of section 2. The right-hand side itself lives in
//! [`crate::fourth::rig`], where the effects hook into it; with no effect it is
//! exactly the nominal right-hand side of section 4 (checked against the
//! vectors of sections 4.1 and 4.2).

/// Number of states of the nominal plant (plant.md section 2).
pub const N_STATES: usize = 11;

/// Plant parameters (plant.md sections 3.1 and 3.2), SI units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Params {
    /// Equivalent moving mass of the actuating piston, kg.
    pub m: f64,
    /// Power cylinder annulus (line 1), m^2.
    pub ap1: f64,
    /// Power cylinder full bore (line 2), m^2.
    pub ap2: f64,
    /// Actuating cylinder full bore (line 1), m^2.
    pub aa1: f64,
    /// Actuating cylinder annulus (line 2), m^2.
    pub aa2: f64,
    /// Viscous friction of the actuating piston, N s/m.
    pub c_visc: f64,
    /// Hose mean radius, m.
    pub a: f64,
    /// Hose length, m.
    pub l: f64,
    /// Oil bulk modulus, Pa.
    pub beta_e: f64,
    /// Lower stroke end, m.
    pub x_min: f64,
    /// Upper stroke end, m.
    pub x_max: f64,
    /// Dead volume at each chamber end, m^3.
    pub v_dead: f64,
    /// Fittings and sensor port per line, m^3.
    pub v_fit: f64,
    /// Ball-screw speed limit, m/s.
    pub v_max: f64,
    /// Servo speed-loop time constant, s.
    pub tau_m: f64,
    /// Accumulator (= P2) pressure at t = 0, Pa gauge.
    pub p_acc0: f64,
    /// Accumulator gas volume at t = 0, m^3.
    pub v_gas0: f64,
    /// Polytropic index of the gas.
    pub n_poly: f64,
    /// Atmospheric pressure, Pa.
    pub p_atm: f64,
    /// Accumulator restrictor conductance, m^3/(s Pa).
    pub g_acc: f64,
    /// End-stop stiffness, N/m.
    pub k_stop: f64,
    /// End-stop damping, N s/m.
    pub c_stop: f64,
    /// Instantaneous hose-wall compliance at P = 0, m^3/Pa.
    pub ce0: f64,
    /// Fast relaxation compliance at P = 0, m^3/Pa.
    pub cf0: f64,
    /// Fast relaxation time constant, s.
    pub tau_f: f64,
    /// Slow creep compliance at P = 0, m^3/Pa.
    pub cs0: f64,
    /// Creep time constant, s.
    pub tau_s: f64,
    /// Stiffening pressure, Pa.
    pub ps: f64,
    /// RK4 step, s.
    pub dt: f64,
}

impl Params {
    /// The nominal values of plant.md section 3.
    pub const NOMINAL: Self = Self {
        m: 50.0,
        ap1: 3.77e-4,
        ap2: 4.91e-4,
        aa1: 3.14e-4,
        aa2: 2.01e-4,
        c_visc: 200.0,
        a: 0.003,
        l: 1.0,
        beta_e: 1.2e9,
        x_min: -0.010,
        x_max: 0.110,
        v_dead: 1.0e-6,
        v_fit: 1.0e-6,
        v_max: 0.10,
        tau_m: 0.010,
        p_acc0: 1.0e6,
        v_gas0: 1.0e-4,
        n_poly: 1.4,
        p_atm: 101_325.0,
        g_acc: 5.0e-10,
        k_stop: 1.0e7,
        c_stop: 2.0e4,
        ce0: 1.2e-13,
        cf0: 1.2e-13,
        tau_f: 0.010,
        cs0: 4.8e-13,
        tau_s: 0.30,
        ps: 1.0e6,
        dt: 1.0e-4,
    };

    /// Oil volume of one hose, pi a^2 l, m^3.
    pub fn v_hose(&self) -> f64 {
        std::f64::consts::PI * self.a * self.a * self.l
    }

    /// Compliance stiffening factor f(P) = 1 / (1 + max(P, -0.9 Ps)/Ps).
    pub fn f(&self, p: f64) -> f64 {
        1.0 / (1.0 + p.max(-0.9 * self.ps) / self.ps)
    }

    /// Integrated stiffening L(P) = Ps ln(1 + max(P, -0.9 Ps)/Ps), Pa.
    pub fn l_of(&self, p: f64) -> f64 {
        self.ps * (p.max(-0.9 * self.ps) / self.ps).ln_1p()
    }

    /// Adiabatic accumulator pressure at gas volume `vg`, Pa gauge.
    pub fn pacc(&self, vg: f64) -> f64 {
        (self.p_acc0 + self.p_atm) * (self.v_gas0 / vg).powf(self.n_poly) - self.p_atm
    }

    /// Line-1 volume at (Xi, Xo), m^3.
    pub fn v1(&self, xi: f64, xo: f64) -> f64 {
        2.0 * self.v_dead
            + self.ap1 * (self.x_max - xi)
            + self.aa1 * (xo - self.x_min)
            + self.v_hose()
            + self.v_fit
    }

    /// Line-2 volume at (Xi, Xo), m^3.
    pub fn v2(&self, xi: f64, xo: f64) -> f64 {
        2.0 * self.v_dead
            + self.ap2 * (xi - self.x_min)
            + self.aa2 * (self.x_max - xo)
            + self.v_hose()
            + self.v_fit
    }

    /// Hydraulic force on the power piston, N (+ = towards extension):
    /// the full bore (line 2) pushes it out, the annulus (line 1) back.
    pub fn power_piston_force(&self, p1: f64, p2: f64) -> f64 {
        self.ap2 * p2 - self.ap1 * p1
    }
}

/// Indices of the state vector: the 11 nominal states of plant.md section 2
/// first, then the states the effects of this family add.
pub mod ix {
    /// Power piston (motor side, encoder) position, m.
    pub const XI: usize = 0;
    /// Its speed, m/s.
    pub const VI: usize = 1;
    /// Actuating piston position, m.
    pub const XO: usize = 2;
    /// Its speed, m/s.
    pub const VO: usize = 3;
    /// Line-1 pressure, Pa.
    pub const P1: usize = 4;
    /// Line-2 pressure, Pa.
    pub const P2: usize = 5;
    /// Hose-1 fast relaxation volume, m^3.
    pub const VF1: usize = 6;
    /// Hose-1 creep volume, m^3.
    pub const VS1: usize = 7;
    /// Hose-2 fast relaxation volume, m^3.
    pub const VF2: usize = 8;
    /// Hose-2 creep volume, m^3.
    pub const VS2: usize = 9;
    /// Accumulator gas volume, m^3.
    pub const VG: usize = 10;
    /// Power piston position behind a coupling with play or compliance, m.
    pub const XP: usize = 11;
    /// Its speed, m/s.
    pub const VP: usize = 12;
    /// Hysteretic (Dahl) force state of a compliant coupling, N.
    pub const ZC: usize = 13;
    /// LuGre bristle deflection, m.
    pub const ZF: usize = 14;
    /// Free air in line 1 (normal volume at P_atm), m^3.
    pub const NA1: usize = 15;
    /// Free air in line 2, m^3.
    pub const NA2: usize = 16;
    /// Bouc-Wen state of hose 1 (dimensionless).
    pub const BW1: usize = 17;
    /// Bouc-Wen state of hose 2.
    pub const BW2: usize = 18;
    /// First of the 5 stop-operator states of hose 1, Pa.
    pub const ST1: usize = 19;
    /// First of the 5 stop-operator states of hose 2, Pa.
    pub const ST2: usize = 24;
    /// Accumulator gas temperature, K.
    pub const TG: usize = 29;
    /// Accumulator wall temperature, K.
    pub const TW: usize = 30;
    /// Drive's speed reference (its first-order command shaping), m/s.
    pub const VREF: usize = 31;
    /// Drive's speed-loop integrator (a force), N.
    pub const IDRV: usize = 32;
    /// LVDT demodulator filter output, m.
    pub const LV1: usize = 33;
    /// Its derivative, m/s.
    pub const LV2: usize = 34;
    /// Line-1 pressure sensor membrane reading, Pa.
    pub const PM1: usize = 35;
    /// Its rate, Pa/s.
    pub const PM1D: usize = 36;
    /// Line-2 pressure sensor membrane reading, Pa.
    pub const PM2: usize = 37;
    /// Its rate, Pa/s.
    pub const PM2D: usize = 38;
    /// Length of the state vector.
    pub const NX: usize = 39;
}
