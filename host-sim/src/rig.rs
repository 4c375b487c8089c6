//! A rig: the plant with unmodelled effects switched on ([`crate::effects`]).
//!
//! The effects enter the plant's equations (plant.md section 4) at these places:
//!
//! * `leakage`: Q1 -= Ql, Q2 += Ql with Ql = G (P1 - P2);
//! * `friction`: the Stribeck force is added to the actuating piston's forces;
//! * `backlash`: the power piston (position xp, an extra state) follows the
//!   motor (the encoder's Xi) only when the play is taken up; the line volumes
//!   and flows use xp and its velocity;
//! * `air`: the oil compressibility V/beta_e of each line becomes V/beta_eff(P);
//! * `motor_limit`: the servo's speed target is cut along the torque-speed line
//!   by the hydraulic force on the power piston, and its acceleration limited;
//! * `hose_hysteresis`: a play operator on each line pressure (extra states h1,
//!   h2) adds its compliance to the line's capacitance while engaged;
//! * `accumulator_thermal`: the gas temperature T (an extra state) relaxes to
//!   ambient; P_acc,abs = P0_abs (V0/Vg) (T/T0);
//! * `sensor_delay` acts on the readings, not here (see [`crate::sensors`]).
//!
//! With no effect active [`Rig::step`] is [`Plant::step`], bit for bit.
//! `air` and `hose_hysteresis` change the explicit pressure equation and are
//! defined for the `nonlinear`, `linear` and `rigid` hoses only.

use crate::effects::{self, Effects, T_AMBIENT_K};
use crate::plant::{HoseModel, Plant, State, N_STATES};

/// Number of extra states the effects carry.
pub const N_EXT: usize = 4;

/// Extra states of the effects (unused ones stay at their initial value).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Ext {
    /// Power piston position behind the play (`backlash`), m.
    pub xp_m: f64,
    /// Play-operator outputs of the line pressures (`hose_hysteresis`), Pa.
    pub h_pa: [f64; 2],
    /// Accumulator gas temperature (`accumulator_thermal`), K.
    pub t_gas_k: f64,
}

impl Ext {
    fn as_array(&self) -> [f64; N_EXT] {
        [self.xp_m, self.h_pa[0], self.h_pa[1], self.t_gas_k]
    }

    fn from_array(a: [f64; N_EXT]) -> Self {
        Self {
            xp_m: a[0],
            h_pa: [a[1], a[2]],
            t_gas_k: a[3],
        }
    }
}

/// The state of a rig: the plant's state and the effects' extra states.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RigState {
    /// The plant state (Xi is the motor / encoder position).
    pub x: State,
    /// The effects' states.
    pub ext: Ext,
}

impl RigState {
    /// True if every entry is finite.
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.ext.as_array().iter().all(|v| v.is_finite())
    }
}

/// The plant with effects.
#[derive(Clone, Debug)]
pub struct Rig {
    plant: Plant,
    effects: Effects,
    /// No effect acts on the plant's equations (none, or only `sensor_delay`):
    /// [`Rig::step`] is [`Plant::step`]. Decided once, not per step.
    plant_only: bool,
}

/// Why effects cannot be combined with a plant.
#[derive(Clone, Debug, PartialEq)]
pub struct RigError(pub String);

impl std::fmt::Display for RigError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for RigError {}

impl Rig {
    /// A rig from a plant and effects (validated).
    pub fn new(plant: Plant, effects: Effects) -> Result<Self, RigError> {
        effects.validate().map_err(RigError)?;
        let explicit = matches!(
            plant.hose_model(),
            HoseModel::Nonlinear | HoseModel::Linear | HoseModel::Rigid
        );
        if !explicit && (effects.air.is_some() || effects.hose_hysteresis.is_some()) {
            return Err(RigError(format!(
                "effects air and hose_hysteresis need an explicit hose model (nonlinear, linear or rigid), not {}",
                plant.hose_model().name()
            )));
        }
        let plant_only = Effects {
            sensor_delay: None,
            ..effects
        }
        .is_none();
        Ok(Self {
            plant,
            effects,
            plant_only,
        })
    }

