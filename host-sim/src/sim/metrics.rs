//! Performance metrics of docs/model.md section 8, on the 1 ms logged grid.
//!
//! Everything works on (t, reference, measured Xo) triples, so the same code
//! scores a simulated trace and a recorded run log. Inputs are SI; reported
//! values are in the units of the paper's tables (mm, %, s, mm^2 s).

use serde::Serialize;

/// Step height the rise time and the percentages refer to, m.
pub const STEP_M: f64 = 0.050;
/// Settling band, m (2 % of 50 mm).
pub const BAND_M: f64 = 0.001;

/// Load-step window of section 8.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct LoadWindow {
    /// Start of the window t_L, s.
    pub t_l_s: f64,
    /// max |e| in [t_L, t_L + 3), mm.
    pub deviation_mm: f64,
    /// The same in % of 50 mm.
    pub deviation_pct: f64,
    /// First instant after the last sample with |e| > 1 mm, minus t_L, s.
    pub settling_s: f64,
}

/// All metrics of one run (those that do not apply are `None`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Metrics {
    /// 10 % -> 90 % of 50 mm, s.
    pub rise_time_s: Option<f64>,
    /// max(Xo, t < 4 s) - 50 mm in % of 50 mm (>= 0).
    pub overshoot_pct: Option<f64>,
    /// Step settling into the 1 mm band, s.
    pub settling_s: Option<f64>,
    /// |mean e| over 3 <= t < 4 s, mm.
    pub sse_mm: Option<f64>,
    /// mean e^2 over 3 <= t < 4 s, mm^2.
    pub mse_mm2: Option<f64>,
    /// sum e^2 * 1 ms over the run, mm^2 s.
    pub ise_mm2s: f64,
    /// Load windows at 4 s and 7 s (step-load scenario).
    pub load: Vec<LoadWindow>,
    /// RMSE over t >= 4 s, mm.
    pub rmse_after_4_mm: Option<f64>,
    /// RMSE over t >= 2 s, mm (sine scenarios and whole-run comparisons).
    pub rmse_after_2_mm: Option<f64>,
    /// max |e| over t >= 2 s, mm.
    pub max_err_after_2_mm: Option<f64>,
    /// Lag of Xo behind the reference at the cross-correlation peak, s.
    pub lag_s: Option<f64>,
}

/// One point of a run: time, reference, measured position (SI).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Time, s.
    pub t_s: f64,
    /// Reference, m.
    pub ref_m: f64,
    /// Measured actuating piston position, m.
    pub xo_m: f64,
}

impl Point {
    fn e(&self) -> f64 {
        self.ref_m - self.xo_m
    }
}

fn crossing(points: &[Point], level: f64) -> Option<f64> {
    points.windows(2).find_map(|w| {
        let (a, b) = (w[0], w[1]);
        if a.xo_m < level && b.xo_m >= level {
            let f = (level - a.xo_m) / (b.xo_m - a.xo_m);
            Some(a.t_s + f * (b.t_s - a.t_s))
        } else {
            None
        }
    })
}

fn window(points: &[Point], t0: f64, t1: f64) -> impl Iterator<Item = &Point> {
    points.iter().filter(move |p| p.t_s >= t0 && p.t_s < t1)
}

