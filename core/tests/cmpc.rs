//! The constrained MPC-ESO's quadratic program against an independent method,
//! and its limits.
//!
//! The reference is a brute-force enumeration of active sets in f64 written
//! here: for every pattern (each move free, at its lower or at its upper
//! bound) the free moves solve the KKT equations by Gaussian elimination, and
//! the pattern is accepted only when the result is primal feasible and the
//! multipliers have the right signs. It shares no code with the solver under
//! test (which evaluates candidates with precomputed f32 inverses and keeps the
//! cheapest), only the design's f64 Hessian and gradient coefficients.

#![allow(clippy::needless_range_loop)] // index loops mirror the matrix notation

use dca_core::cmpc::{
    solve_box_qp, Cmpc, CmpcDesign, CmpcGains, CmpcInput, CmpcParams, N_MOVES, PREVIEW_HORIZON_S,
};
use dca_core::design::{DesignError, PredictionModel};
use dca_core::mpc::{Limits, Observed};
use dca_core::params::PlantParams;
use proptest::prelude::*;

type M3 = [[f64; N_MOVES]; N_MOVES];

/// Solve `a x = b` (n <= 3) by Gaussian elimination with partial pivoting.
fn gauss(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        if a[p][c].abs() < 1e-300 {
            return None;
        }
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            for k in c..n {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|k| a[r][k] * x[k]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

fn cost(h: &M3, g: &[f64; N_MOVES], d: &[f64; N_MOVES]) -> f64 {
    let mut c = 0.0;
    for i in 0..N_MOVES {
        let hd: f64 = (0..N_MOVES).map(|j| h[i][j] * d[j]).sum();
        c += d[i] * (0.5 * hd + g[i]);
    }
    c
}

/// The KKT point of the box QP by enumeration of active sets (f64).
fn kkt_enumeration(h: &M3, g: &[f64; N_MOVES], lo: &[f64; 3], hi: &[f64; 3]) -> [f64; N_MOVES] {
    let mut found = Vec::new();
    for code in 0..27 {
        let mut state = [0u8; 3];
        let mut c = code;
        for s in state.iter_mut() {
            *s = (c % 3) as u8;
            c /= 3;
        }
        let mut d = [0.0; 3];
        for j in 0..3 {
            d[j] = match state[j] {
                1 => lo[j],
                2 => hi[j],
                _ => 0.0,
            };
        }
        let free: Vec<usize> = (0..3).filter(|&j| state[j] == 0).collect();
        if !free.is_empty() {
            let a = free
                .iter()
                .map(|&i| free.iter().map(|&j| h[i][j]).collect())
                .collect();
            let b = free
                .iter()
                .map(|&i| {
                    -(g[i]
                        + (0..3)
                            .filter(|j| state[*j] != 0)
                            .map(|j| h[i][j] * d[j])
                            .sum::<f64>())
                })
                .collect();
            let x = gauss(a, b).expect("positive definite blocks");
            for (k, &i) in free.iter().enumerate() {
                d[i] = x[k];
            }
        }
        let scale = lo.iter().chain(hi).fold(0.0f64, |m, v| m.max(v.abs()));
        let eps = 1e-9 * scale;
        let primal = (0..3).all(|j| d[j] >= lo[j] - eps && d[j] <= hi[j] + eps);
        let grad: Vec<f64> = (0..3)
            .map(|i| g[i] + (0..3).map(|j| h[i][j] * d[j]).sum::<f64>())
            .collect();
        let gscale = g.iter().fold(1e-12f64, |m, v| m.max(v.abs()));
        let dual = (0..3).all(|j| match state[j] {
            1 => grad[j] >= -1e-9 * gscale,
            2 => grad[j] <= 1e-9 * gscale,
            _ => true,
        });
        if primal && dual {
            found.push(d);
        }
    }
    assert!(!found.is_empty(), "no KKT point: {h:?} {g:?} {lo:?} {hi:?}");
    // Degenerate cases (a bound exactly at the free optimum) give the same point twice.
    found[0]
}

fn designs() -> Vec<(CmpcParams, Limits)> {
    let lim = Limits::from_plant(&PlantParams::NOMINAL);
    let base = CmpcParams::LIMIT;
    vec![
        (base, lim),
        (
            CmpcParams {
                blocks: [1, 3, 6],
                rw: 1.0,
                ..base
            },
            lim,
        ),
        (
            CmpcParams {
                np: 60,
                blocks: [3, 10, 20],
                rw: 100.0,
                ts_s: 0.005,
                ..base
            },
            lim,
        ),
    ]
}

/// A small deterministic generator (xorshift64*), uniform in [lo, hi).
struct Rng(u64);
impl Rng {
    fn next(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let u = (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * u
    }
}

#[test]
fn the_solver_finds_the_kkt_point_of_an_independent_f64_enumeration() {
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut worst_rel = 0.0f64;
    let mut active = [0usize; 4];
    for (params, lim) in designs() {
        let d = CmpcDesign::new(&PlantParams::NOMINAL, params).unwrap();
        let g32 = CmpcGains::design(&PlantParams::NOMINAL, params, &lim, 1e-3).unwrap();
        let v_ts = lim.v_max_mps as f64 * params.ts_s;
        for _ in 0..4000 {
            // Random states over what the rig can show: position increments of
            // a period at full speed, speeds, accelerations, the whole stroke.
            let state = [
                rng.next(-2e-3, 2e-3),
                rng.next(-0.3, 0.3),
                rng.next(-50.0, 50.0),
                rng.next(-0.01, 0.11),
            ];
            let (r, v_r, a_r, dft) = (
                rng.next(-0.01, 0.11),
                rng.next(-0.2, 0.2),
                rng.next(-5.0, 5.0),
                rng.next(-1000.0, 1000.0),
            );
            let mut g = [0.0f64; 3];
            let mut g32v = [0.0f32; 3];
            let feature = [state[0], state[1], state[2], state[3], r, v_r, a_r, dft];
            for j in 0..3 {
                g[j] = (0..8).map(|f| d.coef[j][f] * feature[f]).sum::<f64>();
                g32v[j] = g[j] as f32;
            }
            // Bounds as the controller makes them, from a random position and
            // previous move (near the stroke ends too).
            let mut cmpc = Cmpc::new(rng.next(-0.0101, 0.1101) as f32);
            cmpc.u_m = cmpc.u_m.clamp(lim.x_min_m, lim.x_max_m);
            cmpc.du_prev_m = rng.next(-v_ts, v_ts) as f32;
            let (lo, hi) = cmpc.bounds(&g32, &lim);
            let lo64 = lo.map(|v| v as f64);
            let hi64 = hi.map(|v| v as f64);
            let want = kkt_enumeration(&d.h, &g, &lo64, &hi64);
            let got = solve_box_qp(&g32.h, &g32.h_inv, &g32v, &lo, &hi);
            let n_active = (0..3)
                .filter(|&j| want[j] <= lo64[j] || want[j] >= hi64[j])
                .count();
            active[n_active] += 1;
            for j in 0..3 {
                assert!(got.d[j] >= lo[j] && got.d[j] <= hi[j], "infeasible {got:?}");
                let rel = (got.d[j] as f64 - want[j]).abs() / v_ts;
                worst_rel = worst_rel.max(rel);
            }
            // Cost: never worse than the optimum by more than rounding.
            let got64 = got.d.map(|v| v as f64);
            let (cg, cw) = (cost(&d.h, &g, &got64), cost(&d.h, &g, &want));
            let scale = cw.abs() + d.h[0][0] * v_ts * v_ts;
            assert!(cg - cw <= 1e-4 * scale, "cost {cg} vs optimum {cw}");
        }
    }
    // Within 0.5 % of one period's largest move: f32 against f64, gains rounded.
    assert!(
        worst_rel < 5e-3,
        "largest deviation {worst_rel} of v_max Ts"
    );
    // The random states exercise every number of active bounds.
    assert!(
        active.iter().all(|&n| n > 0),
        "active-set counts {active:?}"
    );
}

#[test]
fn the_preview_extrapolates_no_further_than_its_horizon() {
    // The gradient's coefficients of the reference r, its rate and its
    // curvature are -2 sum_i p_i (1, t_i, t_i^2 / 2) over the horizon's rows,
    // with t_i capped at PREVIEW_HORIZON_S: their ratios are weighted means of
    // the capped times, so at most the cap. A horizon shorter than the cap
    // has the uncapped times (ratios within its own length).
    let t_cap = PREVIEW_HORIZON_S;
    for (np, blocks) in [(100, [2, 3, 6]), (60, [1, 2, 4]), (4, [1, 1, 2])] {
        let p = CmpcParams {
            np,
            blocks,
            ..CmpcParams::LIMIT
        };
        let d = CmpcDesign::new(&PlantParams::NOMINAL, p).unwrap();
        let t_max = (np as f64 * p.ts_s).min(t_cap);
        for j in 0..N_MOVES {
            let (r, v, a) = (d.coef[j][4], d.coef[j][5], d.coef[j][6]);
            // The reference enters with a minus sign, its preview with the
            // share's (1 in `limit`): same sign, so the ratios are positive.
            assert!(r.abs() > 0.0, "np {np} move {j}: no reference weight");
            let (tv, ta) = (v / r, a / r);
            assert!(tv > 0.0 && tv <= t_max * (1.0 + 1e-12), "np {np}: {tv} s");
            assert!(
                ta > 0.0 && ta <= 0.5 * t_max * t_max * (1.0 + 1e-12),
                "np {np}: {ta} s^2"
            );
        }
        // The long horizon reaches the cap: its later moves see mostly capped rows.
        if np == 100 {
            assert!(d.coef[2][5] / d.coef[2][4] > 0.9 * t_cap);
        }
    }
}

#[test]
fn without_active_bounds_the_solution_is_the_unconstrained_minimiser() {
    let lim = Limits::from_plant(&PlantParams::NOMINAL);
    let p = CmpcParams::LIMIT;
    let d = CmpcDesign::new(&PlantParams::NOMINAL, p).unwrap();
    let g32 = CmpcGains::design(&PlantParams::NOMINAL, p, &lim, 1e-3).unwrap();
    let g = [1e-3f64, -2e-3, 5e-4].map(|v| v * d.h[0][0] * 1e-3);
    let want = kkt_enumeration(&d.h, &g, &[-1.0; 3], &[1.0; 3]);
    let got = solve_box_qp(
        &g32.h,
        &g32.h_inv,
        &g.map(|v| v as f32),
        &[-1.0; 3],
        &[1.0; 3],
    );
    assert!(!got.constrained);
    for j in 0..3 {
        assert!((got.d[j] as f64 - want[j]).abs() <= 1e-5 * want[j].abs().max(1e-9));
    }
}

#[test]
fn invalid_parameters_are_refused() {
    let p = CmpcParams::LIMIT;
    let bad = [
        (CmpcParams { np: 0, ..p }, DesignError::PredictionHorizon),
        (CmpcParams { np: 101, ..p }, DesignError::PredictionHorizon),
        (CmpcParams { np: 10, ..p }, DesignError::PredictionHorizon),
        (
            CmpcParams {
                blocks: [0, 3, 6],
                ..p
            },
            DesignError::ControlHorizon,
        ),
        (CmpcParams { ts_s: 0.0, ..p }, DesignError::SampleTime),
        (CmpcParams { rw: 0.0, ..p }, DesignError::InputWeight),
        (
            CmpcParams {
                a_max_mps2: f64::NAN,
                ..p
            },
            DesignError::Constraint,
        ),
        (CmpcParams { load_ff: 1.5, ..p }, DesignError::Constraint),
        (CmpcParams { preview: -0.1, ..p }, DesignError::Constraint),
        (CmpcParams { comp_ff: 1.01, ..p }, DesignError::Constraint),
        (
            CmpcParams {
                comp_ff: f64::NAN,
                ..p
            },
            DesignError::Constraint,
        ),
    ];
    for (params, err) in bad {
        assert_eq!(
            CmpcDesign::new(&PlantParams::NOMINAL, params).unwrap_err(),
            err,
            "{params:?}"
        );
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Whatever the state, the applied move keeps the speed limit and the
    /// stroke, and the acceleration limit; where the hard bounds allow no
    /// move within it, the move exceeds it by the least they allow.
    #[test]
    fn every_move_keeps_the_limits(
        u in -0.0101f32..0.1101,
        du_prev in -1e-3f32..1e-3,
        y in -0.02f32..0.12,
        r in -0.01f32..0.11,
        ft in -2000.0f32..2000.0,
        z2 in -1.0f32..1.0,
        z3 in -100.0f32..100.0,
        ticks in 0u8..3,
        u_ff in -0.003f32..0.003,
    ) {
        let lim = Limits::from_plant(&PlantParams::NOMINAL);
        let g = CmpcGains::design(&PlantParams::NOMINAL, CmpcParams::LIMIT, &lim, 1e-3).unwrap();
        let mut c = Cmpc::new(u.clamp(lim.x_min_m, lim.x_max_m));
        // The compliance feedforward's share keeps u + u_ff inside the stroke.
        c.u_ff_m = u_ff.clamp(lim.x_min_m - c.u_m, lim.x_max_m - c.u_m);
        c.du_prev_m = du_prev;
        c.ticks = ticks;
        c.r_prev_m = [r - 1e-4, r - 2e-4];
        let u0 = c.u_m + c.u_ff_m;
        let input = CmpcInput {
            y_m: y,
            r_m: r,
            ft_n: ft,
            xi_m: u0,
            observed: Observed { z2_mps: z2, z3_mps2: z3, b0_v_mps2: 0.0 },
        };
        let out = c.tick(&g, &lim, &input);
        prop_assert!(out.v_cmd_mps.is_finite());
        prop_assert!(out.v_cmd_mps.abs() <= lim.v_max_mps * (1.0 + 1e-5));
        let u1 = c.u_m + c.u_ff_m;
        prop_assert!(u1 >= lim.x_min_m - 1e-6 && u1 <= lim.x_max_m + 1e-6, "{u1}");
        let du = u1 - u0;
        // The acceleration limit holds (then the least violation is 0), or it
        // is exceeded by no more than the hard bounds force; the tolerance
        // (unchanged) covers the f32 rounding of u0, u1 and the bounds.
        let excess_m = acceleration_excess_m(&g, du, du_prev);
        let least_m = least_acceleration_excess_m(&g, &lim, u0, du_prev);
        let rounding_m = g.dd_max_m as f64 * 1e-4 + 1e-7;
        prop_assert!(
            excess_m <= least_m + rounding_m,
            "du {du} du_prev {du_prev}: beyond the limit by {excess_m} m, least {least_m} m"
        );
    }
}

/// How far the change of the increment from `du_prev_m` to `du_m` exceeds the
/// acceleration limit `dd_max_m`, m (0 within it).
fn acceleration_excess_m(g: &CmpcGains, du_m: f32, du_prev_m: f32) -> f64 {
    ((du_m as f64 - du_prev_m as f64).abs() - g.dd_max_m as f64).max(0.0)
}

/// The least excess over the acceleration limit that the hard bounds of the
/// first move leave (docs/control.md, "Constraints"), m, in f64: the distance
/// between the window `du_prev +- dd_max` and the hard box, which is the
/// servo speed `|d| <= v_max Ts` and the end of the first block inside the
/// stroke, `x_min <= u0 + L_1 d <= x_max`, and always holds `d = 0`. No
/// tolerance widens the hard box: a move that ends the first block past the
/// stroke, however little, is one the controller may not take (a tolerance
/// there once counted such moves as within the limit, issue 27).
fn least_acceleration_excess_m(g: &CmpcGains, lim: &Limits, u0_m: f32, du_prev_m: f32) -> f64 {
    let v_ts_m = lim.v_max_mps as f64 * g.ts_s as f64;
    let first = g.first_periods as f64;
    let u0 = u0_m as f64;
    let hard_lo_m = (-v_ts_m).max(((lim.x_min_m as f64 - u0) / first).min(0.0));
    let hard_hi_m = v_ts_m.min(((lim.x_max_m as f64 - u0) / first).max(0.0));
    let dd_m = g.dd_max_m as f64;
    let (window_lo_m, window_hi_m) = (du_prev_m as f64 - dd_m, du_prev_m as f64 + dd_m);
    (window_lo_m - hard_hi_m)
        .max(hard_lo_m - window_hi_m)
        .max(0.0)
}

/// Issue 27's input, shrunk from a failure of the property above: the
/// previous move 0.96 mm per period, 1.57 mm of stroke left. The window of
/// the acceleration limit starts at 0.785 37 mm per period, which would end
/// the first block of two periods 0.72 um past the stroke; the stroke allows
/// at most 0.785 01 mm. So the move is that bound, 0.36 um per period beyond
/// the acceleration limit (0.2 % of it): the soft limit gives way to the hard
/// stroke by the least violation, as documented.
#[test]
fn near_the_stroke_end_the_acceleration_limit_gives_way_by_the_least_violation() {
    let lim = Limits::from_plant(&PlantParams::NOMINAL);
    let g = CmpcGains::design(&PlantParams::NOMINAL, CmpcParams::LIMIT, &lim, 1e-3).unwrap();
    let (u_m, du_prev_m, u_ff_m) = (0.106855296f32, 0.00096037285f32, 0.0015746831f32);
    let mut c = Cmpc::new(u_m);
    c.u_ff_m = u_ff_m;
    c.du_prev_m = du_prev_m;
    c.r_prev_m = [-1e-4, -2e-4];
    let u0 = c.u_m + c.u_ff_m;
    // The hard bound of the first move and the acceleration window (f64).
    let hard_hi_m = (lim.x_max_m as f64 - u0 as f64) / g.first_periods as f64;
    let window_lo_m = du_prev_m as f64 - g.dd_max_m as f64;
    assert!(hard_hi_m < lim.v_max_mps as f64 * g.ts_s as f64);
    let past_stroke_m = u0 as f64 + g.first_periods as f64 * window_lo_m - lim.x_max_m as f64;
    assert!(
        past_stroke_m > 7.0e-7 && past_stroke_m < 7.5e-7,
        "{past_stroke_m} m"
    );
    let least_m = least_acceleration_excess_m(&g, &lim, u0, du_prev_m);
    assert!((least_m - (window_lo_m - hard_hi_m)).abs() < 1e-15);
    assert!(least_m > 3.5e-7 && least_m < 3.7e-7, "{least_m} m");

    let input = CmpcInput {
        y_m: 0.0,
        r_m: 0.0,
        ft_n: 0.0,
        xi_m: u0,
        observed: Observed {
            z2_mps: 0.0,
            z3_mps2: 0.0,
            b0_v_mps2: 0.0,
        },
    };
    c.tick(&g, &lim, &input);
    let u1 = c.u_m + c.u_ff_m;
    let du = u1 - u0;
    // The move is the stroke's bound (to the rounding of a position of 0.1 m
    // in f32, 7.5e-9 m), and beyond the acceleration limit by the least.
    let rounding_m = 2.0 * 0.1 * f32::EPSILON as f64;
    assert!((du as f64 - hard_hi_m).abs() <= rounding_m, "du {du} m");
    let excess_m = acceleration_excess_m(&g, du, du_prev_m);
    assert!((excess_m - least_m).abs() <= rounding_m, "{excess_m} m");
    assert!(u1 <= lim.x_max_m);
}

/// The compliance feedforward's gain: `comp_ff / b2` of the design model.
fn comp_gain(p: &CmpcParams) -> f32 {
    let b2 = PredictionModel::new(&PlantParams::NOMINAL).unwrap().b2_npm;
    (p.comp_ff / b2) as f32
}

/// A load step is fed forward as the displacement that holds Xo in the model's
/// static balance (`b1 y = b2 Xi - Ft`), at most at the servo's speed, without
/// going back on itself; a non-finite reading holds it; with `comp_ff = 0` it
/// never moves.
#[test]
fn a_load_step_is_fed_forward_at_the_servo_speed() {
    let lim = Limits::from_plant(&PlantParams::NOMINAL);
    let dt = 1e-3f32;
    for comp_ff in [0.0, 0.5, 1.0] {
        let p = CmpcParams {
            comp_ff,
            ..CmpcParams::LIMIT
        };
        let g = CmpcGains::design(&PlantParams::NOMINAL, p, &lim, dt as f64).unwrap();
        let mut c = Cmpc::new(0.05);
        // A standing load before the step is the feedforward's zero.
        for _ in 0..20 {
            assert_eq!(c.compliance_ff(&g, &lim, 300.0), 0.0);
        }
        let mut prev = c.u_ff_m;
        let mut saturated_ticks = 0;
        for k in 0..200 {
            let ft = if k == 50 { f32::NAN } else { 1100.0 };
            let v = c.compliance_ff(&g, &lim, ft);
            let step = c.u_ff_m - prev;
            assert!(step >= 0.0, "k {k}: back by {step}");
            assert!(v.abs() <= lim.v_max_mps * (1.0 + 1e-5), "k {k}: {v} m/s");
            assert!((v * dt - step).abs() <= 1e-9, "k {k}: v {v} for {step} m");
            if k == 50 {
                assert_eq!(step, 0.0, "a NaN load holds the feedforward");
            }
            if step >= g.ff_step_m * (1.0 - 1e-5) {
                saturated_ticks += 1;
            }
            prev = c.u_ff_m;
        }
        let want = comp_gain(&p) * 800.0;
        assert!(
            (c.u_ff_m - want).abs() <= 1e-6 * want.max(1e-3),
            "comp_ff {comp_ff}: {} m, want {want} m",
            c.u_ff_m
        );
        if comp_ff == 0.0 {
            assert_eq!(c.u_ff_m, 0.0);
        } else {
            // 800 N is 0.7 mm (comp_ff 0.5) or 1.4 mm of the power piston: several
            // ticks at the servo's speed (0.1 mm per 1 ms tick).
            assert!(saturated_ticks >= 5, "comp_ff {comp_ff}: {saturated_ticks}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    /// Whatever the loads and wherever the program's command is, the feedforward
    /// keeps the servo's speed and never takes `u + u_ff` out of the stroke.
    #[test]
    fn the_compliance_feedforward_keeps_speed_and_stroke(
        u in -0.0101f32..0.1101,
        loads in proptest::collection::vec(-3000.0f32..3000.0, 1..60),
    ) {
        let lim = Limits::from_plant(&PlantParams::NOMINAL);
        let p = CmpcParams { comp_ff: 1.0, ..CmpcParams::LIMIT };
        let g = CmpcGains::design(&PlantParams::NOMINAL, p, &lim, 1e-3).unwrap();
        let mut c = Cmpc::new(u.clamp(lim.x_min_m, lim.x_max_m));
        for ft in loads {
            let before = c.u_ff_m;
            let v = c.compliance_ff(&g, &lim, ft);
            prop_assert!(v.abs() <= lim.v_max_mps * (1.0 + 1e-5));
            prop_assert!((c.u_ff_m - before).abs() <= g.ff_step_m * (1.0 + 1e-5));
            let total = c.u_m + c.u_ff_m;
            prop_assert!(total >= lim.x_min_m - 1e-7 && total <= lim.x_max_m + 1e-7, "{total}");
        }
    }
}
