//! Least squares on the replays' residuals: the residual vector of a model
//! on runs, and a bounded Levenberg-Marquardt fit with finite-difference
//! Jacobians, for the candidates whose parameters are nearly linear in the
//! residual (`parameters`, the force sensor's `sensor_calibration`).
//!
//! The residual is the one the gap is made of: per run, channel (xo, xi, p1,
//! p2) and 10 ms block, the block mean of measured minus replayed, in units
//! of the channel's scale (its noise level with a floor).

use rayon::prelude::*;

use super::measure::{rig_with, BLOCK};
use super::replay::{measured, replay_with_load};
use super::run::Run;
use crate::model::effects::Effects;
use crate::model::plant::Plant;

/// Residual value standing for a diverged replay (in units of the scale).
const DIVERGED: f64 = 1e6;

/// The block-mean residuals of `runs` under `effects` in units of each
/// channel's scale, run by run, channel by channel; `None` when the effects
/// cannot go on the plant.
pub fn residuals(runs: &[Run], base: &Plant, effects: &Effects, dt_s: f64) -> Option<Vec<f64>> {
    let rig = rig_with(base, effects)?;
    let mut out = Vec::new();
    for run in runs {
        let sim = replay_with_load(&run.log, &run.load, &rig, dt_s);
        let meas = measured(&run.log);
        for (c, (meas_c, sim_c)) in meas.iter().zip(&sim.ch).enumerate() {
            for (m, s) in meas_c.chunks(BLOCK).zip(sim_c.chunks(BLOCK)) {
                let r = m.iter().zip(s).map(|(a, b)| a - b).sum::<f64>() / m.len() as f64;
                out.push(if r.is_finite() {
                    r / run.scale[c]
                } else {
                    DIVERGED
                });
            }
        }
    }
    Some(out)
}

/// Expected sum of squares of [`residuals`] from the noise alone: each
/// block mean carries noise^2 / BLOCK / scale^2.
pub fn noise_floor(runs: &[Run]) -> f64 {
    runs.iter()
        .map(|r| {
            let blocks = r.log.len().div_ceil(BLOCK) as f64;
            (0..4)
                .map(|c| blocks * (r.noise[c] / r.scale[c]).powi(2) / BLOCK as f64)
                .sum::<f64>()
        })
        .sum()
}

/// Sum of squares.
pub fn ss(r: &[f64]) -> f64 {
    r.iter().map(|x| x * x).sum()
}

/// A least-squares fit.
#[derive(Clone, Debug, PartialEq)]
pub struct LsqFit {
    /// The parameters.
    pub x: Vec<f64>,
    /// Sum of squared residuals there.
    pub rss: f64,
    /// Number of residuals.
    pub n: usize,
    /// Jacobian columns (one per parameter) at or next to `x`.
    pub jac: Vec<Vec<f64>>,
    /// The residuals at `x`.
    pub r: Vec<f64>,
    /// Residual evaluations (replays of the runs) used.
    pub evals: usize,
}

/// A residual function of the parameters (`None`: not evaluable there).
pub type ResidualFn<'a> = dyn Fn(&[f64]) -> Option<Vec<f64>> + Sync + 'a;

/// Forward-difference Jacobian columns of `f` at `x` (residuals `r0`), with
/// steps `h` (taken backwards where forwards would leave `hi`); evaluated
/// in parallel.
pub fn jacobian(f: &ResidualFn<'_>, x: &[f64], r0: &[f64], h: &[f64], hi: &[f64]) -> Vec<Vec<f64>> {
    (0..x.len())
        .into_par_iter()
        .map(|i| {
            let mut xi = x.to_vec();
            let step = if x[i] + h[i] <= hi[i] { h[i] } else { -h[i] };
            xi[i] += step;
            match f(&xi) {
                Some(r) => r.iter().zip(r0).map(|(a, b)| (a - b) / step).collect(),
                None => vec![0.0; r0.len()],
            }
        })
        .collect()
}

/// Solve the normal equations (J^T J + lambda diag(J^T J)) d = -J^T r for
/// the columns `cols` of `jac`; `None` when singular.
pub fn normal_step(jac: &[Vec<f64>], cols: &[usize], r: &[f64], lambda: f64) -> Option<Vec<f64>> {
    let p = cols.len();
    let mut a = vec![vec![0.0; p]; p];
    let mut g = vec![0.0; p];
    for (i, &ci) in cols.iter().enumerate() {
        for (j, &cj) in cols.iter().enumerate() {
            a[i][j] = dot(&jac[ci], &jac[cj]);
        }
        g[i] = -dot(&jac[ci], r);
    }
    for (i, row) in a.iter_mut().enumerate() {
        row[i] *= 1.0 + lambda;
    }
    solve(a, g)
}

