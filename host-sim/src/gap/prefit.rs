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
use super::run::Run;
use crate::model::effects::{
    self, EffectKind, MotorLimit, Servo, ServoEnvelope, ENVELOPE_SPEEDS_MPS,
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

/// Squared Xi error (in units of the run's Xi scale) of the servo model
/// `servo` on one run; stops early once above `stop`.
fn servo_error(run: &Run, plant: &Plant, servo: Servo<'_>, fine: bool, stop: f64) -> f64 {
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
    let mut err = 0.0;
    for k in 0..n {
        let d = (log.xi_m[k] - xi) / scale;
        err += d * d;
        if err > stop {
            return err;
        }
        let f = plant.piston_force_n(log.p1_pa[k], log.p2_pa[k]);
        let vc = plant
            .software_limited_v_cmd(xi, log.vcmd_mps[k])
            .clamp(-p.v_max_mps, p.v_max_mps);
        let accel = |v: f64| effects::servo_accel(servo, vc, v, p.tau_m_s, f);
        for _ in 0..sub {
            // Midpoint rule on (xi, vi); the servo's time constant is 20 steps.
            let a1 = accel(vi);
            let vm = vi + 0.5 * h * a1;
            let a2 = accel(vm);
            xi += h * vm;
            vi += h * a2;
        }
        if !(xi.is_finite() && vi.is_finite()) {
            return f64::INFINITY;
        }
    }
    err
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
    };
    let (e, m, a) = search.fit(nominal, [MOTOR_FORCE.at(0.5); K])?;
    // A ramp of the drive: each on a log axis under the found mass and
    // forces (knot by knot again); under the best one the masses around
    // and the ramp between its neighbours, kept only where it lowers the
    // error clearly.
    let mut best_ramp: Option<(f64, f64, [f64; K])> = None;
    for ramp in log_axis(RAMP_MPS2.0, RAMP_MPS2.1, RAMP_STEPS) {
        let (er, ar) = search.ramped(ramp).knots(m, a);
        if best_ramp.is_none_or(|(best, _, _)| er < best) {
            best_ramp = Some((er, ramp, ar));
        }
    }
    let with_ramp = best_ramp.and_then(|(er, ramp, ar)| {
        let (er, mr, ar) = search.ramped(ramp).around(m, ar, er);
        // The ramp itself between its neighbours on the axis, the rest
        // held, then the envelope polished under it.
        let step = (RAMP_MPS2.1 / RAMP_MPS2.0).ln() / (RAMP_STEPS - 1) as f64;
        let at_ln = |u: f64, stop: f64| search.ramped(u.exp()).error(mr, &ar, stop);
        let (e_line, u) = golden_line(&at_ln, ramp.ln() - step, ramp.ln() + step, 5);
        let ramp = if e_line < er { u.exp() } else { ramp };
        let under = search.ramped(ramp);
        let (er, mr, ar) = under.polish((under.error(mr, &ar, f64::INFINITY), mr, ar));
        (er < (1.0 - RAMP_GAIN) * e).then(|| (er, envelope(mr, &ar, Some(ramp))))
    });
    Some(match with_ramp {
        Some((er, env)) => (env, er, nominal),
        None => (envelope(m, &a, None), e, nominal),
    })
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
/// before (the envelope never rises with speed) and at least 0.
fn envelope(m: f64, a: &[f64], ramp: Option<f64>) -> ServoEnvelope {
    let mut f = [a[0]; K];
    for k in 1..K {
        f[k] = a[k].clamp(0.0, f[k - 1]);
    }
    ServoEnvelope {
        mass_eq_kg: m,
        force_n: f,
        accel_max_mps2: ramp,
    }
}

/// `n` points from `lo` to `hi` on a log axis.
fn log_axis(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| (lo.ln() + (hi.ln() - lo.ln()) * i as f64 / (n - 1) as f64).exp())
        .collect()
}

/// Golden section of `f(x, stop)` on [lo, hi] after a scan of `n` points,
/// as (value, x). Evaluations stop at four times the best value of the line
/// so far: values near the valley stay exact, so the bracket is found.
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
    for _ in 0..12 {
        let (c, d) = (b - g * (b - a), a + g * (b - a));
        let (ec, ed) = (f(c, 4.0 * out.0), f(d, 4.0 * out.0));
        for (e, u) in [(ec, c), (ed, d)] {
            if e < out.0 {
                out = (e, u);
            }
        }
        if ec < ed {
            b = d;
        } else {
            a = c;
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

    /// Squared Xi error of the envelope (mass `m`, forces `a`), stopping
    /// early above `stop`; infinite for an invalid envelope.
    fn error(&self, m: f64, a: &[f64], stop: f64) -> f64 {
        let s = envelope(m, a, self.ramp);
        if !s.is_valid() {
            return f64::INFINITY;
        }
        total_error(self.runs, self.plant, Servo::Envelope(&s), true, stop)
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
    use super::super::testing::open_loop_run;
    use super::*;
    use crate::model::effects::Effects;

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

    /// A drive that ramps its speed target at 2 m/s^2 whatever the load
    /// (a force at rest no load reaches): the envelope finds the ramp.
    #[test]
    fn learns_the_ramp_of_a_drive() {
        let truth = ServoEnvelope {
            mass_eq_kg: 100.0,
            force_n: [5000.0; 6],
            accel_max_mps2: Some(2.0),
        };
        let run = envelope_run(truth);
        let runs = std::slice::from_ref(&run);
        let (env, err, nominal) = servo_envelope(runs, &Plant::nominal()).expect("fitted");
        assert!(err < 1e-2 * nominal, "{err:e} against {nominal:e}: {env:?}");
        let ramp = env.accel_max_mps2.expect("a ramp");
        assert!((ramp / 2.0 - 1.0).abs() < 0.05, "{env:?}");
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
