//! A rig: the plant with unmodelled effects switched on ([`crate::model::effects`]).
//!
//! The rig names no effect: the equations (docs/model.md section 4) have
//! places where an effect may add a term, and at each the rig asks every
//! active effect, in the rows' order of the catalogue, through its
//! [`RigTerms`] (implemented in the effect's part file):
//!
//! * building the rig: the plant parameters it changes
//!   ([`RigTerms::plant_params`], e.g. `parameters`: the plant is built with
//!   them), whether it suits the plant ([`RigTerms::check_plant`]), and
//!   whether it changes the equations at all ([`RigTerms::ON_EQUATIONS`];
//!   with none such on, [`Rig::step`] is [`Plant::step`]) or the lines'
//!   compliance ([`RigTerms::ON_LINES`], refused on a GRNN hose);
//! * its states: each effect carries [`RigTerms::STATES`] of its own, laid
//!   out in the rows' order ([`N_EXT`] in all, [`Ext`]), at rest as it
//!   says ([`RigTerms::rest_states`]); it reads and writes only its own;
//! * the servo's acceleration ([`RigTerms::servo_accel_mps2`], e.g.
//!   `motor_limit`; else the nominal first-order servo);
//! * a force on the actuating piston ([`RigTerms::piston_force_n`], summed,
//!   e.g. `friction`);
//! * a coupling between the motor (the encoder's Xi) and the power piston
//!   ([`RigTerms::coupling`], e.g. `backlash`): the power piston's position
//!   is one of the effect's states; the line volumes and flows use it, and
//!   its velocity solves the coupling exactly (a massless piston,
//!   [`RigTerms::power_piston_rates`]);
//! * the accumulator's gas law ([`RigTerms::accumulator_flow_m3ps`], e.g.
//!   `accumulator_thermal`: its flow, with its states' rates);
//! * a flow from line 1 to line 2 ([`RigTerms::leak_flow_m3ps`], summed, e.g.
//!   `leakage`): Q1 -= Ql, Q2 += Ql;
//! * each line's compliance ([`RigTerms::add_line_compliance`], e.g. `air`,
//!   `hose_hysteresis`): each effect in turn adds its compliance to the
//!   line's capacitance, reading the pressure rate it gives so far
//!   ([`effects::Line`]);
//! * the step: the smallest factor any effect puts on the plant's largest
//!   stable step ([`RigTerms::step_scale`], e.g. a stiffening hysteresis).
//!
//! `sensor_delay` and `sensor_calibration` (named or general) act on the
//! readings, not here (see [`crate::model::sensors`]).
//!
//! With no effect active [`Rig::step`] is [`Plant::step`], bit for bit.

#[cfg(doc)]
use crate::model::effects::RigTerms;
use crate::model::effects::{self, EffectError, EffectKind, Effects, Gas, Line, Rest};
use crate::model::plant::{HoseModel, Plant, PressureRates, State, N_STATES};

/// Number of extra states the effects carry ([`effects::EXT_STATES`]).
pub const N_EXT: usize = effects::EXT_STATES;

/// Extra states of the effects: each effect's [`RigTerms::STATES`], in the
/// rows' order of the catalogue whether the effect is on or not (those of
/// effects that are off stay at zero).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ext {
    v: [f64; N_EXT],
}

impl Default for Ext {
    fn default() -> Self {
        Self { v: [0.0; N_EXT] }
    }
}

impl Ext {
    /// Every extra state, in the rows' order.
    pub fn values(&self) -> &[f64; N_EXT] {
        &self.v
    }
}

/// The rates of a rig's state: the plant's, then the effects' extra states'.
pub type Rates = ([f64; N_STATES], [f64; N_EXT]);

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
        self.x.is_finite() && self.ext.v.iter().all(|v| v.is_finite())
    }
}

/// The plant with effects.
#[derive(Clone, Debug)]
pub struct Rig {
    plant: Plant,
    effects: Effects,
    /// No effect acts on the plant's equations (none, or only those on the
    /// readings and `parameters`, which changes the plant itself):
    /// [`Rig::step`] is [`Plant::step`]. Decided once, not per step.
    plant_only: bool,
    /// Some effect adds compliance to the lines ([`RigTerms::ON_LINES`]).
    on_lines: bool,
}

