//! Evaluation of the memory GRNN in the integrator from a cached local list of
//! training samples, within a provable bound of the direct sum.
//!
//! In a simulation the hose's query u (z-scored [P, dP/dt, P - P_f1, P - P_f2])
//! moves very little from one evaluation to the next (Newton iterations, RK
//! stages, steps of 2e-4 s). [`LocalCache`] keeps the training samples within a
//! radius R of a centre c, in the order of the training set. A query u within
//! distance delta < R of c is served from the list when
//!
//!   d_r^2 + 2 sigma^2 T <= (R - delta)^2,   d_r = distance to the nearest sample in the list,
//!
//! because every sample outside the list is farther than R - delta from u: the
//! nearest sample is in the list, and so is every sample with
//! d_i^2 <= d_r^2 + 2 sigma^2 T. Otherwise the list is rebuilt around u (one pass
//! over the training set) with R = sqrt(d_r^2 + 2 sigma^2 T) + [`LIST_MARGIN_Z`].
//!
//! **What is summed** depends only on u, never on the cache: with weights relative
//! to the nearest sample, w_i = n_i exp(-(d_i^2 - d_r^2) / (2 sigma^2)) (n_i the
//! sample's multiplicity, >= 1), the samples of the shells
//! d_i^2 - d_r^2 <= 2 sigma^2 t_l for t_l in [`SHELLS`] and finally t = T are
//! summed in training-set order, shell after shell, stopping after shell l as soon
//! as C_l e^-t_l <= (eps / 2) D_I, where D_I is the weight summed so far and C_l
//! the multiplicity of the samples between shell l and T (counted without an
//! exp). A run is therefore bit-identical whatever the cache's history (a fresh
//! cache, another plant's cache, another thread).
//!
//! **Bound.** Let I be the summed samples, O the others. Each sample of O inside T
//! weighs at most its multiplicity times e^-t_l, so these weigh at most
//! C_l e^-t_l <= (eps / 2) D_I; those beyond T weigh less than N e^-T in all
//! (N the total multiplicity), with T = ln(2 N / eps) that is eps / 2 <= (eps / 2)
//! D_I (D_I >= 1: the nearest sample weighs its multiplicity). With yhat_I the
//! ratio over I, yhat - yhat_I = sum_O w_i (Y_i - yhat_I) / (D_I + D_O), so
//!
//!   **|yhat - yhat_I| <= eps (Y_max - Y_min)**,
//!
//! everywhere, however far from the data. Only `f64::exp` is used (no
//! approximation). The slope d yhat / d u_1 (dP/dt, Newton's) is that of the summed
//! ratio.

use super::net::Grnn;

/// Input dimension of [`LocalGrnn`] (the memory GRNN's).
pub const LOCAL_DIM: usize = 4;

/// The list holds the samples within this distance (z units) beyond the radius
/// a query needs: a query may move this far before the list is rebuilt.
pub const LIST_MARGIN_Z: f64 = 0.1;

/// Intermediate shells t_l (units of 2 sigma^2 in squared distance beyond the
/// nearest sample) at which the sum may stop (module documentation).
pub const SHELLS: [f64; 2] = [10.0, 13.0];

/// The memory GRNN's training samples laid out for [`LocalGrnn::eval_z`].
#[derive(Clone, Debug, PartialEq)]
pub struct LocalGrnn {
    sigma: f64,
    /// -1 / (2 sigma^2).
    k: f64,
    eps: f64,
    /// 2 sigma^2 T.
    s2t: f64,
    /// 2 sigma^2 t_l per shell, then 2 sigma^2 T.
    shells: Vec<f64>,
    /// e^-t_l per shell.
    shell_weight: Vec<f64>,
    /// Scaled inputs, one column per input (training-set order).
    x: [Vec<f64>; LOCAL_DIM],
    y: Vec<f64>,
    n: Vec<f64>,
    total: f64,
    y_min: f64,
    y_max: f64,
}

/// The cached list of one query stream (one hose line) and work counters.
#[derive(Clone, Debug, Default)]
pub struct LocalCache {
    valid: bool,
    centre: [f64; LOCAL_DIM],
    radius: f64,
    x: [Vec<f64>; LOCAL_DIM],
    y: Vec<f64>,
    n: Vec<f64>,
    d2: Vec<f64>,
    /// Scratch of the rebuild: squared distances to every training sample.
    all_d2: Vec<f64>,
    stats: LocalStats,
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
    /// Rebuilds of the list (one pass over the training set each).
    pub rebuilds: u64,
}

