//! The nominal plant of docs/model.md sections 2-4 (`hose_model = "nonlinear"`),
//! written from the specification text alone, in binary64, extended with
//! optional state entries for the foreign effects of [`super::effects`].
//!
//! The state vector holds the 11 nominal states of docs/model.md section 2 at the
//! indices [`XI`] ... [`VG`] and, after them, the states some effects need
//! (they stay at their initial value when the effect is absent).
//!
//! Integrator: classical RK4 with inputs held over a base tick of
//! [`BASE_DT`] = 1e-4 s (docs/model.md section 4.2), but taken in
//! [`SUBSTEPS`] = 2 sub-steps of 5e-5 s each. The step function itself is
//! generic in the step length, so the one-step vector of section 4.2
//! (dt = 1e-4 s) can be checked too.

use super::effects::Effects;

/// Equivalent moving mass, kg.
pub const M: f64 = 50.0;
/// Power cylinder annulus (line 1), m^2.
pub const AP1: f64 = 3.77e-4;
/// Power cylinder full bore (line 2), m^2.
pub const AP2: f64 = 4.91e-4;
/// Actuating cylinder full bore (line 1), m^2.
pub const AA1: f64 = 3.14e-4;
/// Actuating cylinder annulus (line 2), m^2.
pub const AA2: f64 = 2.01e-4;
/// Viscous friction of the actuating piston, N s/m.
pub const C_VISC: f64 = 200.0;
/// Hose mean radius, m.
pub const HOSE_A: f64 = 0.003;
/// Hose length, m.
pub const HOSE_L: f64 = 1.0;
/// Oil volume of one hose, m^3.
pub const V_HOSE: f64 = std::f64::consts::PI * HOSE_A * HOSE_A * HOSE_L;
/// Oil bulk modulus, Pa.
pub const BETA_E: f64 = 1.2e9;
/// Lower stroke end, m.
pub const X_MIN: f64 = -0.010;
/// Upper stroke end, m.
pub const X_MAX: f64 = 0.110;
/// Dead volume per chamber end, m^3.
pub const V_DEAD: f64 = 1.0e-6;
/// Fittings volume per line, m^3.
pub const V_FIT: f64 = 1.0e-6;
/// Servo speed limit, m/s.
pub const V_MAX: f64 = 0.10;
/// Servo speed-loop time constant, s.
pub const TAU_M: f64 = 0.010;
/// Accumulator (gauge) pressure at t = 0, Pa.
pub const P_ACC0: f64 = 1.0e6;
/// Accumulator gas volume at t = 0, m^3.
pub const V_GAS0: f64 = 1.0e-4;
/// Polytropic index of the accumulator gas.
pub const N_POLY: f64 = 1.4;
/// Atmospheric pressure, Pa.
pub const P_ATM: f64 = 101_325.0;
/// Accumulator restrictor conductance, m^3/(s Pa).
pub const G_ACC: f64 = 5.0e-10;
/// End-stop stiffness, N/m.
pub const K_STOP: f64 = 1.0e7;
/// End-stop damping, N s/m.
pub const C_STOP: f64 = 2.0e4;
/// Instantaneous hose wall compliance at P = 0, m^3/Pa.
pub const CE0: f64 = 1.2e-13;
/// Fast relaxation compliance at P = 0, m^3/Pa.
pub const CF0: f64 = 1.2e-13;
/// Fast relaxation time constant, s.
pub const TAU_F: f64 = 0.010;
/// Creep compliance at P = 0, m^3/Pa.
pub const CS0: f64 = 4.8e-13;
/// Creep time constant, s.
pub const TAU_S: f64 = 0.30;
/// Hose stiffening pressure, Pa.
pub const PS: f64 = 1.0e6;

/// Base tick (controller tick, input hold interval), s.
pub const BASE_DT: f64 = 1.0e-4;
/// RK4 sub-steps per base tick (5e-5 s each).
pub const SUBSTEPS: u32 = 2;

/// Power piston (nominal) or motor nut (with backlash) position, m; what the encoder reads.
pub const XI: usize = 0;
/// Velocity of [`XI`], m/s.
pub const VI: usize = 1;
/// Actuating piston position, m.
pub const XO: usize = 2;
/// Actuating piston velocity, m/s.
pub const VO: usize = 3;
/// Line-1 pressure (gauge), Pa.
pub const P1: usize = 4;
/// Line-2 pressure (gauge), Pa.
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
/// LuGre bristle deflection (friction effect), m.
pub const LG_Z: usize = 11;
/// Power piston position behind the play (backlash effect), m.
pub const XP: usize = 12;
/// Power piston velocity behind the play (backlash effect), m/s.
pub const VP: usize = 13;
/// Bouc-Wen hysteretic pressure of hose 1 (hose hysteresis effect), Pa.
pub const BW1: usize = 14;
/// Bouc-Wen hysteretic pressure of hose 2, Pa.
pub const BW2: usize = 15;
/// Accumulator gas temperature (thermal effect), K.
pub const TG: usize = 16;
/// Accumulator liner/wall temperature (thermal effect), K.
pub const TW: usize = 17;
/// LVDT demodulator filter output (sensor delay effect), m.
pub const YF: usize = 18;
/// LVDT demodulator filter output rate, m/s.
pub const YFD: usize = 19;
/// Length of the state vector.
pub const N_STATE: usize = 20;

