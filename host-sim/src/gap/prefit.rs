//! Starting points for fits whose objective is a narrow valley.
//!
//! `motor_limit` is the case: the encoder resolves 0.2 um, so a force limit a
//! few per cent off moves the replayed Xi by many noise units, and the gap
//! over (acceleration, mass) is a thin ridge a coarse grid misses. The servo
//! alone, though, is cheap to simulate: it is driven by the recorded command,
//! and the hydraulic force it works against is known from the measured
//! pressures (F = AP1 P1 - AP2 P2). A search of that two-state model
//! against the measured Xi finds the valley in about a second; the
//! full-model fit then starts there.

use super::fit::{minimize, Bound};
use super::lsq;
use super::replay;
use super::run::Run;
use crate::model::effects::{
    self, CommandMap, EffectKind, MotorLimit, NamedEffect, Servo, ServoEnvelope, SpeedLoop,
    COMMAND_SPEEDS_MPS, ENVELOPE_SPEEDS_MPS,
};
use crate::model::plant::Plant;

/// Bounds of the reflected mass in the servo fits, kg.
const MOTOR_MASS: Bound = Bound { lo: 5.0, hi: 1e4 };
/// Bounds of the drive's force in the servo fits, N.
const MOTOR_FORCE: Bound = Bound { lo: 50.0, hi: 1e5 };

/// Relative rise of the servo error within which a knot of the envelope is
/// taken as unconstrained by the runs (its force then stays as high as the
/// error allows).
const FLAT_TOL: f64 = 0.05;

/// The Xi error (in units of the run's Xi scale) of the servo model `servo`
/// on one run, row by row, handed to `each` until it returns false; false
/// where the model diverged. Xi runs open loop from the first row on logs
/// of one controller tick per row, from each row's encoder reading on
/// longer rows (see the body).
fn servo_track(
    run: &Run,
    plant: &Plant,
    servo: Servo<'_>,
    fine: bool,
    mut each: impl FnMut(f64) -> bool,
) -> bool {
    let p = plant.params();
    let log = &run.log;
    let n = log.len();
    let scale = run.scale[1];
    // Two midpoint steps per row; `fine`: steps of at most 0.5 ms, as the
    // replay takes (on 10 ms rows two steps of 5 ms against the servo's
    // 10 ms time constant leave the nominal servo itself far off).
    let sub = if fine {
        ((log.dt_s() / 5e-4).ceil() as usize).max(2)
    } else {
        2
    };
    let h = log.dt_s() / sub as f64;
    let (mut xi, mut vi) = (log.xi_m[0], 0.0);
    // The servo's own states (a speed loop's reference and integrator),
    // at rest with the integrator holding the load.
    let mut own = [0.0, plant.piston_force_n(log.p1_pa[0], log.p2_pa[0])];
    // On rows of several controller ticks the log keeps one command of
    // each row's several, off the row's mean by the controller's answer to
    // sensor noise and by the command's change within the row. Run open
    // loop over the whole run, those departures add up in Xi: on closed-loop
    // runs of a drive with its own speed loop, at 10 ms, the fit then
    // missed the drive that 1 ms logs of the same runs gave within 5 %
    // (docs/gap.md). There each row's error is its own: Xi restarts from
    // the encoder at every row; the servo's speed and states carry on (a
    // drive that cannot follow lags over many rows).
    let restart = log.dt_s() > replay::ONE_TICK_ROW_S;
    for k in 0..n {
        if !each((log.xi_m[k] - xi) / scale) {
            return true;
        }
        if restart {
            xi = log.xi_m[k];
        }
        let f = plant.piston_force_n(log.p1_pa[k], log.p2_pa[k]);
        let vc = plant
            .software_limited_v_cmd(xi, log.vcmd_mps[k])
            .clamp(-p.v_max_mps, p.v_max_mps);
        let rates = |v: f64, own: [f64; 2]| effects::servo_rates(servo, (vc, p.tau_m_s), v, f, own);
        for _ in 0..sub {
            // Midpoint rule on (xi, vi, own); the servo's time constant is
            // 20 steps.
            let (a1, d1) = rates(vi, own);
            let vm = vi + 0.5 * h * a1;
            let om = [own[0] + 0.5 * h * d1[0], own[1] + 0.5 * h * d1[1]];
            let (a2, d2) = rates(vm, om);
            xi += h * vm;
            vi += h * a2;
            own = [own[0] + h * d2[0], own[1] + h * d2[1]];
        }
        if !(xi.is_finite() && vi.is_finite()) {
            return false;
        }
    }
    true
}

/// Squared Xi error (in units of the run's Xi scale) of the servo model
/// `servo` on one run; stops early once above `stop`.
fn servo_error(run: &Run, plant: &Plant, servo: Servo<'_>, fine: bool, stop: f64) -> f64 {
    let mut err = 0.0;
    let finite = servo_track(run, plant, servo, fine, |d| {
        err += d * d;
        err <= stop
    });
    if finite {
        err
    } else {
        f64::INFINITY
    }
}

/// The Xi errors of the servo model `servo` over `runs`, row by row (fine
/// steps); `None` where it diverged.
fn servo_residuals(runs: &[Run], plant: &Plant, servo: Servo<'_>) -> Option<Vec<f64>> {
    let mut r = Vec::new();
    for run in runs {
        if !servo_track(run, plant, servo, true, |d| {
            r.push(d);
            true
        }) {
            return None;
        }
    }
    Some(r)
}

