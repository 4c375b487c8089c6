//! `sensor_calibration`: a static map of one sensor, fitted on the fit runs.
//!
//! * The LVDT, the encoder and the pressures: the recorded channel against
//!   the nominal replay of it, by linear least squares over every sample
//!   (a calibration is a static map from the true to the recorded value,
//!   and the replay, driven by the recorded command and load, is the true
//!   value the model predicts). Both the affine map (gain, offset) and the
//!   quadratic one are tried; the quadratic is kept only when it lowers the
//!   gap by a further 10 %.
//! * The force sensor changes the load the replay applies, so its gain and
//!   offset are fitted through the replays (Levenberg-Marquardt,
//!   [`super::lsq`]).
//!
//! The channel whose map leaves the smallest gap on the fit runs is the
//! candidate. A map of Xo or Xi can also absorb part of a dynamic effect:
//! the check runs, where the dynamics differ, must confirm it (the policy).

use super::lsq::{self, levenberg_marquardt};
use super::measure::gap_bounded;
use super::replay::{measured, Replay};
use super::run::Run;
use crate::model::effects::{CalChannel, Effects, SensorCalibration};
use crate::model::plant::Plant;

/// Relative improvement of the gap the quadratic term must give.
const QUAD_GAIN: f64 = 0.1;

/// The fitted calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct CalFit {
    /// The calibration as an effect.
    pub effects: Effects,
    /// The gap of the fit runs with it.
    pub gap: f64,
    /// Which map held: `affine map of p1_pa`, `quadratic map of xo_m`.
    pub form: String,
    /// Replays of the fit runs used.
    pub evals: usize,
}

fn with(c: SensorCalibration) -> Effects {
    Effects {
        sensor_calibration: Some(c),
        ..Effects::NONE
    }
}

/// Least-squares maps y / span = a + b u (+ q u^2), u = v / span, of the
/// recorded values `y` against the replayed `v`: (gain, offset, quad).
fn static_maps(pairs: &[(f64, f64)], span: f64) -> [Option<[f64; 3]>; 2] {
    let mut out = [None, None];
    for (slot, quad) in out.iter_mut().zip([false, true]) {
        let p = if quad { 3 } else { 2 };
        let mut a = vec![vec![0.0; p]; p];
        let mut b = vec![0.0; p];
        for &(v, y) in pairs {
            let u = v / span;
            let row = [1.0, u, u * u];
            for i in 0..p {
                for j in 0..p {
                    a[i][j] += row[i] * row[j];
                }
                b[i] += row[i] * y / span;
            }
        }
        *slot = lsq::solve(a, b).map(|x| [x[1], x[0] * span, if quad { x[2] } else { 0.0 }]);
    }
    out
}

/// Fit the calibration of each sensor on `runs`, whose nominal replays are
/// `replays`, and keep the best; `None` when no map lowers the gap.
pub fn fit(runs: &[Run], replays: &[Replay], base: &Plant, dt_s: f64) -> Option<CalFit> {
    // The nominal replay counts as one, as when this fit made it itself.
    let mut evals = 1;
    let mut best: Option<CalFit> = None;
    // The gap with `c` when it beats `stop` (None: invalid or not better).
    let try_map = |c: SensorCalibration, stop: f64, evals: &mut usize| -> Option<f64> {
        let e = with(c);
        e.validate().ok()?;
        *evals += 1;
        let g = gap_bounded(runs, base, &e, dt_s, stop);
        (g < stop).then_some(g)
    };
    for ch in [
        CalChannel::Xo,
        CalChannel::Xi,
        CalChannel::P1,
        CalChannel::P2,
    ] {
        let c = ch.index();
        let pairs: Vec<(f64, f64)> = runs
            .iter()
            .zip(replays)
            .flat_map(|(r, s)| {
                measured(&r.log)[c]
                    .iter()
                    .zip(&s.ch[c])
                    .map(|(y, v)| (*v, *y))
                    .collect::<Vec<_>>()
            })
            .filter(|(v, y)| v.is_finite() && y.is_finite())
            .collect();
        let [affine, quad] = static_maps(&pairs, ch.span());
        let cal = |m: [f64; 3]| SensorCalibration {
            channel: ch,
            gain_1: m[0],
            offset_si: m[1],
            quad_1: m[2],
        };
        let stop = best.as_ref().map_or(f64::INFINITY, |b| b.gap);
        // The affine map, then the quadratic one only if clearly better than
        // both the affine map and the best so far.
        let mut here: Option<(SensorCalibration, f64, &str)> = None;
        if let Some(m) = affine {
            if let Some(g) = try_map(cal(m), f64::INFINITY, &mut evals) {
                here = Some((cal(m), g, "affine"));
            }
        }
        if let Some(m) = quad {
            let g_affine = here.map_or(f64::INFINITY, |h| h.1);
            let need = ((1.0 - QUAD_GAIN) * g_affine).min(stop);
            if let Some(g) = try_map(cal(m), need, &mut evals) {
                here = Some((cal(m), g, "quadratic"));
            }
        }
        if let Some((c, g, kind)) = here {
            if g < stop {
                best = Some(CalFit {
                    effects: with(c),
                    gap: g,
                    form: format!("{kind} map of {}", ch.name()),
                    evals: 0,
                });
            }
        }
    }
    // The force sensor: through the replays.
    let f = |x: &[f64]| {
        let c = SensorCalibration {
            channel: CalChannel::Ft,
            gain_1: x[0],
            offset_si: x[1],
            quad_1: 0.0,
        };
        lsq::residuals(runs, base, &with(c), dt_s)
    };
    if let Some(lm) = levenberg_marquardt(
        &f,
        &[1.0, 0.0],
        None,
        &[0.01, 2.0],
        &[0.5, -400.0],
        &[2.0, 400.0],
        4,
    ) {
        evals += lm.evals;
        let c = SensorCalibration {
            channel: CalChannel::Ft,
            gain_1: lm.x[0],
            offset_si: lm.x[1],
            quad_1: 0.0,
        };
        let stop = best.as_ref().map_or(f64::INFINITY, |b| b.gap);
        if let Some(g) = try_map(c, stop, &mut evals) {
            best = Some(CalFit {
                effects: with(c),
                gap: g,
                form: "affine map of ft_n".into(),
                evals: 0,
            });
        }
    }
    best.map(|b| CalFit { evals, ..b })
}
