//! Closures: a form-free term added to one equation of the model at a time,
//! fitted on the fit runs' structural residuals ([`super::equations`]) and
//! judged on the check runs'. Which closure explains the residuals says
//! which equation the rig violates; which of its variables the term depends
//! on says how. The verdict's name follows from the two ([`naming`]).
//!
//! Each closure is linear in its weights: a library of basis functions of
//! one equation's own variables (tents over a variable, play operators and
//! lags for memory, integrals for flows), whose responses in the four
//! residuals are computed by adding each basis function to the equation
//! ([`super::equations::Terms`]), or to a sensor's signal, or by changing a
//! nominal parameter. The weights are the least-squares fit of the fit runs'
//! residuals, every residual in units of its own noise, 10 ms block means.
//! A closure *explains* the share `1 - excess after / excess before` of the
//! residuals' power beyond their noise, on the check runs.

use serde::Serialize;

use super::equations::{noise_of, residuals, with_terms_over, Residual, Residuals, Signals, Terms};
use super::lsq::{dot, solve as gauss};
use super::stats::mean;
use crate::io::runlog::RunLog;
use crate::model::effects::{
    CalChannel, EffectKind, ParameterRatios, LEAK_DP_PA, SCREW_FORCES_N, SEAL_P_REF_PA,
};
use crate::model::plant::Plant;

/// Where a closure adds its term: an equation of the model, a sensor
/// channel, or the nominal parameters of all of them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Site {
    /// The servo's speed loop.
    Servo,
    /// The coupling from the motor (encoder) to the power piston.
    CouplingIn,
    /// The flow and compliance balance of line 1 (oil, hose wall).
    Line1,
    /// The flow and compliance balance of line 2 (oil, hose wall, accumulator).
    Line2,
    /// A flow between the lines, across the pistons' seals.
    Between,
    /// The actuating piston's force balance.
    Force,
    /// One sensor channel.
    Sensor(CalChannel),
    /// The nominal parameters of every equation.
    Parameters,
    /// Every equation at once, by the clock.
    Clock,
}

impl Site {
    /// What the report calls it.
    pub fn name(self) -> String {
        match self {
            Self::Servo => "the servo's speed loop".into(),
            Self::CouplingIn => "the coupling from the motor to the power piston".into(),
            Self::Line1 => "line 1's flow and compliance balance".into(),
            Self::Line2 => "line 2's flow and compliance balance (with the accumulator)".into(),
            Self::Between => "a flow between the lines (the pistons' seals)".into(),
            Self::Force => "the actuating piston's force balance".into(),
            Self::Sensor(c) => format!("the {} sensor channel", c.name()),
            Self::Parameters => "the nominal parameters".into(),
            Self::Clock => "every equation, by the clock".into(),
        }
    }

    /// The part of the rig, as the JSON's `subsystem` says it.
    pub fn subsystem(self) -> &'static str {
        match self {
            Self::Servo => "servo",
            Self::CouplingIn => "coupling",
            Self::Line1 | Self::Line2 => "hose",
            Self::Between => "seals",
            Self::Force => "seals",
            Self::Sensor(_) => "sensors",
            Self::Parameters => "plant",
            Self::Clock => "plant",
        }
    }
}

/// What a closure's term depends on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dependence {
    /// The equation's own terms, scaled (a parameter off).
    OwnTerms,
    /// The line's pressure, statically.
    Pressure,
    /// The pressure difference across the pistons (a flow, integrated).
    PressureDifference,
    /// The line's pressure history (rate-independent: play operators).
    PressureHistory,
    /// Time: relaxation of the line's pressure over time constants.
    Relaxation,
    /// The actuating piston's speed.
    Speed,
    /// The force the coupling carries (relative displacement).
    Force,
    /// The force the coupling carries, with a loop (friction in it).
    ForceHistory,
    /// A flow out of the line to the tank, growing with its pressure.
    Outflow,
    /// The load's position.
    Position,
    /// The servo's requested acceleration, load force and speed.
    Drive,
    /// The sensor's own signal, statically.
    Signal,
    /// The sensor's signal delayed or lagged.
    Rate,
    /// Time itself: a drift.
    Drift,
}

impl Dependence {
    /// What the report calls it.
    pub fn name(self) -> &'static str {
        match self {
            Self::OwnTerms => "its own terms, scaled",
            Self::Pressure => "pressure",
            Self::PressureDifference => "the pressure difference (a flow)",
            Self::PressureHistory => "pressure history (a loop)",
            Self::Relaxation => "time (a relaxation)",
            Self::Speed => "speed",
            Self::Force => "the force it carries (relative displacement)",
            Self::ForceHistory => {
                "the force it carries, with a loop (relative displacement with friction)"
            }
            Self::Outflow => "its pressure, as a flow out of the line (to the tank)",
            Self::Position => "position",
            Self::Drive => "the drive's demand (acceleration, force, speed)",
            Self::Signal => "the signal itself",
            Self::Rate => "the signal's history (a lag)",
            Self::Drift => "time (a drift)",
        }
    }
}

