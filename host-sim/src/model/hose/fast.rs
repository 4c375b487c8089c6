//! Fast GRNN evaluation with stated error bounds against the direct sum.
//!
//! Two evaluators:
//!
//! * [`Truncated`] (any dimension up to 4): the training samples are binned on a
//!   uniform grid in z-space; a query sums only the samples with
//!   d_i^2 <= d_r^2 + 2 sigma^2 T, where `r` is the nearest sample (the grid
//!   cells that can hold them are visited slab by slab; far beyond the data in
//!   the last input the samples are scanned in order of that input instead, `r`
//!   then being the nearest sample met). Every weight is taken relative to `r`,
//!   w_i = exp(-(d_i^2 - d_r^2) / (2 sigma^2)), so w_r = 1, the included weight
//!   D_I >= 1 and each excluded weight is < e^-T. With yhat_I the truncated ratio,
//!   yhat - yhat_I = sum_{i excluded} w_i (Y_i - yhat_I) / (D_I + D_O), hence
//!   **|yhat - yhat_I| <= N e^-T (Y_max - Y_min)** (N training samples, counted
//!   with their multiplicity if merged): a provable
//!   bound that holds everywhere, arbitrarily far outside the data.
//!   T = ln(N / eps) makes the bound eps (Y_max - Y_min).
//! * [`FastGrnn`] (two inputs, the hose map g(P, dP/dt)): inside a box around
//!   the data (the data's z-range plus a margin) a bicubic Hermite table on a
//!   grid of steps (0.3 sigma, 0.1 sigma), with nodal values and exact analytic
//!   derivatives f, f_x, f_y, f_xy (computed with [`Truncated`] at eps = 1e-10);
//!   outside the box [`Truncated`]. Its error bound [`FastGrnn::error_bound`] is
//!   the truncation bound plus twice the largest table error found at every table
//!   cell's centre when the table is built (the centre is where cubic Hermite
//!   interpolation errs most for a smooth function). The table part of the bound
//!   is therefore *checked on a dense test set*, not proven; the tests check it
//!   again on random points inside, around and far outside the data.
//!
//! The table's value is clamped to [Y_min, Y_max] (which the exact GRNN never
//! leaves), so a Newton bracket built from the training range stays valid.

use rayon::prelude::*;

use super::net::{dist2, Grnn};

/// Largest dimension of [`Truncated`].
pub const TRUNC_MAX_DIM: usize = 4;

/// Value, gradient and (two inputs) mixed second derivative of a GRNN in
/// z-space.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ZEval {
    /// yhat.
    pub y: f64,
    /// d yhat / d u_k (z-space).
    pub grad: [f64; TRUNC_MAX_DIM],
    /// d^2 yhat / (d u_0 d u_1) (only when requested).
    pub d01: f64,
    /// Samples whose weight was summed.
    pub n_summed: usize,
}

/// Truncated, grid-binned GRNN evaluation with a provable error bound
/// (module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct Truncated {
    dim: usize,
    sigma: f64,
    /// Exclusion threshold T: excluded weights are < e^-T relative to the reference.
    t: f64,
    lo: [f64; TRUNC_MAX_DIM],
    /// Largest data coordinate per dimension.
    hi: [f64; TRUNC_MAX_DIM],
    cell: f64,
    n: [usize; TRUNC_MAX_DIM],
    stride: [usize; TRUNC_MAX_DIM],
    /// Offsets of the cells' samples in `xs`/`ys` (length = cells + 1).
    start: Vec<u32>,
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// The samples ordered by descending last coordinate (for queries beyond the
    /// data in the last dimension).
    xs_desc: Vec<f64>,
    ys_desc: Vec<f64>,
    /// Sample multiplicities, in the order of `ys` and `ys_desc`, and their sum.
    ws: Vec<f64>,
    ws_desc: Vec<f64>,
    total: f64,
    /// Every `anchor_step`-th sample (cell order, so spread out) is an anchor.
    anchor_step: usize,
    y_min: f64,
    y_max: f64,
}

/// Queries at least this far (z units) beyond the data in the last dimension,
/// and mainly in that direction, scan the samples in order of that coordinate
/// instead of the grid.
const SCAN_BEYOND_Z: f64 = 1.0;

