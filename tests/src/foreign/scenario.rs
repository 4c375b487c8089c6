//! Scenarios, the closed loop with the dca-core controller, and the run log.
//!
//! Per base tick k (t_k = k 1e-4 s), as docs/model.md section 6.1: sample the
//! sensors at t_k, call [`Controller::step`] with the readings (f32) and
//! r(t_k), then advance the plant one tick with that command and Ft(t_k)
//! held. Every tenth tick (1 ms) a row is logged with the readings the
//! controller saw and the command it returned (held over the next ms, since
//! the controller only changes its command at multiples of 1 ms).

use std::collections::VecDeque;
use std::fmt::Write as _;

use dca_core::{Controller, ControllerConfig, ControllerKind, Preset, Sample};

use super::effects::Effects;
use super::plant::{Plant, BASE_DT, P1, P2, SUBSTEPS, XI, XO};
use super::sensors::{SensorMode, Sensors, Signals};
use super::ForeignCase;

/// A closed-loop scenario: controller, reference, load and length.
#[derive(Clone, Copy, Debug)]
pub struct ScenarioSpec {
    /// Short name.
    pub name: &'static str,
    /// Controller (preset "paper").
    pub kind: ControllerKind,
    /// Length, s (rows at 0, 1 ms, ..., duration).
    pub duration_s: f64,
    /// Position reference r(t), m.
    pub reference: fn(f64) -> f64,
    /// Load Ft(t), N.
    pub load: fn(f64) -> f64,
}

fn fit_ref(t: f64) -> f64 {
    if t < 3.0 {
        0.050
    } else if t < 8.5 {
        0.020
    } else {
        0.035
    }
}

fn fit_load(t: f64) -> f64 {
    if t < 5.0 {
        0.0
    } else if t < 7.5 {
        800.0
    } else {
        400.0
    }
}

fn sine_ref(t: f64) -> f64 {
    0.025 * (1.0 - (std::f64::consts::PI * t / 2.0).cos())
}

fn sine_load(t: f64) -> f64 {
    400.0 + 200.0 * (std::f64::consts::PI * t).sin()
}

fn step_ref(_t: f64) -> f64 {
    0.050
}

fn no_load(_t: f64) -> f64 {
    0.0
}

fn stepload_load(t: f64) -> f64 {
    if t < 4.0 {
        0.0
    } else if t < 7.0 {
        800.0
    } else {
        400.0
    }
}

/// The two scenarios of the foreign logs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ForeignScenario {
    /// MPC-ESO; 50 mm step, 20 mm from 3 s, 35 mm from 8.5 s; load 0, 800 N
    /// from 5 s, 400 N from 7.5 s; 10 s.
    Fit,
    /// PID; r = 0.025 (1 - cos(pi t/2)) m; Ft = 400 + 200 sin(pi t) N; 10 s.
    Check,
}

impl ForeignScenario {
    /// Both scenarios.
    pub const ALL: [Self; 2] = [Self::Fit, Self::Check];

    /// `fit` or `check`.
    pub fn name(self) -> &'static str {
        match self {
            Self::Fit => "fit",
            Self::Check => "check",
        }
    }

    /// The scenario definition.
    pub fn spec(self) -> ScenarioSpec {
        match self {
            Self::Fit => ScenarioSpec {
                name: "fit",
                kind: ControllerKind::MpcEso,
                duration_s: 10.0,
                reference: fit_ref,
                load: fit_load,
            },
            Self::Check => ScenarioSpec {
                name: "check",
                kind: ControllerKind::Pid,
                duration_s: 10.0,
                reference: sine_ref,
                load: sine_load,
            },
        }
    }
}

/// The closed-loop scenarios of docs/model.md section 7 (`step`, `sine`,
/// `stepload`, `sineload`) for the controller `kind`, for checking the
/// nominal loop against section 10.
pub fn paper_scenario(name: &str, kind: ControllerKind) -> Option<ScenarioSpec> {
    let spec = |name, duration_s, reference, load| ScenarioSpec {
        name,
        kind,
        duration_s,
        reference,
        load,
    };
    match name {
        "step" => Some(spec("step", 6.0, step_ref, no_load)),
        "sine" => Some(spec("sine", 10.0, sine_ref, no_load)),
        "stepload" => Some(spec("stepload", 10.0, step_ref, stepload_load)),
        "sineload" => Some(spec("sineload", 10.0, step_ref, sine_load)),
        _ => None,
    }
}

/// One logged row (1 ms grid).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LogRow {
    /// Time, s.
    pub t_s: f64,
    /// Reference, m.
    pub ref_m: f64,
    /// Command sent to the drive for the next ms, m/s.
    pub vcmd_mps: f64,
    /// What the sensors reported.
    pub meas: Signals,
    /// Noise-free sensor signals (what the sensors convert: includes sensor
    /// dynamics, excludes noise and quantisation).
    pub signal: Signals,
    /// True actuating piston position, m.
    pub xo_true_m: f64,
}

/// A simulated run.
#[derive(Clone, Debug, PartialEq)]
pub struct ForeignRun {
    /// The controller that ran.
    pub controller: ControllerKind,
    /// Rows at 0, 1 ms, ..., duration.
    pub rows: Vec<LogRow>,
}