impl LocalCache {
    /// An empty cache (the first evaluation builds the list).
    pub fn new() -> Self {
        Self::default()
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
        let t = (2.0 * total / (eps * n_min.min(1.0))).ln().max(1.0);
        let mut shells: Vec<f64> = SHELLS
            .iter()
            .filter(|&&s| s < t)
            .map(|&s| two_s2 * s)
            .collect();
        let shell_weight = SHELLS
            .iter()
            .filter(|&&s| s < t)
            .map(|&s| (-s).exp())
            .collect();
        shells.push(two_s2 * t);
        let xn = net.scaled_inputs();
        let (y_min, y_max) = net.output_range();
        Self {
            sigma,
            k: -1.0 / two_s2,
            eps,
            s2t: two_s2 * t,
            shells,
            shell_weight,
            x: core::array::from_fn(|k| xn.iter().skip(k).step_by(LOCAL_DIM).copied().collect()),
            y: net.outputs().to_vec(),
            n: net.counts().to_vec(),
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
    /// documentation; the result does not depend on the cache's state). A
    /// non-finite input gives a NaN value.
    pub fn eval_z(&self, u: &[f64; LOCAL_DIM], cache: &mut LocalCache) -> LocalEval {
        if !u.iter().all(|v| v.is_finite()) {
            return LocalEval {
                y: f64::NAN,
                dy_du1: 0.0,
            };
        }
        cache.stats.evals += 1;
        if cache.valid {
            let dc2: f64 = (0..LOCAL_DIM)
                .map(|k| (u[k] - cache.centre[k]).powi(2))
                .sum();
            let dc = dc2.sqrt();
            if dc < cache.radius {
                let m = list_distances(u, cache);
                let reach = cache.radius - dc;
                // A relative 1e-12 of slack for the rounding of the distances.
                if m + self.s2t <= reach * reach * (1.0 - 1e-12) {
                    return self.sum(u, m, cache);
                }
            }
        }
        self.rebuild(u, cache);
        let m = list_distances(u, cache);
        self.sum(u, m, cache)
    }

    /// Rebuild the list around `u`: every sample within sqrt(d_r^2 + 2 sigma^2 T)
    /// + [`LIST_MARGIN_Z`], in training-set order.
    fn rebuild(&self, u: &[f64; LOCAL_DIM], c: &mut LocalCache) {
        c.stats.rebuilds += 1;
        let n = self.y.len();
        c.all_d2.resize(n, 0.0);
        let [x0, x1, x2, x3] = &self.x;
        let mut m = f64::INFINITY;
        for (i, d2) in c.all_d2.iter_mut().enumerate() {
            let (a, b, e, f) = (u[0] - x0[i], u[1] - x1[i], u[2] - x2[i], u[3] - x3[i]);
            *d2 = a * a + b * b + e * e + f * f;
            if *d2 < m {
                m = *d2;
            }
        }
        let r = (m + self.s2t).sqrt() + LIST_MARGIN_Z;
        let r2 = r * r;
        for col in &mut c.x {
            col.clear();
        }
        c.y.clear();
        c.n.clear();
        for (i, &d2) in c.all_d2.iter().enumerate() {
            if d2 <= r2 {
                for k in 0..LOCAL_DIM {
                    c.x[k].push(self.x[k][i]);
                }
                c.y.push(self.y[i]);
                c.n.push(self.n[i]);
            }
        }
        c.d2.resize(c.y.len(), 0.0);
        c.centre = *u;
        c.radius = r;
        c.valid = true;
    }

    /// The shell-by-shell sum over the list (module documentation), `m` being
    /// the squared distance to the nearest sample and `c.d2` the list's squared
    /// distances.
    fn sum(&self, u: &[f64; LOCAL_DIM], m: f64, c: &mut LocalCache) -> LocalEval {
        let len = c.y.len();
        let (d2, x1, ys, ns) = (&c.d2[..len], &c.x[1][..len], &c.y[..len], &c.n[..len]);
        let (mut s0, mut sy, mut sa, mut say) = (0.0, 0.0, 0.0, 0.0);
        let mut lower = f64::NEG_INFINITY;
        let last = self.shells.len() - 1;
        let mut kernels = 0u64;
        for (l, &shell) in self.shells.iter().enumerate() {
            let cut = m + shell;
            for j in 0..len {
                let dj = d2[j];
                if dj > lower && dj <= cut {
                    let w = ns[j] * (self.k * (dj - m)).exp();
                    let a = w * (u[1] - x1[j]);
                    s0 += w;
                    sy += w * ys[j];
                    sa += a;
                    say += a * ys[j];
                    kernels += 1;
                }
            }
            if l == last {
                break;
            }
            let outer = m + self.shells[last];
            let rest: f64 = (0..len)
                .filter(|&j| d2[j] > cut && d2[j] <= outer)
                .map(|j| ns[j])
                .sum();
            if rest * self.shell_weight[l] <= 0.5 * self.eps * s0 {
                break;
            }
            lower = cut;
        }
        c.stats.kernels += kernels;
        let y = sy / s0;
        LocalEval {
            y,
            dy_du1: -(say / s0 - y * sa / s0) / (self.sigma * self.sigma),
        }
    }

    /// Number of samples of the total multiplicity N of the bound.
    pub fn total_count(&self) -> f64 {
        self.total
    }
}

/// Squared distances from `u` to the list's samples (into `c.d2`) and their
/// minimum.
#[inline]
fn list_distances(u: &[f64; LOCAL_DIM], c: &mut LocalCache) -> f64 {
    let len = c.y.len();
    c.stats.distances += len as u64;
    let [x0, x1, x2, x3] = &c.x;
    let (x0, x1, x2, x3) = (&x0[..len], &x1[..len], &x2[..len], &x3[..len]);
    let mut m = f64::INFINITY;
    for (j, d2) in c.d2[..len].iter_mut().enumerate() {
        let (a, b, e, f) = (u[0] - x0[j], u[1] - x1[j], u[2] - x2[j], u[3] - x3[j]);
        *d2 = a * a + b * b + e * e + f * f;
        if *d2 < m {
            m = *d2;
        }
    }
    m
}
