//! The one closed loop: the sensors read the plant, a control tick computes the
//! command, the plant moves under it.
//!
//! Both the software loop ([`super::run_with`]: the controller ticked every
//! `controller.base_dt_s`, 1 ms as on the board unless a study asks for a
//! finer tick) and the HIL lockstep ([`crate::hil::run_lockstep`]: the
//! controller ticked every 1 ms, `round(1e-3 / dt)` plant steps per tick) are
//! this loop ([`drive`]); what differs is given as parameters:
//!
//! * the timing ([`Timing`]): the plant step, the plant steps per control tick,
//!   the number of ticks;
//! * who computes the command ([`Stepper`]): the control core in this process
//!   or the scenario's open-loop command (the software loop's steppers), or
//!   dca-app's `ControlLoop` in this process, a board or the emulated firmware
//!   over a serial link (the HIL steppers);
//! * what is recorded of each tick ([`Observer`]).
//!
//! Control tick j, with p plant steps per tick, starts at plant step
//! k0 = j p, t = k0 dt ([`tick_time_s`]):
//! 1. the load Ft(t) and the sensors' readings of the state at t (the sensors
//!    are read once per control tick, so a sensor delay counts control ticks);
//! 2. the stepper gets the sample and the reference r(t) (0 in open loop) and
//!    returns the command;
//! 3. the observer sees the tick, before the plant moves (it may end the run);
//! 4. the plant takes the p RK4 steps k0 .. k0 + p with the command held and
//!    the load evaluated at each step's start, Ft(k dt).

use dca_core::controller::{Controller, Sample};

use crate::model::effects::Effects;
use crate::model::rig::{Rig, RigState};
use crate::model::scenario::{tick_time_s, Command, Scenario};
use crate::model::sensors::{Readings, SensorMode, Sensors};

/// The loop's timing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timing {
    /// Plant step dt, s.
    pub dt_s: f64,
    /// Plant steps per control tick (at least 1).
    pub steps_per_tick: u64,
    /// Number of control ticks.
    pub ticks: u64,
}

/// What a stepper gets at a control tick.
#[derive(Clone, Copy, Debug)]
pub struct ControlInput<'a> {
    /// Control tick index j.
    pub tick: u64,
    /// t = j p dt, s.
    pub t_s: f64,
    /// The readings as the control core's sample (f32).
    pub sample: &'a Sample,
    /// The reference r(t), m (0 in open loop).
    pub ref_m: f64,
}

/// A stepper's answer: at least the drive command to hold until the next tick.
pub trait Drive {
    /// The drive speed command, m/s.
    fn v_cmd_mps(&self) -> f64;
}

/// Who computes the command: one control tick per call.
pub trait Stepper {
    /// The answer of a tick.
    type Output: Drive;
    /// Why a tick failed (ends the run).
    type Error;
    /// One control tick.
    fn step(&mut self, input: &ControlInput<'_>) -> Result<Self::Output, Self::Error>;
    /// The control core, when it runs in this process as a [`Controller`].
    fn controller(&self) -> Option<&Controller> {
        None
    }
}

/// What an observer sees of a control tick (before the plant moves).
pub struct TickView<'a, O> {
    /// Control tick index j.
    pub tick: u64,
    /// Plant step index of the tick, k0 = j p.
    pub k: u64,
    /// t = k0 dt, s.
    pub t_s: f64,
    /// The rig the loop runs.
    pub rig: &'a Rig,
    /// The rig's true state at t.
    pub state: &'a RigState,
    /// The load Ft(t), N.
    pub load_n: f64,
    /// What the sensors reported (SI, f64).
    pub meas: &'a Readings,
    /// The same as the control core's sample (f32).
    pub sample: &'a Sample,
    /// The reference r(t), m (0 in open loop).
    pub ref_m: f64,
    /// The stepper's answer.
    pub output: &'a O,
}

/// Records the ticks of a run (and may end it).
pub trait Observer<S: Stepper> {
    /// One control tick, after the stepper's step and before the plant moves.
    fn observe(&mut self, tick: &TickView<'_, S::Output>, stepper: &S) -> Result<(), S::Error>;
}

/// A run's sensors in `mode`, noise seeded with `seed`, with the sensor
/// effects of `effects` (`sensor_delay`, `sensor_calibration`, named or in
/// their general families) for readings taken every `tick_s` seconds (the
/// control period).
pub fn sensors(mode: SensorMode, seed: u64, effects: &Effects, tick_s: f64) -> Sensors {
    Sensors::new(mode, seed).with_effects(effects, tick_s)
}

/// Run `scenario` on `rig` (see the module documentation): the rig starts at
/// rest under the load Ft(0); `timing.ticks` control ticks.
pub fn drive<S: Stepper, O: Observer<S>>(
    scenario: &Scenario,
    rig: &Rig,
    sensors: &mut Sensors,
    timing: &Timing,
    stepper: &mut S,
    observer: &mut O,
) -> Result<(), S::Error> {
    let dt = timing.dt_s;
    let per_tick = timing.steps_per_tick;
    let load = scenario.load();
    let mut s = rig.initial_state(load.value(0.0));
    for j in 0..timing.ticks {
        let k0 = j * per_tick;
        let t = tick_time_s(k0, dt);
        let ft = load.value(t);
        let x = s.x;
        let truth = Readings {
            xi_m: x.xi_m,
            xo_m: x.xo_m,
            p1_pa: x.p1_pa,
            p2_pa: x.p2_pa,
            ft_n: ft,
        };
        let meas = sensors.read(&truth);
        let sample = meas.to_sample();
        let ref_m = match scenario.command() {
            Command::Reference(r) => r.value(t),
            Command::OpenLoop(_) => 0.0,
        };
        let output = stepper.step(&ControlInput {
            tick: j,
            t_s: t,
            sample: &sample,
            ref_m,
        })?;
        observer.observe(
            &TickView {
                tick: j,
                k: k0,
                t_s: t,
                rig,
                state: &s,
                load_n: ft,
                meas: &meas,
                sample: &sample,
                ref_m,
                output: &output,
            },
            stepper,
        )?;
        let v = output.v_cmd_mps();
        for k in k0..k0 + per_tick {
            // Ft(k0 dt) is the tick's load, already evaluated.
            let ft_k = if k == k0 {
                ft
            } else {
                load.value(tick_time_s(k, dt))
            };
            rig.step(&mut s, v, ft_k, dt);
        }
    }
    Ok(())
}
