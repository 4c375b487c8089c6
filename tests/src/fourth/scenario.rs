//! Scenarios (reference and load), the controllers of `dca_core` at the
//! board's 1 ms tick, the closed loop and the run log of interfaces.md
//! section 1.

use std::f64::consts::PI;

use dca_core::{Controller, ControllerConfig, ControllerKind, Preset, Sample};

use super::plant::ix::*;
use super::rig::Rig;
use super::sensors::Sensors;

/// Length of every run, s.
pub const T_END: f64 = 10.0;
/// The board's controller tick (and the log's step), s.
pub const BOARD_DT: f64 = 1.0e-3;

/// A reference and load programme. All start at rest at 0 with no load.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scenario {
    /// Staircase of seven levels (0.2 s edges); a load ramp to 450 N, then changes to
    /// 150 N and 650 N (load changes have 0.15 s raised-cosine edges in every
    /// scenario).
    Stairs,
    /// Trapezoids (ramps at 30, 15, 40 mm/s with holds); the load ramps up to
    /// 700 N and down to 100 N.
    Ramps,
    /// Smooth approach to 25 mm, then a +-12 mm chirp from 0.15 to 1.2 Hz;
    /// 250 N from 0.8 s.
    Chirp,
    /// Smooth approach to 30 mm, then a 40/20 mm square wave at 0.35 Hz
    /// (0.2 s edges); a 0/500 N square load at 0.25 Hz.
    Square,
    /// Smooth approach to 40 mm and hold; load steps 800, 150, 600, -100,
    /// 350 N.
    LoadSteps,
    /// Ramp to 20 mm, +-3 mm triangle at 0.5 Hz, then a 2 mm 1 Hz sine; a
    /// 300 +- 250 N sine load at 0.3 Hz.
    Reversals,
    /// Steps 35, 10, 45, 25 mm with a small assisting load (-40 N, line 1 at
    /// low pressure) and a 350 N pulse.
    LowLoad,
    /// Ramps at 20 to 100 mm/s between 10 and 45 mm, under 450 N except
    /// for 5.5-8 s without load.
    Heavy,
}

fn smooth(t: f64, t1: f64) -> f64 {
    if t < t1 {
        0.5 * (1.0 - (PI * t / t1).cos())
    } else {
        1.0
    }
}

/// Load changes take this long (a raised-cosine edge): a rig's load is
/// never a perfect step, and a sharp 700 N drop would pull line 1 far below
/// vapour pressure, where no model of plant.md holds.
pub const LOAD_EDGE_S: f64 = 0.15;

/// Piecewise-constant levels: `v0`, then `steps[i].1` from `steps[i].0`,
/// each change with a raised-cosine edge of `edge` seconds.
fn levels(t: f64, v0: f64, edge: f64, steps: &[(f64, f64)]) -> f64 {
    let mut v = v0;
    for &(ts, vs) in steps {
        if t >= ts {
            v += (vs - v) * smooth(t - ts, edge);
        }
    }
    v
}

/// Reference changes of the staircase-like programmes take this long (a
/// raised-cosine edge), so that a velocity-output PI does not accelerate the
/// load hard enough to pull line 1 below zero gauge on a retraction.
pub const REF_EDGE_S: f64 = 0.2;

fn ramp(t: f64, t0: f64, t1: f64, a: f64, b: f64) -> f64 {
    if t < t0 {
        a
    } else if t < t1 {
        a + (b - a) * (t - t0) / (t1 - t0)
    } else {
        b
    }
}

