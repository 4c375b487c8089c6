//! Evaluation of the memory GRNN in the integrator from a cached local list of
//! training samples, within a provable bound of the direct sum.
//!
//! In a simulation the hose's query u (z-scored [P, dP/dt, P - P_f1, P - P_f2])
//! moves very little from one evaluation to the next (Newton iterations, RK
//! stages, steps of 2e-4 s). [`LocalCache`] keeps the training samples within a
//! radius R of a centre c, in their storage order (the cells of a grid over
//! [`GRID_DIMS`], training-set order within a cell). A query u within distance
//! delta < R of c is served from the list when
//!
//!   d_r^2 + 2 sigma^2 T <= (R - delta)^2,   d_r = distance to the nearest sample in the list,
//!
//! because every sample outside the list is farther than R - delta from u: the
//! nearest sample is in the list, and so is every sample with
//! d_i^2 <= d_r^2 + 2 sigma^2 T. Otherwise the list is rebuilt around u with
//! R = sqrt(d_r^2 + 2 sigma^2 T) + [`LIST_MARGIN_Z`], visiting only the grid
//! cells that can hold its samples (`LocalGrnn::rebuild`).
//!
//! **What is summed** depends only on u, never on the list: with weights relative
//! to the nearest sample, w_i = n_i exp(-(d_i^2 - d_r^2) / (2 sigma^2)) (n_i the
//! sample's multiplicity, >= 1), the samples of the shells
//! d_i^2 - d_r^2 <= 2 sigma^2 t_l for t_l in [`SHELLS`] and finally t = T are
//! summed in storage order, shell after shell, stopping after shell l as soon
//! as C_l e^-t_l <= (eps / 2) D_I, where D_I is the weight summed so far and C_l
//! the multiplicity of the samples between shell l and T (counted without an
//! exp). Through a plain cache ([`LocalCache::new`]) a run is therefore
//! bit-identical whatever the cache's history (a fresh cache, another plant's
//! cache, another thread).
//!
//! **Bound.** Let I be the summed samples, O the others. Each sample of O inside T
//! weighs at most its multiplicity times e^-t_l, so these weigh at most
//! C_l e^-t_l <= (eps / 2) D_I; those beyond T weigh less than N e^-T in all
//! (N the total multiplicity), with T = ln(2 N / eps) that is eps / 2 <= (eps / 2)
//! D_I (D_I >= 1: the nearest sample weighs its multiplicity). With yhat_I the
//! ratio over I, yhat - yhat_I = sum_O w_i (Y_i - yhat_I) / (D_I + D_O), so
//!
//!   **|yhat - yhat_I| <= (D_O / D_I) (Y_max - Y_min) <= eps (Y_max - Y_min)**,
//!
//! everywhere, however far from the data. The kernels' exponentials are
//! [`exp_nonpositive`] (inline, within a few ulp of `f64::exp`; the bound is
//! unaffected at this scale). The slope d yhat / d u_1 (dP/dt, Newton's) is
//! that of the summed ratio.
//!
//! **Taylor steps** (only through [`LocalCache::with_taylor`], the plant's
//! caches). Most of the plant's queries lie within 1e-4 z of the one before
//! (the loop at rest, Newton's last iterate, the next RK stage). Such a cache
//! sums its exact evaluations, the *anchors*, to [`ANCHOR_SHARE`] eps instead
//! of eps (the same rule with T_a = ln(2 N / (ANCHOR_SHARE eps)) and the shells
//! [`ANCHOR_SHELLS`]), so that at an anchor u_0 the neglected weight is
//! D_O <= B_0 D_I with B_0 = (C_l e^-t_l + N e^-T_a) / D_I <= ANCHOR_SHARE eps.
//! It keeps there yhat_I(u_0), its gradient g and Hessian H, the mean xbar and
//! covariance S of the summed samples' x under their weights, and the spread
//! Y_I = max - min of their outputs. A later query u = u_0 + delta is served
//! by the second-order step
//!
//!   yhat_I(u_0) + g . delta + delta^T H delta / 2      (slope g_1 + (H delta)_1)
//!
//! when its remainder bound E_2 <= [`STEP_SHARE`] eps and B_0 e^x_1 + E_2 <= eps,
//!
//!   E_2 = (7 / 12) (Y_I / (Y_max - Y_min)) x_2 e^x_2 delta^T S delta / sigma^4,
//!   x_1 = (|delta| R_T - delta . (xbar - u_0)) / sigma^2,   x_2 = |delta| rho / sigma^2,
//!
//! with R_T^2 = d_r^2 + 2 sigma^2 T_a, rho = |xbar - u_0| + the largest distance
//! of a summed sample from u_0, x_1, x_2 < 1 (e^x taken as at most 1 / (1 - x))
//! and |delta| < R_T; otherwise u is evaluated exactly and becomes the anchor.
//! Proof: with a_i = delta . (x_i - u_0) / sigma^2 every kernel at u is its
//! value at u_0 times e^a_i times a common factor, which cancels in the ratio.
//! (i) Truncation at u. D_I grows by at least e^abar, abar = delta . (xbar -
//! u_0) / sigma^2 the weighted mean of a over I (Jensen). A neglected sample
//! inside T_a (|x_i - u_0| <= R_T) grows by at most e^(|delta| R_T / sigma^2);
//! one beyond, at distance d > R_T > |delta|, weighs at most
//! n_i e^-((d^2 - 2 |delta| d - d_r^2) / (2 sigma^2)) <= n_i e^-T_a
//! e^(|delta| R_T / sigma^2), d^2 - 2 |delta| d growing with d. So at u
//! D_O / D_I <= B_0 e^x_1, and |yhat(u) - yhat_I(u)| <= B_0 e^x_1 (Y_max -
//! Y_min) as above. (ii) The remainder. Along u_0 + t delta, yhat_I is the
//! tilted mean f(t) = E_t Y under the weights w_i e^(t a_i); its derivatives
//! are joint cumulants: f' = k(Y, a), f'' = k(Y, a, a) = E_t[(Y - E_t Y)(a -
//! E_t a)^2] (at t = 0: g . delta and delta^T H delta) and f''' = k(Y, a, a, a)
//! = E_t[(Y - E_t Y)(a - E_t a)^3] - 3 k(Y, a) Var_t(a). Every a_i - abar lies
//! in [-x_2, x_2] (|x_i - xbar| <= rho), so |a_i - E_t a| <= 2 x_2 and
//! Var_t(a) <= x_2^2; with |Y - E_t Y| <= Y_I and |k(Y, a)| <= (Y_I / 2)
//! sqrt(Var_t(a)) (Popoviciu), |f'''| <= (2 + 3 / 2) Y_I x_2 Var_t(a). As
//! E_0[e^(t a)] >= e^(t abar) (Jensen), Var_t(a) <= E_t[(a - abar)^2] <=
//! E_0[(a - abar)^2 e^(t (a - abar))] <= e^x_2 Var_0(a) for t in [0, 1], and
//! Var_0(a) = delta^T S delta / sigma^4. The second-order remainder is at most
//! a sixth of the largest |f'''|: E_2. (i) and (ii) together keep
//!
//!   **|value - yhat(u)| <= eps (Y_max - Y_min)**,
//!
//! the same bound as an exact evaluation. [`STEP_SHARE`] keeps the steps' own
//! error well inside it: an exact evaluation errs far less than its bound (4e-2
//! against 76 mm^3/s measured, test `grnn_fast.rs`), and steps that used the
//! whole bound moved the plant's trajectories measurably (test
//! `grnn_plant.rs`). Such a cache's values depend on its queries since its last
//! [`LocalCache::forget`]; the plant forgets at
//! [`crate::model::plant::Plant::initial_state`] and a clone of a plant carries
//! its caches, so runs stay reproducible.

