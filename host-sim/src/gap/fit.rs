//! Bounded minimisation for fitting effect parameters.
//!
//! Each parameter is mapped to u in [0, 1] (logarithmically between its
//! bounds when they span more than a decade, with a lower bound of 0 replaced
//! by 1e-4 of the upper bound), scanned on a coarse full grid (up to three
//! parameters), then refined by Nelder-Mead with the simplex clamped to the
//! unit box.
//! Evaluations are few (each is a replay of whole runs), so the budget is
//! explicit, and each is told the value it must beat to matter (`stop`): an
//! objective may stop early and return any value above it.

/// Bounds of one parameter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bound {
    /// Lower bound.
    pub lo: f64,
    /// Upper bound.
    pub hi: f64,
}

impl Bound {
    fn is_log(&self) -> bool {
        self.hi > 0.0 && (self.lo <= 0.0 || self.hi / self.lo > 10.0)
    }

    fn log_lo(&self) -> f64 {
        if self.lo > 0.0 {
            self.lo
        } else {
            self.hi * 1e-4
        }
    }

    /// Parameter value at u in [0, 1].
    pub fn at(&self, u: f64) -> f64 {
        let u = u.clamp(0.0, 1.0);
        if self.is_log() {
            let (a, b) = (self.log_lo().ln(), self.hi.ln());
            (a + u * (b - a)).exp()
        } else {
            self.lo + u * (self.hi - self.lo)
        }
    }

    /// u in [0, 1] of a parameter value.
    pub fn u_of(&self, x: f64) -> f64 {
        let u = if self.is_log() {
            let (a, b) = (self.log_lo().ln(), self.hi.ln());
            (x.max(self.log_lo()).ln() - a) / (b - a)
        } else {
            (x - self.lo) / (self.hi - self.lo)
        };
        u.clamp(0.0, 1.0)
    }
}

/// Result of a minimisation.
#[derive(Clone, Debug, PartialEq)]
pub struct FitResult {
    /// Best parameters found.
    pub x: Vec<f64>,
    /// Objective there.
    pub value: f64,
    /// Objective evaluations used.
    pub evals: usize,
}

/// The objective on the unit box, counting its evaluations.
struct Objective<'a> {
    f: &'a mut dyn FnMut(&[f64], f64) -> f64,
    bounds: &'a [Bound],
    evals: usize,
}

impl Objective<'_> {
    /// The objective at `u` (infinite when not finite), told to stop above `stop`.
    fn at(&mut self, u: &[f64], stop: f64) -> f64 {
        self.evals += 1;
        let x: Vec<f64> = u.iter().zip(self.bounds).map(|(u, b)| b.at(*u)).collect();
        let v = (self.f)(&x, stop);
        if v.is_finite() {
            v
        } else {
            f64::INFINITY
        }
    }
}

/// Minimise `f` within `bounds` from `x0`, with at most `max_evals`
/// evaluations and `scan` coarse points per parameter. `f(x, stop)` returns
/// the objective at x, or, when that exceeds `stop`, any value above `stop`.
pub fn minimize(
    f: &mut dyn FnMut(&[f64], f64) -> f64,
    bounds: &[Bound],
    x0: &[f64],
    scan: usize,
    max_evals: usize,
) -> FitResult {
    let d = bounds.len();
    let mut obj = Objective {
        f,
        bounds,
        evals: 0,
    };
    let start: Vec<f64> = x0.iter().zip(bounds).map(|(x, b)| b.u_of(*x)).collect();
    let start_value = obj.at(&start, f64::INFINITY);
    // Coarse scan: a full grid of `scan` points per parameter (capped at 27
    // points in all), so that valleys running across parameters are found.
    let per = match d {
        0 => 0,
        1 => scan,
        2 => scan.min(5),
        _ => 3,
    };
    let (best_u, best) = coarse_scan(&mut obj, d, per, (start, start_value));
    let mut simplex = nelder_mead(&mut obj, &best_u, best, 0.5 / per.max(2) as f64, max_evals);
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (u, v) = if simplex[0].1 < best {
        simplex[0].clone()
    } else {
        (best_u, best)
    };
    FitResult {
        x: u.iter().zip(bounds).map(|(u, b)| b.at(*u)).collect(),
        value: v,
        evals: obj.evals,
    }
}

/// The best of `best` and a full grid of `per` points per parameter (cell
/// centres of the unit box; none beyond three parameters).
fn coarse_scan(
    obj: &mut Objective<'_>,
    d: usize,
    per: usize,
    best: (Vec<f64>, f64),
) -> (Vec<f64>, f64) {
    let (mut best_u, mut best) = best;
    let total = if d <= 3 { per.pow(d as u32) } else { 0 };
    for idx in 0..total {
        let mut rest = idx;
        let u: Vec<f64> = (0..d)
            .map(|_| {
                let j = rest % per;
                rest /= per;
                (j as f64 + 0.5) / per as f64
            })
            .collect();
        let v = obj.at(&u, best);
        if v < best {
            best = v;
            best_u = u;
        }
    }
    (best_u, best)
}

