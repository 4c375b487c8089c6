//! Constrained MPC-ESO (`cmpc-eso`, docs/interfaces.md section 7): the MPC-ESO
//! of docs/model.md section 6.4 whose moves are the solution of a quadratic
//! program with the servo's limits, solved every control period at a cost that
//! does not depend on the data.
//!
//! # The problem
//!
//! The prediction model is the augmented incremental model of section 6.3
//! (state `xi = [dx1, dx2, dx3, y]`, the ESO's observed state as in MPC-ESO),
//! with one more known input: the load force `Ft` read by the force sensor.
//! Written with `w = y'' + Ft/m`, the hose model of section 6.2 is unchanged
//! and the load enters as `dy'/dt = ... - Ft/m`: its increment over the last
//! period moves the predicted outputs by `Gamma dFt` (load feedforward).
//!
//! The command is parametrised by [`N_MOVES`] blocks of `L_j` periods; inside
//! block `j` the power-piston position command ramps by the same increment
//! `d_j` every period (the servo runs at the speed `d_j / Ts`), after the last
//! block it holds. Over `np` periods the predicted outputs are
//! `Y = F xi + Gamma dFt + Phi_b d`, and the controller minimises
//!
//! ```text
//! J(d) = |R - Y|^2 + r_w sum_j L_j d_j^2
//!      = 1/2 d^T H d + g^T d + const,   H = 2 (Phi_b^T Phi_b + r_w diag(L))
//! ```
//!
//! (the factor 2 is folded into the stored `H` and `g`), where
//! `R_i = r + v_r t_i + a_r t_i^2 / 2` previews the reference from its own rate
//! and curvature over the last two periods (off across a jump; `t_i` capped at
//! [`PREVIEW_HORIZON_S`], beyond which the preview holds), subject to box
//! constraints on `d`:
//!
//! * every move: the servo speed limit `|d_j| <= v_max Ts` (hard);
//! * the first move, whose first period is applied: the stroke
//!   `X_min <= u + L_1 d_1 <= X_max` (hard) and the acceleration limit
//!   `|d_1 - d_prev| <= s a_max Ts^2` (soft: where it would contradict the
//!   hard bounds it gives way to them, by the least violation); its share
//!   in force `s` starts at 1 and backs off while the moves ring on a rig
//!   whose resonance the full limit excites (`Cmpc::watch_ringing`);
//! * the later moves: `d_j` within `(X_max - u - L_1 max(d_1)) / (L_2 + L_3)`
//!   and the lower counterpart, a sufficient condition for every predicted
//!   position to stay inside the stroke.
//!
//! The hard box always contains `d = 0` (u is kept inside the stroke), so the
//! program is always feasible.
//!
//! # The compliance feedforward
//!
//! A load step compresses the oil and swells the hoses within a quarter of the
//! hydraulic period (about 12 ms), faster than one MPC period plus the servo's
//! lag. So the load read by the force sensor is also fed forward at every base
//! tick, outside the program ([`Cmpc::compliance_ff`]): in the model of section
//! 6.2 the static balance is `b1 y = b2 Xi - Ft`, so holding `y` under a load
//! change `dFt` takes `dXi = dFt / b2`. A share `comp_ff` of that displacement,
//! `u_ff = comp_ff (Ft_f - Ft_0) / b2` with `Ft_f` the load through a 3 ms
//! low-pass (the sensor's noise), is driven at up to the servo's speed per base
//! tick, never out of the stroke. The program sees the rest of the rig: it is
//! given `Xi - u_ff` as the power piston's position and `u + u_ff` as the
//! position its stroke bounds start from; its own load feedforward (`load_ff`)
//! is a separate share through `Gamma`.
//!
//! # The solver and its proof
//!
//! `H` is symmetric positive definite (`r_w > 0`), so the minimiser `d*` is
//! unique and satisfies the KKT conditions with some *pattern*: each move is
//! free, at its lower bound or at its upper bound. For a pattern, the free
//! moves solve `H_ff d_f = -(g_f + H_fa d_a)` with the inverses `H_ff^-1` of all
//! eight principal blocks precomputed at design. [`solve_box_qp`] evaluates
//! all `3^3 = 27` patterns, clips each candidate into the box (so every
//! candidate is feasible) and keeps the one of least cost. The pattern of `d*`
//! yields `d*` itself and every other candidate is feasible, so none costs
//! less: the result is the minimiser, up to f32 rounding. The loop has no
//! data-dependent exit: every call does the same 27 evaluations, which is the
//! worst case by construction; `firmware/count` measures it on the MCU.
//!
//! # Design
//!
//! Offline in f64 ([`CmpcGains::design`], also on the board after a change):
//! the ZOH model of section 6.2 and a load column, the horizon's rows streamed
//! one at a time (no matrix of horizon size is stored), the Hessian, its eight
//! block inverses and the gradient's coefficients, rounded to f32.

use crate::design::{DesignError, Mat3, PredictionModel, Vec3};
use crate::mpc::{clamp, Limits, MpcOutput, Observed};
use crate::params::PlantParams;