use super::net::Grnn;

/// Input dimension of [`LocalGrnn`] (the memory GRNN's).
pub const LOCAL_DIM: usize = 4;

/// The list holds the samples within this distance (z units) beyond the radius
/// a query needs: a query may move this far before the list is rebuilt.
pub const LIST_MARGIN_Z: f64 = 0.1;

/// The inputs by which the training samples are binned for a rebuild of the
/// list (dP/dt, P - P_f1, P - P_f2: indices into u).
pub const GRID_DIMS: [usize; 3] = [1, 2, 3];

/// Cell width of that grid, z units.
pub const GRID_CELL_Z: f64 = 0.25;

/// Intermediate shells t_l (units of 2 sigma^2 in squared distance beyond the
/// nearest sample) at which the sum may stop (module documentation).
pub const SHELLS: [f64; 2] = [10.0, 13.0];

/// Share of the bound eps that an anchor's truncation may take (module
/// documentation, "Taylor steps"): an anchor sums until its neglected weight is
/// within ANCHOR_SHARE eps of its summed weight, the rest of eps is left to the
/// steps taken from it.
pub const ANCHOR_SHARE: f64 = 0.25;

/// Share of the bound eps that the remainder of a Taylor step may take (module
/// documentation, "Taylor steps").
pub const STEP_SHARE: f64 = 0.1;

/// Intermediate shells of an anchor's sum (units of 2 sigma^2, as [`SHELLS`]).
pub const ANCHOR_SHELLS: [f64; 3] = [10.0, 12.0, 14.0];

/// Where a sum may stop (module documentation): the shells and the threshold.
#[derive(Clone, Debug, PartialEq)]
struct StopRule {
    /// 2 sigma^2 t_l per shell, then 2 sigma^2 T.
    shells: Vec<f64>,
    /// e^-t_l per shell.
    shell_weight: Vec<f64>,
    /// The sum stops after shell l once C_l e^-t_l <= stop D_I (eps / 2 of the
    /// rule's eps).
    stop: f64,
    /// N e^-T: the bound on the samples beyond T (units of the nearest
    /// sample's weight).
    beyond: f64,
}

impl StopRule {
    /// The rule that keeps the truncation within `eps` of the output range:
    /// T = ln(2 N / (eps n_min)) and the shells of `at` below it.
    fn new(two_s2: f64, total: f64, n_min: f64, eps: f64, at: &[f64]) -> Self {
        let t = (2.0 * total / (eps * n_min.min(1.0))).ln().max(1.0);
        let mut shells: Vec<f64> = at.iter().filter(|&&s| s < t).map(|&s| two_s2 * s).collect();
        let shell_weight = at.iter().filter(|&&s| s < t).map(|&s| (-s).exp()).collect();
        shells.push(two_s2 * t);
        Self {
            shells,
            shell_weight,
            stop: 0.5 * eps,
            beyond: total * (-t).exp(),
        }
    }

    /// 2 sigma^2 T.
    fn s2t(&self) -> f64 {
        self.shells[self.shells.len() - 1]
    }
}