/// The identifier a located violation is named by: the table of
/// docs/gap.md. `None`: outside the catalogue (`unexplained`).
pub fn naming(site: Site, dep: Dependence) -> Option<EffectKind> {
    use Dependence as D;
    use EffectKind as K;
    match (site, dep) {
        (Site::Parameters, _) => Some(K::Parameters),
        (Site::Servo, D::Drive) => Some(K::MotorLimit),
        (Site::CouplingIn, D::Force | D::ForceHistory) => Some(K::Backlash),
        (Site::Line1 | Site::Line2, D::Pressure) => Some(K::Air),
        (Site::Line1 | Site::Line2, D::PressureHistory) => Some(K::HoseHysteresis),
        (Site::Line2, D::Relaxation) => Some(K::AccumulatorThermal),
        // The hose wall relaxing otherwise than modelled: its creep's
        // compliance or time constant are off.
        (Site::Line1, D::Relaxation) => Some(K::Parameters),
        (Site::Between, D::PressureDifference) => Some(K::Leakage),
        (Site::Force, D::Speed) => Some(K::Friction),
        (Site::Sensor(_), D::Signal) => Some(K::SensorCalibration),
        (Site::Sensor(_), D::Rate) => Some(K::SensorDelay),
        _ => None,
    }
}

/// One closure: a site, what its term depends on, and its basis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Closure {
    /// Where the term is added.
    pub site: Site,
    /// What it depends on.
    pub dep: Dependence,
}

impl Fitted {
    /// The residual whose excess it explains most of on the fit runs.
    pub fn dominant(&self) -> usize {
        (0..4)
            .max_by(|a, b| self.fit_per_residual[*a].total_cmp(&self.fit_per_residual[*b]))
            .unwrap_or(0)
    }
}

impl Closure {
    /// The identifier it names ([`naming`]).
    pub fn names(self) -> Option<EffectKind> {
        naming(self.site, self.dep)
    }

    /// Short label, e.g. `line1 / pressure history`.
    pub fn label(self) -> String {
        format!("{} / {}", self.site.name(), self.dep.name())
    }
}

/// Every closure tried, in a fixed order.
pub fn library() -> Vec<Closure> {
    use Dependence as D;
    let at = |site, dep| Closure { site, dep };
    let mut v = vec![
        at(Site::Parameters, D::OwnTerms),
        at(Site::Servo, D::Drive),
        at(Site::CouplingIn, D::Force),
        at(Site::CouplingIn, D::ForceHistory),
        at(Site::Between, D::PressureDifference),
    ];
    for site in [Site::Line1, Site::Line2] {
        for dep in [D::Pressure, D::PressureHistory, D::Relaxation] {
            v.push(at(site, dep));
        }
    }
    // A flow out of line 2 alone (to the tank). Out of line 1, such a flow
    // cannot be told from a leak into line 2: the accumulator takes up what
    // line 2 receives with a few kilopascals.
    v.push(at(Site::Line2, D::Outflow));
    v.push(at(Site::Force, D::Speed));
    v.push(at(Site::Force, D::Position));
    for ch in CalChannel::ALL {
        v.push(at(Site::Sensor(ch), D::Signal));
        v.push(at(Site::Sensor(ch), D::Rate));
    }
    v.push(at(Site::Clock, D::Drift));
    v
}

/// Knots that must be the same on every run (a closure is a function of the
/// variables): the sensors' ranges over the fit runs.
#[derive(Clone, Debug, PartialEq)]
pub struct Knots {
    /// Per channel (Xo, Xi, P1, P2, Ft): the tents' knots over its range.
    pub sensor: [Vec<f64>; 5],
    /// The LVDT's knots for a force over position.
    pub position: Vec<f64>,
}

impl Knots {
    /// Knots over the fit runs' ranges.
    pub fn of(fit: &[&Signals]) -> Self {
        let span = |f: &dyn Fn(&Signals) -> &[f64]| {
            let lo = fit
                .iter()
                .flat_map(|s| f(s).iter())
                .cloned()
                .fold(f64::INFINITY, f64::min);
            let hi = fit
                .iter()
                .flat_map(|s| f(s).iter())
                .cloned()
                .fold(f64::NEG_INFINITY, f64::max);
            let (lo, hi) = if hi > lo {
                (lo, hi)
            } else {
                (lo - 1.0, lo + 1.0)
            };
            (0..5)
                .map(|i| lo + (hi - lo) * i as f64 / 4.0)
                .collect::<Vec<f64>>()
        };
        let xo = span(&|s| &s.xo);
        Self {
            sensor: [
                xo.clone(),
                span(&|s| &s.xi),
                span(&|s| &s.p1),
                span(&|s| &s.p2),
                span(&|s| &s.ft),
            ],
            position: xo,
        }
    }
}

/// Knots of the servo's table over the acceleration the nominal speed loop
/// asks for, `(v_cmd - v) / tau`, m/s^2 (up to 10 for a full-speed step
/// from rest, 20 for a reversal).
pub const SERVO_ACCEL_MPS2: [f64; 7] = [-20.0, -8.0, -3.0, 0.0, 3.0, 8.0, 20.0];
/// Knots of the servo's table over the hydraulic force on the power piston, N.
pub const SERVO_FORCE_N: [f64; 3] = [-1000.0, 500.0, 2000.0];
/// Knots of the servo's table over the speed's magnitude, m/s.
pub const SERVO_SPEED_MPS: [f64; 3] = [0.0, 0.05, 0.1];
/// Cells of the servo's table (7 x 3 x 3).
pub const SERVO_CELLS: usize = 63;

/// The servo closure's basis: the weight of each cell of its table (a
/// correction of the delivered acceleration over the asked acceleration,
/// the load and the speed, interpolated between the knots and flat beyond)
/// at the asked acceleration `a_mps2`, the force `f_n` and the speed
/// `v_mps`. The weights sum to one.
pub fn servo_cells(a_mps2: f64, f_n: f64, v_mps: f64) -> [f64; SERVO_CELLS] {
    let at = |knots: &[f64], x: f64| {
        tents(&[x], knots)
            .into_iter()
            .map(|t| t[0])
            .collect::<Vec<f64>>()
    };
    let (ta, tf, tv) = (
        at(&SERVO_ACCEL_MPS2, a_mps2),
        at(&SERVO_FORCE_N, f_n),
        at(&SERVO_SPEED_MPS, v_mps.abs()),
    );
    let (na, nf) = (ta.len(), tf.len());
    std::array::from_fn(|k| ta[k % na] * tf[(k / na) % nf] * tv[k / (na * nf)])
}

