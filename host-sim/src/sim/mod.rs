//! Layer `sim`: the closed loop around the model, and what runs it.
//!
//! * this module: the software loop ([`run`], [`run_with`]) and its results;
//! * [`closed_loop`]: the one loop it shares with the HIL lockstep
//!   ([`crate::hil`]): sensors, a control tick from a [`closed_loop::Stepper`],
//!   the plant;
//! * [`metrics`]: the performance metrics of docs/model.md section 8;
//! * [`request`]: `host-sim run`'s request resolved into a [`RunSpec`];
//! * [`config`]: controller configurations and custom scenarios from TOML;
//! * [`batch`]: parameter sweeps and Monte Carlo seeds on every core;
//! * [`tolerance`]: the tolerance specs the Monte Carlo draws rigs from.
//!
//! May import from [`crate::io`], [`crate::model`] and `sim` itself.
//!
//! # The software loop
//! The plant, the sensors and the control core, ticked as on the board: the
//! controller every control tick (`controller.base_dt_s` of the [`RunSpec`]:
//! 1 ms, the board's, wherever host-sim's commands and studies build the
//! spec), the plant in `p` RK4 steps of `dt_s` per tick (10 at the nominal
//! 1e-4 s) with the command held ([`closed_loop::drive`]). A finer control
//! tick is a study of what the board cannot do; it must be a whole number of
//! plant steps and divide 1 ms. Open-loop scenarios apply their command at
//! every plant step.
//!
//! Every control tick j (t_j = j p dt):
//! 1. the sensors read the state at t_j (and the load Ft(t_j));
//! 2. the controller's `step` returns the command (closed loop), or the
//!    scenario gives it (open loop);
//! 3. the plant takes its p RK4 steps with v_cmd held and Ft(t) at each step.
//!
//! A row is logged every millisecond, the first at t = 0 before the first
//! plant step, with what the sensors reported (docs/interfaces.md section 1) and,
//! beside it, the true state for plots and tests.

pub mod batch;
pub mod closed_loop;
pub mod config;
pub mod metrics;
pub mod request;
pub mod tolerance;

use dca_core::controller::{Controller, ControllerConfig, Output, Sample};

use crate::io::num::Num;
use crate::io::runlog::RunLog;
use crate::model::effects::Effects;
use crate::model::plant::{Plant, State};
use crate::model::rig::{Rig, RigError};
use crate::model::scenario::{tick_time_s, Command, Scenario, Signal};
use crate::model::sensors::{Readings, SensorMode};
use closed_loop::{drive, ControlInput, Drive, Observer, Stepper, TickView, Timing};

/// Everything one simulated run is made of.
#[derive(Clone, Debug)]
pub struct RunSpec {
    /// Reference and load profiles, duration.
    pub scenario: Scenario,
    /// The controller (ignored by open-loop scenarios); it ticks every
    /// `controller.base_dt_s` (the board's 1 ms in host-sim's commands).
    pub controller: ControllerConfig,
    /// The plant (hose model, parameters).
    pub plant: Plant,
    /// Unmodelled effects switched on (none: the nominal model).
    pub effects: Effects,
    /// Sensor mode.
    pub sensors: SensorMode,
    /// Noise seed.
    pub seed: u64,
    /// Plant step, s (1e-4 nominal).
    pub dt_s: f64,
}

/// One logged row (1 ms grid).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Row {
    /// Time, s.
    pub t_s: f64,
    /// Reference given to the controller, m (0 in open loop).
    pub ref_m: f64,
    /// Drive speed command applied from this instant, m/s.
    pub vcmd_mps: f64,
    /// What the sensors reported.
    pub meas: Readings,
    /// The true state at this instant.
    pub truth: State,
    /// True actuating piston acceleration, m/s^2.
    pub ao_true_mps2: f64,
    /// ESO estimates [z1 m, z2 m/s, z3 m/s^2] (MPC-ESO only).
    pub eso: Option<[f32; 3]>,
    /// Controller status bits of this tick.
    pub flags: u8,
}

/// A finished run.
#[derive(Clone, Debug)]
pub struct Trace {
    /// Scenario name.
    pub scenario: String,
    /// Controller name, or `open-loop`.
    pub controller: String,
    /// Rows on the 1 ms grid.
    pub rows: Vec<Row>,
}

impl Trace {
    /// The run as metric points (docs/model.md section 8): the measured Xo, or the
    /// true Xo when `truth` is set.
    pub fn points(&self, truth: bool) -> Vec<metrics::Point> {
        self.rows
            .iter()
            .map(|r| metrics::Point {
                t_s: r.t_s,
                ref_m: r.ref_m,
                xo_m: if truth { r.truth.xo_m } else { r.meas.xo_m },
            })
            .collect()
    }

