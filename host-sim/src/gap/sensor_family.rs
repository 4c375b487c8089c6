//! The general families of the sensors, fitted on the fit runs where the
//! named forms do not hold:
//!
//! * `sensor_delay` as a [`SensorFilter`]: a non-negative impulse response
//!   with unit gain at rest on one of Xo, Xi, P1, P2, by non-negative least
//!   squares of the recorded channel against delayed copies of its nominal
//!   replay;
//! * `sensor_calibration` as a [`SensorMap`]: a monotone piecewise-linear
//!   map of one of those channels through six knots spread evenly over the
//!   replayed range (1st to 99th percentile), by linear least squares of
//!   the recorded channel against the replay.
//!
//! Both act on the readings only, so the nominal replays of the fit runs
//! (the diagnosis makes them once) give every channel's design matrix; the
//! channel whose fitted family leaves the smallest gap on the fit runs is
//! the candidate. The force sensor's reading drives the replay's load, so
//! its map is fitted through the replays instead ([`fit_force_map`]), and
//! it has no learned lag.

use super::lsq;
use super::measure::gap_bounded;
use super::replay::{measured, Replay};
use super::run::Run;
use crate::model::effects::{
    self, CalChannel, Effects, SensorFilter, SensorMap, FILTER_TAPS, MAP_KNOTS,
};
use crate::model::plant::Plant;
use crate::model::sensors::filtered;

/// The channels the families act on, in [`super::replay::CHANNELS`] order.
const CHANNELS: [CalChannel; 4] = [
    CalChannel::Xo,
    CalChannel::Xi,
    CalChannel::P1,
    CalChannel::P2,
];

/// Ridge pulling a map's readings towards its knots (the identity), as a
/// share of the mean diagonal of the normal equations: keeps a knot that
/// few samples reach from swinging.
const MAP_RIDGE: f64 = 1e-4;

/// A general family fitted: the effect and the fit runs' gap with it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FamilyFit {
    /// The effect (one field of [`Effects`] set).
    pub effects: Effects,
    /// Gap of the fit runs with it.
    pub gap: f64,
}

/// The candidate of `effects` for each channel, the one with the smallest
/// gap on `runs` (only below `before_fit`, the nominal gap).
fn best_channel(
    runs: &[Run],
    base: &Plant,
    dt_s: f64,
    before_fit: f64,
    candidates: impl Iterator<Item = Effects>,
) -> Option<FamilyFit> {
    let mut best: Option<FamilyFit> = None;
    for e in candidates {
        if e.validate().is_err() {
            continue;
        }
        let stop = best.map_or(before_fit, |b| b.gap);
        let g = gap_bounded(runs, base, &e, dt_s, stop);
        if g < stop {
            best = Some(FamilyFit { effects: e, gap: g });
        }
    }
    best
}

/// `sensor_delay`'s general family on the fit runs `runs`, whose nominal
/// replays are `replays` and nominal gap `before_fit`; `None` when no
/// channel's filter lowers it.
pub fn fit_filter(
    runs: &[Run],
    replays: &[Replay],
    base: &Plant,
    dt_s: f64,
    before_fit: f64,
) -> Option<FamilyFit> {
    let filters: Vec<SensorFilter> = CHANNELS
        .iter()
        .enumerate()
        .filter_map(|(c, &ch)| filter_weights(runs, replays, c).map(|w| (ch, w)))
        .map(|(channel, weights)| SensorFilter { channel, weights })
        .collect();
    best_channel(
        runs,
        base,
        dt_s,
        before_fit,
        filters.into_iter().map(|f| Effects {
            sensor_filter: Some(f),
            ..Effects::NONE
        }),
    )
}