/// The memory GRNN's training samples laid out for [`LocalGrnn::eval_z`].
#[derive(Clone, Debug, PartialEq)]
pub struct LocalGrnn {
    sigma: f64,
    /// -1 / (2 sigma^2).
    k: f64,
    eps: f64,
    /// The sum of a plain evaluation (within eps).
    plain: StopRule,
    /// The sum of an anchor (within [`ANCHOR_SHARE`] eps).
    anchor: StopRule,
    /// The samples binned on [`GRID_DIMS`].
    grid: Grid,
    /// Scaled inputs, one column per input (grid-cell order, then
    /// training-set order).
    x: [Vec<f64>; LOCAL_DIM],
    y: Vec<f64>,
    n: Vec<f64>,
    total: f64,
    y_min: f64,
    y_max: f64,
}

/// The cached list of one query stream (one hose line), the Taylor anchor of a
/// cache made by [`LocalCache::with_taylor`], and work counters.
#[derive(Clone, Debug, Default)]
pub struct LocalCache {
    valid: bool,
    centre: [f64; LOCAL_DIM],
    radius: f64,
    x: [Vec<f64>; LOCAL_DIM],
    y: Vec<f64>,
    n: Vec<f64>,
    d2: Vec<f64>,
    /// The last query's nearest sample (list index).
    near: usize,
    /// The scan's candidates (list indices) and their number.
    cand: Vec<u32>,
    n_cand: usize,
    /// Scratch of the sum: the selected samples' indices and their weights.
    sel: Vec<u32>,
    w: Vec<f64>,
    /// Scratch of the rebuild: the visited samples' squared distances and
    /// indices.
    all_d2: Vec<f64>,
    all_i: Vec<u32>,
    /// Steps from the last exact evaluation allowed ([`LocalCache::with_taylor`]).
    taylor: bool,
    /// The last exact evaluation (the Taylor anchor), if any.
    anchor: Option<Anchor>,
    stats: LocalStats,
}

/// An exact evaluation kept for Taylor steps (module documentation), its
/// quantities scaled for the check.
#[derive(Clone, Copy, Debug)]
struct Anchor {
    u: [f64; LOCAL_DIM],
    /// yhat_I(u_0).
    y: f64,
    /// Gradient of yhat_I at u_0 (z-space).
    grad: [f64; LOCAL_DIM],
    /// B_0 / eps: the bound on D_O / D_I at u_0.
    b0: f64,
    /// R_T / sigma^2.
    r_t: f64,
    /// R_T^2 (z units).
    r_t2: f64,
    /// (xbar - u_0) / sigma^2.
    ebar: [f64; LOCAL_DIM],
    /// rho / sigma^2: |xbar - u_0| plus the summed samples' largest distance
    /// from u_0 (so at least their largest distance from xbar).
    rho: f64,
    /// Half the Hessian of yhat_I at u_0 (upper triangle, row by row).
    half_hess: [f64; 10],
    /// The covariance S of the summed samples' x (upper triangle, row by row)
    /// times 7 Y_I / (12 sigma^4 eps STEP_SHARE (Y_max - Y_min)).
    cov: [f64; 10],
}

impl Anchor {
    /// The second-order step to `u` (module documentation, "Taylor steps"),
    /// with its bounds B_0 e^x_1 / eps and E_2 / (STEP_SHARE eps (Y_max -
    /// Y_min)) (e^x taken as at most 1 / (1 - x)); None unless x_1, x_2 < 1 and
    /// |delta| < R_T.
    #[inline]
    fn step(&self, u: &[f64; LOCAL_DIM]) -> Option<(LocalEval, f64, f64)> {
        let d: [f64; LOCAL_DIM] = core::array::from_fn(|k| u[k] - self.u[k]);
        let dn2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2] + d[3] * d[3];
        let dn = dn2.sqrt();
        let abar =
            d[0] * self.ebar[0] + d[1] * self.ebar[1] + d[2] * self.ebar[2] + d[3] * self.ebar[3];
        let x1 = dn * self.r_t - abar;
        let x2 = dn * self.rho;
        if !(x1 < 1.0 && x2 < 1.0 && dn2 < self.r_t2) {
            return None;
        }
        // x1 may be negative: e^x1 <= 1 then.
        let trunc = self.b0 / (1.0 - x1.max(0.0));
        let rem = quad(&self.cov, &d).max(0.0) * x2 / (1.0 - x2);
        let dy =
            self.grad[0] * d[0] + self.grad[1] * d[1] + self.grad[2] * d[2] + self.grad[3] * d[3];
        let h = &self.half_hess;
        // d/du_1 of d^T (H / 2) d: (H d)_1.
        let hd1 = 2.0 * (h[1] * d[0] + h[4] * d[1] + h[5] * d[2] + h[6] * d[3]);
        let e = LocalEval {
            y: self.y + dy + quad(h, &d),
            dy_du1: self.grad[1] + hd1,
        };
        Some((e, trunc, rem))
    }

    /// The step to `u` if its bounds allow it: E_2 <= STEP_SHARE eps and
    /// B_0 e^x_1 + E_2 <= eps (a relative 1e-12 for rounding).
    #[inline]
    fn accepted_step(&self, u: &[f64; LOCAL_DIM]) -> Option<LocalEval> {
        let (e, trunc, rem) = self.step(u)?;
        (rem <= 1.0 - 1e-12 && trunc + rem * STEP_SHARE <= 1.0 - 1e-12).then_some(e)
    }
}

