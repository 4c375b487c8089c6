//! Structural residuals: each equation group of the nominal model checked on
//! the measurements alone, without replaying the whole model (fault detection
//! and isolation's analytic redundancy relations).
//!
//! Every residual uses a subset of the model's equations and of the sensors,
//! so it is sensitive to a violation of those and blind to the others:
//!
//! | residual | equations it uses | sensors |
//! |---|---|---|
//! | [`Residual::Servo`] | the servo's speed loop (docs/model.md 4: dvi) | encoder, command |
//! | [`Residual::Line1`] | line 1's flow and compliance balance (oil, hose wall) and the couplings of both pistons to it | encoder, LVDT, P1 |
//! | [`Residual::Line2`] | line 2's balance with the accumulator (oil, hose wall, restrictor, gas) and the couplings | encoder, LVDT, P2 |
//! | [`Residual::Force`] | the actuating piston's force balance | LVDT, P1, P2, force |
//!
//! * **Servo** (m/s): the mean speed of the encoder over one row interval
//!   against its one-step prediction by the nominal first-order speed loop
//!   from the previous interval's mean speed and the recorded commands (exact
//!   for the nominal servo with the command held over each row).
//! * **Line 1** (m^3): the volume the pistons pushed into line 1 since the
//!   start, `AP1 dXi - AA1 dXo`, less what the oil's compression and the
//!   hose wall absorbed at the measured pressure (the oil's `V1/beta dP1`
//!   summed along the run; the wall's instantaneous part through its
//!   antiderivative `Ce0 L(P1)`, its two relaxing parts as filters of
//!   `L(P1)`). Line 1 is stiff (1 um of the LVDT is 2 MPa), so its balance
//!   is read in volume, where the LVDT's noise is a few nanolitres.
//! * **Line 2** (Pa): the measured P2 against the pressure the accumulator
//!   gives for the gas volume the pistons' displacement leaves it (the gas
//!   law at `Vg`, less the restrictor's drop `Qa / G_acc`). The accumulator
//!   is some 600 times softer than the line, so line 2 is read in pressure.
//! * **Force** (N): `AA1 P1 - AA2 P2 - Ft - c_visc vo - m ao` through a
//!   critically damped low-pass of 10 ms (or one row, if longer), so that
//!   the speed and acceleration come from the LVDT without differentiating
//!   its noise twice.
//!
//! Each residual starts from the measured rest (the means over the samples
//! before the encoder moves, as the replay does) and is zero, up to the
//! noise, on a run the nominal model describes. Its noise level is found by
//! propagating white noise of each channel's estimated level through the
//! same computation ([`noise_of`]), so that filtered and summed residuals
//! are weighed as they really scatter.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::stats::{mean, noise_sigma};
use crate::io::runlog::RunLog;
use crate::model::plant::Plant;

/// The structural residuals, in the order of [`Residuals::r`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Residual {
    /// The servo's speed loop, m/s.
    Servo,
    /// Line 1's volume balance, m^3.
    Line1,
    /// Line 2's pressure with the accumulator, Pa.
    Line2,
    /// The actuating piston's force balance, N.
    Force,
}

impl Residual {
    /// All four, in index order.
    pub const ALL: [Self; 4] = [Self::Servo, Self::Line1, Self::Line2, Self::Force];

    /// Index in [`Residuals::r`].
    pub fn index(self) -> usize {
        self as usize
    }

    /// Short name for reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Servo => "servo",
            Self::Line1 => "line1",
            Self::Line2 => "line2",
            Self::Force => "force",
        }
    }

    /// The equations and sensors it checks.
    pub fn checks(self) -> &'static str {
        match self {
            Self::Servo => "the servo's speed loop (encoder, command)",
            Self::Line1 => {
                "line 1's flow and compliance balance and the pistons' couplings (encoder, LVDT, P1)"
            }
            Self::Line2 => {
                "line 2's balance with the accumulator and the pistons' couplings (encoder, LVDT, P2)"
            }
            Self::Force => "the actuating piston's force balance (LVDT, P1, P2, force)",
        }
    }

    /// Unit of the residual.
    pub fn unit(self) -> &'static str {
        match self {
            Self::Servo => "m/s",
            Self::Line1 => "m^3",
            Self::Line2 => "Pa",
            Self::Force => "N",
        }
    }
}