/// Number of move blocks (decision variables of the quadratic program).
pub const N_MOVES: usize = 3;
/// Largest prediction horizon, MPC periods.
pub const MAX_HORIZON: usize = 100;
/// Patterns the solver evaluates: each move free, at its lower or upper bound.
pub const N_PATTERNS: usize = 27;
/// Number of [`FEATURES`].
pub const N_FEATURES: usize = 8;
/// What the gradient of the program is linear in, in this order: the
/// augmented state `[dx1, dx2, dx3, y]` (m, m/s, m/s^2, m), the reference (m),
/// its rate (m/s) and curvature (m/s^2), and the load increment (N).
pub const FEATURES: [&str; N_FEATURES] = ["dx1", "dx2", "dx3", "y", "r", "v_r", "a_r", "d_ft"];

/// Tuning of the constrained MPC-ESO (physical units).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CmpcParams {
    /// Prediction horizon, MPC periods.
    pub np: usize,
    /// Length of each move block, MPC periods (each >= 1, sum <= `np`).
    pub blocks: [usize; N_MOVES],
    /// MPC period Ts, s.
    pub ts_s: f64,
    /// Weight on the squared position increments (per period), relative to the
    /// squared output errors.
    pub rw: f64,
    /// Acceleration limit of the power piston, m/s^2 (soft constraint).
    pub a_max_mps2: f64,
    /// Share of the load feedforward, 0 (off) to 1.
    pub load_ff: f64,
    /// Share of the reference preview, 0 (off) to 1.
    pub preview: f64,
    /// Share of the load's static compliance displacement fed forward at every
    /// base tick ([`Cmpc::compliance_ff`]), 0 (off) to 1.
    pub comp_ff: f64,
}

impl CmpcParams {
    /// The `limit` preset's tuning for the rig of docs/model.md: a 1 s horizon
    /// and a gentle acceleration limit, chosen on Monte Carlo runs over rigs
    /// within +-30 % of it (docs/control.md, "A rig that is not the model").
    /// Three quarters of the load's compliance displacement are fed forward:
    /// more leaves the stiffer rigs of that set overshooting after a load
    /// step, less leaves the more compliant ones dipping further.
    pub const LIMIT: Self = Self {
        np: 100,
        blocks: [2, 3, 6],
        ts_s: 0.01,
        rw: 10.0,
        a_max_mps2: 1.75,
        load_ff: 0.0,
        preview: 1.0,
        comp_ff: 0.75,
    };

    /// Check the parameters against the design's bounds: the first check that
    /// fails names the error.
    pub fn validate(&self) -> Result<(), DesignError> {
        let span: usize = self.blocks.iter().sum();
        let positive = |v: f64| v.is_finite() && v > 0.0;
        let share = |v: f64| (0.0..=1.0).contains(&v);
        let checks = [
            (
                self.blocks.iter().all(|&l| (1..=MAX_HORIZON).contains(&l)),
                DesignError::ControlHorizon,
            ),
            (
                (span..=MAX_HORIZON).contains(&self.np),
                DesignError::PredictionHorizon,
            ),
            (positive(self.ts_s), DesignError::SampleTime),
            (positive(self.rw), DesignError::InputWeight),
            (
                positive(self.a_max_mps2)
                    && share(self.load_ff)
                    && share(self.preview)
                    && share(self.comp_ff),
                DesignError::Constraint,
            ),
        ];
        match checks.iter().find(|(ok, _)| !ok) {
            Some(&(_, e)) => Err(e),
            None => Ok(()),
        }
    }
}

/// Precomputed run-time numbers of the constrained MPC-ESO, f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CmpcGains {
    /// Hessian `H` of the quadratic program.
    pub h: [[f32; N_MOVES]; N_MOVES],
    /// `H_ff^-1` for each set of free moves (bit j of the index: move j free),
    /// zero outside the free block.
    pub h_inv: [[[f32; N_MOVES]; N_MOVES]; 8],
    /// Gradient coefficients per move over the [`FEATURES`] (shares included).
    pub coef: [[f32; N_FEATURES]; N_MOVES],
    /// Periods of the first block, `L_1`.
    pub first_periods: f32,
    /// Periods of the later blocks together, `L_2 + L_3`.
    pub later_periods: f32,
    /// MPC period, s.
    pub ts_s: f32,
    /// B2 of the prediction model, 1/s^2.
    pub b2_gain: f32,
    /// Acceleration limit as a bound on the change of the increment, m.
    pub dd_max_m: f32,
    /// Largest reference rate the preview believes, m/s.
    pub v_ref_max_mps: f32,
    /// Largest reference curvature the preview believes, m/s^2.
    pub a_ref_max_mps2: f32,
    /// Compliance feedforward: power-piston displacement per newton of load
    /// (`comp_ff / b2`), m/N.
    pub comp_mpn: f32,
    /// Compliance feedforward: the low-pass's gain per base tick, `dt / tau`.
    pub ff_alpha: f32,
    /// Compliance feedforward: its largest displacement per base tick, m.
    pub ff_step_m: f32,
    /// Base ticks per second, 1/s.
    pub base_hz: f32,
}