impl Truncated {
    /// Bin the training samples of `net` for evaluation with the bound
    /// `eps * (Y_max - Y_min)`. Panics if `net.dim() > 4` or `eps` is not in (0, 1).
    pub fn new(net: &Grnn, eps: f64) -> Self {
        let dim = net.dim();
        assert!(dim <= TRUNC_MAX_DIM, "Truncated supports up to 4 inputs");
        assert!(eps > 0.0 && eps < 1.0, "eps must be in (0, 1)");
        let n_s = net.len();
        let t = (net.total_count() / eps).ln().max(1.0);
        let sigma = net.sigma();
        let xn = net.scaled_inputs();
        let (lo, hi) = data_box(xn, dim);
        let grid = Grid::new(dim, lo, hi, sigma, t);
        let (start, mut xs, mut ys, mut ws) = grid.bin(xn, net.outputs(), net.counts());
        sort_cells_by_last(&start, dim, &mut xs, &mut ys, &mut ws);
        let mut order: Vec<usize> = (0..n_s).collect();
        order.sort_by(|&p, &q| xs[q * dim + dim - 1].total_cmp(&xs[p * dim + dim - 1]));
        let xs_desc: Vec<f64> = order
            .iter()
            .flat_map(|&i| xs[i * dim..(i + 1) * dim].to_vec())
            .collect();
        let ys_desc: Vec<f64> = order.iter().map(|&i| ys[i]).collect();
        let ws_desc: Vec<f64> = order.iter().map(|&i| ws[i]).collect();
        let total = ws.iter().sum();
        let (y_min, y_max) = net.output_range();
        Self {
            dim,
            sigma,
            t,
            lo,
            hi,
            cell: grid.cell,
            n: grid.n,
            stride: grid.stride,
            start,
            xs,
            ys,
            xs_desc,
            ys_desc,
            ws,
            ws_desc,
            total,
            anchor_step: (n_s / 64).max(1),
            y_min,
            y_max,
        }
    }

    /// The provable bound on |truncated - direct sum|: N e^-T (Y_max - Y_min).
    pub fn error_bound(&self) -> f64 {
        self.total * (-self.t).exp() * (self.y_max - self.y_min)
    }

