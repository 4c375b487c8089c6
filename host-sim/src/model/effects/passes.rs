//! The rig's passes over the active effects ([`crate::model::rig`]): one
//! method of [`Effects`] per place in the equations, asking every active
//! effect's [`RigTerms`] there in the rows' order of `effects!`, each with
//! its own slice of the rig's extra states.

use std::ops::Range;

use dca_core::params::PlantParams;

use super::terms::{Gas, Line, PowerPiston, Rest, RigTerms, Visit};
use super::Effects;

/// Whether any active effect changes the equations, or the lines.
struct Any {
    lines: bool,
    equations: bool,
}

impl Visit for Any {
    fn visit<T: RigTerms>(&mut self, _: &T, _: Range<usize>) {
        self.lines |= T::ON_LINES;
        self.equations |= T::ON_EQUATIONS;
    }
}

/// The plant parameters the effects change, each from the last.
struct Params<'a> {
    base: &'a PlantParams,
    out: Option<PlantParams>,
}

impl Visit for Params<'_> {
    fn visit<T: RigTerms>(&mut self, e: &T, _: Range<usize>) {
        if let Some(p) = e.plant_params(self.out.as_ref().unwrap_or(self.base)) {
            self.out = Some(p);
        }
    }
}

/// The first effect that does not suit the plant.
struct Suits<'a> {
    params: &'a PlantParams,
    out: Result<(), String>,
}

impl Visit for Suits<'_> {
    fn visit<T: RigTerms>(&mut self, e: &T, _: Range<usize>) {
        if self.out.is_ok() {
            self.out = e.check_plant(self.params);
        }
    }
}

/// The effects' states at rest.
struct RestStates<'a> {
    rest: Rest,
    ext: &'a mut [f64],
}

impl Visit for RestStates<'_> {
    fn visit<T: RigTerms>(&mut self, e: &T, at: Range<usize>) {
        e.rest_states(&self.rest, &mut self.ext[at]);
    }
}

/// The effects' states kept in their sets after a step.
struct KeepStates<'a> {
    ext: &'a mut [f64],
}

impl Visit for KeepStates<'_> {
    fn visit<T: RigTerms>(&mut self, e: &T, at: Range<usize>) {
        e.keep_states(&mut self.ext[at]);
    }
}

/// The smallest step scale.
struct StepScale {
    c: (f64, f64),
    out: Option<f64>,
}

impl Visit for StepScale {
    fn visit<T: RigTerms>(&mut self, e: &T, _: Range<usize>) {
        if let Some(s) = e.step_scale(self.c.0, self.c.1) {
            self.out = Some(self.out.map_or(s, |o| o.min(s)));
        }
    }
}

/// The servo's acceleration from the first effect that models the servo,
/// with its states' rates.
struct ServoAccel<'a> {
    args: [f64; 4],
    ext: &'a [f64],
    rates: &'a mut [f64],
    out: Option<f64>,
}

impl Visit for ServoAccel<'_> {
    fn visit<T: RigTerms>(&mut self, e: &T, at: Range<usize>) {
        if self.out.is_none() {
            let [vc, tau, v, f] = self.args;
            let own = &self.ext[at.clone()];
            self.out = e.servo_accel_mps2((vc, tau), v, f, own, &mut self.rates[at]);
        }
    }
}

/// The forces on the actuating piston, added in turn.
struct PistonForces<'a> {
    args: [f64; 3],
    f_n: &'a mut f64,
}

impl Visit for PistonForces<'_> {
    fn visit<T: RigTerms>(&mut self, e: &T, _: Range<usize>) {
        let [v, p1, p2] = self.args;
        if let Some(f) = e.piston_force_n(v, p1, p2) {
            *self.f_n += f;
        }
    }
}

/// The leakage flows, summed in turn.
struct LeakFlows {
    args: [f64; 2],
    q_m3ps: f64,
}