/// Nelder-Mead in the unit box from the vertex `best_u` (value `best`) and
/// its neighbours `step` away along each axis, until the simplex is small
/// or flat or `max_evals` evaluations are spent; the final simplex.
fn nelder_mead(
    obj: &mut Objective<'_>,
    best_u: &[f64],
    best: f64,
    step: f64,
    max_evals: usize,
) -> Vec<(Vec<f64>, f64)> {
    let d = best_u.len();
    let mut simplex: Vec<(Vec<f64>, f64)> = vec![(best_u.to_vec(), best)];
    for k in 0..d {
        let mut u = best_u.to_vec();
        u[k] = if u[k] + step <= 1.0 {
            u[k] + step
        } else {
            u[k] - step
        };
        let v = obj.at(&u, f64::INFINITY);
        simplex.push((u, v));
    }
    let clamp = |u: Vec<f64>| -> Vec<f64> { u.into_iter().map(|x| x.clamp(0.0, 1.0)).collect() };
    while obj.evals < max_evals {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let spread = simplex.last().map(|s| s.1).unwrap_or(0.0) - simplex[0].1;
        let size = simplex
            .iter()
            .skip(1)
            .map(|s| {
                s.0.iter()
                    .zip(&simplex[0].0)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max)
            })
            .fold(0.0, f64::max);
        if size < 1e-3 || spread.abs() <= 1e-9 * simplex[0].1.abs() {
            break;
        }
        let centroid: Vec<f64> = (0..d)
            .map(|k| simplex[..d].iter().map(|s| s.0[k]).sum::<f64>() / d as f64)
            .collect();
        let worst = simplex[d].clone();
        let along = |t: f64| -> Vec<f64> {
            clamp(
                centroid
                    .iter()
                    .zip(&worst.0)
                    .map(|(c, w)| c + t * (c - w))
                    .collect(),
            )
        };
        let xr = along(1.0);
        // Each trial is only compared with the worst vertex (reflection,
        // contraction) or with the reflection (expansion): those are its stops.
        let fr = obj.at(&xr, worst.1);
        if fr < simplex[0].1 {
            let xe = along(2.0);
            let fe = obj.at(&xe, fr);
            simplex[d] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < simplex[d - 1].1 {
            simplex[d] = (xr, fr);
        } else {
            let xc = along(if fr < worst.1 { 0.5 } else { -0.5 });
            let fc = obj.at(&xc, worst.1.min(fr));
            if fc < worst.1.min(fr) {
                simplex[d] = (xc, fc);
            } else {
                // Shrink towards the best vertex.
                let b = simplex[0].0.clone();
                for s in simplex.iter_mut().skip(1) {
                    let u: Vec<f64> = s.0.iter().zip(&b).map(|(x, b)| b + 0.5 * (x - b)).collect();
                    let v = obj.at(&u, f64::INFINITY);
                    *s = (u, v);
                }
            }
        }
    }
    simplex
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_map_log_and_linear() {
        let b = Bound {
            lo: 1e-16,
            hi: 1e-11,
        };
        assert!((b.at(b.u_of(3e-14)) / 3e-14 - 1.0).abs() < 1e-12);
        let z = Bound { lo: 0.0, hi: 500.0 };
        assert!((z.at(1.0) - 500.0).abs() < 1e-9);
        assert!((z.at(0.0) - 0.05).abs() < 1e-9);
        let lin = Bound { lo: 1.0, hi: 5.0 };
        assert_eq!(lin.at(0.5), 3.0);
    }

    #[test]
    fn finds_a_log_scale_minimum() {
        let b = [Bound {
            lo: 1e-16,
            hi: 1e-11,
        }];
        let mut f = |x: &[f64], _: f64| (x[0].log10() + 13.3).powi(2);
        let r = minimize(&mut f, &b, &[1e-13], 7, 60);
        assert!((r.x[0].log10() + 13.3).abs() < 0.01, "{r:?}");
        assert!(r.evals <= 60);
    }

    #[test]
    fn finds_a_two_parameter_minimum_within_budget() {
        let b = [Bound { lo: 0.0, hi: 500.0 }, Bound { lo: 1e-4, hi: 5e-2 }];
        let mut f =
            |x: &[f64], _: f64| ((x[0] - 42.0) / 42.0).powi(2) + (x[1].ln() - 3e-3f64.ln()).powi(2);
        let r = minimize(&mut f, &b, &[30.0, 2e-3], 7, 120);
        assert!((r.x[0] - 42.0).abs() < 1.0, "{r:?}");
        assert!((r.x[1] / 3e-3 - 1.0).abs() < 0.05, "{r:?}");
    }

    #[test]
    fn stays_inside_the_bounds() {
        let b = [Bound { lo: 1.0, hi: 2.0 }];
        let mut f = |x: &[f64], _: f64| -x[0];
        let r = minimize(&mut f, &b, &[1.5], 5, 40);
        assert!((r.x[0] - 2.0).abs() < 1e-9, "{r:?}");
    }
}