/// Why effects cannot be combined with a plant.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RigError {
    /// An effect's parameters are out of range.
    #[error(transparent)]
    Effects(#[from] EffectError),
    /// An effect on the lines' compliance on a GRNN hose (named).
    #[error(
        "effects {names} need an explicit hose model (nonlinear, linear or rigid), not {0}",
        names = line_effect_names()
    )]
    ImplicitHose(&'static str),
    /// An effect that does not suit the plant's parameters (what fails,
    /// naming the effect; e.g. `accumulator_thermal`'s general family
    /// relaxing the gas's index to zero or below, a spring of no or
    /// negative stiffness).
    #[error("{0}")]
    Unsuited(String),
}

/// The effects on the lines' compliance ([`EffectKind::on_lines`]): `a`,
/// `a and b`, `a, b and c`.
fn line_effect_names() -> String {
    let names: Vec<&str> = EffectKind::ALL
        .into_iter()
        .filter(|k| k.on_lines())
        .map(|k| k.name())
        .collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
        _ => names.concat(),
    }
}

impl Rig {
    /// A rig from a plant and effects (validated).
    pub fn new(plant: Plant, effects: Effects) -> Result<Self, RigError> {
        effects.validate()?;
        let explicit = matches!(
            plant.hose_model(),
            HoseModel::Nonlinear | HoseModel::Linear | HoseModel::Rigid
        );
        let on_lines = effects.on_lines();
        if !explicit && on_lines {
            return Err(RigError::ImplicitHose(plant.hose_model().name()));
        }
        let plant_only = !effects.on_equations();
        let plant = match effects.plant_params(plant.params()) {
            Some(p) => plant.with_params(p),
            None => plant,
        };
        effects
            .check_plant(plant.params())
            .map_err(RigError::Unsuited)?;
        Ok(Self {
            plant,
            effects,
            plant_only,
            on_lines,
        })
    }

    /// The plant (with the `parameters` effect's ratios, if on).
    pub fn plant(&self) -> &Plant {
        &self.plant
    }

    /// The effects.
    pub fn effects(&self) -> &Effects {
        &self.effects
    }

    /// Rest state (docs/model.md 4.1) with the effects' states at rest.
    pub fn initial_state(&self, ft0_n: f64) -> RigState {
        self.rest_state(ft0_n, 0.0, 0.0)
    }

    /// Rest state under the load `ft0_n` with the motor (encoder) at `xi_m`
    /// and the actuating piston at `xo_m`, the effects' states at rest
    /// ([`RigTerms::rest_states`]: e.g. behind a backlash the power piston
    /// rests on the flank the hydraulic force holds it against).
    pub fn rest_state(&self, ft0_n: f64, xi_m: f64, xo_m: f64) -> RigState {
        let mut x = self.plant.initial_state(ft0_n);
        x.xi_m = xi_m;
        x.xo_m = xo_m;
        let mut ext = Ext::default();
        let rest = Rest {
            xi_m,
            piston_force_n: self.piston_force_n(&x),
        };
        self.effects.rest_states(rest, &mut ext.v);
        RigState { x, ext }
    }

    /// The power piston's position in the state `s` where an effect puts a
    /// coupling between it and the motor ([`RigTerms::coupling`]), m.
    pub fn power_piston_m(&self, s: &RigState) -> Option<f64> {
        let f_n = self.piston_force_n(&s.x);
        self.effects.coupling(&s.ext.v, f_n).map(|c| c.xp_m)
    }

    /// Factor (at most 1) on the largest stable plant step: the fastest mode
    /// (the actuating piston against the lines' hydraulic stiffness) scales
    /// with the inverse of the line capacitance, which an effect may lower
    /// ([`RigTerms::step_scale`]). Taken where that matters most: zero
    /// pressure (the wall at its softest) and the smallest oil volume.
    pub fn step_scale(&self) -> f64 {
        let p = self.plant.params();
        let (v_min, _) = self.plant.line_volumes(p.x_max_m, p.x_min_m);
        let (c_oil, c_wall) = self.capacitance(0.0, v_min);
        self.effects.step_scale(c_oil, c_wall)
    }

    /// Hydraulic force on the power piston, positive opposing extension, N.
    fn piston_force_n(&self, x: &State) -> f64 {
        self.plant.piston_force_n(x.p1_pa, x.p2_pa)
    }