    /// The nominal plant.
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The effects.
    pub fn effects(&self) -> &Effects {
        &self.effects
    }

    /// Rest state (plant.md 4.1) with the effects' states at rest.
    pub fn initial_state(&self, ft0_n: f64) -> RigState {
        let x = self.plant.initial_state(ft0_n);
        RigState {
            x,
            ext: Ext {
                xp_m: x.xi_m,
                h_pa: [x.p1_pa, x.p2_pa],
                t_gas_k: T_AMBIENT_K,
            },
        }
    }

    /// Line capacitance V/beta + Ce(P) of the explicit hose models, m^3/Pa.
    fn capacitance(&self, p_pa: f64, v_m3: f64) -> f64 {
        let p = self.plant.params();
        let h = &p.hose;
        let ce = match self.plant.hose_model() {
            HoseModel::Nonlinear => h.ce0_m3pp * h.stiffening(p_pa),
            HoseModel::Linear => h.ce0_m3pp * h.stiffening(p.p_nom_pa),
            _ => 0.0,
        };
        v_m3 / p.beta_e_pa + ce
    }

    /// Right-hand side of the plant and of the effects' states.
    pub fn derivative(
        &self,
        s: &RigState,
        v_cmd_mps: f64,
        ft_n: f64,
    ) -> ([f64; N_STATES], [f64; N_EXT]) {
        let e = &self.effects;
        let p = self.plant.params();
        let mut x = s.x;
        // Servo (motor side): target, torque-speed cut, acceleration limit.
        let vc = v_cmd_mps.clamp(-p.v_max_mps, p.v_max_mps);
        let mut dvi = (vc - x.vi_mps) / p.tau_m_s;
        // Power piston behind the play.
        let (xp, vp) = match &e.backlash {
            Some(b) => (
                s.ext.xp_m,
                effects::play_rate(x.xi_m, s.ext.xp_m, x.vi_mps, b.play_m),
            ),
            None => (x.xi_m, x.vi_mps),
        };
        if let Some(m) = &e.motor_limit {
            let f_load = p.ap1_m2 * x.p1_pa - p.ap2_m2 * x.p2_pa;
            let target = effects::motor_speed_target(m, vc, f_load);
            dvi = effects::motor_accel(m, (target - x.vi_mps) / p.tau_m_s);
        }
        let motor = (x.xi_m, x.vi_mps);
        x.xi_m = xp;
        x.vi_mps = vp;
        let mut fo = self.plant.forces_n(&x, ft_n);
        if let Some(f) = &e.friction {
            fo += effects::friction_force_n(f, x.vo_mps);
        }
        let flows = self.plant.flows(&x);
        let (mut q1, mut q2, mut qa) = (flows.q1_m3ps, flows.q2_m3ps, flows.qa_m3ps);
        let mut dt_gas = 0.0;
        if let Some(th) = &e.accumulator_thermal {
            // Gas law with temperature: P_abs = P0_abs (V0 / Vg) (T / T0).
            let p_abs0 = p.p_acc0_pa + p.p_atm_pa;
            let pacc =
                p_abs0 * (p.v_gas0_m3 / x.vg_m3) * (s.ext.t_gas_k / T_AMBIENT_K) - p.p_atm_pa;
            let qa_t = p.g_acc_m3pspa * (pacc - x.p2_pa);
            q2 += qa_t - qa;
            qa = qa_t;
            // Adiabatic compression heats the gas (dVg = qa), exchange relaxes it.
            dt_gas = -(p.n_poly - 1.0) * s.ext.t_gas_k * qa / x.vg_m3
                + (T_AMBIENT_K - s.ext.t_gas_k) / th.tau_s;
        }
        if let Some(l) = &e.leakage {
            let ql = effects::leak_flow_m3ps(l, x.p1_pa, x.p2_pa);
            q1 -= ql;
            q2 += ql;
        }
        let mut r = self.plant.pressure_rates(&x, q1, q2);
        let mut dh = [0.0; 2];
        if e.air.is_some() || e.hose_hysteresis.is_some() {
            let (v1, v2) = self.plant.line_volumes(x.xi_m, x.xo_m);
            let lines = [(x.p1_pa, v1), (x.p2_pa, v2)];
            for (j, (pj, vj)) in lines.into_iter().enumerate() {
                let c_nom = self.capacitance(pj, vj);
                let mut c = c_nom;
                if let Some(a) = &e.air {
                    c += vj
                        * (effects::compressibility_ppa(a, p.beta_e_pa, pj, p.p_atm_pa)
                            - 1.0 / p.beta_e_pa);
                }
                let dp_nom = if j == 0 { r.dp1_paps } else { r.dp2_paps };
                let mut dp = dp_nom * c_nom / c;
                if let Some(h) = &e.hose_hysteresis {
                    // Engaged in the direction the pressure moves: extra compliance.
                    if effects::play_rate(pj, s.ext.h_pa[j], dp, 2.0 * h.half_width_pa) != 0.0 {
                        dp = dp_nom * c_nom / (c + h.c_m3pp);
                        dh[j] = dp;
                    }
                }
                if j == 0 {
                    r.dp1_paps = dp;
                } else {
                    r.dp2_paps = dp;
                }
            }
        }
        let d = [
            motor.1,
            dvi,
            x.vo_mps,
            fo / p.m_kg,
            r.dp1_paps,
            r.dp2_paps,
            r.dvf1_m3ps,
            r.dvs1_m3ps,
            r.dvf2_m3ps,
            r.dvs2_m3ps,
            qa,
        ];
        (d, [vp, dh[0], dh[1], dt_gas])
    }