/// The filter weights of channel `c`: the recorded values `y` against the
/// replay `v` through each tap alone (`v_j`, the replay delayed by
/// [`crate::model::effects::FILTER_DELAYS_S`]`[j]`) as `y - v = sum_j w_j (v_j - v)`, `w_j >= 0`,
/// `sum_j w_j = 1` (unit gain at rest), in units of each run's channel
/// scale. `None` when no sample is usable or the channel never moved.
fn filter_weights(runs: &[Run], replays: &[Replay], c: usize) -> Option<[f64; FILTER_TAPS]> {
    const N: usize = FILTER_TAPS;
    let mut g = [[0.0; N]; N];
    let mut b = [0.0; N];
    for (run, sim) in runs.iter().zip(replays) {
        let v = &sim.ch[c];
        if v.iter().any(|x| !x.is_finite()) {
            continue;
        }
        let dt = run.log.dt_s();
        let taps: Vec<Vec<f64>> = (0..N)
            .map(|j| {
                let mut w = [0.0; N];
                w[j] = 1.0;
                let one = SensorFilter {
                    channel: CHANNELS[c],
                    weights: w,
                };
                filtered(&one, v, dt)
            })
            .collect();
        let y = measured(&run.log)[c];
        let s = run.scale[c];
        for k in 0..v.len() {
            if !y[k].is_finite() {
                continue;
            }
            let a: [f64; N] = std::array::from_fn(|j| (taps[j][k] - v[k]) / s);
            let r = (y[k] - v[k]) / s;
            for i in 0..N {
                for j in 0..N {
                    g[i][j] += a[i] * a[j];
                }
                b[i] += a[i] * r;
            }
        }
    }
    // Tap 0 is the replay itself (a zero column): some other tap must move.
    if !g.iter().enumerate().skip(1).any(|(i, row)| row[i] > 0.0) {
        return None;
    }
    simplex_lsq(&g, &b)
}

/// Minimise `w' G w / 2 - b' w` over the simplex `w >= 0`, `sum w = 1`
/// (`G` positive semi-definite): the active-set method of Lawson and
/// Hanson with the equality kept exactly by its multiplier. Starts at the
/// best vertex; adds the coordinate whose multiplier is most negative,
/// solves the equality-constrained problem on the free coordinates, and
/// steps back to the boundary where that leaves a coordinate at or below
/// zero. `None` when a subproblem is singular.
fn simplex_lsq<const N: usize>(g: &[[f64; N]; N], b: &[f64; N]) -> Option<[f64; N]> {
    let scale = (0..N)
        .map(|i| g[i][i])
        .fold(0.0, f64::max)
        .max(f64::MIN_POSITIVE);
    let tol = 1e-12 * scale;
    let vertex = (0..N)
        .min_by(|&i, &j| (0.5 * g[i][i] - b[i]).total_cmp(&(0.5 * g[j][j] - b[j])))
        .unwrap_or(0);
    let mut w = [0.0; N];
    w[vertex] = 1.0;
    let mut free = vec![vertex];
    // The negative gradient b - G w.
    let descent = |w: &[f64; N]| -> [f64; N] {
        std::array::from_fn(|i| b[i] - (0..N).map(|j| g[i][j] * w[j]).sum::<f64>())
    };
    for _ in 0..4 * N {
        let d = descent(&w);
        let mu = free.iter().map(|&i| d[i]).sum::<f64>() / free.len() as f64;
        let Some(enter) = (0..N)
            .filter(|j| !free.contains(j))
            .max_by(|&i, &j| d[i].total_cmp(&d[j]))
            .filter(|&j| d[j] - mu > tol)
        else {
            break;
        };
        free.push(enter);
        for _ in 0..N {
            // The equality-constrained optimum on the free coordinates:
            // [G_FF c1; c1' 0] [s; mu / c] = [b_F; c], the constraint's rows
            // scaled by c (G's largest diagonal) to keep the pivots even.
            let m = free.len();
            let mut a = vec![vec![0.0; m + 1]; m + 1];
            let mut rhs = vec![0.0; m + 1];
            for (r, &i) in free.iter().enumerate() {
                for (col, &j) in free.iter().enumerate() {
                    a[r][col] = g[i][j];
                }
                a[r][m] = scale;
                a[m][r] = scale;
                rhs[r] = b[i];
            }
            rhs[m] = scale;
            let sol = lsq::solve(a, rhs)?;
            if sol[..m].iter().all(|x| *x > 0.0) {
                w = [0.0; N];
                for (r, &i) in free.iter().enumerate() {
                    w[i] = sol[r];
                }
                break;
            }
            // Step from w towards s until a free coordinate reaches zero.
            let alpha = free
                .iter()
                .enumerate()
                .filter(|(r, _)| sol[*r] <= 0.0)
                .map(|(r, &i)| w[i] / (w[i] - sol[r]))
                .fold(1.0, f64::min);
            for (r, &i) in free.iter().enumerate() {
                w[i] += alpha * (sol[r] - w[i]);
            }
            free.retain(|&i| w[i] > 1e-15);
            for (i, x) in w.iter_mut().enumerate() {
                if !free.contains(&i) {
                    *x = 0.0;
                }
            }
            if free.is_empty() {
                return None;
            }
        }
    }
    Some(w)
}