/// d^T A d for the symmetric A given by its upper triangle, row by row.
#[inline(always)]
fn quad(a: &[f64; 10], d: &[f64; LOCAL_DIM]) -> f64 {
    d[0] * (a[0] * d[0] + 2.0 * (a[1] * d[1] + a[2] * d[2] + a[3] * d[3]))
        + d[1] * (a[4] * d[1] + 2.0 * (a[5] * d[2] + a[6] * d[3]))
        + d[2] * (a[7] * d[2] + 2.0 * a[8] * d[3])
        + d[3] * a[9] * d[3]
}

/// Work done through one [`LocalCache`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LocalStats {
    /// Evaluations.
    pub evals: u64,
    /// Kernel evaluations (exp calls).
    pub kernels: u64,
    /// Squared distances computed on the list (cheap, no exp).
    pub distances: u64,
    /// Rebuilds of the list.
    pub rebuilds: u64,
    /// Training samples visited by the rebuilds (a distance each).
    pub visited: u64,
    /// Evaluations served by a Taylor step from the last exact one (no
    /// distance or kernel; [`LocalCache::with_taylor`]).
    pub taylor: u64,
}

impl LocalCache {
    /// An empty cache (the first evaluation builds the list).
    pub fn new() -> Self {
        Self::default()
    }

    /// An empty cache that serves a query by a second-order Taylor step from
    /// its last exact evaluation whenever that provably stays within the
    /// evaluator's bound (module documentation, "Taylor steps"). Its results
    /// then depend on the queries since its last [`LocalCache::forget`]: give
    /// each query stream its own and forget at the start of a run.
    pub fn with_taylor() -> Self {
        Self {
            taylor: true,
            ..Self::default()
        }
    }

    /// Drop the Taylor anchor: the next evaluation is exact (the list is kept;
    /// the exact values do not depend on it).
    pub fn forget(&mut self) {
        self.anchor = None;
    }

    /// Work counters since creation or [`LocalCache::reset_stats`].
    pub fn stats(&self) -> LocalStats {
        self.stats
    }

    /// Zero the work counters (the list is kept: results do not depend on it).
    pub fn reset_stats(&mut self) {
        self.stats = LocalStats::default();
    }
}

/// Value and slope of one evaluation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalEval {
    /// yhat.
    pub y: f64,
    /// d yhat / d u_1 (z-space; input 1 is dP/dt).
    pub dy_du1: f64,
}

impl LocalGrnn {
    /// Lay out the four-input network `net` for evaluation within
    /// `eps * (Y_max - Y_min)` of the direct sum. Panics unless `net` has four
    /// inputs and `eps` is in (0, 1).
    pub fn new(net: &Grnn, eps: f64) -> Self {
        assert_eq!(net.dim(), LOCAL_DIM, "LocalGrnn is for four-input networks");
        assert!(eps > 0.0 && eps < 1.0, "eps must be in (0, 1)");
        let sigma = net.sigma();
        let two_s2 = 2.0 * sigma * sigma;
        let total = net.total_count();
        // Multiplicities are >= 1 (merged samples count their members); divide by
        // the smallest anyway so that D_I >= 1 holds in its units.
        let n_min = net.counts().iter().copied().fold(f64::INFINITY, f64::min);
        let plain = StopRule::new(two_s2, total, n_min, eps, &SHELLS);
        let anchor = StopRule::new(two_s2, total, n_min, eps * ANCHOR_SHARE, &ANCHOR_SHELLS);
        let xn = net.scaled_inputs();
        let col =
            |k: usize| -> Vec<f64> { xn.iter().skip(k).step_by(LOCAL_DIM).copied().collect() };
        let (grid, order) = Grid::new(&core::array::from_fn(|g| col(GRID_DIMS[g])));
        let x = core::array::from_fn(|k| {
            let c = col(k);
            order.iter().map(|&i| c[i]).collect()
        });
        let (y_min, y_max) = net.output_range();
        Self {
            sigma,
            k: -1.0 / two_s2,
            eps,
            plain,
            anchor,
            grid,
            x,
            y: order.iter().map(|&i| net.outputs()[i]).collect(),
            n: order.iter().map(|&i| net.counts()[i]).collect(),
            total,
            y_min,
            y_max,
        }
    }

    /// The provable bound on |evaluated - direct sum|: eps (Y_max - Y_min).
    pub fn error_bound(&self) -> f64 {
        self.eps * (self.y_max - self.y_min)
    }

    /// Number of training samples (after merging).
    pub fn len(&self) -> usize {
        self.y.len()
    }