/// How far ahead the reference preview extrapolates the reference from its
/// rate and curvature, s; beyond it the previewed reference holds. (A rate
/// and a curvature describe a trajectory for a short stretch only:
/// extrapolated over the whole 1 s horizon of `limit`, they put the `sine`
/// scenario's RMSE at 6.9 mm; docs/control.md has the scan.)
pub const PREVIEW_HORIZON_S: f64 = 0.05;

/// Time constant of the compliance feedforward's low-pass on the load, s.
pub const COMP_FF_TAU_S: f64 = 0.003;

/// `a * b` for 4x4 row-major matrices (f64; +, * only, fixed order).
fn row_times(row: &[f64; 4], a: &[[f64; 4]; 4]) -> [f64; 4] {
    let mut out = [0.0; 4];
    for (j, o) in out.iter_mut().enumerate() {
        *o = row[0] * a[0][j] + row[1] * a[1][j] + row[2] * a[2][j] + row[3] * a[3][j];
    }
    out
}

/// One row of the horizon into the Hessian and the gradient coefficients:
/// `h += 2 p p^T`, `coef[j] += 2 p_j feature`.
fn accumulate(
    h: &mut [[f64; N_MOVES]; N_MOVES],
    coef: &mut [[f64; 8]; N_MOVES],
    p: &[f64; N_MOVES],
    feature: &[f64; 8],
) {
    for j in 0..N_MOVES {
        for l in 0..N_MOVES {
            h[j][l] += 2.0 * p[j] * p[l];
        }
        for (c, f) in coef[j].iter_mut().zip(feature) {
            *c += 2.0 * p[j] * f;
        }
    }
}

fn dot4(a: &[f64; 4], b: &[f64; 4]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3]
}

/// The augmented matrices `[[Ad, 0], [Cc Ad, 1]]` and `[b; Cc b]` (row-major).
fn augment(ad: &Mat3, bd: &Vec3, bw: &Vec3) -> ([[f64; 4]; 4], [f64; 4], [f64; 4]) {
    let mut a = [[0.0; 4]; 4];
    for (i, row) in a.iter_mut().take(3).enumerate() {
        for (j, v) in row.iter_mut().take(3).enumerate() {
            *v = ad[(i, j)];
        }
    }
    for j in 0..3 {
        a[3][j] = ad[(0, j)];
    }
    a[3][3] = 1.0;
    let b = [bd[0], bd[1], bd[2], bd[0]];
    let w = [bw[0], bw[1], bw[2], bw[0]];
    (a, b, w)
}

/// Inverse of the principal block of `h` on the moves in `mask` (zero
/// elsewhere), or `None` when that block is not positive definite: Gauss-Jordan
/// elimination without pivoting (a positive definite matrix needs none; a
/// pivot that is not positive means the block is not).
fn block_inverse(h: &[[f64; N_MOVES]; N_MOVES], mask: usize) -> Option<[[f64; N_MOVES]; N_MOVES]> {
    // The fixed moves' rows and columns are replaced by the identity: their
    // entries of the inverse come out as the identity and are zeroed at the end.
    let free = |j: usize| mask & (1 << j) != 0;
    let mut a = [[0.0f64; N_MOVES]; N_MOVES];
    let mut inv = [[0.0f64; N_MOVES]; N_MOVES];
    for i in 0..N_MOVES {
        for j in 0..N_MOVES {
            a[i][j] = if free(i) && free(j) { h[i][j] } else { 0.0 };
        }
        if !free(i) {
            a[i][i] = 1.0;
        }
        inv[i][i] = 1.0;
    }
    for c in 0..N_MOVES {
        let pivot = a[c][c];
        if pivot.is_nan() || pivot <= 0.0 {
            return None;
        }
        for j in 0..N_MOVES {
            a[c][j] /= pivot;
            inv[c][j] /= pivot;
        }
        for r in 0..N_MOVES {
            if r != c {
                let f = a[r][c];
                for j in 0..N_MOVES {
                    a[r][j] -= f * a[c][j];
                    inv[r][j] -= f * inv[c][j];
                }
            }
        }
    }
    for (i, row) in inv.iter_mut().enumerate() {
        if !free(i) {
            row[i] = 0.0;
        }
    }
    Some(inv)
}

fn to_f32_3x3(m: &[[f64; N_MOVES]; N_MOVES]) -> [[f32; N_MOVES]; N_MOVES] {
    m.map(|row| row.map(|v| v as f32))
}

/// The f64 numbers of a design (the gains before rounding), for tests and tools.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CmpcDesign {
    /// The parameters of the design.
    pub params: CmpcParams,
    /// Hessian.
    pub h: [[f64; N_MOVES]; N_MOVES],
    /// Gradient coefficients per move over the [`FEATURES`]: the gradient is
    /// `g_j = sum_f coef[j][f] feature[f]` (shares included).
    pub coef: [[f64; N_FEATURES]; N_MOVES],
    /// B2 of the prediction model, 1/s^2.
    pub b2_gain: f64,
    /// Compliance feedforward gain `comp_ff / b2`, m/N.
    pub comp_mpn: f64,
}