impl Scenario {
    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Self::Stairs => "stairs",
            Self::Ramps => "ramps",
            Self::Chirp => "chirp",
            Self::Square => "square",
            Self::LoadSteps => "loadsteps",
            Self::Reversals => "reversals",
            Self::LowLoad => "lowload",
            Self::Heavy => "heavy",
        }
    }

    /// Position reference r(t), m.
    pub fn reference(self, t: f64) -> f64 {
        match self {
            Self::Stairs => levels(
                t,
                0.0,
                REF_EDGE_S,
                &[
                    (0.3, 0.012),
                    (1.7, 0.030),
                    (3.1, 0.048),
                    (4.6, 0.022),
                    (6.0, 0.040),
                    (7.5, 0.008),
                    (8.8, 0.028),
                ],
            ),
            Self::Ramps => {
                if t < 3.5 {
                    ramp(t, 0.3, 1.8, 0.0, 0.045)
                } else if t < 6.5 {
                    ramp(t, 3.5, 5.5, 0.045, 0.015)
                } else {
                    ramp(t, 6.5, 7.0, 0.015, 0.035)
                }
            }
            Self::Chirp => {
                if t < 1.5 {
                    0.025 * smooth(t, 1.5)
                } else {
                    let tau = t - 1.5;
                    let (f0, f1, tt) = (0.15, 1.2, 8.5);
                    let ph = f0 * tau + (f1 - f0) * tau * tau / (2.0 * tt);
                    0.025 + 0.012 * (2.0 * PI * ph).sin()
                }
            }
            Self::Square => {
                if t < 1.0 {
                    0.030 * smooth(t, 1.0)
                } else {
                    // 40 / 20 mm, half period 1/0.7 s, from 1 s.
                    let half = 1.0 / 0.7;
                    let edges: Vec<(f64, f64)> = (0..7)
                        .map(|i| {
                            (
                                1.0 + half * i as f64,
                                if i % 2 == 0 { 0.040 } else { 0.020 },
                            )
                        })
                        .collect();
                    levels(t, 0.030, REF_EDGE_S, &edges)
                }
            }
            Self::LoadSteps => 0.040 * smooth(t, 1.2),
            Self::Reversals => {
                if t < 1.0 {
                    ramp(t, 0.2, 1.0, 0.0, 0.020)
                } else if t < 6.0 {
                    // Triangle of period 2 s, starting upwards.
                    let ph = ((t - 1.0) / 2.0).fract();
                    let tri = if ph < 0.25 {
                        4.0 * ph
                    } else if ph < 0.75 {
                        2.0 - 4.0 * ph
                    } else {
                        4.0 * ph - 4.0
                    };
                    0.020 + 0.003 * tri
                } else {
                    0.020 + 0.002 * (2.0 * PI * (t - 6.0)).sin()
                }
            }
            Self::LowLoad => levels(
                t,
                0.0,
                REF_EDGE_S,
                &[(0.3, 0.035), (3.0, 0.010), (5.5, 0.045), (8.0, 0.025)],
            ),
            Self::Heavy => {
                let moves = [
                    (0.5, 2.5, 0.040),
                    (3.5, 4.25, 0.010),
                    (4.6, 5.18, 0.045),
                    (6.0, 6.3, 0.020),
                    (6.8, 7.3, 0.045),
                    (8.5, 8.8, 0.015),
                    (9.2, 9.5, 0.035),
                ];
                let mut r = 0.0;
                for (t0, t1, to) in moves {
                    if t >= t0 {
                        r = ramp(t, t0, t1, r, to);
                    }
                }
                r
            }
        }
    }

    /// Load Ft(t), N (positive opposes extension).
    pub fn load(self, t: f64) -> f64 {
        match self {
            Self::Stairs => {
                if t < 5.8 {
                    ramp(t, 2.4, 3.4, 0.0, 450.0)
                } else {
                    levels(t, 450.0, LOAD_EDGE_S, &[(5.8, 150.0), (8.2, 650.0)])
                }
            }
            Self::Ramps => {
                if t < 6.0 {
                    ramp(t, 1.0, 6.0, 0.0, 700.0)
                } else {
                    ramp(t, 6.0, 9.0, 700.0, 100.0)
                }
            }
            Self::Chirp => levels(t, 0.0, LOAD_EDGE_S, &[(0.8, 250.0)]),
            Self::Square => {
                // 0 / 500 N at 0.25 Hz from 1.5 s.
                let edges: Vec<(f64, f64)> = (0..5)
                    .map(|i| (1.5 + 2.0 * i as f64, if i % 2 == 0 { 500.0 } else { 0.0 }))
                    .collect();
                levels(t, 0.0, LOAD_EDGE_S, &edges)
            }
            Self::LoadSteps => levels(
                t,
                0.0,
                LOAD_EDGE_S,
                &[
                    (2.0, 800.0),
                    (4.0, 150.0),
                    (5.5, 600.0),
                    (7.0, -100.0),
                    (8.5, 350.0),
                ],
            ),
            Self::Reversals => {
                if t < 1.0 {
                    0.0
                } else {
                    300.0 * smooth(t - 1.0, 0.5) + 250.0 * (2.0 * PI * 0.3 * (t - 1.0)).sin()
                }
            }
            Self::LowLoad => levels(
                t,
                0.0,
                LOAD_EDGE_S,
                &[(0.5, -40.0), (6.5, 350.0), (7.5, -40.0)],
            ),
            Self::Heavy => {
                if t < 5.5 {
                    ramp(t, 0.2, 1.0, 0.0, 450.0)
                } else {
                    levels(t, 450.0, LOAD_EDGE_S, &[(5.5, 0.0), (8.0, 450.0)])
                }
            }
        }
    }
}