    /// Input dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Evaluate at the scaled input `u` (length `dim`); `mixed` also computes the
    /// mixed second derivative d^2 yhat / (du_0 du_1) (two inputs).
    pub fn eval_z(&self, u: &[f64], mixed: bool) -> ZEval {
        let d = self.dim;
        let two_s2 = 2.0 * self.sigma * self.sigma;
        let mut acc = Acc {
            c: -1.0 / two_s2,
            mixed,
            ..Acc::default()
        };
        let last = d - 1;
        let gap_last = (self.lo[last] - u[last]).max(u[last] - self.hi[last]);
        let gap_other: f64 = (0..last)
            .map(|k| {
                let g = (self.lo[k] - u[k]).max(u[k] - self.hi[k]).max(0.0);
                g * g
            })
            .sum();
        // The scan's band in the last coordinate is about
        // (gap_other + 2 sigma^2 T) / (2 gap_last) wide: use it when that is thin.
        if gap_last >= SCAN_BEYOND_Z && gap_other <= 0.2 * gap_last {
            // Far beyond the data in the last dimension: scan the samples in order
            // of increasing |u_last - x_last|. With d_best the nearest sample so far,
            // a sample is summed if d^2 <= d_best^2 + 2 sigma^2 T, and the scan stops
            // once (u_last - x_last)^2 (a lower bound of d^2 for every later sample)
            // exceeds that: everything skipped is below e^-T of the nearest sample.
            let above = u[last] > self.hi[last];
            let n_s = self.ys_desc.len();
            acc.m = f64::INFINITY;
            acc.r2 = f64::INFINITY;
            for j in 0..n_s {
                let i = if above { j } else { n_s - 1 - j };
                let x = &self.xs_desc[i * d..(i + 1) * d];
                let dl = u[last] - x[last];
                if dl * dl > acc.r2 {
                    break;
                }
                let d2 = dist2(u, x);
                if d2 + two_s2 * self.t < acc.r2 {
                    acc.r2 = d2 + two_s2 * self.t;
                }
                acc.add(u, x, self.ys_desc[i], self.ws_desc[i]);
            }
        } else {
            // tail[k]: squared distance from u to the data's extent in the
            // dimensions after k, a lower bound that prunes whole slabs early.
            let mut tail = [0.0; TRUNC_MAX_DIM];
            for k in (0..last).rev() {
                let m = k + 1;
                let g = (self.lo[m] - u[m]).max(u[m] - self.hi[m]).max(0.0);
                tail[k] = tail[m] + g * g;
            }
            let g0 = (self.lo[0] - u[0]).max(u[0] - self.hi[0]).max(0.0);
            // Guess a squared radius r0^2 that holds the nearest sample; sum every
            // sample within r0^2 + 2 sigma^2 T. If the nearest sample found is
            // within r0^2 the sum holds every sample within d_min^2 + 2 sigma^2 T
            // (the bound's condition); otherwise retry with r0^2 = d_min^2 (or a
            // four times larger guess if nothing was found).
            let mut r0sq = self.cell * self.cell + tail[0] + g0 * g0;
            let mut anchors_tried = false;
            loop {
                acc = Acc {
                    c: -1.0 / two_s2,
                    mixed,
                    m: f64::INFINITY,
                    r2: r0sq + two_s2 * self.t,
                    tail,
                    ..Acc::default()
                };
                self.visit(u, 0, 0.0, 0, &mut acc);
                if acc.n > 0 && acc.m <= r0sq {
                    break;
                }
                r0sq = if acc.n > 0 {
                    acc.m
                } else if !anchors_tried {
                    // Nothing that near: the nearest of a spread-out subset of the
                    // samples certainly holds one.
                    anchors_tried = true;
                    (0..self.ys.len())
                        .step_by(self.anchor_step)
                        .map(|i| dist2(u, &self.xs[i * d..(i + 1) * d]))
                        .fold(f64::INFINITY, f64::min)
                } else {
                    4.0 * r0sq
                };
            }
        }
        let s0 = acc.s0;
        let y = acc.sy / s0;
        let inv_s2 = 1.0 / (self.sigma * self.sigma);
        let mut grad = [0.0; TRUNC_MAX_DIM];
        let mut ea = [0.0; TRUNC_MAX_DIM];
        for k in 0..d {
            ea[k] = acc.sa[k] / s0;
            grad[k] = -(acc.say[k] / s0 - y * ea[k]) * inv_s2;
        }
        let d01 = if mixed && d >= 2 {
            // E[(a0 - E a0)(a1 - E a1)(y - yhat)] / sigma^4.
            let e_a0a1y = acc.saby / s0;
            let e_a0a1 = acc.sab / s0;
            let e_a0y = acc.say[0] / s0;
            let e_a1y = acc.say[1] / s0;
            (e_a0a1y - ea[0] * e_a1y - ea[1] * e_a0y - y * e_a0a1 + 2.0 * y * ea[0] * ea[1])
                * inv_s2
                * inv_s2
        } else {
            0.0
        };
        ZEval {
            y,
            grad,
            d01,
            n_summed: acc.n,
        }
    }

    /// Visit the cells of dimension `k` onwards that can hold samples within the
    /// radius (slab by slab), `acc_d2` being the squared distance from `u` to the
    /// slabs fixed so far and `base` their cell offset.
    fn visit(&self, u: &[f64], k: usize, acc_d2: f64, base: usize, acc: &mut Acc) {
        let d = self.dim;
        let rem = acc.r2 - acc_d2 - acc.tail[k];
        if rem < 0.0 {
            return;
        }
        let r = rem.sqrt();
        let (lo, c) = (self.lo[k], self.cell);
        let jmax = self.n[k] as i64 - 1;
        let j0 = (((u[k] - r - lo) / c).floor() as i64).clamp(0, jmax);
        let j1 = (((u[k] + r - lo) / c).floor() as i64).clamp(0, jmax);
        if k + 1 == d {
            // The last dimension is contiguous in memory: one run of samples.
            let a = self.start[base + j0 as usize * self.stride[k]] as usize;
            let b = self.start[base + j1 as usize * self.stride[k] + 1] as usize;
            // The run is sorted by the last coordinate: keep [u - r, u + r].
            let key = |i: usize| self.xs[i * d + k];
            let (mut p, mut q) = (a, b);
            if b - a > 8 {
                p = a + partition(b - a, |m| key(a + m) < u[k] - r);
                q = p + partition(b - p, |m| key(p + m) <= u[k] + r);
            }
            for i in p..q {
                acc.add(u, &self.xs[i * d..(i + 1) * d], self.ys[i], self.ws[i]);
            }
            return;
        }
        for j in j0..=j1 {
            let s_lo = lo + j as f64 * c;
            let gap = (s_lo - u[k]).max(u[k] - (s_lo + c)).max(0.0);
            self.visit(
                u,
                k + 1,
                acc_d2 + gap * gap,
                base + j as usize * self.stride[k],
                acc,
            );
        }
    }
}

