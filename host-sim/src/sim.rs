//! The software loop: plant, sensors and the control core, ticked as in
//! plant.md section 6.1.
//!
//! Every base tick k (t_k = k dt):
//! 1. the sensors read the state at t_k (and the load Ft(t_k));
//! 2. the controller's `step` returns the command (closed loop), or the
//!    scenario gives it (open loop);
//! 3. the plant takes one RK4 step with (v_cmd, Ft(t_k)) held.
//!
//! A row is logged every millisecond, the first at t = 0 before the first
//! plant step, with what the sensors reported (interfaces.md section 1) and,
//! beside it, the true state for plots and tests.

use dca_core::controller::{Controller, ControllerConfig, Output, Sample};

use crate::effects::Effects;
use crate::plant::{Plant, State};
use crate::rig::Rig;
use crate::scenario::{tick_time_s, Command, Scenario};
use crate::sensors::{Readings, SensorMode, Sensors};

/// Everything one simulated run is made of.
#[derive(Clone, Debug)]
pub struct RunSpec {
    /// Reference and load profiles, duration.
    pub scenario: Scenario,
    /// The controller (ignored by open-loop scenarios).
    pub controller: ControllerConfig,
    /// The plant (hose model, parameters).
    pub plant: Plant,
    /// Unmodelled effects switched on (none: the nominal model).
    pub effects: Effects,
    /// Sensor mode.
    pub sensors: SensorMode,
    /// Noise seed.
    pub seed: u64,
    /// Plant step, s (1e-4 nominal; the controller's base tick follows it).
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
    /// The run as metric points (plant.md section 8): the measured Xo, or the
    /// true Xo when `truth` is set.
    pub fn points(&self, truth: bool) -> Vec<crate::metrics::Point> {
        self.rows
            .iter()
            .map(|r| crate::metrics::Point {
                t_s: r.t_s,
                ref_m: r.ref_m,
                xo_m: if truth { r.truth.xo_m } else { r.meas.xo_m },
            })
            .collect()
    }
}

/// What a per-tick observer sees.
pub struct Tick<'a> {
    /// Base tick index.
    pub k: u64,
    /// t_k, s.
    pub t_s: f64,
    /// The true state at t_k.
    pub state: &'a State,
    /// The sample given to the controller.
    pub sample: &'a Sample,
    /// The reference r(t_k), m (closed loop).
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
    /// The plant step is not positive, or 1 ms is not a whole number of steps.
    Step(f64),
    /// The effects cannot be combined with this plant.
    Effects(String),
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
                "plant step {dt} s must be > 0 and divide the 1 ms log grid"
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

/// Run one scenario; `hook` sees every base tick after the controller step.
pub fn run_with(spec: &RunSpec, mut hook: impl FnMut(&Tick)) -> Result<Trace, SimError> {
    let dt = spec.dt_s;
    let per_ms = libm::round(1e-3 / dt);
    if !(dt > 0.0 && per_ms >= 1.0 && (per_ms * dt - 1e-3).abs() < 1e-12) {
        return Err(SimError::Step(dt));
    }
    let log_every = per_ms as u64;
    let mut cfg = spec.controller;
    cfg.base_dt_s = dt;
    let open_loop = spec.scenario.is_open_loop();
    let mut ctl = if open_loop {
        None
    } else {
        Some(Controller::new(&cfg).map_err(|e| SimError::Config(e.as_str().to_string()))?)
    };
    let rig = Rig::new(spec.plant.clone(), spec.effects).map_err(|e| SimError::Effects(e.0))?;
    let plant = rig.plant();
    let scenario = &spec.scenario;
    let mut sensors = Sensors::new(spec.sensors, spec.seed);
    if let Some(d) = &spec.effects.sensor_delay {
        sensors = sensors.with_delay(d, dt);
    }
    let mut s = rig.initial_state(scenario.load().value(0.0));
    let n = scenario.n_steps(dt);
    let mut rows = Vec::with_capacity((n / log_every) as usize);
    for k in 0..n {
        let t = tick_time_s(k, dt);
        let ft = scenario.load().value(t);
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
        let (ref_m, out) = match (scenario.command(), ctl.as_mut()) {
            (Command::Reference(r), Some(c)) => {
                let r = r.value(t);
                (r, c.step(&sample, r as f32))
            }
            (Command::OpenLoop(v), _) | (Command::Reference(v), None) => (
                0.0,
                Output {
                    v_cmd_mps: v.value(t) as f32,
                    ..Output::default()
                },
            ),
        };
        hook(&Tick {
            k,
            t_s: t,
            state: &x,
            sample: &sample,
            ref_m,
            output: out,
            controller: ctl.as_ref(),
        });
        let v_cmd = if open_loop {
            match scenario.command() {
                Command::OpenLoop(v) => v.value(t),
                Command::Reference(_) => 0.0,
            }
        } else {
            out.v_cmd_mps as f64
        };
        if k % log_every == 0 {
            if !s.is_finite() {
                return Err(SimError::Diverged { t_s: t });
            }
            let d = if spec.effects.is_none() {
                plant.derivative(&x, v_cmd, ft)
            } else {
                rig.derivative(&s, v_cmd, ft).0
            };
            rows.push(Row {
                t_s: t,
                ref_m,
                vcmd_mps: v_cmd,
                meas,
                truth: x,
                ao_true_mps2: d[State::VO],
                eso: ctl.as_ref().and_then(|c| c.eso_estimates()),
                flags: out.flags.0,
            });
        }
        rig.step(&mut s, v_cmd, ft, dt);
    }
    Ok(Trace {
        scenario: scenario.name().to_string(),
        controller: if open_loop {
            "open-loop".to_string()
        } else {
            cfg.kind.name().to_string()
        },
        rows,
    })
}

/// Run one scenario.
pub fn run(spec: &RunSpec) -> Result<Trace, SimError> {
    run_with(spec, |_| {})
}