/// `sensor_calibration`'s general family on the fit runs `runs`, whose
/// nominal replays are `replays` and nominal gap `before_fit`; `None` when
/// no channel's map is monotone and lowers it.
pub fn fit_map(
    runs: &[Run],
    replays: &[Replay],
    base: &Plant,
    dt_s: f64,
    before_fit: f64,
) -> Option<FamilyFit> {
    let maps: Vec<SensorMap> = (0..CHANNELS.len())
        .filter_map(|c| map_of(runs, replays, c))
        .collect();
    best_channel(
        runs,
        base,
        dt_s,
        before_fit,
        maps.into_iter().map(|m| Effects {
            sensor_map: Some(m),
            ..Effects::NONE
        }),
    )
}

/// `sensor_calibration`'s general family on the force sensor: a monotone
/// map through six knots over the recorded load's 1st to 99th percentile on
/// the fit runs `runs` (at least 40 N apart at the ends), fitted through the
/// replays by Levenberg-Marquardt (the map's inverse gives the load the
/// replay applies): the reading at the first knot as an offset (in units of
/// 10 N, within +-400 N) and each segment's slope as a factor on the
/// identity's (in units of 5 %, from 0.2 to 3), so that every step keeps
/// the map monotone; from the identity, at most five (`FORCE_MAP_ITERS`)
/// Jacobians. `None` when the load barely moves or the map does not lower
/// the nominal gap `before_fit`.
pub fn fit_force_map(runs: &[Run], base: &Plant, dt_s: f64, before_fit: f64) -> Option<FamilyFit> {
    let mut loads: Vec<f64> = runs
        .iter()
        .flat_map(|r| r.load.iter().copied())
        .filter(|v| v.is_finite())
        .collect();
    if loads.is_empty() {
        return None;
    }
    loads.sort_by(f64::total_cmp);
    let at = |q: f64| loads[((loads.len() - 1) as f64 * q).round() as usize];
    let (lo, hi) = (at(0.01), at(0.99));
    if hi - lo < 0.01 * CalChannel::Ft.span() {
        return None;
    }
    let knots: [f64; MAP_KNOTS] =
        std::array::from_fn(|i| lo + (hi - lo) * i as f64 / (MAP_KNOTS - 1) as f64);
    let map = |x: &[f64]| {
        let mut readings = [0.0; MAP_KNOTS];
        readings[0] = knots[0] + 10.0 * x[0];
        for i in 1..MAP_KNOTS {
            let slope = (1.0 + 0.05 * x[i]).max(0.2);
            readings[i] = readings[i - 1] + slope * (knots[i] - knots[i - 1]);
        }
        Effects {
            sensor_map: Some(SensorMap {
                channel: CalChannel::Ft,
                knots_si: knots,
                readings_si: readings,
            }),
            ..Effects::NONE
        }
    };
    // Loads often sit at a few levels, which pin the map only there: the
    // slopes in between are held together by a penalty on their changes
    // (a kink of 5 % costs FORCE_MAP_SMOOTH of the noise's sum of squares).
    let w = (FORCE_MAP_SMOOTH * lsq::noise_floor(runs)).sqrt();
    let f = |x: &[f64]| {
        let mut r = lsq::residuals(runs, base, &map(x), dt_s)?;
        r.extend(x[1..].windows(2).map(|p| w * (p[1] - p[0])));
        Some(r)
    };
    let mut lo_x = [-16.0; MAP_KNOTS];
    lo_x[0] = -40.0;
    let mut hi_x = [40.0; MAP_KNOTS];
    hi_x[0] = 40.0;
    let r = lsq::levenberg_marquardt(
        &f,
        &[0.0; MAP_KNOTS],
        None,
        &[0.5; MAP_KNOTS],
        &lo_x,
        &hi_x,
        FORCE_MAP_ITERS,
    )?;
    best_channel(runs, base, dt_s, before_fit, std::iter::once(map(&r.x)))
}

/// Jacobians of the force map's fit.
const FORCE_MAP_ITERS: usize = 5;

/// Weight of the force map's smoothness penalty: the share of the noise's
/// expected sum of squares ([`lsq::noise_floor`]) a change of 5 % between
/// neighbouring slopes costs.
const FORCE_MAP_SMOOTH: f64 = 0.1;