impl CmpcDesign {
    /// Design for the plant `plant` (f64, streaming over the horizon).
    pub fn new(plant: &PlantParams, params: CmpcParams) -> Result<Self, DesignError> {
        params.validate()?;
        let model = PredictionModel::new(plant)?;
        let ts = params.ts_s;
        let (ad, bd) = model.discretise(ts);
        // The load column: dy'/dt gets -Ft/m (module documentation).
        let load = PredictionModel {
            bc: Vec3::new(0.0, -1.0 / plant.m_kg, 0.0),
            ..model
        };
        let (_, bw) = load.discretise(ts);
        let (a, b, w) = augment(&ad, &bd, &bw);

        // Block of each period: the first `L_1` periods move with d_1, ...
        let mut start = [0usize; N_MOVES];
        for j in 1..N_MOVES {
            start[j] = start[j - 1] + params.blocks[j - 1];
        }
        let mut cab = [0.0f64; MAX_HORIZON];
        let mut c_ai = [0.0, 0.0, 0.0, 1.0]; // C A^i
        let mut h = [[0.0; N_MOVES]; N_MOVES];
        // Per move: gradient coefficients of [dx1, dx2, dx3, y, r, v_r, a_r, dFt].
        let mut coef = [[0.0; 8]; N_MOVES];
        for i in 0..params.np {
            if let Some(c) = cab.get_mut(i) {
                *c = dot4(&c_ai, &b);
            }
            let gamma = dot4(&c_ai, &w);
            c_ai = row_times(&c_ai, &a); // the row C A^(i+1) of F
                                         // Row i of Phi_b: sum over the periods k <= i of block j of C A^(i-k) B.
            let mut p = [0.0; N_MOVES];
            for (j, pj) in p.iter_mut().enumerate() {
                let end = (start[j] + params.blocks[j]).min(i + 1);
                for k in start[j]..end {
                    *pj += cab.get(i - k).copied().unwrap_or(0.0);
                }
            }
            // The preview extrapolates the reference only so far ahead.
            let t = min64((i + 1) as f64 * ts, PREVIEW_HORIZON_S);
            let feature = [
                c_ai[0],
                c_ai[1],
                c_ai[2],
                c_ai[3],
                1.0,
                t,
                0.5 * t * t,
                gamma,
            ];
            accumulate(&mut h, &mut coef, &p, &feature);
        }
        // The reference terms enter the gradient with a minus sign (g = -Phi_b^T e).
        let scale = [
            1.0,
            1.0,
            1.0,
            1.0,
            -1.0,
            -params.preview,
            -params.preview,
            params.load_ff,
        ];
        for j in 0..N_MOVES {
            h[j][j] += 2.0 * params.rw * params.blocks[j] as f64;
            for (c, s) in coef[j].iter_mut().zip(scale) {
                *c *= s;
            }
        }
        if !h
            .iter()
            .flatten()
            .chain(coef.iter().flatten())
            .all(|v| v.is_finite())
        {
            return Err(DesignError::Singular);
        }
        Ok(Self {
            params,
            h,
            coef,
            b2_gain: model.b2_gain,
            comp_mpn: params.comp_ff / model.b2_npm,
        })
    }
}

impl CmpcGains {
    /// Design (f64) and round to the f32 run-time numbers; `lim` gives the
    /// speed limit the preview's plausibility bounds scale with, `base_dt_s`
    /// (> 0, as [`crate::controller::Controller::new`] checks) the base tick the
    /// compliance feedforward runs at.
    pub fn design(
        plant: &PlantParams,
        params: CmpcParams,
        lim: &Limits,
        base_dt_s: f64,
    ) -> Result<Self, DesignError> {
        let d = CmpcDesign::new(plant, params)?;
        let mut h_inv = [[[0.0f32; N_MOVES]; N_MOVES]; 8];
        for (mask, inv) in h_inv.iter_mut().enumerate() {
            *inv = to_f32_3x3(&block_inverse(&d.h, mask).ok_or(DesignError::Singular)?);
        }
        let ts = params.ts_s;
        let dt = base_dt_s as f32;
        Ok(Self {
            h: to_f32_3x3(&d.h),
            h_inv,
            coef: d.coef.map(|r| r.map(|x| x as f32)),
            first_periods: params.blocks[0] as f32,
            later_periods: (params.blocks[1] + params.blocks[2]) as f32,
            ts_s: ts as f32,
            b2_gain: d.b2_gain as f32,
            dd_max_m: (params.a_max_mps2 * ts * ts) as f32,
            // The actuating piston moves at most ~1.6 x the power piston's speed
            // (area ratio); a faster reference is a jump, not a trajectory.
            v_ref_max_mps: 2.0 * lim.v_max_mps,
            a_ref_max_mps2: (2.0 * params.a_max_mps2) as f32,
            comp_mpn: d.comp_mpn as f32,
            // f32 from here: the base tick's numbers need no more.
            ff_alpha: min(dt / COMP_FF_TAU_S as f32, 1.0),
            ff_step_m: lim.v_max_mps * dt,
            base_hz: 1.0 / dt,
        })
    }
}

/// Every active-bound pattern: per move 0 (free), 1 (at its lower bound) or 2
/// (at its upper bound), then the mask of the free moves; the first pattern
/// is the unconstrained one.
const PATTERNS: [[u8; N_MOVES + 1]; N_PATTERNS] = {
    let mut out = [[0u8; N_MOVES + 1]; N_PATTERNS];
    let mut code = 0;
    while code < N_PATTERNS {
        let mut c = code;
        let mut j = 0;
        while j < N_MOVES {
            out[code][j] = (c % 3) as u8;
            if c % 3 == 0 {
                out[code][N_MOVES] |= 1 << j;
            }
            c /= 3;
            j += 1;
        }
        code += 1;
    }
    out
};