/// Tents (a partition of unity) over increasing `knots`: flat beyond the
/// ends.
fn tents(x: &[f64], knots: &[f64]) -> Vec<Vec<f64>> {
    let m = knots.len();
    (0..m)
        .map(|i| {
            x.iter()
                .map(|&v| {
                    if i > 0 && v <= knots[i - 1] {
                        return 0.0;
                    }
                    if i + 1 < m && v >= knots[i + 1] {
                        return 0.0;
                    }
                    if v <= knots[i] {
                        if i == 0 {
                            1.0
                        } else {
                            (v - knots[i - 1]) / (knots[i] - knots[i - 1])
                        }
                    } else if i + 1 == m {
                        1.0
                    } else {
                        (knots[i + 1] - v) / (knots[i + 1] - knots[i])
                    }
                })
                .collect()
        })
        .collect()
}

/// Odd tents: `sign(x)` times tents over `abs(x)` (knots from 0).
fn odd_tents(x: &[f64], knots_abs: &[f64]) -> Vec<Vec<f64>> {
    let a: Vec<f64> = x.iter().map(|v| v.abs()).collect();
    tents(&a, knots_abs)
        .into_iter()
        .map(|t| t.iter().zip(x).map(|(ti, xi)| ti * xi.signum()).collect())
        .collect()
}

/// Tents over increasing `knots` extended linearly beyond the end knots (a
/// static map of any shape, linear outside the range it was fitted on).
fn tents_linear(x: &[f64], knots: &[f64]) -> Vec<Vec<f64>> {
    let mut t = tents(x, knots);
    let m = knots.len();
    if m < 2 {
        return t;
    }
    let (k0, k1) = (knots[0], knots[1]);
    let (j0, j1) = (knots[m - 2], knots[m - 1]);
    for (k, &v) in x.iter().enumerate() {
        if v < k0 {
            let u = (k0 - v) / (k1 - k0);
            t[0][k] = 1.0 + u;
            t[1][k] = -u;
        } else if v > j1 {
            let u = (v - j1) / (j1 - j0);
            t[m - 1][k] = 1.0 + u;
            t[m - 2][k] = -u;
        }
    }
    t
}

/// Play operator of half-width `r` on `x`, starting at `x[0]`.
fn play(x: &[f64], r: f64) -> Vec<f64> {
    let mut y = x.first().copied().unwrap_or(0.0);
    x.iter()
        .map(|&v| {
            y = y.clamp(v - r, v + r);
            y
        })
        .collect()
}

/// First-order lag of `x` with time constant `tau` over rows `h` apart,
/// starting at `x[0]`.
fn lagged(x: &[f64], h: f64, tau: f64) -> Vec<f64> {
    let a = (-h / tau).exp();
    let mut y = x.first().copied().unwrap_or(0.0);
    x.iter()
        .map(|&v| {
            y = a * y + (1.0 - a) * v;
            y
        })
        .collect()
}

/// Running integral of `x` over rows `h` apart.
fn integral(x: &[f64], h: f64) -> Vec<f64> {
    let mut acc = 0.0;
    x.iter()
        .map(|v| {
            acc += v * h;
            acc
        })
        .collect()
}

/// Speed of a position signal: central difference over 5 ms either side
/// (at least one row).
fn speed(x: &[f64], h: f64) -> Vec<f64> {
    let n = x.len();
    let m = ((0.005 / h).round() as usize).max(1);
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(m), (k + m).min(n - 1));
            if b > a {
                (x[b] - x[a]) / ((b - a) as f64 * h)
            } else {
                0.0
            }
        })
        .collect()
}

/// `sum over rows of vol(k) dx(k)`: the volume a compressibility shape
/// `w(x)` (per row) takes up along `x` in a line of oil volume `vol`.
fn compressed(x: &[f64], w: &[f64], vol: &[f64]) -> Vec<f64> {
    let mut acc = 0.0;
    let mut out = vec![0.0; x.len()];
    for k in 1..x.len() {
        acc += 0.25 * (vol[k] + vol[k - 1]) * (w[k] + w[k - 1]) * (x[k] - x[k - 1]);
        out[k] = acc;
    }
    out
}

/// One run prepared for the closures: signals, nominal residuals, noise.
pub struct RunData {
    /// The signals.
    pub sig: Signals,
    /// The nominal residuals.
    pub base: Residuals,
    /// Noise level of each residual's block means.
    pub sigma: [f64; 4],
    /// Rows per block (10 ms).
    pub block: usize,
}

impl RunData {
    /// Prepare a log against `plant`.
    pub fn new(log: &RunLog, plant: &Plant) -> Self {
        let sig = Signals::of(log);
        let base = residuals(&sig, plant);
        let noise = noise_of(&sig, plant, &base);
        let block = ((0.01 / sig.h_s).round() as usize).max(1);
        let sigma = std::array::from_fn(|i| {
            let b = block_means(&noise.r[i], block);
            let m = mean(&b);
            let v = b.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / b.len().max(1) as f64;
            v.sqrt().max(f64::MIN_POSITIVE)
        });
        Self {
            sig,
            base,
            sigma,
            block,
        }
    }

    /// Blocks per residual.
    pub fn blocks(&self) -> usize {
        self.sig.len().div_ceil(self.block)
    }

