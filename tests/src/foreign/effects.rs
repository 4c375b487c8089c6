//! Foreign unmodelled effects, one family per identifier of docs/model.md section 12.
//!
//! Each form is deliberately not the textbook one a nominal-model project
//! would reach for first:
//!
//! | identifier | form here |
//! |---|---|
//! | `leakage` | turbulent (orifice) cross-piston leakage, Q ~ sign(dP) sqrt(abs(dP)), laminar below `p_t` |
//! | `friction` | LuGre bristle model on the actuating piston, Coulomb level growing with the line pressures, velocity-fading micro-damping |
//! | `backlash` | play plus Hertzian ball contact (F ~ delta^1.5) with Hunt-Crossley damping; the power piston becomes a separate mass |
//! | `air` | bulk modulus falling exponentially at low pressure, beta_e (1 - a exp(-P/p_c)) |
//! | `sensor_delay` | second-order (demodulator) low-pass on the LVDT plus a whole-tick transport delay on the pressure readings |
//! | `motor_limit` | servo force (current) limit: the speed loop's acceleration is cut to (F_max - load)/m_eq; optional flat speed cap |
//! | `hose_hysteresis` | Bouc-Wen elasto-plastic braid friction locking part of the wall compliance after each pressure reversal |
//! | `accumulator_thermal` | gas energy balance with heat exchange to a liner of finite thermal mass, itself cooled by the shell (two time constants) |

use super::plant::{self, AA1, AA2, BETA_E, N_POLY, P_ACC0, P_ATM, T_AMB, V_GAS0};

/// Orifice-type internal leakage between line 1 and line 2 (across the pistons).
///
/// Q (line 1 -> line 2) = k dP / (dP^2 + p_t^2)^(1/4): sign(dP) k sqrt(abs(dP)) for
/// abs(dP) >> p_t, laminar (k dP / sqrt(p_t)) near dP = 0 so the law stays smooth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OrificeLeakage {
    /// Orifice coefficient, m^3/(s Pa^0.5).
    pub k: f64,
    /// Laminar-turbulent transition pressure, Pa.
    pub p_t: f64,
}

impl OrificeLeakage {
    /// Leakage flow from line 1 to line 2 for dP = P1 - P2, m^3/s.
    pub fn flow(&self, dp: f64) -> f64 {
        self.k * dp / (dp * dp + self.p_t * self.p_t).sqrt().sqrt()
    }
}

/// LuGre friction on the actuating piston (on top of the nominal viscous term).
///
/// dz/dt = v - sigma0 abs(v) z / g(v, P),
/// g = Fc(P) (1 + (r_s - 1) exp(-(v/v_s)^2)), Fc(P) = fc0 + k_p (P1 + P2)/2,
/// F = sigma0 z + sigma1 exp(-(v/v_d)^2) dz/dt.
///
/// The bristle equation is stiff when the presliding distance Fc/sigma0 is
/// small against v dt: keep Fc/sigma0 >= 5 um for the default step
/// ([`Self::presliding`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LuGreFriction {
    /// Coulomb level at zero line pressure, N.
    pub fc0: f64,
    /// Growth of the Coulomb level with the mean line pressure, N/Pa.
    pub k_p: f64,
    /// Static/Coulomb ratio.
    pub r_s: f64,
    /// Stribeck velocity, m/s.
    pub v_s: f64,
    /// Bristle stiffness, N/m.
    pub sigma0: f64,
    /// Bristle micro-damping, N s/m.
    pub sigma1: f64,
    /// Velocity over which the micro-damping fades, m/s.
    pub v_d: f64,
}

impl LuGreFriction {
    /// Smallest presliding distance fc0/sigma0 (Coulomb level at 0 Pa), m.
    pub fn presliding(&self) -> f64 {
        self.fc0 / self.sigma0
    }

    /// (dz/dt, friction force opposing motion) at bristle state `z`, velocity `v`.
    pub fn bristle(&self, z: f64, v: f64, p1: f64, p2: f64) -> (f64, f64) {
        let fc = self.fc0 + self.k_p * 0.5 * (p1.max(0.0) + p2.max(0.0));
        let r = v / self.v_s;
        let g = fc * (1.0 + (self.r_s - 1.0) * (-r * r).exp());
        let zdot = v - self.sigma0 * v.abs() * z / g;
        let q = v / self.v_d;
        let f = self.sigma0 * z + self.sigma1 * (-q * q).exp() * zdot;
        (zdot, f)
    }
}