impl Visit for LeakFlows {
    fn visit<T: RigTerms>(&mut self, e: &T, _: Range<usize>) {
        if let Some(q) = e.leak_flow_m3ps(self.args[0], self.args[1]) {
            self.q_m3ps += q;
        }
    }
}

/// The coupling from the first effect that puts one.
struct Coupling<'a> {
    ext: &'a [f64],
    f_n: f64,
    out: Option<PowerPiston>,
}

impl Visit for Coupling<'_> {
    fn visit<T: RigTerms>(&mut self, e: &T, at: Range<usize>) {
        if self.out.is_none() {
            self.out = e.coupling(&self.ext[at], self.f_n);
        }
    }
}

/// The rates of the states that follow the power piston.
struct PowerPistonRates<'a> {
    vp_mps: f64,
    rates: &'a mut [f64],
}

impl Visit for PowerPistonRates<'_> {
    fn visit<T: RigTerms>(&mut self, e: &T, at: Range<usize>) {
        e.power_piston_rates(self.vp_mps, &mut self.rates[at]);
    }
}

/// The accumulator's flow from the last effect that changes its gas law.
struct AccumulatorFlow<'a> {
    gas: Gas<'a>,
    ext: &'a [f64],
    rates: &'a mut [f64],
    out: Option<f64>,
}

impl Visit for AccumulatorFlow<'_> {
    fn visit<T: RigTerms>(&mut self, e: &T, at: Range<usize>) {
        let own = &self.ext[at.clone()];
        if let Some(q) = e.accumulator_flow_m3ps(&self.gas, own, &mut self.rates[at]) {
            self.out = Some(q);
        }
    }
}

/// The compliances added to one line, in turn.
struct LineCompliances<'a, 'b> {
    line: &'a mut Line<'b>,
    ext: &'a [f64],
    rates: &'a mut [f64],
}

impl Visit for LineCompliances<'_, '_> {
    fn visit<T: RigTerms>(&mut self, e: &T, at: Range<usize>) {
        if T::ON_LINES {
            let own = &self.ext[at.clone()];
            e.add_line_compliance(self.line, own, &mut self.rates[at]);
        }
    }
}

impl Effects {
    /// What the active effects change, in one pass.
    fn any(&self) -> Any {
        let mut any = Any {
            lines: false,
            equations: false,
        };
        self.visit_active(&mut any);
        any
    }

    /// Whether any active effect adds compliance to the lines
    /// ([`RigTerms::ON_LINES`]).
    pub fn on_lines(&self) -> bool {
        self.any().lines
    }

    /// Whether any active effect changes the rig's equations
    /// ([`RigTerms::ON_EQUATIONS`]).
    pub fn on_equations(&self) -> bool {
        self.any().equations
    }

    /// The plant parameters the active effects change from `base`
    /// ([`RigTerms::plant_params`], each from the last); `None` where none
    /// changes them.
    pub fn plant_params(&self, base: &PlantParams) -> Option<PlantParams> {
        let mut v = Params { base, out: None };
        self.visit_active(&mut v);
        v.out
    }

    /// Whether every active effect suits a plant of the parameters `p`
    /// ([`RigTerms::check_plant`]); the first that does not is the error.
    pub fn check_plant(&self, params: &PlantParams) -> Result<(), String> {
        let mut v = Suits {
            params,
            out: Ok(()),
        };
        self.visit_active(&mut v);
        v.out
    }

    /// The active effects' states at rest ([`RigTerms::rest_states`]) in
    /// `ext` (the rig's extra states, zero before).
    pub fn rest_states(&self, rest: Rest, ext: &mut [f64]) {
        self.visit_active(&mut RestStates { rest, ext });
    }

    /// The active effects' states in `ext` brought back into their sets
    /// after a plant step ([`RigTerms::keep_states`]).
    pub fn keep_states(&self, ext: &mut [f64]) {
        self.visit_active(&mut KeepStates { ext });
    }