/// The measured signals of one run, as the residuals read them (a copy, so
/// that a sensor's correction can be tried on it).
#[derive(Clone, Debug, PartialEq)]
pub struct Signals {
    /// Row interval, s.
    pub h_s: f64,
    /// Drive command held over each row, m/s.
    pub vc: Vec<f64>,
    /// Encoder, m.
    pub xi: Vec<f64>,
    /// LVDT, m.
    pub xo: Vec<f64>,
    /// Line-1 pressure, Pa.
    pub p1: Vec<f64>,
    /// Line-2 pressure, Pa.
    pub p2: Vec<f64>,
    /// Load force, N.
    pub ft: Vec<f64>,
    /// Samples at rest at the start (the encoder within 5 um of its first
    /// count, at most 20 ms): the reference of every residual.
    pub still: usize,
}

impl Signals {
    /// The signals of a log.
    pub fn of(log: &RunLog) -> Self {
        let n = log.len();
        let h_s = log.dt_s();
        let head = ((0.02 / h_s.max(1e-6)) as usize).clamp(1, n.max(1));
        let xi0 = log.xi_m.first().copied().unwrap_or(0.0);
        let still = log.xi_m[..head.min(n)]
            .iter()
            .take_while(|x| (*x - xi0).abs() < 5e-6)
            .count()
            .max(1);
        Self {
            h_s,
            vc: log.vcmd_mps.clone(),
            xi: log.xi_m.clone(),
            xo: log.xo_m.clone(),
            p1: log.p1_pa.clone(),
            p2: log.p2_pa.clone(),
            ft: log.ft_n.clone(),
            still,
        }
    }

    /// Rows.
    pub fn len(&self) -> usize {
        self.xi.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.xi.is_empty()
    }

    /// Mean of a signal over the rest at the start.
    fn rest(&self, v: &[f64]) -> f64 {
        mean(&v[..self.still.min(v.len())])
    }
}

/// The four residuals of one run, one value per row.
#[derive(Clone, Debug, PartialEq)]
pub struct Residuals {
    /// In [`Residual::ALL`] order.
    pub r: [Vec<f64>; 4],
}

/// Time constant of the force residual's low-pass, s (at least one row).
pub const FORCE_FILTER_S: f64 = 0.01;

/// One first-order lag `dy/dt = (u - y) / tau` over samples `h` apart with
/// the input linear between samples (exact), starting at `y0`.
fn lag(u: &[f64], h: f64, tau: f64, y0: f64) -> Vec<f64> {
    let a = (-h / tau).exp();
    let b = (1.0 - a) * tau / h;
    let mut y = Vec::with_capacity(u.len());
    let mut prev = y0;
    let mut u_prev = u.first().copied().unwrap_or(y0);
    for &uk in u {
        prev = a * prev + (1.0 - b) * uk + (b - a) * u_prev;
        u_prev = uk;
        y.push(prev);
    }
    y
}

/// Terms added to the model's equations: a closure of one equation is one
/// of these, a function of the run's signals, one value per row (`None`:
/// the nominal equation).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Terms {
    /// Acceleration added to the servo's speed loop, m/s^2.
    pub servo_mps2: Option<Vec<f64>>,
    /// How far the power piston lags behind the encoder (the coupling of
    /// motor and piston), m.
    pub coupling_m: Option<Vec<f64>>,
    /// Volume taken up in each line beyond its oil and hose wall, from the
    /// rest at the start, m^3.
    pub volume_m3: [Option<Vec<f64>>; 2],
    /// Volume leaked from line 1 to line 2 since the start, m^3.
    pub leak_m3: Option<Vec<f64>>,
    /// Force added on the actuating piston (before the residual's
    /// low-pass), N.
    pub force_n: Option<Vec<f64>>,
}

impl Terms {
    /// The residuals a term of this set enters (servo, line 1, line 2,
    /// force).
    pub fn touches(&self) -> [bool; 4] {
        let lines = self.coupling_m.is_some() || self.leak_m3.is_some();
        [
            self.servo_mps2.is_some(),
            lines || self.volume_m3[0].is_some(),
            lines || self.volume_m3[1].is_some(),
            self.force_n.is_some(),
        ]
    }
}

/// Row `k` of an optional term (0 where absent).
fn at(t: &Option<Vec<f64>>, k: usize) -> f64 {
    t.as_ref().map_or(0.0, |v| v[k])
}

/// The residuals of `s` against the nominal model of `plant`.
pub fn residuals(s: &Signals, plant: &Plant) -> Residuals {
    with_terms(s, plant, &Terms::default())
}

/// The residuals of `s` against the model of `plant` with `terms` added.
pub fn with_terms(s: &Signals, plant: &Plant, terms: &Terms) -> Residuals {
    Residuals {
        r: [
            servo(s, plant, terms),
            line1(s, plant, terms),
            line2(s, plant, terms),
            force(s, plant, terms),
        ],
    }
}