/// Ball-screw play with Hertzian contact between the motor nut (encoder) and
/// the power piston, which becomes a mass of its own.
///
/// Penetration delta = abs(d) - play/2 with d = motor - piston (+ the rest
/// offset); contact force k_h delta^1.5 (1 + hc_s d(delta)/dt), never pulling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HertzPlay {
    /// Total play, m.
    pub play: f64,
    /// Hertz contact constant, N/m^1.5.
    pub k_h: f64,
    /// Hunt-Crossley damping lambda/k_h (multiplies the penetration rate), s/m.
    pub hc_s: f64,
    /// Power piston + rod mass, kg.
    pub m_piston: f64,
    /// Power piston seal viscous friction, N s/m.
    pub c_seal: f64,
}

impl HertzPlay {
    /// Force on the piston (+ = extension) for motor-minus-piston `d` and its rate `dd`.
    pub fn coupling_force(&self, d: f64, dd: f64) -> f64 {
        let g = 0.5 * self.play;
        if d > g {
            let delta = d - g;
            (self.k_h * delta * delta.sqrt() * (1.0 + self.hc_s * dd)).max(0.0)
        } else if d < -g {
            let delta = -d - g;
            -(self.k_h * delta * delta.sqrt() * (1.0 - self.hc_s * dd)).max(0.0)
        } else {
            0.0
        }
    }

    /// The static deflection d that carries the force `f` (+ = pushing the piston out).
    pub fn offset_for(&self, f: f64) -> f64 {
        if f == 0.0 {
            return 0.0;
        }
        let delta = (f.abs() / self.k_h).powf(2.0 / 3.0);
        f.signum() * (0.5 * self.play + delta)
    }
}

/// Entrained air as an effective bulk modulus falling exponentially at low pressure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AirExp {
    /// Fractional loss of stiffness at 0 Pa gauge (0 .. 1).
    pub a: f64,
    /// Pressure scale over which the stiffness recovers, Pa.
    pub p_c: f64,
}

impl AirExp {
    /// beta_eff(P) = beta_e (1 - a exp(-max(P, 0)/p_c)), Pa.
    pub fn bulk_modulus(&self, p: f64) -> f64 {
        BETA_E * (1.0 - self.a * (-p.max(0.0) / self.p_c).exp())
    }
}

/// Sensor dynamics: demodulator low-pass on the LVDT and transport delay on
/// the pressure readings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorLag {
    /// Natural frequency of the second-order LVDT filter, Hz.
    pub lvdt_fn_hz: f64,
    /// Damping ratio of the LVDT filter.
    pub lvdt_zeta: f64,
    /// Whole base ticks (1e-4 s) by which the pressure readings are late.
    pub p_delay_ticks: usize,
}

/// Servo force (current) limit, optionally with a low no-load speed
/// (supply voltage): the drive's speed loop target is capped at `v_nl`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ForceLimit {
    /// Rotor inertia reflected to the ball-screw axis, kg.
    pub m_eq: f64,
    /// Largest axial force the drive can produce, N.
    pub f_max: f64,
    /// Highest speed the drive reaches (flat cap, independent of the load), m/s.
    pub v_nl: f64,
}

impl ForceLimit {
    /// Acceleration the drive achieves when its speed loop asks for `a_des`
    /// against the resisting force `f_res` (N, + = resisting extension).
    pub fn acceleration(&self, a_des: f64, f_res: f64) -> f64 {
        let f = (self.m_eq * a_des + f_res).clamp(-self.f_max, self.f_max);
        (f - f_res) / self.m_eq
    }
}

/// Bouc-Wen braid friction in each hose wall.
///
/// A share `phi` of the instantaneous wall compliance Ce0 f(P) sits behind an
/// elasto-plastic (Bouc-Wen) element: right after a pressure reversal that
/// share is stiff (compliance `rho` phi Ce0 f(P)); it yields smoothly as the
/// hysteretic pressure z approaches `z_max`, where the full compliance is
/// back. With s = sign(dP/dt) and k = 1/rho - 1:
///
/// g = 1 - abs(z)/z_max (b sign(s z) + 1 - b),
/// element compliance = phi Ce0 f(P) / (1 + k g), dz/dP = k g / (1 + k g).
///
/// Rate-independent and dissipative (the wall volume lags the pressure); on
/// monotonic loading far from a reversal the hose is the nominal one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoucWenHose {
    /// Share of the instantaneous wall compliance behind the friction element (0 .. 1).
    pub phi: f64,
    /// Pre-yield over post-yield compliance of that share (0 < rho < 1).
    pub rho: f64,
    /// Yield (saturation) level of the hysteretic pressure z, Pa.
    pub z_max: f64,
    /// Share b of the sign-dependent Bouc-Wen term (0.5: classic symmetric form).
    pub b: f64,
}

