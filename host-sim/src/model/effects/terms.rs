//! The terms the effects add to the rig's equations (docs/model.md section
//! 4, [`crate::model::rig`]), below every part file: what a named form or a
//! general family adds at each place of the equations ([`RigTerms`],
//! implemented in its part file beside the form) and what the rig tells it
//! there ([`Rest`], [`Gas`], [`Line`]). The rig's passes over every active
//! effect, in the rows' order of `effects!` (which also lays out the
//! effects' states, [`EXT_STATES`](super::EXT_STATES)), are methods of
//! [`Effects`](super::Effects) in `passes`.
//!
//! The rig knows no effect by name: where the equations have a place for
//! an effect, it asks every active one, and each effect reads and writes
//! only its own states.

use std::ops::Range;

use dca_core::params::PlantParams;

/// The rig at rest, as an effect's states start from it
/// ([`RigTerms::rest_states`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rest {
    /// The motor (encoder) position, m.
    pub xi_m: f64,
    /// The hydraulic force on the power piston, positive opposing
    /// extension, N.
    pub piston_force_n: f64,
}

/// A coupling between the motor and the power piston
/// ([`RigTerms::coupling`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PowerPiston {
    /// The power piston's position (one of the effect's states), m.
    pub xp_m: f64,
    /// The coupling's compliance at the hydraulic force: the derivative of
    /// the motor's lead over the power piston with respect to the force, m/N.
    pub compliance_mpn: f64,
}

/// The accumulator's gas at one instant ([`RigTerms::accumulator_flow_m3ps`]).
#[derive(Clone, Copy, Debug)]
pub struct Gas<'a> {
    /// The plant's parameters.
    pub params: &'a PlantParams,
    /// The gas volume, m^3.
    pub vg_m3: f64,
    /// The pressure of line 2 (the accumulator's port), Pa.
    pub p2_pa: f64,
}

/// One line's capacitance as the rig builds it up, effect by effect
/// ([`RigTerms::add_line_compliance`]): from the explicit hose's nominal
/// capacitance, the oil's `V / beta_e` plus the wall's `Ce(P)`, each effect
/// adds its compliance ([`Line::add_compliance`]); the line's pressure rate
/// follows, the nominal one scaled by the nominal over the capacitance so
/// far ([`Line::dp_paps`]).
#[derive(Clone, Copy, Debug)]
pub struct Line<'a> {
    /// The plant's parameters.
    pub params: &'a PlantParams,
    /// Which line: 0 for line 1, 1 for line 2.
    pub index: usize,
    /// The line pressure, Pa.
    pub p_pa: f64,
    /// The line's oil volume, m^3.
    pub v_m3: f64,
    /// The oil's part of the nominal capacitance, `V / beta_e`, m^3/Pa.
    pub c_oil_m3pp: f64,
    /// The hose wall's part of the nominal capacitance, `Ce(P)`, m^3/Pa.
    pub c_wall_m3pp: f64,
    /// The nominal capacitance, m^3/Pa.
    c_nom_m3pp: f64,
    /// The pressure rate with the nominal capacitance, Pa/s.
    dp_nom_paps: f64,
    /// The capacitance with the effects so far, m^3/Pa.
    c_m3pp: f64,
    /// The pressure rate with it, Pa/s, once asked for (`None` since the
    /// capacitance last changed: each is computed once, when read).
    dp_paps: Option<f64>,
}

impl<'a> Line<'a> {
    /// Line `index` at the pressure `p_pa` with the oil volume `v_m3`, the
    /// nominal capacitance's parts `c_oil_m3pp` and `c_wall_m3pp`, and the
    /// pressure rate `dp_nom_paps` they give.
    pub fn new(
        params: &'a PlantParams,
        index: usize,
        (p_pa, v_m3): (f64, f64),
        (c_oil_m3pp, c_wall_m3pp): (f64, f64),
        dp_nom_paps: f64,
    ) -> Self {
        let c_nom_m3pp = c_oil_m3pp + c_wall_m3pp;
        Self {
            params,
            index,
            p_pa,
            v_m3,
            c_oil_m3pp,
            c_wall_m3pp,
            c_nom_m3pp,
            dp_nom_paps,
            c_m3pp: c_nom_m3pp,
            dp_paps: None,
        }
    }

    /// The capacitance with the effects so far, m^3/Pa.
    pub fn c_m3pp(&self) -> f64 {
        self.c_m3pp
    }

    /// The line's pressure rate with the capacitance so far, Pa/s: the
    /// nominal rate times the nominal capacitance over it.
    pub fn dp_paps(&mut self) -> f64 {
        if let Some(dp) = self.dp_paps {
            return dp;
        }
        let dp = self.dp_nom_paps * self.c_nom_m3pp / self.c_m3pp;
        self.dp_paps = Some(dp);
        dp
    }