/// Squared Xi error of the servo model over `runs` (see [`motor_limit`]).
pub fn total_error(runs: &[Run], plant: &Plant, servo: Servo<'_>, fine: bool, stop: f64) -> f64 {
    let mut e = 0.0;
    for r in runs {
        e += servo_error(r, plant, servo, fine, stop - e);
        if e > stop {
            break;
        }
    }
    e
}

/// Motor-limit parameters (in [`EffectKind::params`] order) that best explain
/// the measured Xi of `runs` through the servo alone, when they explain it
/// better than the nominal servo; `None` otherwise.
///
/// The force limit is the sharp direction: a few per cent decide between a
/// servo pushed back by the load (a huge error) and one that never saturates
/// (the nominal error). So for each mass of a fine log axis the force is
/// scanned (30 % steps: the best point is the first above the valley, its
/// lower neighbour below it) and refined by golden section between the two
/// neighbours. The speed cap, which only acts on fast commands, is scanned
/// on its own with the best force and mass (and the force and mass searched
/// again under a cap); Nelder-Mead polishes the result.
pub fn motor_limit(runs: &[Run], plant: &Plant) -> Option<Vec<f64>> {
    let specs = EffectKind::MotorLimit.params();
    let bounds: Vec<Bound> = specs
        .iter()
        .map(|s| Bound {
            lo: s.min,
            hi: s.max,
        })
        .collect();
    let make = |x: &[f64]| MotorLimit {
        force_max_n: x[0],
        mass_eq_kg: x[1],
        speed_max_mps: x[2],
    };
    let at = |u: [f64; 3]| -> [f64; 3] { std::array::from_fn(|i| bounds[i].at(u[i])) };
    let err =
        |u: [f64; 3], stop: f64| total_error(runs, plant, Servo::Limit(&make(&at(u))), false, stop);
    let nominal = total_error(runs, plant, Servo::Nominal, false, f64::INFINITY);
    let unit = |i: usize, n: usize| i as f64 / (n - 1) as f64;
    // Best (error, [force, mass, speed] on the unit scales) with the speed at `uv`.
    let search = |uv: f64, stop: f64| -> (f64, [f64; 3]) {
        let mut best = (stop, [1.0, 0.0, uv]);
        for im in 0..25 {
            let um = unit(im, 25);
            let n = 30;
            let mut line = (f64::INFINITY, 0usize);
            for i in 0..n {
                let e = err([unit(i, n), um, uv], line.0.min(best.0));
                if e < line.0 {
                    line = (e, i);
                }
            }
            let (mut a, mut b) = (
                unit(line.1.saturating_sub(1), n),
                unit((line.1 + 1).min(n - 1), n),
            );
            let g = 0.5 * (5f64.sqrt() - 1.0);
            let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
            let (mut ec, mut ed) = (
                err([c, um, uv], f64::INFINITY),
                err([d, um, uv], f64::INFINITY),
            );
            for _ in 0..12 {
                if ec < ed {
                    (b, d, ed) = (d, c, ec);
                    c = b - g * (b - a);
                    ec = err([c, um, uv], f64::INFINITY);
                } else {
                    (a, c, ec) = (c, d, ed);
                    d = a + g * (b - a);
                    ed = err([d, um, uv], f64::INFINITY);
                }
            }
            for (e, uf) in [(line.0, unit(line.1, n)), (ec, c), (ed, d)] {
                if e < best.0 {
                    best = (e, [uf, um, uv]);
                }
            }
        }
        best
    };
    let (mut e, mut u) = search(1.0, nominal);
    for i in 0..20 {
        let uv = unit(i, 20);
        let ev = err([u[0], u[1], uv], e);
        if ev < e {
            (e, u[2]) = (ev, uv);
        }
    }
    if u[2] < 1.0 {
        let again = search(u[2], e);
        if again.0 < e {
            (e, u) = again;
        }
    }
    if e >= nominal {
        return None;
    }
    let mut f =
        |x: &[f64], stop: f64| total_error(runs, plant, Servo::Limit(&make(x)), false, stop);
    let r = minimize(&mut f, &bounds, &at(u), 3, 27 + 60);
    (r.value < nominal).then_some(r.x)
}

/// The servo's general family fitted through the servo alone: the force
/// envelope ([`ServoEnvelope`]) that best explains the measured Xi of
/// `runs`, with its squared Xi error and the nominal servo's; `None` when
/// it explains it no better than the nominal servo.
///
/// Each knot's force mostly decides the samples near its speed, so the
/// search goes knot by knot: for each mass of a log axis, the force at rest
/// is scanned (the narrow direction, as in [`motor_limit`]) and refined by
/// golden section, then each further knot between zero and the knot before
/// it (the envelope never rises with speed), from the fastest down, twice
/// over. The best mass is
/// refined on a finer axis around it, and Nelder-Mead polishes the result.
/// Knots the runs never reach stay at the force of the knot before (flat).
/// A ramp of the drive is tried under the result, and the drive's own speed
/// loop ([`SpeedLoop`]) and its command path ([`CommandMap`]) in searches of
/// their own.
pub fn servo_envelope(runs: &[Run], plant: &Plant) -> Option<(ServoEnvelope, f64, f64)> {
    let nominal = total_error(runs, plant, Servo::Nominal, true, f64::INFINITY);
    // Only where the gap is in the servo: the nominal servo leaves Xi off by
    // more than its scale on average.
    let samples: usize = runs.iter().map(|r| r.log.len()).sum();
    if nominal <= samples as f64 {
        return None;
    }
    let search = EnvelopeSearch {
        runs,
        plant,
        ramp: None,
        speed_loop: None,
    };
    let plain = search
        .fit(nominal, [MOTOR_FORCE.at(0.5); K])
        .map(|(e, m, a)| search.with_ramp(e, m, a));
    // The drive's own speed loop: searched on its own (an envelope fitted
    // without it stands in for it far from its values), kept where it
    // removes LOOP_GAIN of the best error so far; searched only where the
    // best envelope leaves the encoder off by more than twice its scale
    // (RMS).
    let best = plain.map_or(nominal, |p| p.0);
    let looped = (best > LOOP_NEEDS * samples as f64)
        .then(|| search.with_loop())
        .flatten()
        .filter(|(el, _)| *el < (1.0 - LOOP_GAIN) * best);
    let enveloped = looped.or(plain);
    // The drive's command path, searched on its own under no force limit
    // (a dead band held by an envelope's low force would be a wrong
    // explanation that fits), kept where it removes LOOP_GAIN of the best
    // error so far.
    let best = enveloped.map_or(nominal, |p| p.0);
    let mapped = search
        .with_command_map()
        .filter(|(em, _)| *em < (1.0 - LOOP_GAIN) * best);
    let (e, env) = mapped.or(enveloped)?;
    Some((env, e, nominal))
}