/// The piecewise-linear map of channel `c` (recorded against replayed);
/// `None` when the channel barely moves (a range under 1 % of its span) or
/// the least-squares map is not monotone.
fn map_of(runs: &[Run], replays: &[Replay], c: usize) -> Option<SensorMap> {
    let ch = CHANNELS[c];
    let pairs: Vec<(f64, f64)> = runs
        .iter()
        .zip(replays)
        .flat_map(|(r, s)| {
            s.ch[c]
                .iter()
                .zip(measured(&r.log)[c])
                .map(|(v, y)| (*v, *y))
                .collect::<Vec<_>>()
        })
        .filter(|(v, y)| v.is_finite() && y.is_finite())
        .collect();
    if pairs.is_empty() {
        return None;
    }
    let mut vs: Vec<f64> = pairs.iter().map(|p| p.0).collect();
    vs.sort_by(f64::total_cmp);
    let at = |q: f64| vs[((vs.len() - 1) as f64 * q).round() as usize];
    let (lo, hi) = (at(0.01), at(0.99));
    if hi - lo < 0.01 * ch.span() {
        return None;
    }
    let knots: [f64; MAP_KNOTS] =
        std::array::from_fn(|i| lo + (hi - lo) * i as f64 / (MAP_KNOTS - 1) as f64);
    // Hat functions extended linearly beyond the end knots: the map's
    // readings enter linearly.
    let basis = |v: f64| {
        let mut row = [0.0; MAP_KNOTS];
        let i = effects::segment(&knots, v);
        let w = (v - knots[i]) / (knots[i + 1] - knots[i]);
        row[i] = 1.0 - w;
        row[i + 1] = w;
        row
    };
    let mut a = vec![vec![0.0; MAP_KNOTS]; MAP_KNOTS];
    let mut b = vec![0.0; MAP_KNOTS];
    // In units of the span, so that the ridge is the same for every channel.
    let span = ch.span();
    for &(v, y) in &pairs {
        let row = basis(v);
        for i in 0..MAP_KNOTS {
            for j in 0..MAP_KNOTS {
                a[i][j] += row[i] * row[j];
            }
            b[i] += row[i] * y / span;
        }
    }
    let ridge = MAP_RIDGE * (0..MAP_KNOTS).map(|i| a[i][i]).sum::<f64>() / MAP_KNOTS as f64;
    for i in 0..MAP_KNOTS {
        a[i][i] += ridge;
        b[i] += ridge * knots[i] / span;
    }
    let x = lsq::solve(a, b)?;
    let map = SensorMap {
        channel: ch,
        knots_si: knots,
        readings_si: std::array::from_fn(|i| x[i] * span),
    };
    map.is_valid().then_some(map)
}

#[cfg(test)]
mod tests {
    use super::super::measure::{gap_of, replays};
    use super::super::testing::open_loop_run;
    use super::*;

    /// Plant steps of the tests' replays, s.
    const DT_S: f64 = 1e-4;

    /// The nominal replays of `runs` and their gap.
    fn nominal(runs: &[Run], base: &Plant) -> (Vec<Replay>, f64) {
        let sims = replays(runs, base, &Effects::NONE, DT_S);
        let before = gap_of(runs, &sims);
        (sims, before)
    }

    /// A nominal open-loop run: moves out and back at several speeds under
    /// a load that steps.
    fn nominal_run() -> Run {
        open_loop_run(
            Effects::NONE,
            3.0,
            (
                vec![0.2, 0.7, 1.0, 1.6, 2.2],
                &[0.0, 0.04, -0.02, 0.06, -0.05, 0.0],
            ),
            (vec![0.1, 1.3], &[0.0, 600.0, 200.0]),
        )
    }

    /// `run` with channel `c` of its log replaced by `f` of it.
    fn recorded(run: Run, c: CalChannel, f: impl Fn(&[f64]) -> Vec<f64>) -> Run {
        let mut log = run.log;
        let col = match c {
            CalChannel::Xo => &mut log.xo_m,
            CalChannel::Xi => &mut log.xi_m,
            CalChannel::P1 => &mut log.p1_pa,
            CalChannel::P2 => &mut log.p2_pa,
            CalChannel::Ft => &mut log.ft_n,
        };
        *col = f(col);
        Run::new(run.name, log)
    }