/// The damped step of [`normal_step`] over every value of `x`, solved again
/// without the values that sit on a bound of `[lo, hi]` it would push them
/// beyond: those stay where they are, and the step of the others is the best
/// one with them held (clipping the full step instead moves the others as if
/// the held values had moved too). `None` when singular.
fn bounded_step(
    jac: &[Vec<f64>],
    r: &[f64],
    lambda: f64,
    x: &[f64],
    lo: &[f64],
    hi: &[f64],
) -> Option<Vec<f64>> {
    let all: Vec<usize> = (0..x.len()).collect();
    let d = normal_step(jac, &all, r, lambda)?;
    let held = |i: usize| (x[i] <= lo[i] && d[i] < 0.0) || (x[i] >= hi[i] && d[i] > 0.0);
    let free: Vec<usize> = all.iter().copied().filter(|&i| !held(i)).collect();
    if free.len() == all.len() {
        return Some(d);
    }
    let mut out = vec![0.0; d.len()];
    if !free.is_empty() {
        for (&i, v) in free.iter().zip(normal_step(jac, &free, r, lambda)?) {
            out[i] = v;
        }
    }
    Some(out)
}

/// Dot product.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// Solve `a x = b` by Gaussian elimination with partial pivoting; `None`
/// when `a` is singular.
pub fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    let scale = a
        .iter()
        .flat_map(|r| r.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()));
    for k in 0..n {
        let piv = (k..n).max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))?;
        if a[piv][k].abs() <= 1e-14 * scale.max(f64::MIN_POSITIVE) {
            return None;
        }
        a.swap(k, piv);
        b.swap(k, piv);
        let (top, rest) = a.split_at_mut(k + 1);
        let pivot = &top[k];
        for (i, row) in rest.iter_mut().enumerate() {
            let f = row[k] / pivot[k];
            for (x, p) in row.iter_mut().zip(pivot).skip(k) {
                *x -= f * p;
            }
            b[k + 1 + i] -= f * b[k];
        }
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        let s: f64 = (k + 1..n).map(|j| a[k][j] * x[j]).sum();
        x[k] = (b[k] - s) / a[k][k];
    }
    Some(x)
}

/// The inverse of `J^T J` for the columns of `jac`; `None` when singular.
pub fn inverse_normal(jac: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let p = jac.len();
    let a: Vec<Vec<f64>> = (0..p)
        .map(|i| (0..p).map(|j| dot(&jac[i], &jac[j])).collect())
        .collect();
    let mut inv = vec![vec![0.0; p]; p];
    for k in 0..p {
        let e: Vec<f64> = (0..p).map(|i| if i == k { 1.0 } else { 0.0 }).collect();
        let col = solve(a.clone(), e)?;
        for (row, v) in inv.iter_mut().zip(col) {
            row[k] = v;
        }
    }
    Some(inv)
}

/// Lag-1 autocorrelation of `r` (0 for fewer than 3 values).
pub fn lag1(r: &[f64]) -> f64 {
    if r.len() < 3 {
        return 0.0;
    }
    let m = r.iter().sum::<f64>() / r.len() as f64;
    let v: f64 = r.iter().map(|x| (x - m).powi(2)).sum();
    if v <= 0.0 {
        return 0.0;
    }
    r.windows(2).map(|w| (w[0] - m) * (w[1] - m)).sum::<f64>() / v
}