/// Jacobians of the command map's Levenberg-Marquardt fit at most.
const MAP_ITERS: usize = 30;
/// The force of the command map's search, N: none of the runs' forces
/// reaches it (the named form's largest).
const MAP_FORCE_N: f64 = MotorLimit::PARAMS[0].max;

/// Squared Xi error per sample (in scale units) above which an envelope
/// leaves room for the drive's speed loop (twice the scale, RMS).
const LOOP_NEEDS: f64 = 4.0;
/// Share of the best error so far the drive's speed loop must remove to be
/// kept.
const LOOP_GAIN: f64 = 0.2;
/// Bandwidths of the drive's speed loop, rad/s: from the nominal servo's
/// (100 rad/s) to the limit.
const LOOP_BANDWIDTH: Bound = Bound {
    lo: 100.0,
    hi: SpeedLoop::BANDWIDTH_MAX_RADPS,
};
/// The loop of the first search: bandwidth, rad/s, and integral corner as
/// a share of it.
const LOOP_START: (f64, f64) = (1000.0, 0.3);
/// The screw's viscous losses of the loop's first search, N s/m (at
/// 0.1 m/s, from none to 800 N).
const LOOP_DAMPING_NSPM: [f64; 5] = [0.0, 1000.0, 2500.0, 5000.0, 8000.0];
/// Masses of the loop's first search (a log axis from twice
/// [`MOTOR_MASS`]'s lowest to 1 t).
const LOOP_MASSES: usize = 9;
/// Grid points (the best per mass) the loop's polish starts from.
const LOOP_STARTS: usize = 3;
/// Jacobians of each Levenberg-Marquardt polish of the loop.
const LOOP_ITERS: usize = 30;

/// The speed loop of the loop search's values `x` (mass, force, loss,
/// bandwidth, corner): the corner at most the bandwidth.
fn loop_of(x: &[f64], windup: bool) -> SpeedLoop {
    SpeedLoop {
        bandwidth_radps: x[3],
        integral_radps: x[4].min(x[3]),
        windup,
        damping_nspm: x[2],
    }
}

/// Ramps of the drive tried, m/s^2 (a log axis between): from a crawl to
/// beyond what the nominal speed loop asks for a full-speed step.
const RAMP_MPS2: (f64, f64) = (0.3, 30.0);
/// Points of the ramps' log axis.
const RAMP_STEPS: usize = 7;
/// Share of the envelope's error a ramp must remove to be kept.
const RAMP_GAIN: f64 = 0.2;

/// Knots of the servo envelope.
const K: usize = ENVELOPE_SPEEDS_MPS.len();

/// The envelope of mass `m` and knot forces `a`, each knot capped by the one
/// before (the envelope never rises with speed) and at least 0, with the
/// ramp `ramp` and no speed loop.
fn envelope(m: f64, a: &[f64], ramp: Option<f64>) -> ServoEnvelope {
    let mut f = [a[0]; K];
    for k in 1..K {
        f[k] = a[k].clamp(0.0, f[k - 1]);
    }
    ServoEnvelope {
        mass_eq_kg: m,
        force_n: f,
        accel_max_mps2: ramp,
        speed_loop: None,
        command_map: None,
    }
}

/// `n` points from `lo` to `hi` on a log axis.
fn log_axis(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (lo.ln() + (hi.ln() - lo.ln()) * i as f64 / (n - 1) as f64).exp())
        .collect()
}

/// Golden section of `f(x, stop)` on [lo, hi] after a scan of `n` points
/// (12 steps, one evaluation each), as (value, x). Evaluations stop at four
/// times the best value of the line so far: values near the valley stay
/// exact, so the bracket is found.
fn golden_line(f: &dyn Fn(f64, f64) -> f64, lo: f64, hi: f64, n: usize) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let at = |i: usize| lo + (hi - lo) * i as f64 / (n - 1) as f64;
    let mut best = (f64::INFINITY, 0usize);
    for i in 0..n {
        let e = f(at(i), 4.0 * best.0);
        if e < best.0 {
            best = (e, i);
        }
    }
    let (mut a, mut b) = (at(best.1.saturating_sub(1)), at((best.1 + 1).min(n - 1)));
    let mut out = (best.0, at(best.1));
    let keep = |e: f64, u: f64, out: &mut (f64, f64)| {
        if e < out.0 {
            *out = (e, u);
        }
        e
    };
    // Each step keeps one inner point (and its value) and evaluates one.
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let mut ec = keep(f(c, 4.0 * out.0), c, &mut out);
    let mut ed = keep(f(d, 4.0 * out.0), d, &mut out);
    for _ in 0..12 {
        if ec < ed {
            (b, d, ed) = (d, c, ec);
            c = b - g * (b - a);
            ec = keep(f(c, 4.0 * out.0), c, &mut out);
        } else {
            (a, c, ec) = (c, d, ed);
            d = a + g * (b - a);
            ed = keep(f(d, 4.0 * out.0), d, &mut out);
        }
    }
    out
}