    /// The residuals as one vector of normalised block means (residual-major).
    pub fn vector(&self, r: &Residuals) -> Vec<f64> {
        let mut out = Vec::with_capacity(4 * self.blocks());
        for (i, ri) in r.r.iter().enumerate() {
            out.extend(
                block_means(ri, self.block)
                    .iter()
                    .map(|x| x / self.sigma[i]),
            );
        }
        out
    }

    /// A response (the residuals with a term, less the nominal ones) as a
    /// normalised block vector, scaled by `1 / eps`.
    fn response(&self, r: &Residuals, eps: f64) -> Vec<f64> {
        let mut out = Vec::with_capacity(4 * self.blocks());
        for (i, (ri, bi)) in r.r.iter().zip(&self.base.r).enumerate() {
            let d: Vec<f64> = ri.iter().zip(bi).map(|(a, b)| (a - b) / eps).collect();
            out.extend(
                block_means(&d, self.block)
                    .iter()
                    .map(|x| x / self.sigma[i]),
            );
        }
        out
    }
}

/// Means of consecutive blocks of `n` values.
fn block_means(v: &[f64], n: usize) -> Vec<f64> {
    v.chunks(n.max(1))
        .map(|c| c.iter().sum::<f64>() / c.len() as f64)
        .collect()
}

/// The runs of weights of closure `c` (of `p` in all) that form ordered
/// chains (tents over one variable, plays over widths, lags over time
/// constants): their fit is kept smooth along each ([`ROUGHNESS`]). A
/// closure's extra terms (a linear compliance beside the plays, a
/// pressure-dependent share beside the tents over speed or pressure
/// difference) stand apart.
fn chains(c: Closure, p: usize) -> Vec<std::ops::Range<usize>> {
    match (c.site, c.dep) {
        (Site::Parameters | Site::Servo | Site::Clock, _) => Vec::new(),
        // The static compressibility's tents, then the plays.
        (Site::Line1 | Site::Line2, Dependence::PressureHistory) => {
            vec![0..LINE_TENTS_PA.len(), LINE_TENTS_PA.len()..p]
        }
        // One chain each (a range is a chain, not a list of indices).
        (Site::CouplingIn, Dependence::ForceHistory) => std::iter::once(1..p).collect(),
        (Site::Between, _) | (Site::Force, Dependence::Speed) => {
            std::iter::once(0..p.saturating_sub(1)).collect()
        }
        _ => std::iter::once(0..p).collect(),
    }
}

/// Knots of a line's static compressibility over its pressure, Pa.
pub const LINE_TENTS_PA: [f64; 7] = [0.0, 0.5e6, 1e6, 2e6, 3e6, 4e6, 6e6];

/// Weight of the roughness penalty: a second difference of the weights
/// along a chain costs this share of what the same weight change does to
/// the fit (a knot the runs barely visit follows its neighbours instead of
/// swinging to fit the noise).
pub const ROUGHNESS: f64 = 0.01;

/// The columns of closure `c` on one run: each basis function's response
/// in the normalised block vector.
pub fn columns(c: Closure, run: &RunData, plant: &Plant, knots: &Knots) -> Vec<Vec<f64>> {
    match (c.site, c.dep) {
        (Site::Parameters, _) => parameter_columns(run, plant),
        (Site::Servo, _) => servo_columns(run, plant),
        (Site::CouplingIn, Dependence::ForceHistory) => coupling_play_columns(run, plant),
        (Site::CouplingIn, _) => coupling_tent_columns(run, plant),
        (Site::Between, _) => leak_columns(run, plant),
        (Site::Line1 | Site::Line2, dep) => line_columns(c.site == Site::Line2, dep, run, plant),
        (Site::Force, Dependence::Speed) => friction_columns(run, plant),
        (Site::Force, _) => {
            let fs = tents_linear(&run.sig.xo, &knots.position);
            let build = |f: Vec<f64>| Terms {
                force_n: Some(f),
                ..Terms::default()
            };
            responses(run, plant, &build, fs, 10.0)
        }
        (Site::Sensor(ch), dep) => sensor_columns(ch, dep, run, plant, knots),
        (Site::Clock, _) => clock_columns(run),
    }
}

/// The responses of the terms `build` makes of each basis function in
/// `fs`, each scaled by `eps` before the replay and by `1 / eps` after.
fn responses(
    run: &RunData,
    plant: &Plant,
    build: &dyn Fn(Vec<f64>) -> Terms,
    fs: Vec<Vec<f64>>,
    eps: f64,
) -> Vec<Vec<f64>> {
    fs.into_iter()
        .map(|f| {
            let f: Vec<f64> = f.iter().map(|x| x * eps).collect();
            let t = build(f);
            run.response(&with_terms_over(&run.sig, plant, &t, &run.base), eps)
        })
        .collect()
}

/// The piston's hydraulic force at each row, N.
fn piston_force_n(s: &Signals, plant: &Plant) -> Vec<f64> {
    (0..s.len())
        .map(|k| plant.piston_force_n(s.p1[k], s.p2[k]))
        .collect()
}

/// The mean of `v` over the run's still start.
fn still_mean(v: &[f64], still: usize) -> f64 {
    let n = still.min(v.len());
    v[..n].iter().sum::<f64>() / n.max(1) as f64
}

/// Each nominal parameter 5 % off, one at a time.
fn parameter_columns(run: &RunData, plant: &Plant) -> Vec<Vec<f64>> {
    (0..7)
        .map(|i| {
            let mut a = [1.0; 7];
            a[i] = 1.05f64;
            let ratios = ParameterRatios::from_array(a);
            let pl = plant.with_params(ratios.apply(plant.params()));
            run.response(&residuals(&run.sig, &pl), 0.05f64.ln_1p())
        })
        .collect()
}

