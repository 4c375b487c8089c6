//! This family's scenarios (staircase under load ramps, pulses and a pulling load
//! for the fit run; trapezoids, a chirp and a step under slow load ramps and load
//! pulses for the check run), the closed loop at the board's 1 ms tick, and
//! the run-log writer of docs/interfaces.md section 1.

use std::io::Write;
use std::path::Path;

use dca_core::controller::{Controller, ControllerConfig, ControllerKind, Preset, Sample};

use super::plant::{Rig, DT_S};
use super::sensors::Sensors;

/// Control tick and log row period, s (the board's and the HIL link's 1 kHz).
pub const TICK_S: f64 = 1.0e-3;

/// Which of the two scenarios.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scenario {
    /// Fit run: a staircase 0-20-45-30-60-15 mm, load ramp to 600 N, pulses to
    /// 1100 N and 800 N, a pulling load of -60 N, 10 s; MPC-ESO.
    Fit,
    /// Check run: trapezoidal moves (up at 25 mm/s, down at 40 mm/s), a 0.3-1.5 Hz
    /// chirp of +-5 mm around 20 mm and a 30 mm step at 8 s, under a slow load
    /// ramp to 900 N, 450 N load pulses and a second ramp from 250 to 700 N, 10 s;
    /// fuzzy PID.
    Check,
}

fn lin(t: f64, t0: f64, t1: f64, a: f64, b: f64) -> f64 {
    a + (b - a) * ((t - t0) / (t1 - t0)).clamp(0.0, 1.0)
}

impl Scenario {
    /// Duration, s.
    pub fn duration_s(self) -> f64 {
        10.0
    }

    /// The controller that runs it.
    pub fn controller(self) -> ControllerKind {
        match self {
            Scenario::Fit => ControllerKind::MpcEso,
            Scenario::Check => ControllerKind::FuzzyPid,
        }
    }

    /// Position reference at t, m.
    pub fn reference_m(self, t: f64) -> f64 {
        match self {
            Scenario::Fit => {
                if t < 0.3 {
                    0.0
                } else if t < 2.0 {
                    0.020
                } else if t < 4.0 {
                    0.045
                } else if t < 6.0 {
                    0.030
                } else if t < 8.0 {
                    0.060
                } else {
                    0.015
                }
            }
            Scenario::Check => {
                if t < 3.5 {
                    lin(t, 0.2, 2.2, 0.0, 0.050)
                } else if t < 5.0 {
                    lin(t, 3.5, 4.25, 0.050, 0.020)
                } else if t < 8.0 {
                    let tc = t - 5.0;
                    let (f0, f1, tt) = (0.3, 1.5, 3.0);
                    let phase =
                        2.0 * std::f64::consts::PI * (f0 * tc + (f1 - f0) * tc * tc / (2.0 * tt));
                    0.020 + 0.005 * phase.sin()
                } else {
                    0.045
                }
            }
        }
    }

    /// Load at t, N (positive against extension).
    pub fn load_n(self, t: f64) -> f64 {
        match self {
            Scenario::Fit => {
                if t < 3.0 {
                    lin(t, 1.0, 3.0, 0.0, 600.0)
                } else if t < 5.0 {
                    if (3.3..3.8).contains(&t) {
                        1100.0
                    } else {
                        600.0
                    }
                } else if t < 7.0 {
                    lin(t, 5.0, 5.2, 600.0, -60.0)
                } else if (9.0..9.4).contains(&t) {
                    800.0
                } else {
                    300.0
                }
            }
            Scenario::Check => {
                if t < 4.0 {
                    lin(t, 1.0, 4.0, 150.0, 900.0)
                } else if t < 8.0 {
                    let base = lin(t, 4.0, 4.1, 900.0, 250.0);
                    let pulse = [5.5, 6.5, 7.5].iter().any(|&p| (p..p + 0.25).contains(&t));
                    base + if pulse { 450.0 } else { 0.0 }
                } else {
                    lin(t, 8.0, 10.0, 250.0, 700.0)
                }
            }
        }
    }
}

/// A run log: one row per tick, the columns of docs/interfaces.md section 1.
#[derive(Clone, Debug, Default)]
pub struct Log {
    /// Controller name for the metadata line.
    pub controller: String,
    /// Rows: t_s, ref_m, vcmd_mps, xi_m, xo_m, p1_pa, p2_pa, ft_n.
    pub rows: Vec<[f64; 8]>,
}

impl Log {
    /// Every `n`-th row, as the board's console records at 1/n of the tick rate.
    pub fn decimate(&self, n: usize) -> Log {
        Log {
            controller: self.controller.clone(),
            rows: self.rows.iter().step_by(n).copied().collect(),
        }
    }

    /// Write the log as CSV (docs/interfaces.md section 1).
    pub fn write(&self, path: &Path) -> std::io::Result<()> {
        let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
        writeln!(w, "# dca-log v1")?;
        writeln!(w, "# controller={}", self.controller)?;
        writeln!(w, "# source=dca-tests third family")?;
        writeln!(w, "t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n")?;
        for r in &self.rows {
            writeln!(
                w,
                "{:.4},{:.9},{:.9},{:.9},{:.9},{:.1},{:.1},{:.3}",
                r[0], r[1], r[2], r[3], r[4], r[5], r[6], r[7]
            )?;
        }
        w.flush()
    }
}

/// Run `scenario` in closed loop on `rig` with realistic sensors (noise seed
/// `seed`); the controller ticks every 1 ms, the plant steps 10 x 0.1 ms.
///
/// Returns the log, or an error text if the controller cannot be built or the
/// state stops being finite.
pub fn run(rig: &Rig, scenario: Scenario, seed: u64) -> Result<Log, String> {
    let kind = scenario.controller();
    let mut cfg = ControllerConfig::preset(Preset::Paper, kind);
    cfg.base_dt_s = TICK_S;
    let mut ctl = Controller::new(&cfg).map_err(|e| format!("controller: {e:?}"))?;
    let mut sensors = Sensors::new(rig.effects, seed);
    let mut x = rig.rest(scenario.load_n(0.0));
    let n_ticks = (scenario.duration_s() / TICK_S).round() as usize;
    let sub = (TICK_S / DT_S).round() as usize;
    let mut log = Log {
        controller: kind.name().to_string(),
        rows: Vec::with_capacity(n_ticks),
    };
    for k in 0..n_ticks {
        let t = k as f64 * TICK_S;
        let r = scenario.reference_m(t);
        let rd = sensors.read(t, &x, scenario.load_n(t));
        let sample = Sample {
            xo_m: rd.xo_m as f32,
            xi_m: rd.xi_m as f32,
            p1_pa: rd.p1_pa as f32,
            p2_pa: rd.p2_pa as f32,
            ft_n: rd.ft_n as f32,
        };
        let v = f64::from(ctl.step(&sample, r as f32).v_cmd_mps);
        log.rows
            .push([t, r, v, rd.xi_m, rd.xo_m, rd.p1_pa, rd.p2_pa, rd.ft_n]);
        for j in 0..sub {
            let tj = t + j as f64 * DT_S;
            rig.step(tj, &mut x, v, scenario.load_n(tj), DT_S);
        }
        if !x.iter().all(|v| v.is_finite()) {
            return Err(format!("state not finite at t = {t:.3} s"));
        }
    }
    Ok(log)
}