/// The plant state (nominal states first, then effect states).
pub type State = [f64; N_STATE];

/// Ambient and initial gas temperature, K (only the thermal effect uses it).
pub const T_AMB: f64 = 293.15;

/// Hose stiffening factor f(P) = 1 / (1 + max(P, -0.9 Ps)/Ps).
#[inline]
pub fn stiff(p: f64) -> f64 {
    1.0 / (1.0 + p.max(-0.9 * PS) / PS)
}

/// L(P) = Ps ln(1 + max(P, -0.9 Ps)/Ps), Pa.
#[inline]
pub fn log_p(p: f64) -> f64 {
    PS * (p.max(-0.9 * PS) / PS).ln_1p()
}

/// Nominal (adiabatic, n = 1.4) accumulator gauge pressure at gas volume `vg`, Pa.
#[inline]
pub fn pacc_adiabatic(vg: f64) -> f64 {
    (P_ACC0 + P_ATM) * (V_GAS0 / vg).powf(N_POLY) - P_ATM
}

/// Line volumes (V1, V2) at power piston position `xp` and actuating piston `xo`, m^3.
#[inline]
pub fn line_volumes(xp: f64, xo: f64) -> (f64, f64) {
    let v1 = 2.0 * V_DEAD + AP1 * (X_MAX - xp) + AA1 * (xo - X_MIN) + V_HOSE + V_FIT;
    let v2 = 2.0 * V_DEAD + AP2 * (xp - X_MIN) + AA2 * (X_MAX - xo) + V_HOSE + V_FIT;
    (v1, v2)
}

/// Rest state of docs/model.md section 4.1 for the load `ft0`; the effect states
/// start at their equilibrium (zero deflections, ambient temperatures).
pub fn initial_state(ft0: f64) -> State {
    let mut x = [0.0; N_STATE];
    let p2 = P_ACC0;
    let p1 = (AA2 * p2 + ft0) / AA1;
    x[P1] = p1;
    x[P2] = p2;
    x[VF1] = CF0 * log_p(p1);
    x[VS1] = CS0 * log_p(p1);
    x[VF2] = CF0 * log_p(p2);
    x[VS2] = CS0 * log_p(p2);
    x[VG] = V_GAS0;
    x[TG] = T_AMB;
    x[TW] = T_AMB;
    x
}

/// Hydraulic force on the power piston, + = extension, N.
#[inline]
pub fn power_piston_force(p1: f64, p2: f64) -> f64 {
    AP2 * p2 - AP1 * p1
}