/// Only the residuals that `terms` enter, the others copied from `base`.
pub fn with_terms_over(s: &Signals, plant: &Plant, terms: &Terms, base: &Residuals) -> Residuals {
    let t = terms.touches();
    Residuals {
        r: [
            if t[0] {
                servo(s, plant, terms)
            } else {
                base.r[0].clone()
            },
            if t[1] {
                line1(s, plant, terms)
            } else {
                base.r[1].clone()
            },
            if t[2] {
                line2(s, plant, terms)
            } else {
                base.r[2].clone()
            },
            if t[3] {
                force(s, plant, terms)
            } else {
                base.r[3].clone()
            },
        ],
    }
}

/// The command the servo gets: clamped to +-v_max, and stopped at the
/// ball screw's software limit.
fn servo_input(s: &Signals, plant: &Plant, k: usize) -> f64 {
    let v_max = plant.params().v_max_mps;
    plant
        .software_limited_v_cmd(s.xi[k], s.vc[k])
        .clamp(-v_max, v_max)
}

/// Servo residual: each row interval's mean encoder speed against its
/// one-step prediction (see the module's documentation); 0 on the first
/// row and the last. An added acceleration `a` acts as the target `u + tau a`.
fn servo(s: &Signals, plant: &Plant, terms: &Terms) -> Vec<f64> {
    let n = s.len();
    let h = s.h_s;
    let tau = plant.params().tau_m_s;
    let e = (-h / tau).exp();
    let phi = tau / h * (1.0 - e);
    let mut r = vec![0.0; n];
    // Mean speed over interval k (rows k to k + 1).
    let vbar = |k: usize| (s.xi[k + 1] - s.xi[k]) / h;
    let u = |k: usize| servo_input(s, plant, k) + tau * at(&terms.servo_mps2, k);
    for k in 0..n.saturating_sub(2) {
        let pred = (1.0 - phi) * u(k + 1) + (phi - e) * u(k) + e * vbar(k);
        r[k + 1] = vbar(k + 1) - pred;
    }
    r
}

/// Volume of oil compressed along the measured pressure `p` of one line
/// whose oil volume at row k is `vol(k)`, from the reference pressure
/// `p_ref`: sum of V (mid-row) / beta dP.
fn oil_volume(p: &[f64], p_ref: f64, beta: f64, vol: impl Fn(usize) -> f64) -> Vec<f64> {
    let mut out = Vec::with_capacity(p.len());
    let mut acc = vol(0) / beta * (p[0] - p_ref);
    out.push(acc);
    for k in 1..p.len() {
        acc += 0.5 * (vol(k) + vol(k - 1)) / beta * (p[k] - p[k - 1]);
        out.push(acc);
    }
    out
}

/// Volume the hose wall of one line took up since the reference pressure
/// `p_ref`, along the measured pressure `p`: instantaneous `Ce0 L(P)` and
/// the fast and slow relaxing parts (lags of `Cf0 L(P)`, `Cs0 L(P)` from
/// equilibrium at `p_ref`).
fn wall_volume(p: &[f64], p_ref: f64, h: f64, plant: &Plant) -> Vec<f64> {
    let hose = plant.params().hose;
    let l: Vec<f64> = p.iter().map(|&x| hose.log_pressure(x)).collect();
    let l_ref = hose.log_pressure(p_ref);
    let fast: Vec<f64> = l.iter().map(|x| hose.cf0_m3pp * x).collect();
    let slow: Vec<f64> = l.iter().map(|x| hose.cs0_m3pp * x).collect();
    let vf = lag(&fast, h, hose.tau_f_s, hose.cf0_m3pp * l_ref);
    let vs = lag(&slow, h, hose.tau_s_s, hose.cs0_m3pp * l_ref);
    l.iter()
        .zip(vf.iter().zip(&vs))
        .map(|(lk, (f, sl))| {
            hose.ce0_m3pp * (lk - l_ref)
                + (f - hose.cf0_m3pp * l_ref)
                + (sl - hose.cs0_m3pp * l_ref)
        })
        .collect()
}

/// The power piston's position: the encoder less the coupling's lag.
fn piston(s: &Signals, terms: &Terms, k: usize) -> f64 {
    s.xi[k] - at(&terms.coupling_m, k)
}