    /// Line capacitance of the explicit hose models, m^3/Pa: the oil's
    /// V/beta and the hose wall's Ce(P).
    fn capacitance(&self, p_pa: f64, v_m3: f64) -> (f64, f64) {
        let p = self.plant.params();
        let h = &p.hose;
        let ce = match self.plant.hose_model() {
            HoseModel::Nonlinear => h.ce0_m3pp * h.stiffening(p_pa),
            HoseModel::Linear => h.ce0_m3pp * h.stiffening(p.p_nom_pa),
            _ => 0.0,
        };
        (v_m3 / p.beta_e_pa, ce)
    }

    /// Right-hand side of the plant and of the effects' states.
    pub fn derivative(&self, s: &RigState, v_cmd_mps: f64, ft_n: f64) -> Rates {
        let mut out = ([0.0; N_STATES], [0.0; N_EXT]);
        self.derivative_into(s, v_cmd_mps, ft_n, &mut out);
        out
    }

    /// [`Rig::derivative`] into `out` (the effects' rates zero before): the
    /// steps build it in place.
    fn derivative_into(&self, s: &RigState, v_cmd_mps: f64, ft_n: f64, out: &mut Rates) {
        let e = &self.effects;
        let p = self.plant.params();
        let ext = &s.ext.v;
        let de = &mut out.1;
        let mut x = s.x;
        // Servo (motor side): target, then the effects' limits, if any.
        let vc = v_cmd_mps.clamp(-p.v_max_mps, p.v_max_mps);
        let f_piston = self.piston_force_n(&x);
        let dvi = e
            .servo_accel_mps2((vc, p.tau_m_s), (x.vi_mps, f_piston), ext, de)
            .unwrap_or_else(|| self.nominal_servo_rate(vc, x.vi_mps));
        let mut fo = self.plant.forces_n(&x, ft_n);
        e.add_piston_forces_n(&mut fo, x.vo_mps, x.p1_pa, x.p2_pa);
        let motor = (x.xi_m, x.vi_mps);
        // The lines see the power piston: behind a coupling, at its state.
        let coupling = e.coupling(ext, f_piston);
        if let Some(c) = &coupling {
            x.xi_m = c.xp_m;
        }
        // Accumulator flow (with the effects' gas states) and leakage depend
        // on the state only; the piston's velocity enters through Q1 and Q2.
        let qa_nom = self.plant.accumulator_flow_m3ps(&x);
        let gas = Gas {
            params: p,
            vg_m3: x.vg_m3,
            p2_pa: x.p2_pa,
        };
        let qa = e.accumulator_flow_m3ps(gas, ext, de).unwrap_or(qa_nom);
        let ql = e.leak_flow_m3ps(x.p1_pa, x.p2_pa);
        let lines = |vp: f64, de: &mut [f64; N_EXT]| {
            self.line_rates(ext, &x, vp, (qa_nom, qa - qa_nom), ql, de)
        };
        // Behind a coupling the piston sits where it carries the hydraulic
        // force: xp = xi - g(F), so vp = vi - g'(F) dF/dt, and dF/dt is affine
        // in vp (through Q1, Q2): solved exactly from two evaluations.
        let (vp, r) = match coupling {
            Some(c) => {
                let g1 = c.compliance_mpn;
                let df = |r: &PressureRates| p.ap1_m2 * r.dp1_paps - p.ap2_m2 * r.dp2_paps;
                let dv = 1e-3;
                let f0 = df(&lines(motor.1, de));
                let slope = ((df(&lines(motor.1 + dv, de)) - f0) / dv).max(0.0);
                let vp = motor.1 - g1 * f0 / (1.0 + g1 * slope);
                (vp, lines(vp, de))
            }
            None => (motor.1, lines(motor.1, de)),
        };
        e.power_piston_rates(vp, de);
        out.0 = [
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
    }

    /// Pressure and hose-volume rates with the power piston (position in
    /// `x.xi_m`) moving at `vp`, the accumulator's nominal flow and the
    /// effects' change of it `(qa_nom, dqa)` and the leakage `ql` from line 1
    /// to line 2; the effects on the lines' compliance
    /// ([`RigTerms::add_line_compliance`]) write their states' rates (from
    /// the extra states `ext`) into `de`.
    fn line_rates(
        &self,
        ext: &[f64; N_EXT],
        x: &State,
        vp: f64,
        (qa_nom, dqa): (f64, f64),
        ql: f64,
        de: &mut [f64; N_EXT],
    ) -> PressureRates {
        let p = self.plant.params();
        let mut xv = *x;
        xv.vi_mps = vp;
        // The nominal accumulator flow is the state's, known already (its
        // gas law is the dearest term of the rates).
        let flows = self.plant.flows_with_qa(&xv, qa_nom);
        let q1 = flows.q1_m3ps - ql;
        let q2 = flows.q2_m3ps + dqa + ql;
        let mut r = self.plant.pressure_rates(&xv, q1, q2);
        if !self.on_lines {
            return r;
        }
        let (v1, v2) = self.plant.line_volumes(xv.xi_m, xv.xo_m);
        for (j, (pj, vj)) in [(xv.p1_pa, v1), (xv.p2_pa, v2)].into_iter().enumerate() {
            let dp_nom = if j == 0 { r.dp1_paps } else { r.dp2_paps };
            let mut line = Line::new(p, j, (pj, vj), self.capacitance(pj, vj), dp_nom);
            self.effects.add_line_compliances(&mut line, ext, de);
            let dp = line.dp_paps();
            if j == 0 {
                r.dp1_paps = dp;
            } else {
                r.dp2_paps = dp;
            }
        }
        r
    }

    /// Whether the servo ignores the hydraulics: no effect models it (the
    /// named motor limit or the servo's envelope), so its states follow from
    /// the command alone ([`Rig::step_servo`]).
    pub fn servo_alone(&self) -> bool {
        self.effects.motor_limit.is_none() && self.effects.servo_envelope.is_none()
    }

    /// The nominal servo's acceleration towards `vc_mps` (within +-v_max)
    /// at the speed `vi_mps` where no effect models the servo, m/s^2, as
    /// the rig's right-hand side writes it.
    #[inline]
    fn nominal_servo_rate(&self, vc_mps: f64, vi_mps: f64) -> f64 {
        (vc_mps - vi_mps) / self.plant.params().tau_m_s
    }

    /// One step of the servo's states `(xi_m, vi_mps)` alone, bit for bit
    /// those [`Rig::step`] gives the whole rig, where [`Rig::servo_alone`]
    /// holds (the same RK4 stages and arithmetic on the two states, whose
    /// rates depend on nothing else). The replay's probe of a row's command
    /// needs Xi only, at a fraction of the whole rig's cost.
    pub fn step_servo(&self, (xi_m, vi_mps): (f64, f64), v_cmd_mps: f64, dt_s: f64) -> (f64, f64) {
        let p = self.plant.params();
        let v = self.plant.software_limited_v_cmd(xi_m, v_cmd_mps);
        let vc = v.clamp(-p.v_max_mps, p.v_max_mps);
        // The speed's rate as each step writes it: `Plant::derivative` on
        // the plain plant, `derivative_into` with effects.
        let dvi = |vi: f64| {
            if self.plant_only {
                self.plant.servo_rate(vc, vi)
            } else {
                self.nominal_servo_rate(vc, vi)
            }
        };
        let half = 0.5 * dt_s;
        let k1 = dvi(vi_mps);
        let v2 = vi_mps + half * k1;
        let k2 = dvi(v2);
        let v3 = vi_mps + half * k2;
        let k3 = dvi(v3);
        let v4 = vi_mps + dt_s * k3;
        let k4 = dvi(v4);
        let sixth = dt_s / 6.0;
        (
            xi_m + sixth * (vi_mps + 2.0 * v2 + 2.0 * v3 + v4),
            vi_mps + sixth * (k1 + 2.0 * k2 + 2.0 * k3 + k4),
        )
    }

    /// One RK4 step with inputs held (docs/model.md 4.2), software limit first.
    pub fn step(&self, s: &mut RigState, v_cmd_mps: f64, ft_n: f64, dt_s: f64) {
        if self.plant_only {
            self.plant.step(&mut s.x, v_cmd_mps, ft_n, dt_s);
            return;
        }
        let v = self.plant.software_limited_v_cmd(s.x.xi_m, v_cmd_mps);
        let (x0, e0) = (s.x.as_array(), s.ext.v);
        let at = |d: &Rates, h: f64| RigState {
            x: State::from_array(std::array::from_fn(|i| x0[i] + h * d.0[i])),
            ext: Ext {
                v: std::array::from_fn(|i| e0[i] + h * d.1[i]),
            },
        };
        let zero: Rates = ([0.0; N_STATES], [0.0; N_EXT]);
        let [mut d1, mut d2, mut d3, mut d4] = [zero; 4];
        self.derivative_into(s, v, ft_n, &mut d1);
        self.derivative_into(&at(&d1, 0.5 * dt_s), v, ft_n, &mut d2);
        self.derivative_into(&at(&d2, 0.5 * dt_s), v, ft_n, &mut d3);
        self.derivative_into(&at(&d3, dt_s), v, ft_n, &mut d4);
        let sixth = dt_s / 6.0;
        let rk4 = |y: f64, k: [f64; 4]| y + sixth * (k[0] + 2.0 * k[1] + 2.0 * k[2] + k[3]);
        s.x = State::from_array(std::array::from_fn(|i| {
            rk4(x0[i], [d1.0[i], d2.0[i], d3.0[i], d4.0[i]])
        }));
        s.ext.v = std::array::from_fn(|i| rk4(e0[i], [d1.1[i], d2.1[i], d3.1[i], d4.1[i]]));
        self.effects.keep_states(&mut s.ext.v);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::effects::{self, EffectKind};

    /// Elements of the hysteresis spectrum per line.
    const NS: usize = effects::SPECTRUM_YIELDS_PA.len();

    /// Elements of the gas relaxation.
    const NG: usize = effects::GAS_TAUS_S.len();

    fn rig(k: Option<(EffectKind, &[f64])>) -> Rig {
        let mut e = Effects::NONE;
        if let Some((k, v)) = k {
            e.set(k, Some(v));
        }
        Rig::new(Plant::nominal(), e).unwrap()
    }

    /// [`run`] on the nominal plant with the effects `e`.
    fn run_with(e: Effects) -> Vec<RigState> {
        run(&Rig::new(Plant::nominal(), e).unwrap())
    }

    /// The largest difference of Xo between two runs' states, um.
    fn xo_dev_um(a: &[RigState], b: &[RigState]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x.x.xo_m - y.x.xo_m).abs() / 1e-6)
            .fold(0.0, f64::max)
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
    fn the_servo_stepped_alone_is_the_whole_rigs_servo_bit_for_bit() {
        let params: &[f64] = &[1.0, 1.0, 1.0, 1.0, 1.37, 1.0, 1.0];
        let rigs = [
            rig(None),
            rig(Some((EffectKind::Backlash, &[100e-6, 2e7]))),
            rig(Some((EffectKind::HoseHysteresis, &[0.0, 1.0, 3e5]))),
            rig(Some((EffectKind::Parameters, params))),
        ];
        for r in &rigs {
            assert!(r.servo_alone());
            let mut s = r.initial_state(0.0);
            let mut m = (s.x.xi_m, s.x.vi_mps);
            let mut top: f64 = 0.0;
            // Up against the stroke's end (the software limit) and back,
            // beyond v_max, under a load.
            for k in 0..40_000 {
                let v = match k {
                    0..20_000 => 0.08,
                    20_000..25_000 => -0.2,
                    _ => 0.01,
                };
                r.step(&mut s, v, 500.0, 1e-4);
                m = r.step_servo(m, v, 1e-4);
                assert_eq!(m, (s.x.xi_m, s.x.vi_mps), "step {k}");
                top = top.max(m.0);
            }
            assert!(top >= r.plant().params().x_max_m, "{top}");
        }
        let limited = rig(Some((EffectKind::MotorLimit, &[2000.0, 200.0, 0.1])));
        assert!(!limited.servo_alone());
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
    fn backlash_flank_follows_the_piston_force() {
        let r = rig(Some((EffectKind::Backlash, &[200e-6, 1e7])));
        let b = r.effects().backlash.unwrap();
        // At rest the accumulator's pressure on the full bore pushes the
        // piston out: it rests ahead of the motor, on the far flank.
        let mut s = r.initial_state(0.0);
        let f0 = r.piston_force_n(&s.x);
        assert!(f0 < -100.0, "{f0}");
        let lead = r.power_piston_m(&s).unwrap() - s.x.xi_m;
        assert!((lead - (100e-6 - f0 / 1e7)).abs() < 1e-7, "{lead:e}");
        // At rest the state does not move.
        let (_, de) = r.derivative(&s, 0.0, 0.0);
        assert!(de.iter().all(|d| d.abs() < 1e-12), "{de:?}");
        // 800 N on the load turns the force over: the piston crosses the play
        // and lags the motor by the half play plus the deflection.
        for _ in 0..5000 {
            r.step(&mut s, 0.0, 800.0, 1e-4);
        }
        let f = r.piston_force_n(&s.x);
        assert!(f > 100.0, "{f}");
        let lag = s.x.xi_m - r.power_piston_m(&s).unwrap();
        let want = effects::backlash_offset_m(&b, f);
        assert!(
            want > 100e-6 && (lag - want).abs() < 1e-6,
            "{lag:e} vs {want:e}"
        );
    }

    #[test]
    fn motor_limit_slows_the_servo_under_load() {
        // 1000 N drive force against about 700 N of hydraulic force.
        let r = rig(Some((EffectKind::MotorLimit, &[1000.0, 500.0, 0.1])));
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
        // The speed cap alone.
        let capped = rig(Some((EffectKind::MotorLimit, &[1e5, 1e3, 0.02])));
        let mut c = capped.initial_state(0.0);
        for _ in 0..3000 {
            capped.step(&mut c, 0.05, 0.0, 1e-4);
        }
        assert!((c.x.vi_mps - 0.02).abs() < 1e-6, "{}", c.x.vi_mps);
    }

    #[test]
    fn air_and_friction_and_hysteresis_and_thermal_change_the_response() {
        let base = run(&rig(None));
        for (k, v) in [
            (EffectKind::Air, &[0.01][..]),
            (EffectKind::Friction, &[60.0, 90.0, 2e-3][..]),
            (EffectKind::HoseHysteresis, &[1e-12, 0.0, 1e5][..]),
            (EffectKind::HoseHysteresis, &[0.0, 1.0, 3e5][..]),
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

    /// The hysteresis spectrum: zero compliances are the nominal rig and one
    /// element the named form's Dahl element (no stuck share), to rounding
    /// (the capacitance is summed in another order); two elements of
    /// different yields differ from either.
    #[test]
    fn hysteresis_spectrum_is_a_sum_of_named_elements() {
        let with = |c: [f64; NS]| {
            run_with(Effects {
                hose_spectrum: Some(effects::HysteresisSpectrum::plays(c)),
                ..Effects::NONE
            })
        };
        let base = run(&rig(None));
        let xs = |v: &[RigState]| {
            v.iter()
                .map(|s| (s.x.xo_m, s.x.p1_pa, s.x.p2_pa))
                .collect::<Vec<_>>()
        };
        let same = |a: &[RigState], b: &[RigState]| {
            xs(a).iter().zip(xs(b)).all(|(x, y)| {
                (x.0 - y.0).abs() < 1e-12 && (x.1 - y.1).abs() < 1e-6 && (x.2 - y.2).abs() < 1e-6
            })
        };
        assert!(same(&with([0.0; NS]), &base));
        let one = with([0.0, 0.0, 1e-12, 0.0, 0.0]);
        let named = run(&rig(Some((EffectKind::HoseHysteresis, &[1e-12, 0.0, 1e5]))));
        assert!(same(&one, &named));
        assert!(!same(&one, &base));
        let two = with([5e-13, 0.0, 0.0, 0.0, 1e-12]);
        for other in [&base, &named] {
            let diff = xs(&two)
                .iter()
                .zip(xs(other))
                .map(|(a, b)| (a.0 - b.0).abs() / 1e-6)
                .fold(0.0, f64::max);
            assert!(diff > 1.0, "{diff}");
        }
        // Both named and general at once are refused.
        let mut e = Effects::NONE;
        e.set(EffectKind::HoseHysteresis, Some(&[1e-12, 0.0, 1e5]));
        e.hose_spectrum = Some(effects::HysteresisSpectrum::plays([1e-13; NS]));
        assert!(Rig::new(Plant::nominal(), e).is_err());
    }

    /// The spectrum's stops: a stop and a play of the same compliance at
    /// one yield add that compliance whatever the engagement, so the pair
    /// at the smallest yield and at the largest give the same rig (to
    /// rounding), unlike the nominal one; a stop alone differs from the
    /// play alone (it gives right after a reversal, the play once the
    /// pressure has moved on).
    #[test]
    fn a_stop_and_a_play_of_one_compliance_add_it_whatever_the_history() {
        let with = |plays: [f64; NS], stops: [f64; NS]| {
            run_with(Effects {
                hose_spectrum: Some(effects::HysteresisSpectrum {
                    c_m3pp: plays,
                    stop_c_m3pp: stops,
                }),
                ..Effects::NONE
            })
        };
        let c = 1e-12;
        let small = with([c, 0.0, 0.0, 0.0, 0.0], [c, 0.0, 0.0, 0.0, 0.0]);
        let large = with([0.0, 0.0, 0.0, 0.0, c], [0.0, 0.0, 0.0, 0.0, c]);
        assert!(xo_dev_um(&small, &large) < 1e-6);
        assert!(xo_dev_um(&small, &run(&rig(None))) > 1.0);
        let stop = with([0.0; NS], [0.0, 0.0, c, 0.0, 0.0]);
        let play = with([0.0, 0.0, c, 0.0, 0.0], [0.0; NS]);
        assert!(xo_dev_um(&stop, &play) > 1.0);
        assert!(xo_dev_um(&stop, &run(&rig(None))) > 1.0);
    }

    /// The gas relaxation: zero weights are the nominal rig to rounding; one
    /// element of weight n_poly - 1 is the named thermal form of the same
    /// time constant to first order in the temperature (within 1 % of the
    /// named form's departure from the nominal rig); two elements of other
    /// time constants differ from both; both forms at once are refused, and
    /// so are weights that relax the index to zero.
    #[test]
    fn gas_relaxation_of_one_element_is_the_named_thermal_form() {
        let with = |w: [f64; NG]| {
            run_with(Effects {
                gas_relaxation: Some(effects::GasRelaxation { weights: w }),
                ..Effects::NONE
            })
        };
        let dev = |a: &[RigState], b: &[RigState]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| {
                    (x.x.xo_m - y.x.xo_m).abs() / 1e-6 + (x.x.p2_pa - y.x.p2_pa).abs() / 1e3
                })
                .fold(0.0, f64::max)
        };
        let base = run(&rig(None));
        assert!(dev(&with([0.0; NG]), &base) < 1e-6);
        let n1 = Plant::nominal().params().n_poly - 1.0;
        let one = with([0.0, 0.0, n1, 0.0, 0.0, 0.0]);
        let named = run(&rig(Some((EffectKind::AccumulatorThermal, &[1.0]))));
        let effect = dev(&named, &base);
        assert!(effect > 5.0, "{effect}");
        assert!(
            dev(&one, &named) < 0.01 * effect,
            "{} vs {effect}",
            dev(&one, &named)
        );
        let two = with([0.2, 0.0, 0.0, 0.0, 0.2, 0.0]);
        assert!(dev(&two, &named) > 0.2 * effect && dev(&two, &base) > 0.2 * effect);
        assert!(two.iter().all(|s| s.is_finite()));
        let mut e = Effects::NONE;
        e.set(EffectKind::AccumulatorThermal, Some(&[1.0]));
        e.gas_relaxation = Some(effects::GasRelaxation { weights: [0.1; NG] });
        assert!(Rig::new(Plant::nominal(), e).is_err());
        let mut p = *Plant::nominal().params();
        p.n_poly = 0.9;
        let soft = Effects {
            gas_relaxation: Some(effects::GasRelaxation {
                weights: [0.16; NG],
            }),
            ..Effects::NONE
        };
        assert!(matches!(
            Rig::new(Plant::nominal().with_params(p), soft),
            Err(RigError::Unsuited(_))
        ));
        // Weights that sum beyond the bound are refused too.
        let e = Effects {
            gas_relaxation: Some(effects::GasRelaxation { weights: [0.2; NG] }),
            ..Effects::NONE
        };
        assert!(Rig::new(Plant::nominal(), e).is_err());
    }

    /// The screw map: through the named form's deflections at its knots it
    /// follows the named backlash closely (the play crossed over 10 N as
    /// the named form's tanh nearly is); a Hertzian contact differs; both
    /// forms at once are refused; the map is odd and its compliance is its
    /// slope.
    #[test]
    fn screw_map_through_the_named_deflections_follows_the_named_backlash() {
        let b = effects::Backlash {
            play_m: 100e-6,
            stiffness_npm: 2e7,
        };
        let deflection_m: [f64; 6] =
            std::array::from_fn(|i| effects::backlash_offset_m(&b, effects::SCREW_FORCES_N[i + 1]));
        let map = effects::ScrewMap { deflection_m };
        for f in [-1500.0, -40.0, 0.0, 5.0, 60.0, 2500.0, 5000.0] {
            assert_eq!(map.offset_m(-f), -map.offset_m(f));
            let h = 1e-3;
            let slope = (map.offset_m(f + h) - map.offset_m(f - h)) / (2.0 * h);
            if !effects::SCREW_FORCES_N.contains(&f.abs()) {
                assert!((slope - map.compliance_mpn(f)).abs() < 1e-12, "{f}");
            }
        }
        let with_map = |m: effects::ScrewMap| {
            run_with(Effects {
                screw_map: Some(m),
                ..Effects::NONE
            })
        };
        let dev = xo_dev_um;
        let base = run(&rig(None));
        let named = run(&rig(Some((EffectKind::Backlash, &[100e-6, 2e7]))));
        let effect = dev(&named, &base);
        assert!(effect > 5.0, "{effect}");
        let same = with_map(map);
        assert!(
            dev(&same, &named) < 0.1 * effect,
            "{} vs {effect}",
            dev(&same, &named)
        );
        // A contact whose compliance falls with the force.
        let hertz = effects::ScrewMap {
            deflection_m: [20e-6, 40e-6, 45e-6, 50e-6, 60e-6, 80e-6],
        };
        let h = with_map(hertz);
        assert!(dev(&h, &named) > 0.3 * effect && dev(&h, &base) > 0.3 * effect);
        let mut e = Effects::NONE;
        e.set(EffectKind::Backlash, Some(&[100e-6, 2e7]));
        e.screw_map = Some(map);
        assert!(Rig::new(Plant::nominal(), e).is_err());
    }

    /// The index a step compression meets: the nominal one at once, falling
    /// by each element's weight over its time constant.
    #[test]
    fn gas_index_falls_by_the_relaxed_weights() {
        let g = effects::GasRelaxation {
            weights: [0.0, 0.1, 0.0, 0.3, 0.0, 0.0],
        };
        assert_eq!(g.index_after(1.4, 0.0), 1.4);
        assert!((g.index_after(1.4, 1e4) - 1.0).abs() < 1e-12);
        let at_tau = g.index_after(1.4, 3.0);
        let want = 1.4 - 0.1 * (1.0 - (-10.0_f64).exp()) - 0.3 * (1.0 - (-1.0_f64).exp());
        assert!((at_tau - want).abs() < 1e-12);
    }

    #[test]
    fn step_scale_keeps_a_stiffened_line_stable() {
        let r = rig(Some((EffectKind::HoseHysteresis, &[0.0, 1.0, 3e5])));
        let scale = r.step_scale();
        assert!(scale < 0.5 && scale > 0.05, "{scale}");
        // A 1 s load cycle at the replay's step (5e-4 s) times the scale, and
        // at a 20 times finer step: the same trajectory.
        let sim = |n: usize| {
            let h = 1.0 / n as f64;
            let mut s = r.initial_state(0.0);
            for k in 0..n {
                let t = k as f64 * h;
                let ft = 400.0 + 300.0 * (2.0 * std::f64::consts::PI * 2.0 * t).sin();
                let v = 0.03 * (2.0 * std::f64::consts::PI * t).cos();
                r.step(&mut s, v, ft, h);
            }
            s
        };
        let n = (1.0 / (5e-4 * scale)).ceil() as usize;
        let coarse = sim(n);
        let fine = sim(20 * n);
        assert!(coarse.is_finite());
        // Within a fifth of the sensor noise (the engagement switches with the
        // sign of dP/dt, and the inputs are held over each step).
        assert!(
            (coarse.x.xo_m - fine.x.xo_m).abs() < 2e-6,
            "{coarse:?} {fine:?}"
        );
        assert!((coarse.x.p1_pa - fine.x.p1_pa).abs() < 1e3);
        // Without the scale the same step diverges or is far off.
        let unscaled = sim(2000);
        assert!(
            !unscaled.is_finite() || (unscaled.x.p1_pa - fine.x.p1_pa).abs() > 1e3,
            "{unscaled:?}"
        );
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