/// Right-hand side dx/dt for the drive command `v_cmd` (m/s) and load `ft` (N).
pub fn derivative(x: &State, v_cmd: f64, ft: f64, fx: &Effects) -> State {
    let mut d = [0.0; N_STATE];
    let mut vc = v_cmd.clamp(-V_MAX, V_MAX);
    if let Some(ml) = &fx.motor_limit {
        vc = vc.clamp(-ml.v_nl, ml.v_nl);
    }
    let p1 = x[P1];
    let p2 = x[P2];
    let f_h = power_piston_force(p1, p2);

    // Servo (motor side) and the power piston the oil sees.
    let (xp, vp) = match &fx.backlash {
        Some(_) => (x[XP], x[VP]),
        None => (x[XI], x[VI]),
    };
    let a_des = (vc - x[VI]) / TAU_M;
    // Force the motor has to deliver on top of its own inertia: the coupling
    // force (backlash) or the hydraulic force on the rigidly attached piston.
    let f_res = match &fx.backlash {
        Some(b) => {
            let fc = b.coupling_force(x[XI] + fx.backlash_offset - xp, x[VI] - vp);
            d[XP] = vp;
            d[VP] = (fc + f_h - b.c_seal * vp) / b.m_piston;
            fc
        }
        None => -f_h,
    };
    d[XI] = x[VI];
    d[VI] = match &fx.motor_limit {
        Some(ml) => ml.acceleration(a_des, f_res),
        None => a_des,
    };

    // Actuating piston.
    let xo = x[XO];
    let vo = x[VO];
    let mut fs = 0.0;
    if xo > X_MAX {
        fs = -K_STOP * (xo - X_MAX) - if vo > 0.0 { C_STOP * vo } else { 0.0 };
    }
    if xo < X_MIN {
        fs = -K_STOP * (xo - X_MIN) - if vo < 0.0 { C_STOP * vo } else { 0.0 };
    }
    let f_fric = match &fx.friction {
        Some(f) => {
            let (zdot, force) = f.bristle(x[LG_Z], vo, p1, p2);
            d[LG_Z] = zdot;
            force
        }
        None => 0.0,
    };
    d[XO] = vo;
    d[VO] = (AA1 * p1 - AA2 * p2 - ft - C_VISC * vo + fs - f_fric) / M;

    // Accumulator on line 2.
    let pacc = match &fx.thermal {
        Some(th) => th.gas_pressure(x[VG], x[TG]),
        None => pacc_adiabatic(x[VG]),
    };
    let qa = G_ACC * (pacc - p2);
    let q_leak = match &fx.leakage {
        Some(l) => l.flow(p1 - p2),
        None => 0.0,
    };
    let q1 = AP1 * vp - AA1 * vo - q_leak;
    let q2 = AA2 * vo - AP2 * vp + qa + q_leak;

    // Hose relaxation flows.
    d[VF1] = (CF0 * log_p(p1) - x[VF1]) / TAU_F;
    d[VS1] = (CS0 * log_p(p1) - x[VS1]) / TAU_S;
    d[VF2] = (CF0 * log_p(p2) - x[VF2]) / TAU_F;
    d[VS2] = (CS0 * log_p(p2) - x[VS2]) / TAU_S;

    // Continuity of each line.
    let (v1, v2) = line_volumes(xp, xo);
    let (b1, b2) = match &fx.air {
        Some(a) => (a.bulk_modulus(p1), a.bulk_modulus(p2)),
        None => (BETA_E, BETA_E),
    };
    let n1 = q1 - d[VF1] - d[VS1];
    let n2 = q2 - d[VF2] - d[VS2];
    let (c1, c2, dz1, dz2) = match &fx.hysteresis {
        Some(bw) => {
            // dP has the sign of n (all compliances > 0), so the Bouc-Wen
            // branch is known before dP is: the equation stays explicit.
            let (ce1, dz1) = bw.element(p1, x[BW1], n1);
            let (ce2, dz2) = bw.element(p2, x[BW2], n2);
            let keep = 1.0 - bw.phi;
            (
                v1 / b1 + keep * CE0 * stiff(p1) + ce1,
                v2 / b2 + keep * CE0 * stiff(p2) + ce2,
                dz1,
                dz2,
            )
        }
        None => (
            v1 / b1 + CE0 * stiff(p1),
            v2 / b2 + CE0 * stiff(p2),
            0.0,
            0.0,
        ),
    };
    d[P1] = n1 / c1;
    d[P2] = n2 / c2;
    d[BW1] = dz1 * d[P1];
    d[BW2] = dz2 * d[P2];
    d[VG] = qa;

    if let Some(th) = &fx.thermal {
        let (dtg, dtw) = th.temperature_rates(pacc, qa, x[TG], x[TW]);
        d[TG] = dtg;
        d[TW] = dtw;
    }
    if let Some(s) = &fx.sensor_delay {
        let wn = 2.0 * std::f64::consts::PI * s.lvdt_fn_hz;
        d[YF] = x[YFD];
        d[YFD] = wn * wn * (xo - x[YF]) - 2.0 * s.lvdt_zeta * wn * x[YFD];
    }
    d
}

fn axpy(x: &State, k: &State, h: f64) -> State {
    let mut y = *x;
    for i in 0..N_STATE {
        y[i] += h * k[i];
    }
    y
}

/// One classical RK4 step of length `dt` with the inputs held.
pub fn rk4_step(x: &State, v_cmd: f64, ft: f64, fx: &Effects, dt: f64) -> State {
    let k1 = derivative(x, v_cmd, ft, fx);
    let k2 = derivative(&axpy(x, &k1, 0.5 * dt), v_cmd, ft, fx);
    let k3 = derivative(&axpy(x, &k2, 0.5 * dt), v_cmd, ft, fx);
    let k4 = derivative(&axpy(x, &k3, dt), v_cmd, ft, fx);
    let mut y = *x;
    for i in 0..N_STATE {
        y[i] += dt / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    }
    y
}

/// The plant with its effects, advanced one base tick at a time.
#[derive(Clone, Debug)]
pub struct Plant {
    /// Current state.
    pub x: State,
    /// The effects in force (resolved parameters).
    pub fx: Effects,
    /// RK4 sub-steps per base tick.
    pub substeps: u32,
}

impl Plant {
    /// A plant at rest under the load `ft0` (docs/model.md section 4.1).
    pub fn new(fx: Effects, ft0: f64) -> Self {
        let mut fx = fx;
        fx.settle(ft0);
        let x = initial_state(ft0);
        Self {
            x,
            fx,
            substeps: SUBSTEPS,
        }
    }

    /// Advance one base tick with `v_cmd` and `ft` held, after the
    /// ball-screw software limit of docs/model.md section 4.2.
    pub fn step(&mut self, v_cmd: f64, ft: f64) {
        let xi = self.x[XI];
        let v = if (xi >= X_MAX && v_cmd > 0.0) || (xi <= X_MIN && v_cmd < 0.0) {
            0.0
        } else {
            v_cmd
        };
        let h = BASE_DT / self.substeps as f64;
        for _ in 0..self.substeps {
            self.x = rk4_step(&self.x, v, ft, &self.fx, h);
        }
    }

    /// Position the LVDT converts (filtered when the sensor-delay effect is on), m.
    pub fn lvdt_signal(&self) -> f64 {
        if self.fx.sensor_delay.is_some() {
            self.x[YF]
        } else {
            self.x[XO]
        }
    }
}