/// The servo table's cells ([`servo_cells`]) at each row: the acceleration
/// the nominal loop asks from the interval's mean speed, the load and the
/// speed.
fn servo_columns(run: &RunData, plant: &Plant) -> Vec<Vec<f64>> {
    let s = &run.sig;
    let p = plant.params();
    let (h, n) = (s.h_s, s.len());
    let f_piston = piston_force_n(s, plant);
    let vbar: Vec<f64> = (0..n)
        .map(|k| {
            if k + 1 < n {
                (s.xi[k + 1] - s.xi[k]) / h
            } else {
                0.0
            }
        })
        .collect();
    let phi: Vec<[f64; SERVO_CELLS]> = (0..n)
        .map(|k| {
            let a = (s.vc[k].clamp(-p.v_max_mps, p.v_max_mps) - vbar[k]) / p.tau_m_s;
            servo_cells(a, f_piston[k], vbar[k])
        })
        .collect();
    let fs: Vec<Vec<f64>> = (0..SERVO_CELLS)
        .map(|j| phi.iter().map(|f| f[j]).collect())
        .collect();
    let build = |f: Vec<f64>| Terms {
        servo_mps2: Some(f),
        ..Terms::default()
    };
    responses(run, plant, &build, fs, 1.0)
}

/// A spring beside plays of several widths: a coupling whose deflection
/// lags the force by friction.
fn coupling_play_columns(run: &RunData, plant: &Plant) -> Vec<Vec<f64>> {
    let f_piston = piston_force_n(&run.sig, plant);
    let f0 = still_mean(&f_piston, run.sig.still);
    let rel = |v: Vec<f64>| -> Vec<f64> { v.iter().map(|y| y - f0).collect() };
    let fs: Vec<Vec<f64>> = std::iter::once(rel(f_piston.clone()))
        .chain(
            [10.0, 30.0, 100.0, 300.0, 1000.0]
                .iter()
                .map(|r| rel(play(&f_piston, *r))),
        )
        .collect();
    let build = |f: Vec<f64>| Terms {
        coupling_m: Some(f),
        ..Terms::default()
    };
    responses(run, plant, &build, fs, 1e-8)
}

/// The coupling at its general family's knots (its start, see
/// [`super::diagnose`]).
fn coupling_tent_columns(run: &RunData, plant: &Plant) -> Vec<Vec<f64>> {
    let fs = odd_tents(&piston_force_n(&run.sig, plant), &SCREW_FORCES_N);
    let build = |f: Vec<f64>| Terms {
        coupling_m: Some(f),
        ..Terms::default()
    };
    responses(run, plant, &build, fs, 1e-5)
}

/// Scale of the leak closure's level column, Pa: its weight over this is
/// the leakage map's level conductance, m^3/(s Pa).
pub const LEAK_LEVEL_PA: f64 = 1e6;

/// A flow between the lines of any shape over their pressure difference
/// (the leakage map's knots: each tent's weight is the flow there, m^3/s),
/// and a share that grows with their mean pressure, integrated.
fn leak_columns(run: &RunData, plant: &Plant) -> Vec<Vec<f64>> {
    let s = &run.sig;
    let (h, n) = (s.h_s, s.len());
    let dp: Vec<f64> = (0..n).map(|k| s.p1[k] - s.p2[k]).collect();
    let mut fs: Vec<Vec<f64>> = odd_tents(&dp, &LEAK_DP_PA)
        .into_iter()
        .map(|f| integral(&f, h))
        .collect();
    let level: Vec<f64> = (0..n)
        .map(|k| dp[k] * 0.5 * (s.p1[k] + s.p2[k]) / SEAL_P_REF_PA / LEAK_LEVEL_PA)
        .collect();
    fs.push(integral(&level, h));
    let build = |f: Vec<f64>| Terms {
        leak_m3: Some(f),
        ..Terms::default()
    };
    responses(run, plant, &build, fs, 1e-7)
}

/// A volume taken up or lost by line 1 (or line 2 where `line2`), by its
/// dependence: a compressibility, a hysteresis loop, an outflow or a lag.
fn line_columns(line2: bool, dep: Dependence, run: &RunData, plant: &Plant) -> Vec<Vec<f64>> {
    let s = &run.sig;
    let (h, n) = (s.h_s, s.len());
    let j = usize::from(line2);
    let pj = if j == 0 { &s.p1 } else { &s.p2 };
    let vol: Vec<f64> = (0..n)
        .map(|k| {
            let (v1, v2) = plant.line_volumes(s.xi[k], s.xo[k]);
            if j == 0 {
                v1
            } else {
                v2
            }
        })
        .collect();
    let hose = plant.params().hose;
    let lp: Vec<f64> = pj.iter().map(|x| hose.log_pressure(*x)).collect();
    let lp0 = still_mean(&lp, s.still);
    let rel = |v: Vec<f64>| -> Vec<f64> { v.iter().map(|y| (y - lp0) * 1e-13).collect() };
    let p0 = still_mean(pj, s.still);
    // A compressibility of any shape over the pressure, times the line's
    // oil volume, taken up along the run.
    let static_part = || -> Vec<Vec<f64>> {
        tents(pj, &LINE_TENTS_PA)
            .into_iter()
            .map(|w| compressed(pj, &w, &vol).iter().map(|v| v / 1e9).collect())
            .collect()
    };
    let fs: Vec<Vec<f64>> = match dep {
        Dependence::Pressure => static_part(),
        // The static compressibility beside plays of several widths on the
        // pressure (a Prandtl-Ishlinskii loop): the loop must explain what a
        // static law cannot.
        Dependence::PressureHistory => static_part()
            .into_iter()
            .chain(
                [1e4, 3e4, 1e5, 3e5, 1e6]
                    .iter()
                    .map(|r| play(pj, *r).iter().map(|y| (y - p0) * 1e-13).collect()),
            )
            .collect(),
        // A flow out of the line of any shape over its pressure, integrated
        // into the volume lost.
        Dependence::Outflow => tents(pj, &[0.0, 1e6, 2e6, 3e6, 4e6, 6e6])
            .into_iter()
            .map(|q| integral(&q, h).iter().map(|v| v * 1e-7).collect())
            .collect(),
        _ => [0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0]
            .iter()
            .map(|tau| rel(lagged(&lp, h, *tau)))
            .collect(),
    };
    let build = |f: Vec<f64>| {
        let mut t = Terms::default();
        t.volume_m3[j] = Some(f);
        t
    };
    responses(run, plant, &build, fs, 1.0)
}