    /// The run as a run log (what the sensors reported), with the ESO
    /// estimates and the controller flags as optional columns.
    pub fn to_runlog(&self, meta: &[(&str, String)]) -> RunLog {
        let mut log = RunLog {
            meta: std::iter::once(("controller".to_string(), self.controller.clone()))
                .chain(std::iter::once((
                    "scenario".to_string(),
                    self.scenario.clone(),
                )))
                .chain(meta.iter().map(|(k, v)| (k.to_string(), v.clone())))
                .collect(),
            ..RunLog::default()
        };
        let has_eso = self.rows.iter().any(|r| r.eso.is_some());
        for r in &self.rows {
            log.t_s.push(r.t_s);
            log.ref_m.push(r.ref_m);
            log.vcmd_mps.push(r.vcmd_mps);
            log.xi_m.push(r.meas.xi_m);
            log.xo_m.push(r.meas.xo_m);
            log.p1_pa.push(r.meas.p1_pa);
            log.p2_pa.push(r.meas.p2_pa);
            log.ft_n.push(r.meas.ft_n);
            if has_eso {
                let z = r.eso.unwrap_or([0.0; 3]);
                for (name, v) in ["z1_m", "z2_mps", "z3_mps2"].iter().zip(z) {
                    log.extra
                        .entry(name.to_string())
                        .or_default()
                        .push(v as f64);
                }
            }
            log.extra
                .entry("flags".to_string())
                .or_default()
                .push(r.flags as f64);
        }
        log
    }
}

/// What a per-tick observer sees.
pub struct Tick<'a> {
    /// Plant step index of the control tick.
    pub k: u64,
    /// Its time, s.
    pub t_s: f64,
    /// The true state then.
    pub state: &'a State,
    /// The sample given to the controller.
    pub sample: &'a Sample,
    /// The reference then, m (closed loop).
    pub ref_m: f64,
    /// The controller's output (the open-loop command in open loop).
    pub output: Output,
    /// The controller after its step (closed loop).
    pub controller: Option<&'a Controller>,
}

/// Why a run could not start.
#[derive(Clone, Debug, PartialEq)]
pub enum SimError {
    /// The controller configuration was refused.
    Config(String),
    /// The plant step is outside [`MIN_DT_S`] to 1 ms, or 1 ms is not a
    /// whole number of steps.
    Step(f64),
    /// The control tick is not a whole number of plant steps or does not
    /// divide 1 ms.
    Tick {
        /// The control tick, s.
        tick_s: f64,
        /// The plant step, s.
        dt_s: f64,
    },
    /// The effects cannot be combined with this plant.
    Effects(RigError),
    /// The plant's state stopped being finite (checked on the 1 ms grid).
    Diverged {
        /// The first logged instant with a non-finite state, s.
        t_s: f64,
    },
}

impl std::fmt::Display for SimError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Config(s) => write!(f, "controller configuration refused: {s}"),
            Self::Effects(s) => write!(f, "effects refused: {s}"),
            Self::Step(dt) => write!(
                f,
                "plant step {}{} must be within {} to 0.001 s and divide the 1 ms log grid",
                Num(*dt),
                if dt.is_nan() { " (not a number)" } else { " s" },
                Num(MIN_DT_S)
            ),
            Self::Tick { tick_s, dt_s } => write!(
                f,
                "control tick {} s must be a whole number of plant steps ({} s) and divide \
                 the 1 ms log grid (the board's tick is 0.001 s)",
                Num(*tick_s),
                Num(*dt_s)
            ),
            Self::Diverged { t_s } => write!(
                f,
                "the simulated plant diverged (state not finite at t = {t_s:.3} s): an \
                 effect or plant step far from its usual range?"
            ),
        }
    }
}

impl std::error::Error for SimError {}

/// The control core in this process, ticked with the reference as f32.
struct ControllerStepper(Controller);

impl Stepper for ControllerStepper {
    type Output = SimCommand;
    type Error = SimError;

    fn step(&mut self, input: &ControlInput<'_>) -> Result<SimCommand, SimError> {
        let output = self.0.step(input.sample, input.ref_m as f32);
        Ok(SimCommand {
            output,
            v_cmd_mps: output.v_cmd_mps as f64,
        })
    }

    fn controller(&self) -> Option<&Controller> {
        Some(&self.0)
    }
}

/// The scenario's open-loop speed command v_cmd(t), applied as f64.
struct OpenLoopStepper<'a>(&'a Signal);

impl Stepper for OpenLoopStepper<'_> {
    type Output = SimCommand;
    type Error = SimError;

    fn step(&mut self, input: &ControlInput<'_>) -> Result<SimCommand, SimError> {
        let v = self.0.value(input.t_s);
        Ok(SimCommand {
            output: Output {
                v_cmd_mps: v as f32,
                ..Output::default()
            },
            v_cmd_mps: v,
        })
    }
}

/// A software stepper's answer: the controller's output (the open-loop
/// command as f32 in open loop) and the command applied, m/s.
#[derive(Clone, Copy, Debug)]
struct SimCommand {
    output: Output,
    v_cmd_mps: f64,
}

impl Drive for SimCommand {
    fn v_cmd_mps(&self) -> f64 {
        self.v_cmd_mps
    }
}

/// The software loop's observer: the hook at every tick, a [`Row`] every
/// `log_every` plant steps (1 ms), the state checked for divergence on that
/// grid.
struct Logger<H> {
    log_every: u64,
    /// No effect on: the row's acceleration from the plant alone.
    nominal: bool,
    rows: Vec<Row>,
    hook: H,
}