/// Smallest and largest coordinate per dimension of the row-major inputs `xn`.
fn data_box(xn: &[f64], dim: usize) -> ([f64; TRUNC_MAX_DIM], [f64; TRUNC_MAX_DIM]) {
    let mut lo = [0.0; TRUNC_MAX_DIM];
    let mut hi = [0.0; TRUNC_MAX_DIM];
    for k in 0..dim {
        lo[k] = xn
            .iter()
            .skip(k)
            .step_by(dim)
            .copied()
            .fold(f64::INFINITY, f64::min);
        hi[k] = xn
            .iter()
            .skip(k)
            .step_by(dim)
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
    }
    (lo, hi)
}

/// The uniform grid of [`Truncated`]'s cells over the data box.
struct Grid {
    dim: usize,
    lo: [f64; TRUNC_MAX_DIM],
    cell: f64,
    n: [usize; TRUNC_MAX_DIM],
    stride: [usize; TRUNC_MAX_DIM],
    n_cells: usize,
}

impl Grid {
    /// Cells of half the interior cut-off radius sigma sqrt(2 T), coarser if
    /// that would make more than ~2^22 cells (16 MB of offsets).
    fn new(
        dim: usize,
        lo: [f64; TRUNC_MAX_DIM],
        hi: [f64; TRUNC_MAX_DIM],
        sigma: f64,
        t: f64,
    ) -> Self {
        let mut cell = 0.5 * sigma * (2.0 * t).sqrt();
        let count = |c: f64| -> f64 {
            (0..dim)
                .map(|k| ((hi[k] - lo[k]) / c).floor() + 1.0)
                .product::<f64>()
        };
        while count(cell) > f64::from(1u32 << 22) {
            cell *= 1.25;
        }
        let mut n = [1usize; TRUNC_MAX_DIM];
        for k in 0..dim {
            n[k] = ((hi[k] - lo[k]) / cell).floor() as usize + 1;
        }
        let mut stride = [0usize; TRUNC_MAX_DIM];
        let mut s = 1;
        for k in (0..dim).rev() {
            stride[k] = s;
            s *= n[k];
        }
        Self {
            dim,
            lo,
            cell,
            n,
            stride,
            n_cells: s,
        }
    }

    /// The cell of the scaled input `r`.
    fn cell_of(&self, r: &[f64]) -> usize {
        (0..self.dim)
            .map(|k| {
                (((r[k] - self.lo[k]) / self.cell).floor() as usize).min(self.n[k] - 1)
                    * self.stride[k]
            })
            .sum()
    }

    /// The samples (scaled inputs `xn`, outputs `ys`, multiplicities `ws`)
    /// in cell order: the cells' offsets (one more than cells) and the
    /// reordered inputs, outputs and multiplicities.
    fn bin(&self, xn: &[f64], ys: &[f64], ws: &[f64]) -> (Vec<u32>, Vec<f64>, Vec<f64>, Vec<f64>) {
        let dim = self.dim;
        let mut counts = vec![0u32; self.n_cells + 1];
        for r in xn.chunks_exact(dim) {
            counts[self.cell_of(r) + 1] += 1;
        }
        for i in 0..self.n_cells {
            counts[i + 1] += counts[i];
        }
        let start = counts.clone();
        let mut fill = counts;
        let mut xs = vec![0.0; xn.len()];
        let mut out_y = vec![0.0; ys.len()];
        let mut out_w = vec![0.0; ys.len()];
        for ((r, &y), &w) in xn.chunks_exact(dim).zip(ys).zip(ws) {
            let c = self.cell_of(r);
            let j = fill[c] as usize;
            fill[c] += 1;
            xs[j * dim..(j + 1) * dim].copy_from_slice(r);
            out_y[j] = y;
            out_w[j] = w;
        }
        (start, xs, out_y, out_w)
    }
}