    /// Whether there are no training samples (never for a fitted network).
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }

    /// Value and slope at the scaled input `u`, through `cache` (module
    /// documentation): through a plain cache the result does not depend on the
    /// cache's state; through a Taylor cache it may be a Taylor step from the
    /// cache's last exact evaluation, within the same bound. A non-finite
    /// input gives a NaN value.
    pub fn eval_z(&self, u: &[f64; LOCAL_DIM], cache: &mut LocalCache) -> LocalEval {
        if !u.iter().all(|v| v.is_finite()) {
            return LocalEval {
                y: f64::NAN,
                dy_du1: 0.0,
            };
        }
        cache.stats.evals += 1;
        if let Some(a) = &cache.anchor {
            if let Some(e) = a.accepted_step(u) {
                cache.stats.taylor += 1;
                return e;
            }
        }
        let rule = if cache.taylor {
            &self.anchor
        } else {
            &self.plain
        };
        if cache.valid {
            let dc2: f64 = (0..LOCAL_DIM)
                .map(|k| (u[k] - cache.centre[k]).powi(2))
                .sum();
            let dc = dc2.sqrt();
            if dc < cache.radius {
                let m = self.scan(u, rule.s2t(), cache);
                let reach = cache.radius - dc;
                // A relative 1e-12 of slack for the rounding of the distances.
                if m + rule.s2t() <= reach * reach * (1.0 - 1e-12) {
                    return self.sum_for(u, m, rule, cache);
                }
            }
        }
        self.rebuild(u, rule.s2t(), cache);
        let m = self.scan(u, rule.s2t(), cache);
        self.sum_for(u, m, rule, cache)
    }

    /// The plain sum or, for a Taylor cache, an anchor's.
    #[inline]
    fn sum_for(
        &self,
        u: &[f64; LOCAL_DIM],
        m: f64,
        rule: &StopRule,
        c: &mut LocalCache,
    ) -> LocalEval {
        if c.taylor {
            self.sum::<true>(u, m, rule, c)
        } else {
            self.sum::<false>(u, m, rule, c)
        }
    }

    /// Rebuild the list around `u`: every sample within R = sqrt(d_r^2 + 2
    /// sigma^2 T) plus [`LIST_MARGIN_Z`], in storage order. Only the grid cells
    /// within b = sqrt(m_ub + 2 sigma^2 T) plus [`LIST_MARGIN_Z`] of `u` in
    /// [`GRID_DIMS`] are visited, m_ub >= d_r^2 being the squared distance to
    /// the old list's nearest sample (all cells if there is none): the nearest
    /// sample is within sqrt(m_ub) < b, so it is found, and then R <= b.
    fn rebuild(&self, u: &[f64; LOCAL_DIM], s2t: f64, c: &mut LocalCache) {
        c.stats.rebuilds += 1;
        let dist2 = |x: &[Vec<f64>; LOCAL_DIM], i: usize| {
            let (a, b, e, f) = (
                u[0] - x[0][i],
                u[1] - x[1][i],
                u[2] - x[2][i],
                u[3] - x[3][i],
            );
            a * a + b * b + e * e + f * f
        };
        let m_ub = if c.valid && c.near < c.y.len() {
            dist2(&c.x, c.near)
        } else {
            f64::INFINITY
        };
        let b = (m_ub + s2t).sqrt() + LIST_MARGIN_Z;
        c.all_d2.clear();
        c.all_i.clear();
        let mut m = f64::INFINITY;
        self.grid.visit(u, b, |range| {
            for i in range {
                let d2 = dist2(&self.x, i);
                m = m.min(d2);
                c.all_d2.push(d2);
                c.all_i.push(i as u32);
            }
        });
        c.stats.visited += c.all_i.len() as u64;
        let r = (m + s2t).sqrt() + LIST_MARGIN_Z;
        let r2 = r * r;
        for col in &mut c.x {
            col.clear();
        }
        c.y.clear();
        c.n.clear();
        c.near = usize::MAX;
        for (&d2, &i) in c.all_d2.iter().zip(&c.all_i) {
            if d2 <= r2 {
                let i = i as usize;
                if d2 <= m && c.near == usize::MAX {
                    c.near = c.y.len();
                }
                for k in 0..LOCAL_DIM {
                    c.x[k].push(self.x[k][i]);
                }
                c.y.push(self.y[i]);
                c.n.push(self.n[i]);
            }
        }
        c.d2.resize(c.y.len(), 0.0);
        c.sel.resize(c.y.len(), 0);
        c.cand.resize(c.y.len(), 0);
        c.w.resize(c.y.len(), 0.0);
        c.centre = *u;
        c.radius = r;
        c.valid = true;
    }

    /// The shell-by-shell sum over the list (module documentation) under
    /// `rule`, `m` being the squared distance to the nearest sample and `c.d2`
    /// the list's squared distances. Per shell, one branch-free pass selects its
    /// samples (in list order) and counts the multiplicity beyond it; their
    /// exponentials are then taken in one batch and summed in that order. An
    /// `ANCHOR` sum also keeps what a Taylor step from `u` needs in `c.anchor`.
    fn sum<const ANCHOR: bool>(
        &self,
        u: &[f64; LOCAL_DIM],
        m: f64,
        rule: &StopRule,
        c: &mut LocalCache,
    ) -> LocalEval {
        let len = c.y.len();
        let LocalCache {
            x,
            y,
            n,
            d2,
            cand,
            n_cand,
            sel,
            w,
            stats,
            anchor,
            ..
        } = c;
        let cand = &cand[..*n_cand];
        let (d2, ys, ns) = (&d2[..len], &y[..len], &n[..len]);
        let xs: [&[f64]; LOCAL_DIM] = core::array::from_fn(|k| &x[k][..len]);
        let (sel, w) = (&mut sel[..len], &mut w[..len]);
        let (mut s0, mut sy, mut sa, mut say) = (0.0, 0.0, 0.0, 0.0);
        let mut mom = Moments::default();
        let mut lower = f64::NEG_INFINITY;
        let last = rule.shells.len() - 1;
        let outer = m + rule.shells[last];
        let (mut cut, mut neglected) = (outer, 0.0);
        for (l, &shell) in rule.shells.iter().enumerate() {
            cut = m + shell;
            let mut count = 0usize;
            let mut rest = 0.0;
            for &j in cand {
                let dj = d2[j as usize];
                // count <= the candidates seen < len: in bounds.
                sel[count] = j;
                count += usize::from(dj > lower && dj <= cut);
                rest += if dj > cut && dj <= outer {
                    ns[j as usize]
                } else {
                    0.0
                };
            }
            let (sel, w) = (&sel[..count], &mut w[..count]);
            for (wt, &j) in w.iter_mut().zip(sel) {
                *wt = self.k * (d2[j as usize] - m);
            }
            for wt in w.iter_mut() {
                *wt = exp_nonpositive(*wt);
            }
            if ANCHOR {
                for (&e, &j) in w.iter().zip(sel) {
                    let j = j as usize;
                    mom.add(ns[j] * e, ys[j], core::array::from_fn(|k| xs[k][j] - u[k]));
                }
            } else {
                for (&e, &j) in w.iter().zip(sel) {
                    let j = j as usize;
                    let wj = ns[j] * e;
                    let a = wj * (u[1] - xs[1][j]);
                    s0 += wj;
                    sy += wj * ys[j];
                    sa += a;
                    say += a * ys[j];
                }
            }
            stats.kernels += count as u64;
            if l == last {
                break;
            }
            let total = if ANCHOR { mom.s0 } else { s0 };
            if rest * rule.shell_weight[l] <= rule.stop * total {
                neglected = rest * rule.shell_weight[l];
                break;
            }
            lower = cut;
        }
        if ANCHOR {
            let a = self.anchor_of(u, &mom, neglected + rule.beyond, m + rule.s2t(), cut);
            *anchor = Some(a);
            return LocalEval {
                y: a.y,
                dy_du1: a.grad[1],
            };
        }
        let y = sy / s0;
        LocalEval {
            y,
            dy_du1: -(say / s0 - y * sa / s0) / (self.sigma * self.sigma),
        }
    }

    /// The anchor at `u` from the moments of its sum, `neglected` the bound on
    /// the weight left out (units of the nearest sample's), `r_t2` = R_T^2 and
    /// `r_i2` the squared distance within which the samples were summed.
    fn anchor_of(
        &self,
        u: &[f64; LOCAL_DIM],
        mo: &Moments,
        neglected: f64,
        r_t2: f64,
        r_i2: f64,
    ) -> Anchor {
        let s2 = self.sigma * self.sigma;
        let y = mo.sy / mo.s0;
        let ebar: [f64; LOCAL_DIM] = core::array::from_fn(|k| mo.se[k] / mo.s0);
        let grad = core::array::from_fn(|k| (mo.sey[k] / mo.s0 - y * ebar[k]) / s2);
        let spread = (mo.y_max - mo.y_min).max(0.0) / (self.y_max - self.y_min);
        let scale = 7.0 * spread / (12.0 * s2 * s2 * self.eps * STEP_SHARE);
        let ey: [f64; LOCAL_DIM] = core::array::from_fn(|k| mo.sey[k] / mo.s0);
        let (mut cov, mut half_hess) = ([0.0; 10], [0.0; 10]);
        let mut i = 0;
        for k in 0..LOCAL_DIM {
            for l in k..LOCAL_DIM {
                let ee = mo.see[i] / mo.s0;
                cov[i] = (ee - ebar[k] * ebar[l]) * scale;
                // The third joint central moment of (y, e_k, e_l).
                let k3 = mo.syee[i] / mo.s0 - ebar[l] * ey[k] - ebar[k] * ey[l] - y * ee
                    + 2.0 * y * ebar[k] * ebar[l];
                half_hess[i] = 0.5 * k3 / (s2 * s2);
                i += 1;
            }
        }
        let eb = ebar.iter().map(|e| e * e).sum::<f64>().sqrt();
        Anchor {
            u: *u,
            y,
            grad,
            b0: neglected / mo.s0 / self.eps,
            r_t: r_t2.sqrt() / s2,
            r_t2,
            ebar: ebar.map(|e| e / s2),
            rho: (eb + r_i2.sqrt()) / s2,
            half_hess,
            cov,
        }
    }

    /// Squared distances from `u` to the list's samples (into `c.d2`), their
    /// minimum m, and in the same pass the candidates `c.cand` (list order):
    /// the samples within m_ub + 2 sigma^2 T, m_ub >= m being the squared
    /// distance to the previous query's nearest sample. Every sample of the
    /// outermost shell (d^2 <= m + 2 sigma^2 T) is a candidate, so the sum
    /// needs only these.
    #[inline]
    fn scan(&self, u: &[f64; LOCAL_DIM], s2t: f64, c: &mut LocalCache) -> f64 {
        let len = c.y.len();
        c.stats.distances += len as u64;
        let [x0, x1, x2, x3] = &c.x;
        let (x0, x1, x2, x3) = (&x0[..len], &x1[..len], &x2[..len], &x3[..len]);
        let dist2 = |j: usize| {
            let (a, b, e, f) = (u[0] - x0[j], u[1] - x1[j], u[2] - x2[j], u[3] - x3[j]);
            a * a + b * b + e * e + f * f
        };
        let cut = if c.near < len {
            dist2(c.near) + s2t
        } else {
            f64::INFINITY
        };
        let (d2, cand) = (&mut c.d2[..len], &mut c.cand[..len]);
        let mut m = f64::INFINITY;
        let mut count = 0usize;
        for (j, d2j) in d2.iter_mut().enumerate() {
            let d = dist2(j);
            *d2j = d;
            if d < m {
                m = d;
            }
            // count <= j < len: in bounds.
            cand[count] = j as u32;
            count += usize::from(d <= cut);
        }
        c.n_cand = count;
        // The nearest sample is a candidate (m <= m_ub).
        c.near = cand[..count]
            .iter()
            .map(|&j| j as usize)
            .find(|&j| d2[j] <= m)
            .unwrap_or(0);
        m
    }

    /// Number of samples of the total multiplicity N of the bound.
    pub fn total_count(&self) -> f64 {
        self.total
    }
}