/// The steps of [`servo_envelope`]'s search over the runs.
#[derive(Clone, Copy)]
struct EnvelopeSearch<'a> {
    /// The runs whose Xi the envelope explains.
    runs: &'a [Run],
    /// The nominal plant.
    plant: &'a Plant,
    /// The drive's ramp the envelopes are tried with.
    ramp: Option<f64>,
    /// The drive's speed loop they are tried with.
    speed_loop: Option<SpeedLoop>,
}

impl EnvelopeSearch<'_> {
    /// The same search with the drive's ramp `ramp_mps2`.
    fn ramped(self, ramp_mps2: f64) -> Self {
        Self {
            ramp: Some(ramp_mps2),
            ..self
        }
    }

    /// The envelope search from the forces `a0`: a coarse log axis of
    /// masses, then a finer one around the best from its forces, then the
    /// polish; `None` where no mass explains Xi better than the nominal
    /// servo (its error `nominal`).
    fn fit(&self, nominal: f64, a0: [f64; K]) -> Option<(f64, f64, [f64; K])> {
        let mut best = (nominal, 0.0, [0.0; K]);
        for m in log_axis(MOTOR_MASS.lo, 1e3, 8) {
            let (e, a) = self.knots(m, a0);
            if e < best.0 {
                best = (e, m, a);
            }
        }
        if best.1 == 0.0 {
            return None;
        }
        Some(self.around(best.1, best.2, best.0))
    }

    /// The finer log axis of masses around `m0` from the forces `a0`
    /// (whose error is `e0`), each from the best forces so far, then the
    /// polish.
    fn around(&self, m0: f64, a0: [f64; K], e0: f64) -> (f64, f64, [f64; K]) {
        let mut best = (e0, m0, a0);
        for m in log_axis(m0 / 1.9, m0 * 1.9, 6) {
            let (e, a) = self.knots(m, best.2);
            if e < best.0 {
                best = (e, m, a);
            }
        }
        self.polish(best)
    }

    /// A ramp of the drive under the envelope of mass `m` and forces `a`
    /// (error `e` without it): each ramp on a log axis (knot by knot again);
    /// under the best one the masses around and the ramp between its
    /// neighbours, kept only where it lowers the error clearly. The error
    /// and the envelope, ramped or not.
    fn with_ramp(&self, e: f64, m: f64, a: [f64; K]) -> (f64, ServoEnvelope) {
        let mut best_ramp: Option<(f64, f64, [f64; K])> = None;
        for ramp in log_axis(RAMP_MPS2.0, RAMP_MPS2.1, RAMP_STEPS) {
            let (er, ar) = self.ramped(ramp).knots(m, a);
            if best_ramp.is_none_or(|(best, _, _)| er < best) {
                best_ramp = Some((er, ramp, ar));
            }
        }
        let with_ramp = best_ramp.and_then(|(er, ramp, ar)| {
            let (er, mr, ar) = self.ramped(ramp).around(m, ar, er);
            // The ramp itself between its neighbours on the axis, the rest
            // held, then the envelope polished under it.
            let step = (RAMP_MPS2.1 / RAMP_MPS2.0).ln() / (RAMP_STEPS - 1) as f64;
            let at_ln = |u: f64, stop: f64| self.ramped(u.exp()).error(mr, &ar, stop);
            let (e_line, u) = golden_line(&at_ln, ramp.ln() - step, ramp.ln() + step, 5);
            let ramp = if e_line < er { u.exp() } else { ramp };
            let under = self.ramped(ramp);
            let (er, mr, ar) = under.polish((under.error(mr, &ar, f64::INFINITY), mr, ar));
            (er < (1.0 - RAMP_GAIN) * e).then(|| (er, envelope(mr, &ar, Some(ramp))))
        });
        with_ramp.unwrap_or((e, envelope(m, &a, None)))
    }

    /// The same search under the speed loop `lp`.
    fn looped(self, lp: SpeedLoop) -> Self {
        Self {
            speed_loop: Some(lp),
            ..self
        }
    }

    /// The drive's own speed loop ([`SpeedLoop`]), searched on its own
    /// under a flat envelope, the screw's viscous loss taking force with
    /// speed. With and without windup, the loop at [`LOOP_START`]: over a
    /// log axis of masses and the losses [`LOOP_DAMPING_NSPM`], the force on
    /// a golden line for each (the narrow direction); from the best
    /// [`LOOP_STARTS`] masses, Levenberg-Marquardt on the encoder's errors
    /// over mass, force, loss, bandwidth and corner ([`Self::loop_lm`]: the
    /// valley is too narrow for Nelder-Mead); then the knots under the best loop
    /// ([`Self::knots`]) where they lower its error, and its two rates once
    /// more ([`Self::loop_rates`]). The error and the envelope.
    fn with_loop(&self) -> Option<(f64, ServoEnvelope)> {
        let (bw, share) = LOOP_START;
        let bounds = [
            MOTOR_MASS,
            MOTOR_FORCE,
            Bound {
                lo: 0.0,
                hi: LOOP_DAMPING_NSPM[LOOP_DAMPING_NSPM.len() - 1] * 2.0,
            },
            LOOP_BANDWIDTH,
            Bound {
                lo: 1.0,
                hi: LOOP_BANDWIDTH.hi,
            },
        ];
        let mut polished: Option<(f64, Vec<f64>, SpeedLoop)> = None;
        for windup in [true, false] {
            let make = |x: &[f64]| loop_of(x, windup);
            // The best point of the grid per mass, the best masses first.
            let mut grid: Vec<(f64, [f64; 3])> = Vec::new();
            for m in log_axis(MOTOR_MASS.lo * 2.0, 1e3, LOOP_MASSES) {
                let mut at_m: Option<(f64, [f64; 3])> = None;
                for c in LOOP_DAMPING_NSPM {
                    let under = self.looped(make(&[m, 0.0, c, bw, share * bw]));
                    let line = |u: f64, stop: f64| under.error(m, &[MOTOR_FORCE.at(u); K], stop);
                    let (e, u) = golden_line(&line, 0.0, 1.0, 15);
                    if at_m.is_none_or(|b| e < b.0) {
                        at_m = Some((e, [m, MOTOR_FORCE.at(u), c]));
                    }
                }
                grid.extend(at_m);
            }
            grid.sort_by(|a, b| a.0.total_cmp(&b.0));
            for (e0, [m, f, c]) in grid.into_iter().take(LOOP_STARTS) {
                let x0 = [m, f, c, bw, share * bw];
                let (e, x) = match self.loop_lm(&x0, &bounds, windup) {
                    Some((e, x)) if e < e0 => (e, x),
                    _ => (e0, x0.to_vec()),
                };
                if polished.as_ref().is_none_or(|p| e < p.0) {
                    polished = Some((e, x.clone(), make(&x)));
                }
            }
        }
        let (e, x, lp) = polished?;
        let m = x[0];
        let (e, a) = match self.looped(lp).knots(m, [x[1]; K]) {
            (ek, a) if ek < e => (ek, a),
            _ => (e, [x[1]; K]),
        };
        let (e, lp) = self.loop_rates(m, &a, (e, lp));
        let mut env = envelope(m, &a, self.ramp);
        env.speed_loop = Some(lp);
        e.is_finite().then_some((e, env))
    }

    /// The drive's command path ([`CommandMap`]) under an envelope that
    /// never limits: Levenberg-Marquardt on the encoder's errors over the
    /// map's increments between its knots (each non-negative, so the map
    /// never falls; in mm/s), from the ideal path. The error and the
    /// envelope.
    fn with_command_map(&self) -> Option<(f64, ServoEnvelope)> {
        let n = COMMAND_SPEEDS_MPS.len() - 1;
        let span = |i: usize| (COMMAND_SPEEDS_MPS[i + 1] - COMMAND_SPEEDS_MPS[i]) * 1e3;
        let map_of = |u: &[f64]| {
            let mut t = 0.0;
            CommandMap {
                target_mps: std::array::from_fn(|i| {
                    t += u[i].max(0.0) * 1e-3;
                    t
                }),
            }
        };
        let mass = MotorLimit::PARAMS[1].typical;
        let with = |m: CommandMap| {
            let mut s = envelope(mass, &[MAP_FORCE_N; K], self.ramp);
            s.speed_loop = self.speed_loop;
            s.command_map = Some(m);
            s
        };
        let u0: Vec<f64> = (0..n).map(span).collect();
        // A knot the runs never reach has no say in the errors: a row per
        // increment, of one unit per knot span from the ideal path (the
        // errors are in units of the encoder's scale, thousands where the
        // path differs), keeps it there and the normal equations regular.
        let f = |u: &[f64]| {
            let s = with(map_of(u));
            let mut r = servo_residuals(self.runs, self.plant, Servo::Envelope(&s))?;
            r.extend(
                u.iter()
                    .zip(&u0)
                    .enumerate()
                    .map(|(i, (x, x0))| (x - x0) / span(i)),
            );
            Some(r)
        };
        let h: Vec<f64> = (0..n).map(|i| 0.02 * span(i)).collect();
        let hi: Vec<f64> = (0..n).map(|i| 3.0 * span(i)).collect();
        let r = lsq::levenberg_marquardt(&f, &u0, None, &h, &vec![0.0; n], &hi, MAP_ITERS)?;
        let s = with(map_of(&r.x));
        let e = total_error(
            self.runs,
            self.plant,
            Servo::Envelope(&s),
            true,
            f64::INFINITY,
        );
        s.is_valid().then_some((e, s))
    }

    /// Levenberg-Marquardt on the Xi errors over the loop's mass, force,
    /// loss, bandwidth and corner (`x0`, within `bounds`; the forces and
    /// rates in log scale, the loss in kN s/m) under a flat envelope: the
    /// squared error and the values.
    fn loop_lm(&self, x0: &[f64; 5], bounds: &[Bound; 5], windup: bool) -> Option<(f64, Vec<f64>)> {
        const LOG: [bool; 5] = [true, true, false, true, true];
        let to_u = |x: f64, i: usize| if LOG[i] { x.ln() } else { x / 1e3 };
        let of_u = |u: f64, i: usize| if LOG[i] { u.exp() } else { u * 1e3 };
        let f = |u: &[f64]| {
            let x: Vec<f64> = (0..5).map(|i| of_u(u[i], i)).collect();
            let s = self.looped(loop_of(&x, windup)).servo(x[0], &[x[1]; K])?;
            servo_residuals(self.runs, self.plant, Servo::Envelope(&s))
        };
        let u0: Vec<f64> = (0..5).map(|i| to_u(x0[i], i)).collect();
        let lo: Vec<f64> = (0..5).map(|i| to_u(bounds[i].lo.max(1e-3), i)).collect();
        let hi: Vec<f64> = (0..5).map(|i| to_u(bounds[i].hi, i)).collect();
        let r = lsq::levenberg_marquardt(&f, &u0, None, &[1e-3; 5], &lo, &hi, LOOP_ITERS)?;
        Some((r.rss, (0..5).map(|i| of_u(r.x[i], i)).collect()))
    }

    /// The loop's bandwidth, then its integral corner, each on a golden
    /// line in log scale (a factor of 3 either way) under the envelope of
    /// mass `m` and forces `a`, from `best` (error, loop).
    fn loop_rates(&self, m: f64, a: &[f64], best: (f64, SpeedLoop)) -> (f64, SpeedLoop) {
        let (mut e, mut lp) = best;
        let span = 3f64.ln();
        let bw = |u: f64, stop: f64| {
            let mut l = lp;
            l.bandwidth_radps = u.exp().min(SpeedLoop::BANDWIDTH_MAX_RADPS);
            l.integral_radps = l.integral_radps.min(l.bandwidth_radps);
            self.looped(l).error(m, a, stop)
        };
        let u0 = lp.bandwidth_radps.ln();
        let (eb, u) = golden_line(&bw, u0 - span, u0 + span, 5);
        if eb < e {
            e = eb;
            lp.bandwidth_radps = u.exp().min(SpeedLoop::BANDWIDTH_MAX_RADPS);
            lp.integral_radps = lp.integral_radps.min(lp.bandwidth_radps);
        }
        let ki = |u: f64, stop: f64| {
            let mut l = lp;
            l.integral_radps = u.exp().min(l.bandwidth_radps);
            self.looped(l).error(m, a, stop)
        };
        let u0 = lp.integral_radps.max(1e-3).ln();
        let (ei, u) = golden_line(&ki, u0 - span, u0 + span, 5);
        if ei < e {
            e = ei;
            lp.integral_radps = u.exp().min(lp.bandwidth_radps);
        }
        (e, lp)
    }

    /// Squared Xi error of the envelope (mass `m`, forces `a`), stopping
    /// early above `stop`; infinite for an invalid envelope.
    fn error(&self, m: f64, a: &[f64], stop: f64) -> f64 {
        match self.servo(m, a) {
            Some(s) => total_error(self.runs, self.plant, Servo::Envelope(&s), true, stop),
            None => f64::INFINITY,
        }
    }

    /// The envelope of mass `m` and forces `a` with this search's ramp and
    /// speed loop; `None` where it is invalid.
    fn servo(&self, m: f64, a: &[f64]) -> Option<ServoEnvelope> {
        let mut s = envelope(m, a, self.ramp);
        s.speed_loop = self.speed_loop;
        s.is_valid().then_some(s)
    }

    /// Knot-by-knot search at mass `m` from the forces `a0`: twice over, the
    /// force at rest, then each further knot from the fastest down; then
    /// the knots the runs leave free raised ([`Self::raise`]).
    fn knots(&self, m: f64, a0: [f64; K]) -> (f64, [f64; K]) {
        let mut a = a0;
        let mut e = f64::INFINITY;
        for sweep in 0..2 {
            self.force_at_rest(m, sweep, &mut a, &mut e);
            // From the fastest knot down: lowering one caps only the
            // speeds above it (a knot lowered first would cap them all).
            for k in (1..K).rev() {
                let top = a[k - 1];
                let fk = |x: f64, stop: f64| {
                    let mut y = a;
                    y[k] = x;
                    self.error(m, &y, stop)
                };
                let (ek, xk) = golden_line(&fk, 0.0, top, 9);
                if ek < e {
                    (e, a[k]) = (ek, xk);
                }
            }
        }
        self.raise(m, &mut a, e)
    }

    /// The force at rest on a log axis (u in [0, 1] of MOTOR_FORCE), all
    /// knots scaled with it: the whole axis on the first sweep, a narrow
    /// span around the current force after. Updates `a` and its error `e`
    /// where better.
    fn force_at_rest(&self, m: f64, sweep: usize, a: &mut [f64; K], e: &mut f64) {
        let (lo, hi) = if sweep == 0 {
            (0.0, 1.0)
        } else {
            let u = MOTOR_FORCE.u_of(a[0]);
            ((u - 0.05).max(0.0), (u + 0.05).min(1.0))
        };
        let from = *a;
        let f0 = |u: f64, stop: f64| {
            let mut y = from;
            let ratio = MOTOR_FORCE.at(u) / from[0];
            for v in y.iter_mut() {
                *v *= ratio;
            }
            self.error(m, &y, stop)
        };
        let (e0, u0) = golden_line(&f0, lo, hi, if sweep == 0 { 30 } else { 5 });
        if e0 < *e {
            let ratio = MOTOR_FORCE.at(u0) / a[0];
            for v in a.iter_mut() {
                *v *= ratio;
            }
            *e = e0;
        }
    }

    /// Where the runs never press the drive at a knot's speed, the error is
    /// flat below the knot before: each knot is raised to the highest force
    /// within FLAT_TOL of the error `e` (limit only where the data show it).
    fn raise(&self, m: f64, a: &mut [f64; K], e: f64) -> (f64, [f64; K]) {
        let tol = e * (1.0 + FLAT_TOL) + 1.0;
        for k in 1..K {
            let fits = |x: f64| {
                let mut y = *a;
                y[k] = x;
                self.error(m, &y, tol) <= tol
            };
            let (mut lo, mut hi) = (a[k].min(a[k - 1]), a[k - 1]);
            if fits(hi) {
                a[k] = hi;
                continue;
            }
            for _ in 0..10 {
                let mid = 0.5 * (lo + hi);
                if fits(mid) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            a[k] = lo;
        }
        (self.error(m, a, f64::INFINITY), *a)
    }

    /// Nelder-Mead over the mass and the forces together from `best`
    /// (error, mass, forces), the free knots raised again; the better of
    /// the two.
    fn polish(&self, best: (f64, f64, [f64; K])) -> (f64, f64, [f64; K]) {
        let mut bounds = vec![MOTOR_MASS, MOTOR_FORCE];
        let top = best.2[0];
        bounds.extend([Bound { lo: 0.0, hi: top }; K - 1]);
        let mut x0 = vec![best.1];
        x0.extend(best.2);
        let mut f = |x: &[f64], stop: f64| self.error(x[0], &x[1..], stop);
        let r = minimize(&mut f, &bounds, &x0, 0, 300);
        if r.value < best.0 {
            let mut a = [0.0; K];
            a.copy_from_slice(&r.x[1..]);
            let (e, a) = self.raise(r.x[0], &mut a, r.value);
            (e, r.x[0], a)
        } else {
            best
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::{open_loop_run, rows_run};
    use super::*;
    use crate::model::effects::Effects;
    use crate::model::scenario::{Piecewise, Signal};
    use rand::{Rng, SeedableRng};

    /// An open-loop run of the rig with a motor limit; the prefit finds it.
    #[test]
    fn finds_a_force_limit_from_the_encoder() {
        let truth = [1200.0, 150.0, 0.1];
        let mut e = Effects::NONE;
        e.set(EffectKind::MotorLimit, Some(&truth));
        let run = open_loop_run(
            e,
            3.0,
            (vec![0.5, 1.0, 1.5, 2.0], &[0.0, 0.1, 0.0, -0.1, 0.0]),
            (vec![0.2], &[0.0, 800.0]),
        );
        let x = motor_limit(std::slice::from_ref(&run), &Plant::nominal()).expect("found");
        // The force limit is what the encoder sees best.
        assert!((x[0] / 1200.0 - 1.0).abs() < 0.03, "{x:?}");
    }

    /// An open-loop run of the rig with the servo envelope `truth`: extend at
    /// full command against 800 N, return, stall against 1400 N.
    fn envelope_run(truth: ServoEnvelope) -> Run {
        let e = Effects {
            servo_envelope: Some(truth),
            ..Effects::NONE
        };
        open_loop_run(
            e,
            3.0,
            (
                vec![0.3, 0.8, 1.3, 1.6, 2.1],
                &[0.0, 0.1, 0.0, -0.05, 0.0, 0.02],
            ),
            (vec![0.1, 2.0], &[0.0, 800.0, 1400.0]),
        )
    }

    /// A drive whose own PI speed loop winds up while its current limit
    /// holds it back, with a screw losing force to speed: the loop's
    /// search finds it (its integrator winding up, mass, force and loss
    /// within a few per cent) where the envelope alone cannot follow the
    /// catch-up.
    #[test]
    fn learns_a_speed_loop_that_winds_up() {
        let truth = ServoEnvelope {
            mass_eq_kg: 80.0,
            force_n: [1500.0; K],
            accel_max_mps2: None,
            speed_loop: Some(SpeedLoop {
                bandwidth_radps: 1000.0,
                integral_radps: 400.0,
                windup: true,
                damping_nspm: 2000.0,
            }),
            command_map: None,
        };
        let run = envelope_run(truth);
        let runs = std::slice::from_ref(&run);
        let (env, err, nominal) = servo_envelope(runs, &Plant::nominal()).expect("fitted");
        assert!(err < 1e-3 * nominal, "{err:e} against {nominal:e}: {env:?}");
        let lp = env.speed_loop.expect("a speed loop");
        assert!(lp.windup, "{env:?}");
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(rel(env.mass_eq_kg, 80.0) < 0.1, "{env:?}");
        assert!(rel(env.force_n[0], 1500.0) < 0.03, "{env:?}");
        assert!(rel(lp.damping_nspm, 2000.0) < 0.1, "{env:?}");
    }

    /// Rows of ten ticks, as a console capture keeps them, of a drive whose
    /// force is capped at 1500 N under a controller of the encoder (a
    /// proportional loop on position steps, its command scattered tick by
    /// tick by up to +-20 mm/s as an answer to sensor noise would; the log
    /// keeps each row's first tick): the envelope finds the cap within 5 %
    /// and the mass within 20 %.
    #[test]
    fn learns_a_force_cap_from_rows_of_ten_ticks() {
        let cap = 1500.0;
        let truth = ServoEnvelope {
            mass_eq_kg: 150.0,
            force_n: [cap; K],
            accel_max_mps2: None,
            speed_loop: None,
            command_map: None,
        };
        let e = Effects {
            servo_envelope: Some(truth),
            ..Effects::NONE
        };
        // The scatter: uniform in [-20, 20) mm/s, seeded.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let reference = Signal::Piecewise(
            Piecewise::constants(vec![0.3, 1.3, 2.1], &[0.0, 0.04, 0.01, 0.03]).unwrap(),
        );
        let v_max = Plant::nominal().params().v_max_mps;
        let command = |k: usize, xi_m: f64| {
            let r = reference.value(k as f64 * 1e-3);
            (30.0 * (r - xi_m)).clamp(-v_max, v_max) + rng.random_range(-0.02..0.02)
        };
        let load = (vec![0.1, 1.0, 2.0], &[0.0, 800.0, 1400.0, 600.0][..]);
        let run = Run::new("t".into(), rows_run(e, 3.0, command, load).log.decimate(10));
        assert!((run.log.dt_s() - 0.01).abs() < 1e-9);
        let runs = std::slice::from_ref(&run);
        let (env, _, _) = servo_envelope(runs, &Plant::nominal()).expect("fitted");
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(rel(env.force_n[0], cap) < 0.05, "{env:?}");
        assert!(rel(env.mass_eq_kg, 150.0) < 0.2, "{env:?}");
    }

    /// A drive that ramps its speed target at 2 m/s^2 whatever the load
    /// (a force at rest no load reaches): the envelope finds the ramp.
    #[test]
    fn learns_the_ramp_of_a_drive() {
        let truth = ServoEnvelope {
            mass_eq_kg: 100.0,
            force_n: [5000.0; 6],
            accel_max_mps2: Some(2.0),
            speed_loop: None,
            command_map: None,
        };
        let run = envelope_run(truth);
        let runs = std::slice::from_ref(&run);
        let (env, err, nominal) = servo_envelope(runs, &Plant::nominal()).expect("fitted");
        assert!(err < 1e-2 * nominal, "{err:e} against {nominal:e}: {env:?}");
        let ramp = env.accel_max_mps2.expect("a ramp");
        assert!((ramp / 2.0 - 1.0).abs() < 0.05, "{env:?}");
    }

    /// A drive with a dead band of 1 mm/s in its command path (the target
    /// is the command less 1 mm/s) and no force limit, run through slow
    /// commands on either side of it: the command map's search finds the
    /// band and the unit slope above it where the envelope cannot.
    #[test]
    fn learns_the_dead_band_of_a_drive() {
        let band = CommandMap {
            target_mps: std::array::from_fn(|i| (COMMAND_SPEEDS_MPS[i + 1] - 1e-3).max(0.0)),
        };
        let truth = ServoEnvelope {
            mass_eq_kg: 200.0,
            force_n: [1e5; K],
            accel_max_mps2: None,
            speed_loop: None,
            command_map: Some(band),
        };
        let e = Effects {
            servo_envelope: Some(truth),
            ..Effects::NONE
        };
        let run = open_loop_run(
            e,
            4.0,
            (
                vec![0.3, 0.8, 1.3, 1.8, 2.3, 2.8, 3.3],
                &[0.0, 0.0008, 0.003, -0.002, 0.0015, -0.006, 0.02, 0.0],
            ),
            (vec![0.1], &[0.0, 300.0]),
        );
        let runs = std::slice::from_ref(&run);
        let (env, err, nominal) = servo_envelope(runs, &Plant::nominal()).expect("fitted");
        assert!(err < 1e-2 * nominal, "{err:e} against {nominal:e}: {env:?}");
        let map = env.command_map.expect("a command map");
        for c in [0.8e-3, 1.5e-3, 2e-3, 3e-3, 6e-3, 20e-3] {
            let (got, want) = (map.target_of(c), (c - 1e-3).max(0.0));
            assert!(
                (got - want).abs() < 0.05e-3 + 0.03 * want,
                "{c}: {got} {want}: {map:?}"
            );
            assert_eq!(map.target_of(-c), -got);
        }
    }

    /// A torque-speed curve that the named form cannot take (the force
    /// falls with speed): the envelope finds the force at rest and the
    /// fall where the run motors under load, keeps the knots the run never
    /// presses flat, and is not fitted where the servo follows its command.
    #[test]
    fn learns_a_falling_force_envelope_and_nothing_from_a_nominal_servo() {
        let truth = ServoEnvelope {
            mass_eq_kg: 150.0,
            force_n: [1200.0, 1200.0, 1200.0, 900.0, 600.0, 300.0],
            accel_max_mps2: None,
            speed_loop: None,
            command_map: None,
        };
        // Full command against 800 N settles where A(v) = 800 N, near
        // 67 mm/s.
        let run = envelope_run(truth);
        let runs = std::slice::from_ref(&run);
        let (env, err, nominal) = servo_envelope(runs, &Plant::nominal()).expect("fitted");
        assert!(err < 1e-2 * nominal, "{err:e} against {nominal:e}: {env:?}");
        let rel = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(rel(env.force_n[0], 1200.0) < 0.03, "{env:?}");
        // Where the run motors under load, the speed at which 800 N is all
        // the drive has (the settling speed, 66.7 mm/s; one load level shows
        // where the curve crosses it, not its slope).
        let crossing = |s: &ServoEnvelope| {
            let (mut lo, mut hi) = (0.0, 0.1);
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if s.available_n(mid) > 800.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            lo
        };
        assert!((crossing(&env) - crossing(&truth)).abs() < 2e-3, "{env:?}");
        assert!(env.is_valid());
        // No ramp where the drive has none.
        assert_eq!(env.accel_max_mps2, None, "{env:?}");
        // The nominal rig gives no envelope.
        let clean = open_loop_run(
            Effects::NONE,
            3.0,
            (vec![0.3, 0.8, 1.3, 1.6], &[0.0, 0.1, 0.0, -0.05, 0.0]),
            (vec![0.1], &[0.0, 800.0]),
        );
        assert!(servo_envelope(std::slice::from_ref(&clean), &Plant::nominal()).is_none());
    }
}