impl BoucWenHose {
    /// (element compliance m^3/Pa, dz/dP) at line pressure `p`, state `z`,
    /// when dP/dt has the sign of `n`.
    pub fn element(&self, p: f64, z: f64, n: f64) -> (f64, f64) {
        let s = if z * n > 0.0 {
            1.0
        } else if z * n < 0.0 {
            -1.0
        } else {
            0.0
        };
        let g = (1.0 - z.abs() / self.z_max * (self.b * s + 1.0 - self.b)).max(0.0);
        let k = 1.0 / self.rho - 1.0;
        let c_post = self.phi * plant::CE0 * plant::stiff(p);
        (c_post / (1.0 + k * g), k * g / (1.0 + k * g))
    }
}

/// Accumulator gas energy balance with a liner of finite thermal mass.
///
/// m c_v dTg/dt = -P_abs dVg/dt - H_gw (Tg - Tw); C_w dTw/dt = H_gw (Tg - Tw) - H_wa (Tw - T_amb),
/// ideal gas P_abs = m R Tg / Vg, c_p/c_v = 1.4 (the nominal adiabatic law is the
/// limit H_gw -> 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GasWallThermal {
    /// Gas-to-liner time constant m c_v / H_gw, s.
    pub tau_gas_s: f64,
    /// Liner thermal mass over the gas's, C_w / (m c_v).
    pub wall_ratio: f64,
    /// Liner-to-shell time constant C_w / H_wa, s.
    pub tau_wall_s: f64,
}

impl GasWallThermal {
    fn mr() -> f64 {
        (P_ACC0 + P_ATM) * V_GAS0 / T_AMB
    }

    /// Gauge gas pressure at volume `vg` and temperature `tg`, Pa.
    pub fn gas_pressure(&self, vg: f64, tg: f64) -> f64 {
        Self::mr() * tg / vg - P_ATM
    }

    /// (dTg/dt, dTw/dt) for the gauge pressure `pacc` and gas volume rate `qa`.
    pub fn temperature_rates(&self, pacc: f64, qa: f64, tg: f64, tw: f64) -> (f64, f64) {
        let mcv = Self::mr() / (N_POLY - 1.0);
        let h_gw = mcv / self.tau_gas_s;
        let cw = self.wall_ratio * mcv;
        let h_wa = cw / self.tau_wall_s;
        let q_gw = h_gw * (tg - tw);
        let dtg = (-(pacc + P_ATM) * qa - q_gw) / mcv;
        let dtw = (q_gw - h_wa * (tw - T_AMB)) / cw;
        (dtg, dtw)
    }
}

/// One effect of a case.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Effect {
    /// `leakage`.
    Leakage(OrificeLeakage),
    /// `friction`.
    Friction(LuGreFriction),
    /// `backlash`.
    Backlash(HertzPlay),
    /// `air`.
    Air(AirExp),
    /// `sensor_delay`.
    SensorDelay(SensorLag),
    /// `motor_limit`.
    MotorLimit(ForceLimit),
    /// `hose_hysteresis`.
    HoseHysteresis(BoucWenHose),
    /// `accumulator_thermal`.
    AccumulatorThermal(GasWallThermal),
}