/// The training samples binned on a uniform grid over [`GRID_DIMS`], cells
/// numbered row-major; the samples are stored in cell order (training-set order
/// within a cell), so that the cells of a box, visited in their order, give the
/// samples in storage order.
#[derive(Clone, Debug, PartialEq)]
struct Grid {
    lo: [f64; 3],
    n: [usize; 3],
    /// The samples of cell k are start[k]..start[k + 1].
    start: Vec<u32>,
}

impl Grid {
    /// The grid over the given columns (one per binned input) and the storage
    /// order of the samples (training-set indices).
    fn new(cols: &[Vec<f64>; 3]) -> (Self, Vec<usize>) {
        let len = cols[0].len();
        let lo = cols
            .each_ref()
            .map(|c| c.iter().copied().fold(f64::INFINITY, f64::min));
        let hi = cols
            .each_ref()
            .map(|c| c.iter().copied().fold(f64::NEG_INFINITY, f64::max));
        let n: [usize; 3] = core::array::from_fn(|g| ((hi[g] - lo[g]) / GRID_CELL_Z) as usize + 1);
        let mut grid = Self {
            lo,
            n,
            start: Vec::new(),
        };
        let key = |i: usize| -> usize {
            let c: [usize; 3] = core::array::from_fn(|g| grid.cell(g, cols[g][i]));
            (c[0] * n[1] + c[1]) * n[2] + c[2]
        };
        let keys: Vec<usize> = (0..len).map(key).collect();
        let mut order: Vec<usize> = (0..len).collect();
        order.sort_by_key(|&i| keys[i]);
        let mut start = vec![0u32; n[0] * n[1] * n[2] + 1];
        for &k in &keys {
            start[k + 1] += 1;
        }
        for k in 1..start.len() {
            start[k] += start[k - 1];
        }
        grid.start = start;
        (grid, order)
    }