/// A force against the output's speed of any shape, and a share that grows
/// with the lines' pressure.
fn friction_columns(run: &RunData, plant: &Plant) -> Vec<Vec<f64>> {
    let s = &run.sig;
    let v = speed(&s.xo, s.h_s);
    let mut fs = odd_tents(&v, &[0.0, 1e-3, 3e-3, 10e-3, 30e-3, 100e-3]);
    fs.push(
        (0..s.len())
            .map(|k| (s.p1[k] + s.p2[k]) / 1e6 * (v[k] / 1e-3).clamp(-1.0, 1.0))
            .collect(),
    );
    let build = |f: Vec<f64>| Terms {
        force_n: Some(f),
        ..Terms::default()
    };
    responses(run, plant, &build, fs, 10.0)
}

/// A channel's recorded values.
fn channel_of(s: &Signals, ch: CalChannel) -> &Vec<f64> {
    match ch {
        CalChannel::Xo => &s.xo,
        CalChannel::Xi => &s.xi,
        CalChannel::P1 => &s.p1,
        CalChannel::P2 => &s.p2,
        CalChannel::Ft => &s.ft,
    }
}

/// A sensor's reading off by a static map of any shape (`Signal`) or by
/// lags of several time constants: each basis function replayed as the
/// channel's reading moved by it.
fn sensor_columns(
    ch: CalChannel,
    dep: Dependence,
    run: &RunData,
    plant: &Plant,
    knots: &Knots,
) -> Vec<Vec<f64>> {
    let s = &run.sig;
    let h = s.h_s;
    let i = ch.index();
    let y = channel_of(s, ch).clone();
    let eps = [1e-5, 1e-6, 1e4, 1e4, 10.0][i];
    let fs: Vec<Vec<f64>> = match dep {
        Dependence::Signal => tents_linear(&y, &knots.sensor[i]),
        _ => {
            let taus: &[f64] = if h < 0.005 {
                &[1e-3, 3e-3, 10e-3, 30e-3]
            } else {
                &[10e-3, 30e-3]
            };
            taus.iter()
                .map(|tau| {
                    lagged(&y, h, *tau)
                        .iter()
                        .zip(&y)
                        .map(|(a, b)| (a - b) / eps)
                        .collect()
                })
                .collect()
        }
    };
    fs.into_iter()
        .map(|f| {
            let mut t = s.clone();
            let v: Vec<f64> = y.iter().zip(&f).map(|(a, b)| a - eps * b).collect();
            match ch {
                CalChannel::Xo => t.xo = v,
                CalChannel::Xi => t.xi = v,
                CalChannel::P1 => t.p1 = v,
                CalChannel::P2 => t.p2 = v,
                CalChannel::Ft => t.ft = v,
            }
            run.response(&residuals(&t, plant), eps)
        })
        .collect()
}

/// A clock off by a rate: the elapsed time's block means in each residual
/// but the first.
fn clock_columns(run: &RunData) -> Vec<Vec<f64>> {
    let n = run.sig.len();
    let h = run.sig.h_s;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * h).collect();
    let nb = run.blocks();
    (1..4)
        .map(|r| {
            let mut col = vec![0.0; 4 * nb];
            let b = block_means(&t, run.block);
            for (k, v) in b.iter().enumerate() {
                col[r * nb + k] = *v;
            }
            col
        })
        .collect()
}

/// How a closure did: its weights' fit and what it explains.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Fitted {
    /// Where.
    #[serde(skip)]
    pub closure: Closure,
    /// Label for reports.
    pub label: String,
    /// The identifier it names (`unexplained` outside the catalogue).
    pub names: String,
    /// Share of the fit runs' residual excess it explains (penalised by
    /// twice its number of weights, as Akaike's criterion).
    pub fit_explained: f64,
    /// Share of the check runs' residual excess it explains.
    pub check_explained: f64,
    /// Number of weights.
    pub weights: usize,
    /// The fitted weights, in the order of the closure's basis (each the
    /// SI amount of its basis function in the equation's term).
    #[serde(skip)]
    pub w: Vec<f64>,
    /// What it leaves of the check runs' excess, per block (in units of
    /// the noise's power; 0: the noise alone).
    pub check_left: f64,
    /// What it leaves of the fit runs' excess, per block, penalised as
    /// `fit_explained`.
    pub fit_left: f64,
    /// What it leaves of the excess of all runs, per block: the fit runs'
    /// (penalised) and the check runs' together. Closures are ranked by it:
    /// where the check runs show the violation, their excess weighs in as
    /// much as the fit runs'; where they do not, every closure leaves them
    /// at their noise and the fit runs decide.
    pub left: f64,
    /// Share of the explained excess per residual (servo, line1, line2,
    /// force) on the check runs.
    pub per_residual: [f64; 4],
    /// The same on the fit runs.
    pub fit_per_residual: [f64; 4],
}