    /// Factor (at most 1) on the plant's largest stable step: the smallest
    /// of the active effects' ([`RigTerms::step_scale`]), 1 where none has
    /// one.
    pub fn step_scale(&self, c_oil_m3pp: f64, c_wall_m3pp: f64) -> f64 {
        let mut v = StepScale {
            c: (c_oil_m3pp, c_wall_m3pp),
            out: None,
        };
        self.visit_active(&mut v);
        v.out.unwrap_or(1.0)
    }

    /// The servo's acceleration from the first active effect that models
    /// the servo ([`RigTerms::servo_accel_mps2`]), its states' rates into
    /// `rates` (the effects' states `ext`); `None`: the nominal servo.
    #[inline(always)]
    pub fn servo_accel_mps2(
        &self,
        (vc_mps, tau_s): (f64, f64),
        (v_mps, f_load_n): (f64, f64),
        ext: &[f64],
        rates: &mut [f64],
    ) -> Option<f64> {
        let mut v = ServoAccel {
            args: [vc_mps, tau_s, v_mps, f_load_n],
            ext,
            rates,
            out: None,
        };
        self.visit_active(&mut v);
        v.out
    }

    /// Add the force every active effect puts on the actuating piston
    /// ([`RigTerms::piston_force_n`]) to `f_n`, in the rows' order.
    #[inline(always)]
    pub fn add_piston_forces_n(&self, f_n: &mut f64, vo_mps: f64, p1_pa: f64, p2_pa: f64) {
        self.visit_active(&mut PistonForces {
            args: [vo_mps, p1_pa, p2_pa],
            f_n,
        });
    }

    /// The flow from line 1 to line 2 every active effect lets through
    /// ([`RigTerms::leak_flow_m3ps`]), summed in the rows' order, m^3/s.
    #[inline(always)]
    pub fn leak_flow_m3ps(&self, p1_pa: f64, p2_pa: f64) -> f64 {
        let mut v = LeakFlows {
            args: [p1_pa, p2_pa],
            q_m3ps: 0.0,
        };
        self.visit_active(&mut v);
        v.q_m3ps
    }

    /// The coupling between the motor and the power piston from the first
    /// active effect that puts one ([`RigTerms::coupling`]), from the
    /// rig's extra states `ext` under the hydraulic force `f_n`.
    #[inline(always)]
    pub fn coupling(&self, ext: &[f64], f_n: f64) -> Option<PowerPiston> {
        let mut v = Coupling {
            ext,
            f_n,
            out: None,
        };
        self.visit_active(&mut v);
        v.out
    }

    /// The rates of the states that follow the power piston, moving at
    /// `vp_mps` ([`RigTerms::power_piston_rates`]), into `rates`.
    #[inline(always)]
    pub fn power_piston_rates(&self, vp_mps: f64, rates: &mut [f64]) {
        self.visit_active(&mut PowerPistonRates { vp_mps, rates });
    }

    /// The accumulator's flow from the last active effect that changes its
    /// gas law ([`RigTerms::accumulator_flow_m3ps`]), with the rates of the
    /// states of each such effect into `rates`; `None`: the plant's.
    #[inline(always)]
    pub fn accumulator_flow_m3ps(
        &self,
        gas: Gas<'_>,
        ext: &[f64],
        rates: &mut [f64],
    ) -> Option<f64> {
        let mut v = AccumulatorFlow {
            gas,
            ext,
            rates,
            out: None,
        };
        self.visit_active(&mut v);
        v.out
    }

    /// Add every active effect's compliance to the line `line`
    /// ([`RigTerms::add_line_compliance`]), in the rows' order, with the
    /// rates of their states into `rates`.
    #[inline(always)]
    pub fn add_line_compliances(&self, line: &mut Line<'_>, ext: &[f64], rates: &mut [f64]) {
        self.visit_active(&mut LineCompliances { line, ext, rates });
    }
}