/// What every candidate of [`solve_box_qp`] needs, computed once per call.
struct Candidates<'a> {
    h: &'a [[f32; N_MOVES]; N_MOVES],
    h_inv: &'a [[[f32; N_MOVES]; N_MOVES]; 8],
    g: &'a [f32; N_MOVES],
    lo: &'a [f32; N_MOVES],
    hi: &'a [f32; N_MOVES],
    /// The bound of move j for state s (0 free, 1 lower, 2 upper; row 3 unused).
    value: [[f32; N_MOVES]; 4],
    /// `H[:, j] value[s][j]`.
    column: [[[f32; N_MOVES]; N_MOVES]; 4],
    /// Half the Hessian's diagonal.
    half: [f32; N_MOVES],
}

impl Candidates<'_> {
    /// One pattern's candidate: (d, the unclipped solution x, the cost).
    #[inline(always)]
    fn eval(&self, &[s0, s1, s2, free]: &[u8; N_MOVES + 1]) -> ([f32; 3], [f32; 3], f32) {
        let (h, g, lo, hi) = (self.h, self.g, self.lo, self.hi);
        let (s0, s1, s2) = (s0 as usize & 3, s1 as usize & 3, s2 as usize & 3);
        // Gradient with the free moves at 0: q = g + H d_a.
        let c = &self.column;
        let (c0, c1, c2) = (&c[s0][0], &c[s1][1], &c[s2][2]);
        let q = [
            g[0] + c0[0] + c1[0] + c2[0],
            g[1] + c0[1] + c1[1] + c2[1],
            g[2] + c0[2] + c1[2] + c2[2],
        ];
        // The free moves: d_f = -H_ff^-1 q_f (rows of fixed moves are zero),
        // clipped into the box; the fixed moves at their bound.
        let inv = &self.h_inv[free as usize & 7];
        let x = [
            -(inv[0][0] * q[0] + inv[0][1] * q[1] + inv[0][2] * q[2]),
            -(inv[1][0] * q[0] + inv[1][1] * q[1] + inv[1][2] * q[2]),
            -(inv[2][0] * q[0] + inv[2][1] * q[1] + inv[2][2] * q[2]),
        ];
        let pick = |s: usize, j: usize| {
            if s == 0 {
                clamp(x[j], lo[j], hi[j])
            } else {
                self.value[s][j]
            }
        };
        let d = [pick(s0, 0), pick(s1, 1), pick(s2, 2)];
        // Cost 1/2 d^T H d + g^T d, H symmetric.
        let half = &self.half;
        let cost = d[0] * (half[0] * d[0] + h[0][1] * d[1] + h[0][2] * d[2] + g[0])
            + d[1] * (half[1] * d[1] + h[1][2] * d[2] + g[1])
            + d[2] * (half[2] * d[2] + g[2]);
        (d, x, cost)
    }
}

/// Box-constrained strictly convex quadratic program in [`N_MOVES`] variables:
/// minimise `1/2 d^T H d + g^T d` subject to `lo <= d <= hi`, by evaluating
/// all [`N_PATTERNS`] active-bound patterns (module documentation). Requires
/// `lo <= hi`; a non-finite `g` gives the free pattern clipped into the box
/// (the clip maps NaN to the lower bound): always feasible.
#[inline(never)]
pub fn solve_box_qp(
    h: &[[f32; N_MOVES]; N_MOVES],
    h_inv: &[[[f32; N_MOVES]; N_MOVES]; 8],
    g: &[f32; N_MOVES],
    lo: &[f32; N_MOVES],
    hi: &[f32; N_MOVES],
) -> BoxQpSolution {
    // Written out for three moves (straight-line arithmetic per pattern: the
    // instruction count of this loop is what firmware/count measures).
    const _: () = assert!(N_MOVES == 3);
    // The bounds and their Hessian columns, once: value[s][j] and
    // column[s][j] = H[:, j] value[s][j] for s = 1 (lower), 2 (upper); s = 0
    // (free) contributes nothing.
    // (Four rows, the last unused: an index masked with 3 needs no bounds check.)
    let value = [[0.0f32; N_MOVES], *lo, *hi, [0.0; N_MOVES]];
    let mut column = [[[0.0f32; N_MOVES]; N_MOVES]; 4];
    for s in 1..3 {
        for j in 0..N_MOVES {
            let v = value[s][j];
            column[s][j] = [h[0][j] * v, h[1][j] * v, h[2][j] * v];
        }
    }
    let all = Candidates {
        h,
        h_inv,
        g,
        lo,
        hi,
        value,
        column,
        half: [0.5 * h[0][0], 0.5 * h[1][1], 0.5 * h[2][2]],
    };
    // The cheapest pattern: only its index and cost are kept in the loop (a
    // selection, no data-dependent branch), the winner is evaluated again.
    let mut k = 0usize;
    let mut best_cost = f32::INFINITY;
    for (code, pattern) in PATTERNS.iter().enumerate() {
        let cost = all.eval(pattern).2;
        let better = cost < best_cost;
        k = if better { code } else { k };
        best_cost = if better { cost } else { best_cost };
    }
    let (d, x, _) = all.eval(&PATTERNS[k % N_PATTERNS]);
    BoxQpSolution {
        d,
        // Constrained unless the free pattern won, unclipped.
        constrained: k != 0 || d != x,
    }
}