impl ForeignRun {
    /// The run log in the format of docs/interfaces.md section 1.
    pub fn to_csv(&self) -> String {
        let mut s = String::with_capacity(100 * (self.rows.len() + 4));
        s.push_str("# dca-log v1\n");
        let _ = writeln!(s, "# controller={}", self.controller.name());
        s.push_str("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
        for r in &self.rows {
            let _ = writeln!(
                s,
                "{:.4},{:.9},{:.9},{:.9},{:.9},{:.1},{:.1},{:.3}",
                r.t_s,
                r.ref_m,
                r.vcmd_mps,
                r.meas.xi_m,
                r.meas.xo_m,
                r.meas.p1_pa,
                r.meas.p2_pa,
                r.meas.ft_n
            );
        }
        s
    }
}

/// Run `case` in `spec` with sensors `mode`; `seed` seeds the sensor noise
/// (mixed with the case's `noise_salt`).
pub fn simulate(
    case: &ForeignCase,
    spec: &ScenarioSpec,
    mode: SensorMode,
    seed: u64,
) -> ForeignRun {
    simulate_substeps(case, spec, mode, seed, SUBSTEPS)
}

/// [`simulate`] with `substeps` RK4 steps per base tick (for convergence checks).
pub fn simulate_substeps(
    case: &ForeignCase,
    spec: &ScenarioSpec,
    mode: SensorMode,
    seed: u64,
    substeps: u32,
) -> ForeignRun {
    let cfg = ControllerConfig::preset(Preset::Paper, spec.kind);
    assert!(
        (cfg.base_dt_s - BASE_DT).abs() < 1e-15,
        "the preset's base tick must be the plant's"
    );
    let mut ctl = Controller::new(&cfg).expect("paper preset designs");
    let fx = Effects::from_list(&case.effects);
    let mut plant = Plant::new(fx, (spec.load)(0.0));
    plant.substeps = substeps.max(1);
    let p_delay = fx.sensor_delay.map_or(0, |s| s.p_delay_ticks);
    // Holds the last `p_delay` pressures (the initial ones before t = 0).
    let mut p_hist: VecDeque<(f64, f64)> = VecDeque::with_capacity(p_delay + 1);
    for _ in 0..p_delay {
        p_hist.push_back((plant.x[P1], plant.x[P2]));
    }
    let noise_seed = seed ^ case.noise_salt.wrapping_mul(0xA076_1D64_78BD_642F);
    let mut sensors = Sensors::new(mode, noise_seed);
    let n = (spec.duration_s / BASE_DT).round() as u64;
    let mut rows = Vec::with_capacity((n / 10 + 1) as usize);
    for k in 0..=n {
        let t = k as f64 * BASE_DT;
        let r = (spec.reference)(t);
        let ft = (spec.load)(t);
        // Pressure transport delay: the reading of tick k is the value of tick k - d.
        p_hist.push_back((plant.x[P1], plant.x[P2]));
        let (p1, p2) = p_hist.pop_front().expect("history");
        let signal = Signals {
            xi_m: plant.x[XI],
            xo_m: plant.lvdt_signal(),
            p1_pa: p1,
            p2_pa: p2,
            ft_n: ft,
        };
        let meas = sensors.read(&signal);
        let sample = Sample {
            xo_m: meas.xo_m as f32,
            xi_m: meas.xi_m as f32,
            p1_pa: meas.p1_pa as f32,
            p2_pa: meas.p2_pa as f32,
            ft_n: meas.ft_n as f32,
        };
        let v = ctl.step(&sample, r as f32).v_cmd_mps as f64;
        if k % 10 == 0 {
            rows.push(LogRow {
                t_s: t,
                ref_m: r,
                vcmd_mps: v,
                meas,
                signal,
                xo_true_m: plant.x[XO],
            });
        }
        if k < n {
            plant.step(v, ft);
        }
    }
    ForeignRun {
        controller: spec.kind,
        rows,
    }
}

/// RMS differences between two runs' noise-free signals.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Magnitude {
    /// RMS of the encoder-signal (Xi) difference, um (no noise on this channel).
    pub xi_um: f64,
    /// RMS of the LVDT-signal difference, um.
    pub xo_um: f64,
    /// RMS of the P1 difference, kPa.
    pub p1_kpa: f64,
    /// RMS of the P2 difference, kPa.
    pub p2_kpa: f64,
}

impl Magnitude {
    /// Each channel over its sensor noise (10 um, 5 kPa, 5 kPa).
    pub fn over_noise(&self) -> [f64; 3] {
        [self.xo_um / 10.0, self.p1_kpa / 5.0, self.p2_kpa / 5.0]
    }

    /// The largest of [`Self::over_noise`].
    pub fn max_over_noise(&self) -> f64 {
        self.over_noise().into_iter().fold(0.0, f64::max)
    }
}

/// RMS over the run of (a - b) on the noise-free signals Xo, P1, P2 (and Xi).
pub fn rms_delta(a: &ForeignRun, b: &ForeignRun) -> Magnitude {
    assert_eq!(a.rows.len(), b.rows.len());
    let mut s = [0.0; 4];
    for (ra, rb) in a.rows.iter().zip(&b.rows) {
        let d = [
            ra.signal.xo_m - rb.signal.xo_m,
            ra.signal.p1_pa - rb.signal.p1_pa,
            ra.signal.p2_pa - rb.signal.p2_pa,
            ra.signal.xi_m - rb.signal.xi_m,
        ];
        for i in 0..4 {
            s[i] += d[i] * d[i];
        }
    }
    let n = a.rows.len() as f64;
    Magnitude {
        xi_um: (s[3] / n).sqrt() * 1e6,
        xo_um: (s[0] / n).sqrt() * 1e6,
        p1_kpa: (s[1] / n).sqrt() * 1e-3,
        p2_kpa: (s[2] / n).sqrt() * 1e-3,
    }
}