/// Within each cell (offsets `start`), order the samples by their last
/// coordinate: a run of cells along the last dimension is then sorted by it
/// as a whole, and [`Truncated::visit`] can cut it to the slab it needs by
/// bisection.
fn sort_cells_by_last(start: &[u32], dim: usize, xs: &mut [f64], ys: &mut [f64], ws: &mut [f64]) {
    for c in 0..start.len() - 1 {
        let (a, b) = (start[c] as usize, start[c + 1] as usize);
        if b - a > 1 {
            let mut order: Vec<usize> = (a..b).collect();
            order.sort_by(|&p, &q| xs[p * dim + dim - 1].total_cmp(&xs[q * dim + dim - 1]));
            let cx: Vec<f64> = order
                .iter()
                .flat_map(|&i| xs[i * dim..(i + 1) * dim].to_vec())
                .collect();
            let cy: Vec<f64> = order.iter().map(|&i| ys[i]).collect();
            let cw: Vec<f64> = order.iter().map(|&i| ws[i]).collect();
            xs[a * dim..b * dim].copy_from_slice(&cx);
            ys[a..b].copy_from_slice(&cy);
            ws[a..b].copy_from_slice(&cw);
        }
    }
}

/// Number of leading indices in 0..n for which `pred` holds (`pred` must be
/// true on a prefix and false after it).
#[inline]
fn partition(n: usize, pred: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0, n);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if pred(mid) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Running sums of a truncated evaluation.
#[derive(Default)]
struct Acc {
    c: f64,
    /// Squared distance the weights are relative to (starts at the reference's).
    m: f64,
    r2: f64,
    mixed: bool,
    s0: f64,
    sy: f64,
    sa: [f64; TRUNC_MAX_DIM],
    say: [f64; TRUNC_MAX_DIM],
    sab: f64,
    saby: f64,
    n: usize,
    tail: [f64; TRUNC_MAX_DIM],
}

impl Acc {
    #[inline]
    fn add(&mut self, u: &[f64], x: &[f64], y: f64, count: f64) {
        let d2 = dist2(u, x);
        if d2 > self.r2 {
            return;
        }
        if d2 < self.m {
            // Re-reference the sums to the nearer sample (no overflow far away,
            // where the reference need not be the nearest sample).
            let f = (self.c * (self.m - d2)).exp();
            self.s0 *= f;
            self.sy *= f;
            for k in 0..u.len() {
                self.sa[k] *= f;
                self.say[k] *= f;
            }
            self.sab *= f;
            self.saby *= f;
            self.m = d2;
        }
        let w = count * (self.c * (d2 - self.m)).exp();
        self.n += 1;
        self.s0 += w;
        self.sy += w * y;
        for k in 0..u.len() {
            let a = w * (u[k] - x[k]);
            self.sa[k] += a;
            self.say[k] += a * y;
        }
        if self.mixed {
            let ab = w * (u[0] - x[0]) * (u[1] - x[1]);
            self.sab += ab;
            self.saby += ab * y;
        }
    }
}

/// Options of [`FastGrnn`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FastOptions {
    /// Table step per input in units of sigma (z-space). The second input
    /// (dP/dt) needs the finer step: between the data's dP/dt levels the GRNN
    /// switches from one level to the next over ~sigma^2 / spacing.
    pub step_sigmas: [f64; 2],
    /// Table margin beyond the data's z-range, per input (z units).
    pub margin_z: [f64; 2],
    /// Relative truncation bound eps of the evaluator outside the table.
    pub trunc_eps: f64,
}

impl Default for FastOptions {
    fn default() -> Self {
        Self {
            step_sigmas: [0.15, 0.1],
            margin_z: [1.0, 2.0],
            trunc_eps: 1e-6,
        }
    }
}