    /// The cell index of coordinate `v` in binned input `g`, clamped to the grid.
    #[inline]
    fn cell(&self, g: usize, v: f64) -> usize {
        ((v - self.lo[g]) / GRID_CELL_Z).clamp(0.0, (self.n[g] - 1) as f64) as usize
    }

    /// Call `f` with the storage ranges of the cells that meet the box of
    /// half-width `b` around `u` (in the binned inputs), in storage order.
    #[inline]
    fn visit(&self, u: &[f64; LOCAL_DIM], b: f64, mut f: impl FnMut(core::ops::Range<usize>)) {
        let lo: [usize; 3] = core::array::from_fn(|g| self.cell(g, u[GRID_DIMS[g]] - b));
        let hi: [usize; 3] = core::array::from_fn(|g| self.cell(g, u[GRID_DIMS[g]] + b));
        for i0 in lo[0]..=hi[0] {
            for i1 in lo[1]..=hi[1] {
                let row = (i0 * self.n[1] + i1) * self.n[2];
                let (a, z) = (self.start[row + lo[2]], self.start[row + hi[2] + 1]);
                if a < z {
                    f(a as usize..z as usize);
                }
            }
        }
    }
}

/// Weighted moments of an anchor's sum: the weight, of y, of e = x - u_0, of
/// e y and e e^T (upper triangle), and the summed samples' range of y.
#[derive(Clone, Copy, Debug)]
struct Moments {
    s0: f64,
    sy: f64,
    se: [f64; LOCAL_DIM],
    sey: [f64; LOCAL_DIM],
    see: [f64; 10],
    syee: [f64; 10],
    y_min: f64,
    y_max: f64,
}

impl Default for Moments {
    fn default() -> Self {
        Self {
            s0: 0.0,
            sy: 0.0,
            se: [0.0; LOCAL_DIM],
            sey: [0.0; LOCAL_DIM],
            see: [0.0; 10],
            syee: [0.0; 10],
            y_min: f64::INFINITY,
            y_max: f64::NEG_INFINITY,
        }
    }
}

impl Moments {
    #[inline(always)]
    fn add(&mut self, w: f64, y: f64, e: [f64; LOCAL_DIM]) {
        self.s0 += w;
        self.sy += w * y;
        let mut i = 0;
        for k in 0..LOCAL_DIM {
            let we = w * e[k];
            self.se[k] += we;
            self.sey[k] += we * y;
            for el in &e[k..] {
                let wee = we * el;
                self.see[i] += wee;
                self.syee[i] += wee * y;
                i += 1;
            }
        }
        self.y_min = self.y_min.min(y);
        self.y_max = self.y_max.max(y);
    }
}