/// Line 1's volume balance (see the module's documentation).
fn line1(s: &Signals, plant: &Plant, terms: &Terms) -> Vec<f64> {
    let p = plant.params();
    let (xi0, xo0, p0) = (s.rest(&s.xi), s.rest(&s.xo), s.rest(&s.p1));
    let oil = oil_volume(&s.p1, p0, p.beta_e_pa, |k| {
        plant.line_volumes(s.xi[k], s.xo[k]).0
    });
    let wall = wall_volume(&s.p1, p0, s.h_s, plant);
    (0..s.len())
        .map(|k| {
            p.ap1_m2 * (piston(s, terms, k) - xi0)
                - p.aa1_m2 * (s.xo[k] - xo0)
                - oil[k]
                - wall[k]
                - at(&terms.volume_m3[0], k)
                - at(&terms.leak_m3, k)
        })
        .collect()
}

/// Line 2's pressure with the accumulator (see the module's documentation).
fn line2(s: &Signals, plant: &Plant, terms: &Terms) -> Vec<f64> {
    let p = plant.params();
    let n = s.len();
    let (xi0, xo0, p0) = (s.rest(&s.xi), s.rest(&s.xo), s.rest(&s.p2));
    let oil = oil_volume(&s.p2, p0, p.beta_e_pa, |k| {
        plant.line_volumes(s.xi[k], s.xo[k]).1
    });
    let wall = wall_volume(&s.p2, p0, s.h_s, plant);
    // The gas volume at rest that gives the measured rest pressure.
    let vg0 = p.v_gas0_m3 * ((p.p_acc0_pa + p.p_atm_pa) / (p0 + p.p_atm_pa)).powf(1.0 / p.n_poly);
    let vg: Vec<f64> = (0..n)
        .map(|k| {
            vg0 + oil[k]
                + wall[k]
                + at(&terms.volume_m3[1], k)
                + p.ap2_m2 * (piston(s, terms, k) - xi0)
                - p.aa2_m2 * (s.xo[k] - xo0)
                - at(&terms.leak_m3, k)
        })
        .collect();
    (0..n)
        .map(|k| {
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            let qa = if b > a {
                (vg[b] - vg[a]) / ((b - a) as f64 * s.h_s)
            } else {
                0.0
            };
            s.p2[k] - (plant.p_acc_pa(vg[k]) - qa / p.g_acc_m3pspa)
        })
        .collect()
}

/// The force residual's low-pass time constant on rows `h` apart.
pub fn force_filter_s(h: f64) -> f64 {
    FORCE_FILTER_S.max(h)
}

/// The actuating piston's force balance through the low-pass (see the
/// module's documentation).
fn force(s: &Signals, plant: &Plant, terms: &Terms) -> Vec<f64> {
    let p = plant.params();
    let tau = force_filter_s(s.h_s);
    let w = 1.0 / tau;
    let xo0 = s.rest(&s.xo);
    let y1 = lag(&s.xo, s.h_s, tau, xo0);
    let y2 = lag(&y1, s.h_s, tau, xo0);
    let f: Vec<f64> = (0..s.len())
        .map(|k| p.aa1_m2 * s.p1[k] - p.aa2_m2 * s.p2[k] - s.ft[k] + at(&terms.force_n, k))
        .collect();
    let f0 = s.rest(&f);
    let g1 = lag(&f, s.h_s, tau, f0);
    let g2 = lag(&g1, s.h_s, tau, f0);
    (0..s.len())
        .map(|k| {
            let v = w * (y1[k] - y2[k]);
            let a = w * w * (s.xo[k] - 2.0 * y1[k] + y2[k]);
            g2[k] - p.c_visc_nspm * v - p.m_kg * a
        })
        .collect()
}

/// Noise levels of the channels (Xo, Xi, P1, P2, Ft) estimated from the
/// signals (the encoder at least a tenth of a micrometre: its quantum).
pub fn channel_noise(s: &Signals) -> [f64; 5] {
    [
        noise_sigma(&s.xo),
        noise_sigma(&s.xi).max(1e-7),
        noise_sigma(&s.p1),
        noise_sigma(&s.p2),
        noise_sigma(&s.ft),
    ]
}