fn mean(v: impl Iterator<Item = f64>) -> Option<f64> {
    let (s, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    (n > 0).then(|| s / n as f64)
}

/// Settling after `t0`: the first logged instant after the last sample in
/// [t0, t1) with |e| > band, minus t0 (0 if never outside).
fn settling_after(points: &[Point], t0: f64, t1: f64) -> f64 {
    let inside: Vec<&Point> = window(points, t0, t1).collect();
    match inside.iter().rposition(|p| p.e().abs() > BAND_M) {
        None => 0.0,
        Some(i) => match inside.get(i + 1) {
            Some(p) => p.t_s - t0,
            None => t1 - t0,
        },
    }
}

/// Pearson correlation of two equally long series (0 if either is constant).
fn pearson(a: impl Iterator<Item = f64> + Clone, b: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = a.clone().count() as f64;
    let (ma, mb) = (a.clone().sum::<f64>() / n, b.clone().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    if saa > 0.0 && sbb > 0.0 {
        sab / (saa * sbb).sqrt()
    } else {
        0.0
    }
}

/// Lag (s) of the position behind the reference over t >= t0: the shift in
/// 0 ..= max_lag_s that maximises the correlation of the overlapping parts.
fn lag(points: &[Point], t0: f64, max_lag_s: f64) -> Option<f64> {
    let w: Vec<&Point> = points.iter().filter(|p| p.t_s >= t0).collect();
    if w.len() < 3 {
        return None;
    }
    let dt = w[1].t_s - w[0].t_s;
    let max_lag = ((max_lag_s / dt) as usize).min(w.len() / 2);
    let mut best = (f64::MIN, 0usize);
    for l in 0..=max_lag {
        let n = w.len() - l;
        let c = pearson(
            w[..n].iter().map(|p| p.ref_m),
            w[l..].iter().map(|p| p.xo_m),
        );
        if c > best.0 {
            best = (c, l);
        }
    }
    Some(best.1 as f64 * dt)
}

/// Which metrics apply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// A 50 mm step (step, stepload, sineload).
    Step,
    /// A moving reference (sine).
    Tracking,
}

/// Metrics of one run.
pub fn compute(points: &[Point], kind: Kind, load_steps_s: &[f64]) -> Metrics {
    let to_mm = 1e3;
    let dt = if points.len() > 1 {
        points[1].t_s - points[0].t_s
    } else {
        1e-3
    };
    let ise = points.iter().map(|p| p.e() * p.e()).sum::<f64>() * dt * to_mm * to_mm;
    let rmse = |t0: f64| {
        mean(window(points, t0, f64::INFINITY).map(|p| p.e() * p.e())).map(|m| m.sqrt() * to_mm)
    };
    let mut m = Metrics {
        ise_mm2s: ise,
        rmse_after_2_mm: rmse(2.0),
        max_err_after_2_mm: window(points, 2.0, f64::INFINITY)
            .map(|p| p.e().abs() * to_mm)
            .reduce(f64::max),
        ..Metrics::default()
    };
    match kind {
        Kind::Step => {
            m.rise_time_s = match (
                crossing(points, 0.1 * STEP_M),
                crossing(points, 0.9 * STEP_M),
            ) {
                (Some(a), Some(b)) => Some(b - a),
                _ => None,
            };
            m.overshoot_pct = window(points, 0.0, 4.0)
                .map(|p| p.xo_m)
                .reduce(f64::max)
                .map(|x| ((x - STEP_M) / STEP_M * 100.0).max(0.0));
            m.settling_s = Some(settling_after(points, 0.0, 4.0));
            m.sse_mm = mean(window(points, 3.0, 4.0).map(|p| p.e())).map(|e| e.abs() * to_mm);
            m.mse_mm2 =
                mean(window(points, 3.0, 4.0).map(|p| p.e() * p.e())).map(|e| e * to_mm * to_mm);
            m.rmse_after_4_mm = rmse(4.0);
            m.load = load_steps_s
                .iter()
                .map(|&t_l| {
                    let dev = window(points, t_l, t_l + 3.0)
                        .map(|p| p.e().abs())
                        .fold(0.0, f64::max);
                    LoadWindow {
                        t_l_s: t_l,
                        deviation_mm: dev * to_mm,
                        deviation_pct: dev / STEP_M * 100.0,
                        settling_s: settling_after(points, t_l, t_l + 3.0),
                    }
                })
                .collect();
        }
        Kind::Tracking => {
            m.lag_s = lag(points, 2.0, 1.0);
        }
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A first-order step response with time constant tau.
    fn first_order(tau: f64, t_end: f64) -> Vec<Point> {
        (0..(t_end * 1000.0) as usize)
            .map(|i| {
                let t = i as f64 * 1e-3;
                Point {
                    t_s: t,
                    ref_m: STEP_M,
                    xo_m: STEP_M * (1.0 - (-t / tau).exp()),
                }
            })
            .collect()
    }

    #[test]
    fn rise_time_of_a_first_order_lag() {
        let m = compute(&first_order(0.3, 6.0), Kind::Step, &[]);
        // ln(9) tau = 0.659 s.
        let want = 9f64.ln() * 0.3;
        assert!((m.rise_time_s.unwrap() - want).abs() < 1e-3, "{m:?}");
        assert_eq!(m.overshoot_pct, Some(0.0));
        // |e| <= 1 mm once exp(-t/0.3) <= 0.02: t = 1.174 s.
        assert!((m.settling_s.unwrap() - 0.3 * 50f64.ln()).abs() < 2e-3);
        // ISE = 2500 mm^2 * tau / 2.
        assert!((m.ise_mm2s - 2500.0 * 0.15).abs() < 2.0, "{}", m.ise_mm2s);
    }

    #[test]
    fn load_window_deviation_and_settling() {
        let mut pts = first_order(0.05, 10.0);
        for p in pts.iter_mut() {
            if p.t_s >= 4.0 && p.t_s < 4.5 {
                p.xo_m -= 0.002; // 2 mm sag for 0.5 s
            }
        }
        let m = compute(&pts, Kind::Step, &[4.0, 7.0]);
        assert!((m.load[0].deviation_mm - 2.0).abs() < 1e-9);
        assert!((m.load[0].deviation_pct - 4.0).abs() < 1e-9);
        assert!((m.load[0].settling_s - 0.5).abs() < 1e-9);
        assert_eq!(m.load[1].settling_s, 0.0);
    }

    #[test]
    fn lag_of_a_delayed_sine() {
        let pts: Vec<Point> = (0..10_000)
            .map(|i| {
                let t = i as f64 * 1e-3;
                let r = |t: f64| 0.025 * (1.0 - (std::f64::consts::PI * t / 2.0).cos());
                Point {
                    t_s: t,
                    ref_m: r(t),
                    xo_m: r(t - 0.2),
                }
            })
            .collect();
        let m = compute(&pts, Kind::Tracking, &[]);
        assert!((m.lag_s.unwrap() - 0.2).abs() < 2e-3, "{:?}", m.lag_s);
    }
}