/// e^x for x in [-700, 0] (the kernels' exponents, which are >= -T), inline
/// and without a branch: x = n ln 2 + r with |r| <= ln 2 / 2 (two-part ln 2),
/// e^r by its Taylor polynomial of degree 12 (truncation below 2e-16
/// relative), 2^n from the exponent bits. Within a few ulp of `f64::exp`
/// (test `exp_nonpositive_matches_std`), several times cheaper in the sum.
#[inline(always)]
pub fn exp_nonpositive(x: f64) -> f64 {
    // 1.5 * 2^52: adding it rounds to an integer held in the low mantissa bits.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    // ln 2 in two parts; LN2_HI has trailing zero bits, so n LN2_HI is exact.
    const LN2_HI: f64 = 0.693_147_180_369_123_8;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    debug_assert!((-700.0..=0.0).contains(&x), "exp_nonpositive({x})");
    let t = x * core::f64::consts::LOG2_E + SHIFT;
    let n = t - SHIFT;
    let r = (x - n * LN2_HI) - n * LN2_LO;
    // 1 / k! for k = 12 down to 0 (Horner).
    const INV_FACT: [f64; 13] = [
        1.0 / 479_001_600.0,
        1.0 / 39_916_800.0,
        1.0 / 3_628_800.0,
        1.0 / 362_880.0,
        1.0 / 40_320.0,
        1.0 / 5040.0,
        1.0 / 720.0,
        1.0 / 120.0,
        1.0 / 24.0,
        1.0 / 6.0,
        0.5,
        1.0,
        1.0,
    ];
    let mut p = INV_FACT[0];
    for c in &INV_FACT[1..] {
        p = p * r + c;
    }
    // The low bits of t hold n (two's complement); shifted into the exponent
    // field and biased, they are 2^n.
    let scale = f64::from_bits((t.to_bits() << 52).wrapping_add(1023 << 52));
    p * scale
}

#[cfg(test)]
mod tests {
    use super::{exp_nonpositive, LocalCache, LocalGrnn, LOCAL_DIM, STEP_SHARE};
    use crate::model::hose::net::Grnn;

    /// A small network whose every sample is summed at an anchor (data in a
    /// ball, a wide sigma), so that a Taylor step errs by its remainder alone:
    /// the anchor's gradient and Hessian against central differences of the
    /// direct sum, and |step - direct sum| <= E_2 (module documentation) for
    /// steps from 1e-3 z to where x_2 nears 1 (a wrong gradient or Hessian errs
    /// by O(|delta|) or O(|delta|^2), far beyond E_2 = O(|delta|^3) there).
    #[test]
    fn taylor_step_matches_direct_sum_within_its_remainder() {
        // xorshift64: a fixed stream of uniforms in [0, 1).
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut rnd = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut ball = || loop {
            let p: [f64; LOCAL_DIM] = core::array::from_fn(|_| 2.0 * rnd() - 1.0);
            if p.iter().map(|v| v * v).sum::<f64>() <= 1.0 {
                break p;
            }
        };
        let (mut x, mut y) = (Vec::new(), Vec::new());
        for _ in 0..200 {
            let p = ball();
            x.extend_from_slice(&p);
            y.push((3.0 * p[0]).sin() + 2.0 * p[1] * p[2] - 4.0 * p[3] * p[3]);
        }
        let net = Grnn::fit(&x, LOCAL_DIM, &y, 1.5).unwrap();
        let local = LocalGrnn::new(&net, 1e-3);
        let f = |u: &[f64; LOCAL_DIM]| net.predict_scaled(u);
        let at = |u: &[f64; LOCAL_DIM], d: &[f64; LOCAL_DIM], t: f64| -> [f64; LOCAL_DIM] {
            core::array::from_fn(|k| u[k] + t * d[k])
        };
        let mut checked = 0;
        for _ in 0..8 {
            let u0: [f64; LOCAL_DIM] = net.scale_input(&ball())[..LOCAL_DIM].try_into().unwrap();
            let mut cache = LocalCache::with_taylor();
            local.eval_z(&u0, &mut cache);
            assert_eq!(cache.stats().kernels, 200, "every sample summed");
            let a = cache.anchor.unwrap();
            for k in 0..LOCAL_DIM {
                let mut e = [0.0; LOCAL_DIM];
                e[k] = 1.0;
                let h = 1e-4;
                let fd = (f(&at(&u0, &e, h)) - f(&at(&u0, &e, -h))) / (2.0 * h);
                assert!(
                    (a.grad[k] - fd).abs() < 1e-6 * (1.0 + fd.abs()),
                    "grad {k}: {} vs {fd}",
                    a.grad[k]
                );
            }
            let d: [f64; LOCAL_DIM] = {
                let v = ball();
                let n = v.iter().map(|c| c * c).sum::<f64>().sqrt();
                v.map(|c| c / n)
            };
            let h = 1e-3;
            let fd2 = (f(&at(&u0, &d, h)) - 2.0 * f(&u0) + f(&at(&u0, &d, -h))) / (h * h);
            let hess = 2.0 * super::quad(&a.half_hess, &d);
            assert!(
                (hess - fd2).abs() < 1e-4 * (1.0 + fd2.abs()),
                "Hessian: {hess} vs {fd2}"
            );
            let scale = STEP_SHARE * 1e-3 * (local.y_max - local.y_min);
            let mut s = 1e-3;
            while let Some((e, _, rem)) = a.step(&at(&u0, &d, s)) {
                let err = (e.y - f(&at(&u0, &d, s))).abs();
                assert!(
                    err <= rem * scale * (1.0 + 1e-9) + 1e-12,
                    "step {s}: {err} > E_2 {}",
                    rem * scale
                );
                checked += 1;
                s *= 1.5;
            }
        }
        assert!(checked > 40, "{checked} steps checked");
    }

    /// The inline exp against the standard library's over the kernels' range.
    #[test]
    fn exp_nonpositive_matches_std() {
        let mut worst = 0.0f64;
        for i in 0..=400_000 {
            let x = -60.0 * f64::from(i) / 400_000.0;
            let (a, b) = (exp_nonpositive(x), x.exp());
            worst = worst.max(((a - b) / b).abs());
        }
        assert!(worst < 1e-15, "worst relative difference {worst:e}");
        assert_eq!(exp_nonpositive(0.0), 1.0);
    }
}