/// The result of [`solve_box_qp`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxQpSolution {
    /// The minimiser.
    pub d: [f32; N_MOVES],
    /// True when a bound is active at the minimiser (the unconstrained
    /// minimiser lies outside the box).
    pub constrained: bool,
}

/// Run-time state of the constrained MPC-ESO.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Cmpc {
    /// Power-piston position command u, m.
    pub u_m: f32,
    /// Observed state at the previous MPC tick.
    pub x_prev: [f32; 3],
    /// Increment applied at the previous MPC tick, m.
    pub du_prev_m: f32,
    /// Reference at the previous two MPC ticks, m.
    pub r_prev_m: [f32; 2],
    /// Load force at the previous MPC tick, N.
    pub ft_prev_n: f32,
    /// MPC ticks done (saturates at 2: what the differences need).
    pub ticks: u8,
    /// Speed of the program's move in force, m/s.
    pub v_mpc_mps: f32,
    /// Compliance feedforward: displacement commanded so far, m.
    pub u_ff_m: f32,
    /// Compliance feedforward: the low-passed load, N.
    pub ft_lp_n: f32,
    /// Compliance feedforward: the load it started from, N.
    pub ft0_n: f32,
    /// Compliance feedforward: a finite load has been read.
    pub ff_started: bool,
    /// Share of the acceleration limit in force (1 at the start; lowered
    /// while the moves ring, [`Cmpc::tick`]).
    pub a_scale: f32,
    /// Ringing: the sign of the last change of the increment at the
    /// acceleration limit.
    pub ring_sign: i8,
    /// Ringing: reversals at the limit since the last quiet spell of more
    /// than [`RING_GAP`] ticks.
    pub ring_count: u8,
    /// Ringing: MPC ticks since a change of the increment was last at the
    /// acceleration limit.
    pub ring_age: u8,
}

/// Ringing: longest quiet spell, in MPC ticks, between two changes of the
/// increment at the acceleration limit (whatever their signs) that keeps
/// them in one oscillation (80 ms at 10 ms).
pub const RING_GAP: u8 = 8;
/// Ringing: reversals at the acceleration limit (three periods of the
/// oscillation) after which the limit backs off.
pub const RING_SWINGS: u8 = 6;
/// Ringing: the factor the acceleration limit backs off by.
pub const RING_BACKOFF: f32 = 0.8;
/// Ringing: the smallest share of the acceleration limit.
pub const A_SCALE_MIN: f32 = 0.4;

/// What one constrained MPC tick reads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CmpcInput {
    /// Measured Xo, m.
    pub y_m: f32,
    /// Reference, m (inside the stroke).
    pub r_m: f32,
    /// Measured load force, N (non-finite: no load feedforward this tick).
    pub ft_n: f32,
    /// Measured power-piston position (encoder), m (non-finite: the command
    /// stands in for it).
    pub xi_m: f32,
    /// The ESO's estimates.
    pub observed: Observed,
}

impl Cmpc {
    /// Start from rest with the power piston at `u0_m`.
    pub fn new(u0_m: f32) -> Self {
        Self {
            u_m: u0_m,
            a_scale: 1.0,
            ..Self::default()
        }
    }

    /// The bounds of the moves (module documentation).
    pub fn bounds(&self, g: &CmpcGains, lim: &Limits) -> ([f32; N_MOVES], [f32; N_MOVES]) {
        let v = lim.v_max_mps * g.ts_s;
        // Where the power piston is commanded to, the feedforward's share included.
        let u = self.u_m + self.u_ff_m;
        // The end of the first block inside the stroke (then the applied
        // first period is, too).
        let hard_lo = max(-v, min((lim.x_min_m - u) / g.first_periods, 0.0));
        let hard_hi = min(v, max((lim.x_max_m - u) / g.first_periods, 0.0));
        // The soft acceleration limit (its share in force) gives way to the
        // hard bounds.
        let dd = g.dd_max_m * self.a_scale;
        let lo1 = clamp(self.du_prev_m - dd, hard_lo, hard_hi);
        let hi1 = clamp(self.du_prev_m + dd, hard_lo, hard_hi);
        let reach_up = g.first_periods * max(hi1, 0.0);
        let reach_down = g.first_periods * min(lo1, 0.0);
        let up = (lim.x_max_m - u - reach_up) / g.later_periods;
        let down = (lim.x_min_m - u - reach_down) / g.later_periods;
        let (lo_l, hi_l) = (max(-v, min(down, 0.0)), min(v, max(up, 0.0)));
        ([lo1, lo_l, lo_l], [hi1, hi_l, hi_l])
    }