    /// Add the compliances `dc_m3pp`, m^3/Pa, to the capacitance in turn.
    pub fn add_compliance(&mut self, dc_m3pp: impl IntoIterator<Item = f64>) {
        for dc in dc_m3pp {
            self.c_m3pp += dc;
        }
        self.dp_paps = None;
    }
}

/// What a named form or a general family adds to the rig's equations, one
/// hook per place (each a no-op by default). The rig calls the hooks of
/// every active effect in the rows' order of `effects!`; an effect with
/// states of its own ([`RigTerms::STATES`]) gets its slice of the rig's
/// extra states (`own`) and of their rates (`rates`), nothing else.
pub trait RigTerms {
    /// How many states of its own the effect carries.
    const STATES: usize = 0;
    /// Whether it changes the rig's equations at all (false for effects on
    /// the readings only, and for `parameters`, which builds the plant with
    /// other parameters, [`RigTerms::plant_params`]); with none such on, the
    /// rig steps the plant alone.
    const ON_EQUATIONS: bool = true;
    /// Whether it adds compliance to the lines
    /// ([`RigTerms::add_line_compliance`]): it changes the explicit
    /// pressure equation and needs an explicit hose model (nonlinear, linear
    /// or rigid).
    const ON_LINES: bool = false;
    /// The plant parameters it changes from `p`, if any (the rig builds its
    /// plant with them).
    fn plant_params(&self, _p: &PlantParams) -> Option<PlantParams> {
        None
    }
    /// Whether it suits a plant of the parameters `p` (the error names the
    /// effect and what fails).
    fn check_plant(&self, _p: &PlantParams) -> Result<(), String> {
        Ok(())
    }
    /// Its states at rest, written to `own` (all zero before).
    fn rest_states(&self, _rest: &Rest, _own: &mut [f64]) {}
    /// Its states brought back into the set their exact solution never
    /// leaves, after each plant step (e.g. a rate-independent element's
    /// hysteretic pressure within its yield: on a step over which the
    /// pressure moves by many yields, RK4 would otherwise overshoot and
    /// diverge).
    fn keep_states(&self, _own: &mut [f64]) {}
    /// Factor (at most 1) on the plant's largest stable step, from the line
    /// capacitance at its softest (its oil's and its wall's part), where it
    /// stiffens the lines.
    fn step_scale(&self, _c_oil_m3pp: f64, _c_wall_m3pp: f64) -> Option<f64> {
        None
    }
    /// The servo's acceleration where it models the servo, m/s^2, with its
    /// states' rates: the speed command `vc_mps` (within the nominal
    /// +-v_max) and the servo's time constant `tau_s`, the servo's speed
    /// `v_mps`, the hydraulic force `f_load_n` on the power piston
    /// (positive opposing extension).
    fn servo_accel_mps2(
        &self,
        _command: (f64, f64),
        _v_mps: f64,
        _f_load_n: f64,
        _own: &[f64],
        _rates: &mut [f64],
    ) -> Option<f64> {
        None
    }
    /// The force it puts on the actuating piston against extension, N, at
    /// the piston's speed and the line pressures.
    fn piston_force_n(&self, _vo_mps: f64, _p1_pa: f64, _p2_pa: f64) -> Option<f64> {
        None
    }
    /// The coupling it puts between the motor and the power piston, if any,
    /// from its states `own`, under the hydraulic force `f_n` on the power
    /// piston (positive opposing extension). The lines then see the power
    /// piston, whose velocity the rig solves from the compliance
    /// ([`RigTerms::power_piston_rates`]).
    fn coupling(&self, _own: &[f64], _f_n: f64) -> Option<PowerPiston> {
        None
    }
    /// Its states' rates given the power piston's velocity `vp_mps`, m/s
    /// (where it holds the power piston's position).
    fn power_piston_rates(&self, _vp_mps: f64, _rates: &mut [f64]) {}
    /// The accumulator's flow into line 2, m^3/s, where it changes the
    /// accumulator's gas law, with its states' rates.
    fn accumulator_flow_m3ps(
        &self,
        _gas: &Gas<'_>,
        _own: &[f64],
        _rates: &mut [f64],
    ) -> Option<f64> {
        None
    }
    /// The flow it lets from line 1 to line 2, m^3/s.
    fn leak_flow_m3ps(&self, _p1_pa: f64, _p2_pa: f64) -> Option<f64> {
        None
    }
    /// Add its compliance to the line `line` (reading the pressure rate
    /// [`Line::dp_paps`] before and after, as the effect needs), with its
    /// states' rates; only where [`RigTerms::ON_LINES`].
    fn add_line_compliance(&self, _line: &mut Line<'_>, _own: &[f64], _rates: &mut [f64]) {}
}

/// A visit of every active effect (the catalogue's `visit_active`): each
/// with the range of its states in the rig's extra states.
pub(super) trait Visit {
    /// Visit the active effect `effect`, whose states are `states`.
    fn visit<T: RigTerms>(&mut self, effect: &T, states: Range<usize>);
}