/// The residuals' excess over their noise per residual: sum over blocks of
/// the squared normalised block means, less one per block (the noise).
fn excess(y: &[f64], nb: usize) -> [f64; 4] {
    std::array::from_fn(|i| y[i * nb..(i + 1) * nb].iter().map(|v| v * v).sum::<f64>() - nb as f64)
}

/// The offset columns of one run: a constant on line 1 and on line 2 (their
/// start is a noisy reference).
fn offsets(nb: usize) -> Vec<Vec<f64>> {
    (1..3)
        .map(|r| {
            let mut c = vec![0.0; 4 * nb];
            for v in &mut c[r * nb..(r + 1) * nb] {
                *v = 1.0;
            }
            c
        })
        .collect()
}

/// The ridge on the servo table's cells in its least-squares fit: a
/// correction of 1 m/s^2 in a cell costs as much as this many noise units
/// of one 10 ms block.
pub const SERVO_RIDGE: f64 = 3.0;

/// Least squares `y ~ X w` (columns `x`): each column scaled to unit norm,
/// lightly ridged (1e-9 on the unit diagonal), columns of zeros left at 0;
/// the weights.
fn solve(x: &[Vec<f64>], y: &[f64]) -> Vec<f64> {
    let p = x.len();
    let norms: Vec<f64> = x.iter().map(|c| dot(c, c).sqrt()).collect();
    let live: Vec<usize> = (0..p)
        .filter(|&i| norms[i] > 0.0 && norms[i].is_finite())
        .collect();
    let m = live.len();
    let mut a = vec![vec![0.0; m]; m];
    let mut b = vec![0.0; m];
    for (ii, &i) in live.iter().enumerate() {
        for (jj, &j) in live.iter().enumerate().skip(ii) {
            let v = dot(&x[i], &x[j]) / (norms[i] * norms[j]);
            a[ii][jj] = v;
            a[jj][ii] = v;
        }
        b[ii] = dot(&x[i], y) / norms[i];
        a[ii][ii] += 1e-9;
    }
    let mut w = vec![0.0; p];
    if let Some(z) = gauss(a, b) {
        for (ii, &i) in live.iter().enumerate() {
            w[i] = z[ii] / norms[i];
        }
    }
    w
}

/// `y` less the fitted columns, then less its best offsets.
fn after(y: &[f64], cols: &[Vec<f64>], w: &[f64], nb: usize) -> Vec<f64> {
    let mut r = y.to_vec();
    for (c, wi) in cols.iter().zip(w) {
        for (ri, ci) in r.iter_mut().zip(c) {
            *ri -= wi * ci;
        }
    }
    let off = offsets(nb);
    let wo = solve(&off, &r);
    for (c, wi) in off.iter().zip(&wo) {
        for (ri, ci) in r.iter_mut().zip(c) {
            *ri -= wi * ci;
        }
    }
    r
}

/// The residuals of all runs, before any closure: per run the normalised
/// block vector with its offsets removed.
pub fn before(runs: &[RunData]) -> Vec<Vec<f64>> {
    runs.iter()
        .map(|r| after(&r.vector(&r.base), &[], &[], r.blocks()))
        .collect()
}

/// Fit closure `c` on the fit runs and judge it on the check runs.
pub fn fit_closure(
    c: Closure,
    fit: &[RunData],
    check: &[RunData],
    plant: &Plant,
    knots: &Knots,
) -> Fitted {
    // The stacked design of the fit runs: the closure's columns and each
    // run's own offsets.
    let fit_cols: Vec<Vec<Vec<f64>>> = fit.iter().map(|r| columns(c, r, plant, knots)).collect();
    let p = fit_cols.first().map_or(0, Vec::len);
    let total: usize = fit.iter().map(|r| 4 * r.blocks()).sum();
    let mut x: Vec<Vec<f64>> = vec![Vec::with_capacity(total); p];
    let mut y = Vec::with_capacity(total);
    let mut offs: Vec<Vec<f64>> = Vec::new();
    let mut at = 0;
    for (r, cols) in fit.iter().zip(&fit_cols) {
        let nb = r.blocks();
        for (xi, ci) in x.iter_mut().zip(cols) {
            xi.extend_from_slice(ci);
        }
        y.extend(r.vector(&r.base));
        for o in offsets(nb) {
            let mut full = vec![0.0; total];
            full[at..at + 4 * nb].copy_from_slice(&o);
            offs.push(full);
        }
        at += 4 * nb;
    }
    let mut design = x.clone();
    design.extend(offs);
    // The roughness penalty: rows of second differences along the chain,
    // in units of the columns' mean norm.
    for ch in chains(c, p) {
        if ch.len() < 3 {
            continue;
        }
        let scale = ROUGHNESS.sqrt() * x[ch.clone()].iter().map(|v| dot(v, v).sqrt()).sum::<f64>()
            / ch.len() as f64;
        for i in ch.start + 1..ch.end - 1 {
            for (j, col) in design.iter_mut().enumerate() {
                col.push(match j {
                    _ if j == i - 1 || j == i + 1 => scale,
                    _ if j == i => -2.0 * scale,
                    _ => 0.0,
                });
            }
            y.push(0.0);
        }
    }
    // The servo's table: cells the runs visit little are held near zero by
    // a ridge in its own units (m/s^2), not its columns' norms.
    if c.site == Site::Servo {
        for i in 0..p {
            for (j, col) in design.iter_mut().enumerate() {
                col.push(if j == i { SERVO_RIDGE } else { 0.0 });
            }
            y.push(0.0);
        }
    }
    let w_all = solve(&design, &y);
    let w = &w_all[..p];
    let judge = |runs: &[RunData], cols: &[Vec<Vec<f64>>]| -> ([f64; 4], [f64; 4]) {
        let mut b = [0.0; 4];
        let mut a = [0.0; 4];
        for (r, cl) in runs.iter().zip(cols) {
            let nb = r.blocks();
            let y = r.vector(&r.base);
            let eb = excess(&after(&y, &[], &[], nb), nb);
            let ea = excess(&after(&y, cl, w, nb), nb);
            for i in 0..4 {
                b[i] += eb[i];
                a[i] += ea[i];
            }
        }
        (b, a)
    };
    let (fb, fa) = judge(fit, &fit_cols);
    let check_cols: Vec<Vec<Vec<f64>>> =
        check.iter().map(|r| columns(c, r, plant, knots)).collect();
    let (cb, ca) = judge(check, &check_cols);
    let share = |b: [f64; 4], a: [f64; 4], pen: f64| {
        let tb: f64 = b.iter().sum();
        let ta: f64 = a.iter().sum::<f64>() + pen;
        if tb > 0.0 {
            1.0 - ta / tb
        } else {
            0.0
        }
    };
    let tb: f64 = cb.iter().sum();
    let rows = |runs: &[RunData]| runs.iter().map(|r| 4 * r.blocks()).sum::<usize>().max(1) as f64;
    let (nf, nc) = (rows(fit), rows(check));
    let fit_total = fa.iter().sum::<f64>() + 2.0 * p as f64;
    let check_total: f64 = ca.iter().sum();
    Fitted {
        closure: c,
        label: c.label(),
        names: c.names().map_or("unexplained", |k| k.name()).to_string(),
        fit_explained: share(fb, fa, 2.0 * p as f64),
        check_explained: share(cb, ca, 0.0),
        weights: p,
        // The residuals' response to each basis function was fitted to
        // the nominal residuals, which the term must cancel.
        w: w.iter().map(|v| -v).collect(),
        check_left: check_total / nc,
        fit_left: fit_total / nf,
        left: (fit_total + check_total) / (nf + nc),
        per_residual: std::array::from_fn(|i| if tb > 0.0 { (cb[i] - ca[i]) / tb } else { 0.0 }),
        fit_per_residual: {
            let t: f64 = fb.iter().sum();
            std::array::from_fn(|i| if t > 0.0 { (fb[i] - fa[i]) / t } else { 0.0 })
        },
    }
}