    /// The reference's rate and curvature over the last two periods, or zero
    /// across a jump.
    fn preview(&self, g: &CmpcGains, r_m: f32) -> (f32, f32) {
        if self.ticks < 2 {
            return (0.0, 0.0);
        }
        let v1 = (r_m - self.r_prev_m[0]) / g.ts_s;
        let v0 = (self.r_prev_m[0] - self.r_prev_m[1]) / g.ts_s;
        let smooth = v1.abs() <= g.v_ref_max_mps && v0.abs() <= g.v_ref_max_mps;
        if !smooth {
            return (0.0, 0.0);
        }
        let a = clamp((v1 - v0) / g.ts_s, -g.a_ref_max_mps2, g.a_ref_max_mps2);
        (v1, a)
    }

    /// One MPC tick: the moves of the constrained program, the first applied.
    #[inline(never)]
    pub fn tick(&mut self, g: &CmpcGains, lim: &Limits, input: &CmpcInput) -> MpcOutput {
        let o = &input.observed;
        let y = input.y_m;
        // The program's share of the power piston's position.
        let xi = if input.xi_m.is_finite() {
            input.xi_m - self.u_ff_m
        } else {
            self.u_m
        };
        let x_now = [y, o.z2_mps, o.z3_mps2 + o.b0_v_mps2 - g.b2_gain * xi];
        let started = self.ticks > 0;
        let dx = if started {
            [
                y - self.x_prev[0],
                x_now[1] - self.x_prev[1],
                x_now[2] - self.x_prev[2],
            ]
        } else {
            [0.0; 3]
        };
        let dft = if started && input.ft_n.is_finite() && self.ft_prev_n.is_finite() {
            input.ft_n - self.ft_prev_n
        } else {
            0.0
        };
        let (v_ref, a_ref) = self.preview(g, input.r_m);
        let feature = [dx[0], dx[1], dx[2], y, input.r_m, v_ref, a_ref, dft];
        let mut grad = [0.0f32; N_MOVES];
        for (gj, c) in grad.iter_mut().zip(&g.coef) {
            *gj = c.iter().zip(&feature).fold(0.0, |acc, (c, f)| acc + c * f);
        }
        let (lo, hi) = self.bounds(g, lim);
        let sol = solve_box_qp(&g.h, &g.h_inv, &grad, &lo, &hi);
        let d = sol.d;
        let u_new = clamp(
            self.u_m + d[0],
            lim.x_min_m - self.u_ff_m,
            lim.x_max_m - self.u_ff_m,
        );
        let du = u_new - self.u_m;
        self.watch_ringing(g, du - self.du_prev_m);
        self.x_prev = x_now;
        self.du_prev_m = du;
        self.r_prev_m = [input.r_m, self.r_prev_m[0]];
        self.ft_prev_n = input.ft_n;
        self.ticks = self.ticks.saturating_add(1).min(2);
        self.u_m = u_new;
        self.v_mpc_mps = du / g.ts_s;
        MpcOutput {
            v_cmd_mps: self.v_mpc_mps,
            saturated: sol.constrained,
        }
    }

    /// The acceleration limit backs off while the moves ring: a rig whose
    /// hydraulic resonance lies lower than the design's (a smaller actuating
    /// area, a softer hose, a heavier load) is driven into a limit cycle by
    /// moves that reverse at the acceleration limit. `dd_m` is this tick's
    /// change of the increment; at the limit in force (to 1 %, either side:
    /// a change the speed or stroke bounds force beyond it does not count)
    /// and opposite in sign to the last such change, it counts one reversal.
    /// A quiet spell of more than [`RING_GAP`] ticks between two changes at
    /// the limit (whatever their signs) starts the count again: separate
    /// moves, each reversing once, are not ringing. [`RING_SWINGS`]
    /// reversals in a row lower the share of the limit by [`RING_BACKOFF`],
    /// down to [`A_SCALE_MIN`]. The share
    /// never rises again in a run (a new controller starts at 1): a limit
    /// cycle is a property of the rig, not a passing event. (Reversals
    /// between the speed or stroke bounds do not count: on rigs with a low
    /// loop gain they are the controller working, and backing off there
    /// made the tracking worse.)
    fn watch_ringing(&mut self, g: &CmpcGains, dd_m: f32) {
        self.ring_age = self.ring_age.saturating_add(1);
        let limit = g.dd_max_m * self.a_scale;
        let a = dd_m.abs();
        // Written so that a NaN change never counts.
        if !(a >= 0.99 * limit && a <= 1.01 * limit) {
            return;
        }
        if self.ring_age > RING_GAP {
            self.ring_count = 0;
        }
        let sign = if dd_m > 0.0 { 1 } else { -1 };
        if sign != self.ring_sign {
            self.ring_count += 1;
            self.ring_sign = sign;
            if self.ring_count >= RING_SWINGS {
                self.a_scale = max(self.a_scale * RING_BACKOFF, A_SCALE_MIN);
                self.ring_count = 0;
            }
        }
        self.ring_age = 0;
    }