/// Levenberg-Marquardt from `x0` (residuals `r0` there, if known) within
/// `[lo, hi]`: at most `iters` Jacobians (steps `h`), each followed by up to
/// three damped trial steps; stops once a step lowers the sum of squares by
/// less than 0.1 %. `None` when `f` cannot be evaluated at `x0`.
pub fn levenberg_marquardt(
    f: &ResidualFn<'_>,
    x0: &[f64],
    r0: Option<Vec<f64>>,
    h: &[f64],
    lo: &[f64],
    hi: &[f64],
    iters: usize,
) -> Option<LsqFit> {
    let mut evals = 0;
    let mut r = match r0 {
        Some(r) => r,
        None => {
            evals += 1;
            f(x0)?
        }
    };
    let mut x = x0.to_vec();
    let mut rss = ss(&r);
    let mut lambda = 1e-3;
    let mut jac = Vec::new();
    for _ in 0..iters {
        jac = jacobian(f, &x, &r, h, hi);
        evals += x.len();
        let mut improved = None;
        for _ in 0..3 {
            let Some(d) = bounded_step(&jac, &r, lambda, &x, lo, hi) else {
                lambda *= 10.0;
                continue;
            };
            let xn: Vec<f64> = x
                .iter()
                .zip(&d)
                .zip(lo.iter().zip(hi))
                .map(|((x, d), (l, u))| (x + d).clamp(*l, *u))
                .collect();
            evals += 1;
            match f(&xn) {
                Some(rn) if ss(&rn) < rss => {
                    improved = Some((xn, rn));
                    lambda = (lambda / 3.0).max(1e-7);
                    break;
                }
                _ => lambda *= 8.0,
            }
        }
        let Some((xn, rn)) = improved else { break };
        let rn_ss = ss(&rn);
        let gain = (rss - rn_ss) / rss.max(f64::MIN_POSITIVE);
        x = xn;
        r = rn;
        rss = rn_ss;
        if gain < 1e-3 {
            break;
        }
    }
    if jac.is_empty() {
        jac = jacobian(f, &x, &r, h, hi);
        evals += x.len();
    }
    Some(LsqFit {
        n: r.len(),
        x,
        rss,
        jac,
        r,
        evals,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_a_curve_and_solves_small_systems() {
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let truth = [2.0, 0.7];
        let model =
            |x: &[f64]| -> Vec<f64> { t.iter().map(|t| x[0] * (-x[1] * t).exp()).collect() };
        let y = model(&truth);
        let f = |x: &[f64]| -> Option<Vec<f64>> {
            Some(model(x).iter().zip(&y).map(|(m, y)| y - m).collect())
        };
        let fit = levenberg_marquardt(
            &f,
            &[1.0, 0.3],
            None,
            &[1e-6, 1e-6],
            &[0.0, 0.0],
            &[5.0, 5.0],
            30,
        )
        .unwrap();
        assert!(
            (fit.x[0] - 2.0).abs() < 1e-4 && (fit.x[1] - 0.7).abs() < 1e-4,
            "{fit:?}"
        );
        // Bounds hold.
        let b = levenberg_marquardt(
            &f,
            &[1.0, 0.3],
            None,
            &[1e-6, 1e-6],
            &[0.0, 0.0],
            &[1.5, 5.0],
            30,
        )
        .unwrap();
        assert!(b.x[0] <= 1.5);
        let x = solve(vec![vec![2.0, 1.0], vec![1.0, 3.0]], vec![3.0, 5.0]).unwrap();
        assert!(
            (x[0] - 0.8).abs() < 1e-12 && (x[1] - 1.4).abs() < 1e-12,
            "{x:?}"
        );
        assert!(solve(vec![vec![1.0, 2.0], vec![2.0, 4.0]], vec![1.0, 2.0]).is_none());
        let inv = inverse_normal(&[vec![1.0, 0.0], vec![0.0, 2.0]]).unwrap();
        assert!((inv[1][1] - 0.25).abs() < 1e-12 && inv[0][1].abs() < 1e-12);
        assert!(lag1(&[1.0, -1.0, 1.0, -1.0, 1.0, -1.0]) < -0.5);
    }

    /// Two correlated values, the free optimum with the first below its
    /// bound: the first stays on it and the second takes the best value with
    /// the first held, in one Jacobian (the problem is linear). Clipping the
    /// full step instead moves the second as if the first had left its bound
    /// (measured before the held step: 1.31 after one Jacobian, sum of squares
    /// 0.15 against 0.0045).
    #[test]
    fn a_value_on_its_bound_is_held_while_the_others_move() {
        // Residuals y - A x with A = [[1, 1], [1, 1.1]] and y = A (-1, 2).
        let a = [[1.0, 1.0], [1.0, 1.1]];
        let y = [1.0, 1.2];
        let f = |x: &[f64]| -> Option<Vec<f64>> {
            Some(
                a.iter()
                    .zip(&y)
                    .map(|(row, y)| y - row[0] * x[0] - row[1] * x[1])
                    .collect(),
            )
        };
        // With x0 = 0: x1 = (1 + 1.1 * 1.2) / (1 + 1.1^2).
        let x1: f64 = (1.0 + 1.1 * 1.2) / (1.0 + 1.21);
        let best = (1.0 - x1).powi(2) + (1.2 - 1.1 * x1).powi(2);
        for iters in [1, 2, 5] {
            let fit = levenberg_marquardt(
                &f,
                &[0.0, 0.0],
                None,
                &[1e-6, 1e-6],
                &[0.0, 0.0],
                &[10.0, 10.0],
                iters,
            )
            .unwrap();
            assert_eq!(fit.x[0], 0.0, "{iters}: {fit:?}");
            assert!((fit.x[1] - x1).abs() < 1e-2, "{iters}: {fit:?}");
            assert!(fit.rss < best + 1e-4, "{iters}: {fit:?}, best {best}");
        }
    }
}