    /// One RK4 step with inputs held (plant.md 4.2), software limit first.
    pub fn step(&self, s: &mut RigState, v_cmd_mps: f64, ft_n: f64, dt_s: f64) {
        if self.plant_only {
            self.plant.step(&mut s.x, v_cmd_mps, ft_n, dt_s);
            return;
        }
        let v = self.plant.software_limited_v_cmd(s.x.xi_m, v_cmd_mps);
        let (x0, e0) = (s.x.as_array(), s.ext.as_array());
        let at = |dx: &[f64; N_STATES], de: &[f64; N_EXT], h: f64| RigState {
            x: State::from_array(std::array::from_fn(|i| x0[i] + h * dx[i])),
            ext: Ext::from_array(std::array::from_fn(|i| e0[i] + h * de[i])),
        };
        let (k1, l1) = self.derivative(s, v, ft_n);
        let (k2, l2) = self.derivative(&at(&k1, &l1, 0.5 * dt_s), v, ft_n);
        let (k3, l3) = self.derivative(&at(&k2, &l2, 0.5 * dt_s), v, ft_n);
        let (k4, l4) = self.derivative(&at(&k3, &l3, dt_s), v, ft_n);
        let sixth = dt_s / 6.0;
        s.x = State::from_array(std::array::from_fn(|i| {
            x0[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
        }));
        s.ext = Ext::from_array(std::array::from_fn(|i| {
            e0[i] + sixth * (l1[i] + 2.0 * l2[i] + 2.0 * l3[i] + l4[i])
        }));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::EffectKind;

    fn rig(k: Option<(EffectKind, &[f64])>) -> Rig {
        let mut e = Effects::NONE;
        if let Some((k, v)) = k {
            e.set(k, Some(v));
        }
        Rig::new(Plant::nominal(), e).unwrap()
    }

    /// Move out at 20 mm/s for 0.5 s, hold with 800 N from 1 s; states at 3 s.
    fn run(r: &Rig) -> Vec<RigState> {
        let mut s = r.initial_state(0.0);
        let mut out = Vec::new();
        for k in 0..30_000 {
            let t = k as f64 * 1e-4;
            let v = if t < 0.5 { 0.02 } else { 0.0 };
            let ft = if t >= 1.0 { 800.0 } else { 0.0 };
            r.step(&mut s, v, ft, 1e-4);
            if k % 1000 == 999 {
                out.push(s);
            }
        }
        out
    }

    #[test]
    fn no_effect_is_the_nominal_plant_bit_for_bit() {
        let r = rig(None);
        let p = Plant::nominal();
        let mut x = p.initial_state(0.0);
        let mut s = r.initial_state(0.0);
        for k in 0..5000 {
            let v = if k < 2000 { 0.03 } else { -0.01 };
            p.step(&mut x, v, 300.0, 1e-4);
            r.step(&mut s, v, 300.0, 1e-4);
        }
        assert_eq!(s.x, x);
        // The derivative with effects off equals the plant's, up to the order
        // of the additions (the rig adds the same terms).
        let (d, _) = r.derivative(&s, 0.05, 300.0);
        let dp = p.derivative(&x, 0.05, 300.0);
        for i in 0..N_STATES {
            assert!(
                (d[i] - dp[i]).abs() <= 1e-12 * dp[i].abs().max(1e-9),
                "{i}: {} vs {}",
                d[i],
                dp[i]
            );
        }
    }

    #[test]
    fn leakage_lets_the_load_push_the_piston_back() {
        let nominal = run(&rig(None));
        let leaky = run(&rig(Some((EffectKind::Leakage, &[1e-12]))));
        // Under 800 N (1-3 s) oil leaks from line 1: Xo sinks against Xi.
        // States every 0.1 s: index 12 is t = 1.3 s, index 29 is t = 3.0 s.
        let sag = |s: &[RigState]| s[29].x.xo_m - s[12].x.xo_m;
        assert!(
            sag(&leaky) < sag(&nominal) - 1e-4,
            "{} vs {}",
            sag(&leaky),
            sag(&nominal)
        );
    }

    #[test]
    fn backlash_delays_the_piston_behind_the_motor() {
        let r = rig(Some((EffectKind::Backlash, &[200e-6])));
        let mut s = r.initial_state(0.0);
        for _ in 0..1000 {
            r.step(&mut s, 0.02, 0.0, 1e-4);
        }
        // The piston lags the motor by the half play once it is taken up.
        let lag = s.x.xi_m - s.ext.xp_m;
        assert!((lag - 100e-6).abs() < 5e-6, "{lag:e}");
    }

    #[test]
    fn motor_limit_slows_the_servo_under_load() {
        let r = rig(Some((EffectKind::MotorLimit, &[2.0, 1500.0])));
        let mut s = r.initial_state(800.0);
        for _ in 0..2000 {
            r.step(&mut s, 0.05, 800.0, 1e-4);
        }
        let free = rig(None);
        let mut f = free.initial_state(800.0);
        for _ in 0..2000 {
            free.step(&mut f, 0.05, 800.0, 1e-4);
        }
        assert!(s.x.xi_m < 0.8 * f.x.xi_m, "{} vs {}", s.x.xi_m, f.x.xi_m);
    }

    #[test]
    fn air_and_friction_and_hysteresis_and_thermal_change_the_response() {
        let base = run(&rig(None));
        for (k, v) in [
            (EffectKind::Air, &[0.01][..]),
            (EffectKind::Friction, &[60.0, 90.0, 2e-3][..]),
            (EffectKind::HoseHysteresis, &[1e-12, 1e5][..]),
            (EffectKind::AccumulatorThermal, &[2.0][..]),
        ] {
            let with = run(&rig(Some((k, v))));
            let diff = with
                .iter()
                .zip(&base)
                .map(|(a, b)| {
                    (a.x.xo_m - b.x.xo_m).abs() / 1e-6 + (a.x.p2_pa - b.x.p2_pa).abs() / 1e3
                })
                .fold(0.0, f64::max);
            assert!(diff > 1.0, "{}: {diff}", k.name());
            assert!(with.iter().all(|s| s.is_finite()), "{}", k.name());
        }
    }

    #[test]
    fn explicit_hose_needed_for_air() {
        let mut e = Effects::NONE;
        e.set(EffectKind::Air, Some(&[0.01]));
        assert!(Rig::new(
            Plant::new(dca_core::params::PlantParams::NOMINAL, HoseModel::Rigid),
            e
        )
        .is_ok());
        e.set(EffectKind::Leakage, Some(&[-1.0]));
        assert!(Rig::new(Plant::nominal(), e).is_err());
    }
}