    #[test]
    fn learns_a_moving_average_on_the_encoder() {
        let truth = SensorFilter {
            channel: CalChannel::Xi,
            weights: [1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        };
        let run = recorded(nominal_run(), CalChannel::Xi, |v| filtered(&truth, v, 1e-3));
        let runs = std::slice::from_ref(&run);
        let base = Plant::nominal();
        let (sims, before) = nominal(runs, &base);
        let f = fit_filter(runs, &sims, &base, DT_S, before).expect("fitted");
        let got = f.effects.sensor_filter.expect("a filter");
        assert_eq!(got.channel, CalChannel::Xi);
        assert!(f.gap < 0.01 * before, "{} against {before}", f.gap);
        assert!(
            (got.mean_delay_s() - 2e-3).abs() < 1e-4,
            "{:?}",
            got.normalised()
        );
        // The map's family cannot take a lag: the xi map it finds leaves
        // most of the gap.
        let m = fit_map(runs, &sims, &base, DT_S, before);
        assert!(m.is_none_or(|m| m.gap > 0.3 * before), "{m:?}");
    }

    #[test]
    fn learns_an_lvdt_linearity_error_of_any_shape() {
        // An S-shaped linearity error of +-0.15 mm over the LVDT's 120 mm
        // (one period of a sine), which no quadratic takes.
        let truth = |x: f64| x + 0.15e-3 * (2.0 * std::f64::consts::PI * x / 0.12).sin();
        let run = recorded(nominal_run(), CalChannel::Xo, |v| {
            v.iter().map(|x| truth(*x)).collect()
        });
        let runs = std::slice::from_ref(&run);
        let base = Plant::nominal();
        let (sims, before) = nominal(runs, &base);
        let f = fit_map(runs, &sims, &base, DT_S, before).expect("fitted");
        let got = f.effects.sensor_map.expect("a map");
        assert_eq!(got.channel, CalChannel::Xo);
        assert!(f.gap < 0.1 * before, "{} against {before}", f.gap);
        // At its knots (over the range the run covers) the learned map reads
        // within 15 um of the true one, and it inverts exactly.
        for k in got.knots_si {
            assert!((got.map(k) - truth(k)).abs() < 15e-6, "{got:?}");
            assert!((got.invert(got.map(k)) - k).abs() < 1e-12);
        }
        // The filter's family cannot take a static map: it leaves most of
        // the gap.
        let lag = fit_filter(runs, &sims, &base, DT_S, before);
        assert!(lag.is_none_or(|l| l.gap > 0.3 * before), "{lag:?}");
    }

    #[test]
    fn the_simplex_least_squares_keeps_its_bounds() {
        // Unconstrained optimum (2, -1, 0) off the simplex: the nearest point
        // in G's metric is (1, 0, 0).
        let g = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        let u = simplex_lsq(&g, &[2.0, -1.0, 0.0]).unwrap();
        assert_eq!(u, [1.0, 0.0, 0.0]);
        // An interior optimum is found as is: G = I, b = (0.5, 0.3, 0.2).
        let u = simplex_lsq(&g, &[0.5, 0.3, 0.2]).unwrap();
        for (a, b) in u.iter().zip([0.5, 0.3, 0.2]) {
            assert!((a - b).abs() < 1e-12, "{u:?}");
        }
        // Two of three on an edge: (0.8, 0.6, -0.4) projects onto w2 = 0
        // and then the edge through (0.6, 0.4, 0).
        let u = simplex_lsq(&g, &[0.8, 0.6, -0.4]).unwrap();
        for (a, b) in u.iter().zip([0.6, 0.4, 0.0]) {
            assert!((a - b).abs() < 1e-12, "{u:?}");
        }
        // Strongly correlated columns (the delayed copies of a smooth
        // signal): the optimum on the simplex, not the best single column.
        let x = |k: f64| (0.3 * k).sin() + 0.5 * (1.1 * k).sin() + 0.2 * (2.3 * k).sin();
        let mut g = [[0.0; 3]; 3];
        for k in 0..200 {
            let a: [f64; 3] = std::array::from_fn(|j| x(k as f64 - j as f64));
            for i in 0..3 {
                for j in 0..3 {
                    g[i][j] += a[i] * a[j];
                }
            }
        }
        let truth = [0.5, 0.0, 0.5];
        let b: [f64; 3] = std::array::from_fn(|i| (0..3).map(|j| g[i][j] * truth[j]).sum());
        let u = simplex_lsq(&g, &b).unwrap();
        for (a, b) in u.iter().zip(truth) {
            assert!((a - b).abs() < 1e-9, "{u:?}");
        }
    }
}