/// The residuals' excess over noise per residual on some runs, in units of
/// blocks (mean excess per block), with the offsets removed.
pub fn residual_excess(runs: &[RunData]) -> [f64; 4] {
    let mut e = [0.0; 4];
    let mut blocks = 0usize;
    for (r, y) in runs.iter().zip(before(runs)) {
        let nb = r.blocks();
        let x = excess(&y, nb);
        for i in 0..4 {
            e[i] += x[i];
        }
        blocks += nb;
    }
    e.map(|v| v / blocks.max(1) as f64)
}

/// The residual names in order.
pub fn residual_names() -> [&'static str; 4] {
    Residual::ALL.map(Residual::name)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_identifier_of_the_catalogue_has_a_place_and_a_dependence() {
        for k in EffectKind::ALL {
            assert!(
                library().iter().any(|c| c.names() == Some(k)),
                "{} is named by no closure",
                k.name()
            );
        }
        // Outside the catalogue: a force over the load's position, a drift.
        assert_eq!(naming(Site::Force, Dependence::Position), None);
        assert_eq!(naming(Site::Clock, Dependence::Drift), None);
    }

    #[test]
    fn tents_are_a_partition_of_unity_and_extend_linearly() {
        let knots = [0.0, 1.0, 3.0];
        let x = [-1.0, 0.0, 0.5, 1.0, 2.0, 3.0, 5.0];
        for (flat, t) in [(true, tents(&x, &knots)), (false, tents_linear(&x, &knots))] {
            for k in 0..x.len() {
                let s: f64 = t.iter().map(|c| c[k]).sum();
                assert!((s - 1.0).abs() < 1e-12, "sum {s} at {}", x[k]);
            }
            // Weights 2 x at the knots reproduce 2 x inside; beyond, flat or linear.
            let f = |k: usize| t[0][k] * 0.0 + t[1][k] * 2.0 + t[2][k] * 6.0;
            assert!((f(2) - 1.0).abs() < 1e-12);
            assert!((f(4) - 4.0).abs() < 1e-12);
            assert!((f(6) - if flat { 6.0 } else { 10.0 }).abs() < 1e-12);
            assert!((f(0) - if flat { 0.0 } else { -2.0 }).abs() < 1e-12);
        }
    }

    #[test]
    fn odd_tents_turn_with_the_sign() {
        let t = odd_tents(&[-0.5, 0.5], &[0.0, 1.0]);
        assert_eq!(t[0], [-0.5, 0.5]);
        assert_eq!(t[1], [-0.5, 0.5]);
    }

    #[test]
    fn a_play_holds_until_pushed() {
        assert_eq!(
            play(&[0.0, 1.0, 3.0, 2.0, 0.0], 1.0),
            [0.0, 0.0, 2.0, 2.0, 1.0]
        );
    }

    #[test]
    fn least_squares_leaves_empty_columns_at_zero() {
        let x = vec![vec![1.0, 2.0, 3.0], vec![0.0; 3], vec![1.0, 0.0, 1.0]];
        let y = [3.0, 4.0, 7.0];
        let w = solve(&x, &y);
        assert!(
            (w[0] - 2.0).abs() < 1e-6 && w[1] == 0.0 && (w[2] - 1.0).abs() < 1e-6,
            "{w:?}"
        );
    }
}