impl<S, H> Observer<S> for Logger<H>
where
    S: Stepper<Output = SimCommand, Error = SimError>,
    H: FnMut(&Tick),
{
    fn observe(&mut self, t: &TickView<'_, SimCommand>, stepper: &S) -> Result<(), SimError> {
        let x = t.state.x;
        (self.hook)(&Tick {
            k: t.k,
            t_s: t.t_s,
            state: &x,
            sample: t.sample,
            ref_m: t.ref_m,
            output: t.output.output,
            controller: stepper.controller(),
        });
        if t.k.is_multiple_of(self.log_every) {
            if !t.state.is_finite() {
                return Err(SimError::Diverged { t_s: t.t_s });
            }
            let v_cmd = t.output.v_cmd_mps;
            let d = if self.nominal {
                t.rig.plant().derivative(&x, v_cmd, t.load_n)
            } else {
                t.rig.derivative(t.state, v_cmd, t.load_n).0
            };
            self.rows.push(Row {
                t_s: t.t_s,
                ref_m: t.ref_m,
                vcmd_mps: v_cmd,
                meas: *t.meas,
                truth: x,
                ao_true_mps2: d[State::VO],
                eso: stepper.controller().and_then(|c| c.eso_estimates()),
                flags: t.output.output.flags.0,
            });
        }
        Ok(())
    }
}

/// The smallest plant step, s: 1000 steps per logged millisecond (the
/// nominal step is 1e-4 s); a finer one would make a run of seconds take
/// hours.
pub const MIN_DT_S: f64 = 1e-6;

/// The plant steps per logged millisecond for the plant step `dt_s`, if it
/// is usable: within [`MIN_DT_S`] to 1 ms and dividing 1 ms.
pub fn steps_per_ms(dt_s: f64) -> Result<u64, SimError> {
    let per_ms = libm::round(1e-3 / dt_s);
    if (MIN_DT_S..=1e-3).contains(&dt_s) && per_ms >= 1.0 && (per_ms * dt_s - 1e-3).abs() < 1e-12 {
        Ok(per_ms as u64)
    } else {
        Err(SimError::Step(dt_s))
    }
}

/// The plant steps per control tick for the tick `tick_s` and the plant step
/// `dt_s` (already checked by [`steps_per_ms`]): the tick must be a whole
/// number of plant steps and divide 1 ms.
pub fn steps_per_tick(tick_s: f64, dt_s: f64) -> Result<u64, SimError> {
    let per_ms = steps_per_ms(dt_s)?;
    let n = libm::round(tick_s / dt_s);
    let whole = n >= 1.0 && (n * dt_s - tick_s).abs() < 1e-12;
    if whole && per_ms.is_multiple_of(n as u64) {
        Ok(n as u64)
    } else {
        Err(SimError::Tick { tick_s, dt_s })
    }
}

/// Run one scenario; `hook` sees every control tick after the controller
/// step (every plant step in open loop).
pub fn run_with(spec: &RunSpec, hook: impl FnMut(&Tick)) -> Result<Trace, SimError> {
    let dt = spec.dt_s;
    let log_every = steps_per_ms(dt)?;
    let cfg = spec.controller;
    let scenario = &spec.scenario;
    // The controller, or the open-loop command.
    let source = match scenario.command() {
        Command::Reference(_) => {
            Ok(Controller::new(&cfg).map_err(|e| SimError::Config(e.as_str().to_string()))?)
        }
        Command::OpenLoop(v) => Err(v),
    };
    // The controller's tick, or every plant step for the open-loop command.
    let per_tick = match source {
        Ok(_) => steps_per_tick(cfg.base_dt_s, dt)?,
        Err(_) => 1,
    };
    let tick_s = tick_time_s(per_tick, dt);
    let rig = Rig::new(spec.plant.clone(), spec.effects).map_err(SimError::Effects)?;
    let mut sensors = closed_loop::sensors(spec.sensors, spec.seed, &spec.effects, tick_s);
    let timing = Timing {
        dt_s: dt,
        steps_per_tick: per_tick,
        ticks: scenario.n_steps(tick_s),
    };
    let mut logger = Logger {
        log_every,
        nominal: spec.effects.is_none(),
        rows: Vec::with_capacity((timing.ticks * per_tick / log_every) as usize),
        hook,
    };
    let controller = match source {
        Ok(c) => {
            let mut stepper = ControllerStepper(c);
            drive(
                scenario,
                &rig,
                &mut sensors,
                &timing,
                &mut stepper,
                &mut logger,
            )?;
            cfg.kind.name().to_string()
        }
        Err(v) => {
            let mut stepper = OpenLoopStepper(v);
            drive(
                scenario,
                &rig,
                &mut sensors,
                &timing,
                &mut stepper,
                &mut logger,
            )?;
            "open-loop".to_string()
        }
    };
    Ok(Trace {
        scenario: scenario.name().to_string(),
        controller,
        rows: logger.rows,
    })
}

/// Run one scenario.
pub fn run(spec: &RunSpec) -> Result<Trace, SimError> {
    run_with(spec, |_| {})
}