/// Fast evaluation of a two-input GRNN: Hermite table near the data, truncated
/// sum elsewhere (module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct FastGrnn {
    mean: [f64; 2],
    inv_std: [f64; 2],
    sigma: f64,
    y_min: f64,
    y_max: f64,
    trunc: Truncated,
    /// Table origin (z), step (z) and node counts.
    t_lo: [f64; 2],
    h: [f64; 2],
    inv_h: [f64; 2],
    t_n: [usize; 2],
    /// Per node: [f, h0 f_x, h1 f_y, h0 h1 f_xy].
    nodes: Vec<[f64; 4]>,
    table_bound: f64,
}

impl FastGrnn {
    /// Build with the default options. Panics unless `net` has two inputs.
    pub fn new(net: &Grnn) -> Self {
        Self::with_options(net, FastOptions::default())
    }

    /// Build with the given options. Panics unless `net` has two inputs.
    pub fn with_options(net: &Grnn, o: FastOptions) -> Self {
        assert_eq!(net.dim(), 2, "FastGrnn is for two-input networks");
        let sc = net.scaler();
        let sigma = net.sigma();
        let fine = Truncated::new(net, 1e-10);
        let xn = net.scaled_inputs();
        let h = [o.step_sigmas[0] * sigma, o.step_sigmas[1] * sigma];
        let mut t_lo = [0.0; 2];
        let mut t_n = [0usize; 2];
        for k in 0..2 {
            let lo = xn
                .iter()
                .skip(k)
                .step_by(2)
                .copied()
                .fold(f64::INFINITY, f64::min);
            let hi = xn
                .iter()
                .skip(k)
                .step_by(2)
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            t_lo[k] = lo - o.margin_z[k];
            t_n[k] = ((hi + o.margin_z[k] - t_lo[k]) / h[k]).ceil() as usize + 1;
        }
        let nodes: Vec<[f64; 4]> = (0..t_n[0] * t_n[1])
            .into_par_iter()
            .map(|i| {
                let u = [
                    t_lo[0] + (i / t_n[1]) as f64 * h[0],
                    t_lo[1] + (i % t_n[1]) as f64 * h[1],
                ];
                let e = fine.eval_z(&u, true);
                [e.y, h[0] * e.grad[0], h[1] * e.grad[1], h[0] * h[1] * e.d01]
            })
            .collect();
        let (y_min, y_max) = net.output_range();
        let mut f = Self {
            mean: [sc.mean[0], sc.mean[1]],
            inv_std: [1.0 / sc.std[0], 1.0 / sc.std[1]],
            sigma,
            y_min,
            y_max,
            trunc: Truncated::new(net, o.trunc_eps),
            t_lo,
            h,
            inv_h: [1.0 / h[0], 1.0 / h[1]],
            t_n,
            nodes,
            table_bound: 0.0,
        };
        // Largest table error at the cell centres (against the fine evaluator,
        // itself within 1e-10 of the range of the direct sum).
        let worst = (0..(t_n[0] - 1) * (t_n[1] - 1))
            .into_par_iter()
            .map(|c| {
                let u = [
                    t_lo[0] + ((c / (t_n[1] - 1)) as f64 + 0.5) * h[0],
                    t_lo[1] + ((c % (t_n[1] - 1)) as f64 + 0.5) * h[1],
                ];
                let (v, _) = f.table_z(u).expect("centre is inside");
                (v - fine.eval_z(&u, false).y).abs()
            })
            .reduce(|| 0.0, f64::max);
        f.table_bound = 2.0 * worst + fine.error_bound();
        f
    }

    /// Spread sigma of the underlying network.
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Smallest and largest training output.
    pub fn output_range(&self) -> (f64, f64) {
        (self.y_min, self.y_max)
    }

    /// Bound on |fast - direct sum| for the value (module documentation): the
    /// truncation bound (provable) plus the table bound (checked on the cell
    /// centres when the table was built, with a factor 2).
    pub fn error_bound(&self) -> f64 {
        self.table_bound.max(self.trunc.error_bound())
    }

