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
use crate::model::effects::{self, EffectKind, MotorLimit};
use crate::model::plant::Plant;

/// Squared Xi error (in units of `scale_m`) of the servo model with `limit`
/// (or none) on one run; stops early once above `stop`.
fn servo_error(run: &Run, plant: &Plant, limit: Option<&MotorLimit>, stop: f64) -> f64 {
    let p = plant.params();
    let log = &run.log;
    let n = log.len();
    let scale = run.scale[1];
    let sub = 2;
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
        let accel = |v: f64| effects::servo_accel(limit, vc, v, p.tau_m_s, f);
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
pub fn total_error(runs: &[Run], plant: &Plant, limit: Option<&MotorLimit>, stop: f64) -> f64 {
    let mut e = 0.0;
    for r in runs {
        e += servo_error(r, plant, limit, stop - e);
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
    let err = |u: [f64; 3], stop: f64| total_error(runs, plant, Some(&make(&at(u))), stop);
    let nominal = total_error(runs, plant, None, f64::INFINITY);
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
    let mut f = |x: &[f64], stop: f64| total_error(runs, plant, Some(&make(x)), stop);
    let r = minimize(&mut f, &bounds, &at(u), 3, 27 + 60);
    (r.value < nominal).then_some(r.x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::runlog::RunLog;
    use crate::model::effects::Effects;
    use crate::model::rig::Rig;
    use crate::model::scenario::{Command, Piecewise, Scenario, Signal};

    /// An open-loop run of the rig with a motor limit; the prefit finds it.
    #[test]
    fn finds_a_force_limit_from_the_encoder() {
        let truth = [1200.0, 150.0, 0.1];
        let mut e = Effects::NONE;
        e.set(EffectKind::MotorLimit, Some(&truth));
        let rig = Rig::new(Plant::nominal(), e).unwrap();
        let steps = |t: Vec<f64>, v: &[f64]| Signal::Piecewise(Piecewise::constants(t, v).unwrap());
        let sc = Scenario::new(
            "t",
            3.0,
            Command::OpenLoop(steps(vec![0.5, 1.0, 1.5, 2.0], &[0.0, 0.1, 0.0, -0.1, 0.0])),
            steps(vec![0.2], &[0.0, 800.0]),
        );
        let mut s = rig.initial_state(0.0);
        let mut text = String::from("t_s,ref_m,vcmd_mps,xi_m,xo_m,p1_pa,p2_pa,ft_n\n");
        for k in 0..3000 {
            let t = k as f64 * 1e-3;
            let Command::OpenLoop(v) = sc.command() else {
                unreachable!()
            };
            let v = v.value(t);
            let ft = sc.load().value(t);
            text.push_str(&format!(
                "{t},0,{v},{},{},{},{},{ft}\n",
                s.x.xi_m, s.x.xo_m, s.x.p1_pa, s.x.p2_pa
            ));
            for _ in 0..10 {
                rig.step(&mut s, v, ft, 1e-4);
            }
        }
        let run = Run::new("t".into(), RunLog::parse(&text, "t").unwrap());
        let x = motor_limit(std::slice::from_ref(&run), &Plant::nominal()).expect("found");
        // The force limit is what the encoder sees best.
        assert!((x[0] / 1200.0 - 1.0).abs() < 0.03, "{x:?}");
    }
}