/// The residuals' response to white noise of the channels' levels
/// (`channel_noise`) added to the signals: one realisation per row, from a
/// fixed seed.
pub fn noise_of(s: &Signals, plant: &Plant, base: &Residuals) -> Residuals {
    let sd = channel_noise(s);
    let mut rng = ChaCha8Rng::seed_from_u64(0x5eed);
    let mut noisy = s.clone();
    for (v, sigma) in [
        (&mut noisy.xo, sd[0]),
        (&mut noisy.xi, sd[1]),
        (&mut noisy.p1, sd[2]),
        (&mut noisy.p2, sd[3]),
        (&mut noisy.ft, sd[4]),
    ] {
        for x in v.iter_mut() {
            let z: f64 = StandardNormal.sample(&mut rng);
            *x += sigma * z;
        }
    }
    let r = residuals(&noisy, plant);
    Residuals {
        r: std::array::from_fn(|i| r.r[i].iter().zip(&base.r[i]).map(|(a, b)| a - b).collect()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gap::validation::fit_scenario;
    use crate::model::effects::{EffectKind, Effects};
    use crate::model::sensors::SensorMode;
    use crate::sim::{run, RunSpec};
    use dca_core::controller::{ControllerConfig, ControllerKind, Preset};

    /// The suite's fit scenario on a rig with `effects`, ideal sensors.
    fn ideal(effects: &Effects) -> Signals {
        let spec = RunSpec {
            scenario: fit_scenario(),
            controller: ControllerConfig::preset(Preset::Paper, ControllerKind::MpcEso),
            plant: Plant::nominal(),
            effects: *effects,
            sensors: SensorMode::Ideal,
            seed: 1,
            dt_s: 1e-4,
        };
        let trace = run(&spec).expect("valid run");
        let mut text = Vec::new();
        trace.to_runlog(&[]).write_to(&mut text).expect("in memory");
        let log =
            RunLog::parse(std::str::from_utf8(&text).expect("utf-8"), "ideal").expect("reads");
        Signals::of(&log)
    }

    fn max_abs(v: &[f64]) -> f64 {
        v.iter().fold(0.0, |m, x| m.max(x.abs()))
    }

    /// On the nominal plant every equation balances to a fraction of what
    /// one sensor's noise makes it scatter (the encoder's quantum is 1e-4
    /// m/s of a 1 ms speed; the LVDT's 10 um are 3e-9 m^3 of line 1; P2's
    /// 5 kPa; the force residual's few newtons), except for a few rows at
    /// the load's steps, which the residuals' sampled filters smear.
    #[test]
    fn the_nominal_plant_balances_every_equation() {
        let s = ideal(&Effects::NONE);
        let r = residuals(&s, &Plant::nominal());
        let worst: [f64; 4] = std::array::from_fn(|i| max_abs(&r.r[i]));
        let rms: [f64; 4] = std::array::from_fn(|i| crate::gap::stats::rms(&r.r[i]));
        assert!(worst[0] < 1e-5, "servo {:e} m/s", worst[0]);
        assert!(worst[1] < 3e-10, "line 1 {:e} m^3", worst[1]);
        assert!(
            rms[2] < 200.0 && worst[2] < 2e3,
            "line 2 {:e} / {:e} Pa",
            rms[2],
            worst[2]
        );
        assert!(
            rms[3] < 1.0 && worst[3] < 20.0,
            "force {:e} / {:e} N",
            rms[3],
            worst[3]
        );
    }

    /// A leak between the lines unbalances line 1 by the volume it carries
    /// and leaves the servo and the force balance as they were.
    #[test]
    fn a_leak_unbalances_the_lines_only() {
        let mut e = Effects::NONE;
        e.set(EffectKind::Leakage, Some(&[1e-13]));
        let (clean, leaky) = (ideal(&Effects::NONE), ideal(&e));
        let plant = Plant::nominal();
        let (rc, rl) = (residuals(&clean, &plant), residuals(&leaky, &plant));
        assert!(max_abs(&rl.r[1]) > 1e-7, "line 1 {:e}", max_abs(&rl.r[1]));
        assert!(max_abs(&rl.r[0]) < 2.0 * max_abs(&rc.r[0]) + 1e-9);
        assert!(max_abs(&rl.r[3]) < 2.0 * max_abs(&rc.r[3]) + 1.0);
    }

    /// A term added to an equation enters exactly its residuals.
    #[test]
    fn terms_enter_the_residuals_they_touch() {
        let s = ideal(&Effects::NONE);
        let plant = Plant::nominal();
        let base = residuals(&s, &plant);
        let n = s.len();
        let t = Terms {
            volume_m3: [Some(vec![1e-9; n]), None],
            ..Terms::default()
        };
        let r = with_terms_over(&s, &plant, &t, &base);
        assert_eq!(t.touches(), [false, true, false, false]);
        for k in 0..n {
            assert!((base.r[1][k] - r.r[1][k] - 1e-9).abs() < 1e-18);
        }
        assert_eq!(r.r[0], base.r[0]);
    }
}