    /// Number of table nodes.
    pub fn table_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// The table's box in original units: ([x0 lo, x0 hi], [x1 lo, x1 hi]).
    pub fn table_box(&self) -> [[f64; 2]; 2] {
        core::array::from_fn(|k| {
            let lo = self.t_lo[k];
            let hi = lo + (self.t_n[k] - 1) as f64 * self.h[k];
            [
                self.mean[k] + lo / self.inv_std[k],
                self.mean[k] + hi / self.inv_std[k],
            ]
        })
    }

    /// Table value and z-gradient at `u`, `None` outside the table.
    #[inline]
    fn table_z(&self, u: [f64; 2]) -> Option<(f64, [f64; 2])> {
        let fx = (u[0] - self.t_lo[0]) * self.inv_h[0];
        let fy = (u[1] - self.t_lo[1]) * self.inv_h[1];
        let (n0, n1) = (self.t_n[0], self.t_n[1]);
        // Written so that NaN falls through to the outside branch.
        if !(fx >= 0.0 && fy >= 0.0 && fx <= (n0 - 1) as f64 && fy <= (n1 - 1) as f64) {
            return None;
        }
        let i = (fx as usize).min(n0 - 2);
        let j = (fy as usize).min(n1 - 2);
        let (t, s) = (fx - i as f64, fy - j as f64);
        let (p, q, dp, dq) = hermite(t);
        let (ps, qs, dps, dqs) = hermite(s);
        let mut v = 0.0;
        let mut gx = 0.0;
        let mut gy = 0.0;
        for (a, (pa, qa, dpa, dqa)) in [
            (0, (p[0], q[0], dp[0], dq[0])),
            (1, (p[1], q[1], dp[1], dq[1])),
        ] {
            for (b, (pb, qb, dpb, dqb)) in [
                (0, (ps[0], qs[0], dps[0], dqs[0])),
                (1, (ps[1], qs[1], dps[1], dqs[1])),
            ] {
                let nd = &self.nodes[(i + a) * n1 + j + b];
                v += nd[0] * pa * pb + nd[1] * qa * pb + nd[2] * pa * qb + nd[3] * qa * qb;
                gx += nd[0] * dpa * pb + nd[1] * dqa * pb + nd[2] * dpa * qb + nd[3] * dqa * qb;
                gy += nd[0] * pa * dpb + nd[1] * qa * dpb + nd[2] * pa * dqb + nd[3] * qa * dqb;
            }
        }
        Some((v, [gx * self.inv_h[0], gy * self.inv_h[1]]))
    }

    /// Value and gradient (with respect to the original inputs) at `x`.
    #[inline]
    pub fn eval(&self, x: [f64; 2]) -> (f64, [f64; 2]) {
        let u = [
            (x[0] - self.mean[0]) * self.inv_std[0],
            (x[1] - self.mean[1]) * self.inv_std[1],
        ];
        let (v, g) = match self.table_z(u) {
            Some((v, g)) => {
                if v > self.y_max {
                    (self.y_max, [0.0; 2])
                } else if v < self.y_min {
                    (self.y_min, [0.0; 2])
                } else {
                    (v, g)
                }
            }
            None => {
                let e = self.trunc.eval_z(&u, false);
                (e.y, [e.grad[0], e.grad[1]])
            }
        };
        (v, [g[0] * self.inv_std[0], g[1] * self.inv_std[1]])
    }

    /// Value at `x`.
    #[inline]
    pub fn predict(&self, x: [f64; 2]) -> f64 {
        self.eval(x).0
    }
}

/// Cubic Hermite basis at t in [0, 1]: value weights (p0, p1), slope weights
/// (q0, q1) and their derivatives with respect to t.
#[inline]
fn hermite(t: f64) -> ([f64; 2], [f64; 2], [f64; 2], [f64; 2]) {
    let t2 = t * t;
    let t3 = t2 * t;
    (
        [2.0 * t3 - 3.0 * t2 + 1.0, -2.0 * t3 + 3.0 * t2],
        [t3 - 2.0 * t2 + t, t3 - t2],
        [6.0 * t2 - 6.0 * t, -6.0 * t2 + 6.0 * t],
        [3.0 * t2 - 4.0 * t + 1.0, 3.0 * t2 - 2.0 * t],
    )
}