/// A controller of `dca_core` with its preset.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ctl {
    /// The law.
    pub kind: ControllerKind,
    /// The parameter preset.
    pub preset: Preset,
}

impl Ctl {
    /// `kind@preset`, e.g. `mpc-eso@paper`.
    pub fn label(self) -> String {
        format!("{}@{}", self.kind.name(), self.preset.name())
    }

    /// The designed controller at the board tick.
    pub fn build(self) -> Controller {
        let mut cfg = ControllerConfig::preset(self.preset, self.kind);
        cfg.base_dt_s = BOARD_DT;
        Controller::new(&cfg).unwrap_or_else(|e| panic!("{}: {}", self.label(), e.as_str()))
    }
}

/// One run: scenario, controller, noise seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunSpec {
    /// The programme.
    pub scenario: Scenario,
    /// The controller.
    pub ctl: Ctl,
    /// Noise seed.
    pub seed: u64,
}

/// A run log: one row per board tick, the columns of interfaces.md
/// section 1 (t, ref, vcmd, xi, xo, p1, p2, ft).
#[derive(Clone, Debug, PartialEq)]
pub struct Log {
    /// Controller label for the metadata line.
    pub controller: String,
    /// Rows.
    pub rows: Vec<[f64; 8]>,
}

/// Column indices of [`Log::rows`].
pub mod col {
    /// t_s.
    pub const T: usize = 0;
    /// ref_m.
    pub const REF: usize = 1;
    /// vcmd_mps.
    pub const VCMD: usize = 2;
    /// xi_m.
    pub const XI: usize = 3;
    /// xo_m.
    pub const XO: usize = 4;
    /// p1_pa.
    pub const P1: usize = 5;
    /// p2_pa.
    pub const P2: usize = 6;
    /// ft_n.
    pub const FT: usize = 7;
}

impl Log {
    /// The CSV text of interfaces.md section 1, keeping every `every`-th row.
    pub fn to_csv(&self, every: usize) -> String {
        let mut s = String::with_capacity(self.rows.len() / every * 90 + 200);
        s.push_str("# dca-log v1\n");
        s.push_str(&format!("# controller={}\n", self.controller));
        s.push_str("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
        for r in self.rows.iter().step_by(every) {
            s.push_str(&format!(
                "{:.3},{:.6},{:.6},{:.8},{:.8},{:.1},{:.1},{:.2}\n",
                r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7]
            ));
        }
        s
    }
}

/// Run `rig` in closed loop: every board tick (1 ms) the sensors are read,
/// the controller steps and a row is logged; the plant runs RK4 at its own
/// step with the command and the load held (the load sampled at each plant
/// step, plant.md section 4.2). Realistic sensors when `noisy`.
pub fn run(rig: &Rig, spec: &RunSpec, noisy: bool) -> Log {
    let p = &rig.p;
    let n_sub = (BOARD_DT / p.dt).round() as usize;
    let n_rows = (T_END / BOARD_DT).round() as usize + 1;
    let mut ctl = spec.ctl.build();
    let mut sensors = Sensors::new(spec.seed, noisy, &rig.effects, p.dt);
    let sc = spec.scenario;
    let mut x = rig.rest(sc.load(0.0));
    sensors.record(&x);
    let mut rows = Vec::with_capacity(n_rows);
    let mut v_cmd = 0.0;
    for row in 0..n_rows {
        let k0 = row * n_sub;
        let t = k0 as f64 * p.dt;
        let ft = sc.load(t);
        let m = sensors.read(t, &x, ft);
        let r = sc.reference(t);
        let out = ctl.step(
            &Sample {
                xo_m: m.xo as f32,
                xi_m: m.xi as f32,
                p1_pa: m.p1 as f32,
                p2_pa: m.p2 as f32,
                ft_n: m.ft as f32,
            },
            r as f32,
        );
        if out.v_cmd_mps.is_finite() {
            v_cmd = f64::from(out.v_cmd_mps);
        }
        rows.push([t, r, v_cmd, m.xi, m.xo, m.p1, m.p2, m.ft]);
        if row + 1 == n_rows {
            break;
        }
        for j in 0..n_sub {
            let k = k0 + j;
            let tk = k as f64 * p.dt;
            x = rig.step(tk, &x, v_cmd, sc.load(tk));
            sensors.record(&x);
        }
        debug_assert!(x[XO].is_finite());
    }
    Log {
        controller: spec.ctl.label(),
        rows,
    }
}