impl Effect {
    /// The identifier of docs/model.md section 12.
    pub fn identifier(&self) -> &'static str {
        match self {
            Self::Leakage(_) => "leakage",
            Self::Friction(_) => "friction",
            Self::Backlash(_) => "backlash",
            Self::Air(_) => "air",
            Self::SensorDelay(_) => "sensor_delay",
            Self::MotorLimit(_) => "motor_limit",
            Self::HoseHysteresis(_) => "hose_hysteresis",
            Self::AccumulatorThermal(_) => "accumulator_thermal",
        }
    }

    /// Form and parameters in one line.
    pub fn describe(&self) -> String {
        match self {
            Self::Leakage(l) => format!(
                "orifice leakage k = {:.3e} m^3/(s Pa^0.5), p_t = {:.0} kPa",
                l.k,
                l.p_t / 1e3
            ),
            Self::Friction(f) => format!(
                "LuGre fc0 = {} N, k_p = {} N/MPa, Fs/Fc = {}, v_s = {} mm/s, sigma0 = {:.1e} N/m, sigma1 = {} N s/m, v_d = {} mm/s",
                f.fc0,
                f.k_p * 1e6,
                f.r_s,
                f.v_s * 1e3,
                f.sigma0,
                f.sigma1,
                f.v_d * 1e3
            ),
            Self::Backlash(b) => format!(
                "play {} um, Hertz k_h = {:.1e} N/m^1.5, Hunt-Crossley {} s/m, piston {} kg, seal {} N s/m",
                b.play * 1e6,
                b.k_h,
                b.hc_s,
                b.m_piston,
                b.c_seal
            ),
            Self::Air(a) => format!(
                "beta_e (1 - {} exp(-P / {} MPa))",
                a.a,
                a.p_c / 1e6
            ),
            Self::SensorDelay(s) => format!(
                "LVDT 2nd-order fn = {} Hz zeta = {}, pressure delay {} x 0.1 ms",
                s.lvdt_fn_hz, s.lvdt_zeta, s.p_delay_ticks
            ),
            Self::MotorLimit(m) => format!(
                "force limit {} N, m_eq = {} kg, speed cap {} mm/s",
                m.f_max,
                m.m_eq,
                m.v_nl * 1e3
            ),
            Self::HoseHysteresis(h) => format!(
                "Bouc-Wen braid friction on {} of Ce0, pre/post-yield compliance {}, z_max = {} kPa, b = {}",
                h.phi,
                h.rho,
                h.z_max / 1e3,
                h.b
            ),
            Self::AccumulatorThermal(t) => format!(
                "gas-liner tau = {} s, liner/gas heat capacity = {}, liner-shell tau = {} s",
                t.tau_gas_s, t.wall_ratio, t.tau_wall_s
            ),
        }
    }
}

/// The effects in force in one run (at most one of each kind).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Effects {
    /// Cross-piston orifice leakage.
    pub leakage: Option<OrificeLeakage>,
    /// LuGre friction.
    pub friction: Option<LuGreFriction>,
    /// Play with Hertz contact.
    pub backlash: Option<HertzPlay>,
    /// Entrained air.
    pub air: Option<AirExp>,
    /// Sensor dynamics.
    pub sensor_delay: Option<SensorLag>,
    /// Servo force limit.
    pub motor_limit: Option<ForceLimit>,
    /// Bouc-Wen hose.
    pub hysteresis: Option<BoucWenHose>,
    /// Accumulator thermal dynamics.
    pub thermal: Option<GasWallThermal>,
    /// Motor-minus-piston deflection at the initial rest (backlash only), m.
    pub backlash_offset: f64,
}

impl Effects {
    /// Collect a list of effects (a later entry of the same kind replaces an earlier one).
    pub fn from_list(list: &[Effect]) -> Self {
        let mut e = Self::default();
        for eff in list {
            match *eff {
                Effect::Leakage(p) => e.leakage = Some(p),
                Effect::Friction(p) => e.friction = Some(p),
                Effect::Backlash(p) => e.backlash = Some(p),
                Effect::Air(p) => e.air = Some(p),
                Effect::SensorDelay(p) => e.sensor_delay = Some(p),
                Effect::MotorLimit(p) => e.motor_limit = Some(p),
                Effect::HoseHysteresis(p) => e.hysteresis = Some(p),
                Effect::AccumulatorThermal(p) => e.thermal = Some(p),
            }
        }
        e
    }

    /// Compute the rest deflection of the coupling for the initial load `ft0`
    /// (the motor holds the piston against the rest hydraulic force).
    pub fn settle(&mut self, ft0: f64) {
        if let Some(b) = &self.backlash {
            let p2 = P_ACC0;
            let p1 = (AA2 * p2 + ft0) / AA1;
            let f_h = plant::power_piston_force(p1, p2);
            self.backlash_offset = b.offset_for(-f_h);
        }
    }
}