    /// One base tick of the compliance feedforward (module documentation): the
    /// speed, m/s, to add to the program's for this base tick. The load `ft_n`
    /// through the low-pass, its change since the start times `comp_ff / b2` is
    /// the displacement to reach, at most [`CmpcGains::ff_step_m`] per tick and
    /// never further out of the stroke than `u + u_ff` already is. A
    /// non-finite load holds the feedforward where it is.
    #[inline]
    pub fn compliance_ff(&mut self, g: &CmpcGains, lim: &Limits, ft_n: f32) -> f32 {
        if !ft_n.is_finite() {
            return 0.0;
        }
        if !self.ff_started {
            self.ft_lp_n = ft_n;
            self.ft0_n = ft_n;
            self.ff_started = true;
        }
        self.ft_lp_n += g.ff_alpha * (ft_n - self.ft_lp_n);
        let target = g.comp_mpn * (self.ft_lp_n - self.ft0_n);
        let step = clamp(target - self.u_ff_m, -g.ff_step_m, g.ff_step_m);
        let u = self.u_m + self.u_ff_m;
        let step = clamp(step, min(lim.x_min_m - u, 0.0), max(lim.x_max_m - u, 0.0));
        self.u_ff_m += step;
        step * g.base_hz
    }
}

fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

fn min64(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gains() -> CmpcGains {
        let p = PlantParams::NOMINAL;
        CmpcGains::design(&p, CmpcParams::LIMIT, &Limits::from_plant(&p), 1e-3).unwrap()
    }

    /// Feed `watch_ringing` `n` changes of the increment at the limit in
    /// force, alternating in sign (the first opposite to the last one fed)
    /// every `every` ticks (the ticks between are quiet); the share of the
    /// limit afterwards.
    fn ring(c: &mut Cmpc, g: &CmpcGains, every: usize, n: usize) -> f32 {
        // Opposite to the last reversal counted.
        let mut sign = if c.ring_sign > 0 { -1.0 } else { 1.0 };
        for _ in 0..n {
            c.watch_ringing(g, sign * g.dd_max_m * c.a_scale);
            for _ in 1..every {
                c.watch_ringing(g, 0.0);
            }
            sign = -sign;
        }
        c.a_scale
    }

    #[test]
    fn the_acceleration_limit_backs_off_while_the_moves_ring() {
        let g = gains();
        let gap = usize::from(RING_GAP);
        let swings = usize::from(RING_SWINGS);
        // Reversals within the gap: one back-off per RING_SWINGS of them,
        // down to the floor and no further.
        let mut c = Cmpc::new(0.0);
        assert_eq!(c.a_scale, 1.0);
        assert_eq!(ring(&mut c, &g, gap, swings - 1), 1.0);
        assert_eq!(ring(&mut c, &g, gap, 1), RING_BACKOFF);
        assert_eq!(ring(&mut c, &g, 2, 100 * swings), A_SCALE_MIN);
        // Reversals further apart than the gap are a slow swing, not ringing.
        let mut c = Cmpc::new(0.0);
        assert_eq!(ring(&mut c, &g, gap + 2, 10 * swings), 1.0);
        // Moves below the limit in force never count.
        let mut c = Cmpc::new(0.0);
        for k in 0..1000 {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            c.watch_ringing(&g, sign * 0.98 * g.dd_max_m);
        }
        assert_eq!(c.a_scale, 1.0);
        // Separate moves in alternating directions (a square wave), each
        // accelerating and braking at the limit, are not ringing.
        let mut c = Cmpc::new(0.0);
        for k in 0..100 {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            for dd in [sign, -sign] {
                for _ in 0..20 {
                    c.watch_ringing(&g, dd * g.dd_max_m);
                }
            }
            for _ in 0..=gap {
                c.watch_ringing(&g, 0.0);
            }
        }
        assert_eq!(c.a_scale, 1.0);
        // Changes beyond the limit (forced by the speed or stroke bounds)
        // and NaN never count.
        let mut c = Cmpc::new(0.0);
        for k in 0..1000 {
            let sign = if k % 2 == 0 { 1.0 } else { -1.0 };
            c.watch_ringing(&g, sign * 1.05 * g.dd_max_m);
            c.watch_ringing(&g, f32::NAN);
        }
        assert_eq!(c.a_scale, 1.0);
        // Changes at the limit of one sign (an acceleration held) never count.
        let mut c = Cmpc::new(0.0);
        for _ in 0..1000 {
            c.watch_ringing(&g, g.dd_max_m);
        }
        assert_eq!(c.a_scale, 1.0);
    }

    /// The box of the first move narrows with the share in force.
    #[test]
    fn the_share_in_force_narrows_the_acceleration_bound() {
        let g = gains();
        let p = PlantParams::NOMINAL;
        let lim = Limits::from_plant(&p);
        let mut c = Cmpc::new(0.05);
        c.du_prev_m = 1e-4;
        let (lo, hi) = c.bounds(&g, &lim);
        c.a_scale = 0.5;
        let (lo2, hi2) = c.bounds(&g, &lim);
        assert!((hi[0] - c.du_prev_m - g.dd_max_m).abs() < 1e-9);
        assert!((hi2[0] - c.du_prev_m - 0.5 * g.dd_max_m).abs() < 1e-9);
        assert!((c.du_prev_m - lo2[0] - 0.5 * g.dd_max_m).abs() < 1e-9);
        assert!(lo2[0] > lo[0]);
    }
}
