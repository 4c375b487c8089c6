//! The generalised regression neural network of the paper's eq. 19-24 with
//! z-score input scaling (docs/model.md section 9), its accuracy measures (eq. 26 as
//! reconstructed) and k-fold cross-validation of the spread sigma.
//!
//! yhat(x) = sum_i Y_i exp(-|xn - xn_i|^2 / (2 sigma^2)) / sum_i exp(...),
//! xn = (x - mean) / std with the mean and (population) standard deviation of the
//! training inputs. [`Grnn::predict`] is the direct ("naive") sum: one `exp` per
//! training sample per call. It is evaluated relative to the nearest training
//! sample (every weight is multiplied by exp(+d_min^2 / (2 sigma^2)), which
//! cancels in the ratio), so it stays finite arbitrarily far from the data,
//! where the textbook form underflows to 0/0.

use rayon::prelude::*;

use super::split::{k_folds, Shuffle};

/// Why a network could not be fitted.
#[derive(Clone, Debug, PartialEq)]
pub enum FitError {
    /// No training samples.
    Empty,
    /// Input rows and outputs disagree in number, or the input length is not a
    /// multiple of the dimension.
    Shape(String),
    /// A training input or output is not finite.
    NotFinite,
    /// An input column is constant (z-score undefined).
    ConstantInput(usize),
    /// The spread (or another hyper-parameter) is not positive and finite.
    BadParameter(String),
}

impl std::fmt::Display for FitError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Empty => write!(f, "no training samples"),
            Self::Shape(s) => write!(f, "shape mismatch: {s}"),
            Self::NotFinite => write!(f, "training data contain a non-finite value"),
            Self::ConstantInput(i) => write!(f, "input column {i} is constant"),
            Self::BadParameter(s) => write!(f, "bad parameter: {s}"),
        }
    }
}

impl std::error::Error for FitError {}

/// Per-input affine scaling xn = (x - mean) / std.
#[derive(Clone, Debug, PartialEq)]
pub struct ZScore {
    /// Mean of each input column.
    pub mean: Vec<f64>,
    /// Population standard deviation of each input column.
    pub std: Vec<f64>,
}

impl ZScore {
    /// Fit to row-major inputs of dimension `dim`.
    pub fn fit(x: &[f64], dim: usize) -> Result<Self, FitError> {
        let n = x.len() / dim;
        if n == 0 {
            return Err(FitError::Empty);
        }
        let mut mean = vec![0.0; dim];
        for r in x.chunks_exact(dim) {
            for (m, v) in mean.iter_mut().zip(r) {
                *m += v;
            }
        }
        mean.iter_mut().for_each(|m| *m /= n as f64);
        let mut var = vec![0.0; dim];
        for r in x.chunks_exact(dim) {
            for k in 0..dim {
                var[k] += (r[k] - mean[k]) * (r[k] - mean[k]);
            }
        }
        let std: Vec<f64> = var.iter().map(|v| (v / n as f64).sqrt()).collect();
        if let Some(k) = std.iter().position(|s| s.is_nan() || *s <= 0.0) {
            return Err(FitError::ConstantInput(k));
        }
        Ok(Self { mean, std })
    }

    /// Scale one input row into `out`.
    #[inline]
    pub fn apply(&self, x: &[f64], out: &mut [f64]) {
        for k in 0..x.len() {
            out[k] = (x[k] - self.mean[k]) / self.std[k];
        }
    }
}

/// A fitted GRNN.
#[derive(Clone, Debug, PartialEq)]
pub struct Grnn {
    dim: usize,
    sigma: f64,
    scale: ZScore,
    /// Scaled training inputs, row-major.
    xn: Vec<f64>,
    /// Training outputs.
    y: Vec<f64>,
    /// Multiplicity of each training sample (1 unless samples were merged, see
    /// [`Grnn::fit_merged`]).
    counts: Vec<f64>,
    y_min: f64,
    y_max: f64,
}

/// Largest input dimension supported (the memory hose uses 4).
pub const MAX_DIM: usize = 8;

impl Grnn {
    /// Fit to row-major inputs `x` (n rows of `dim` values) and outputs `y` with the
    /// spread `sigma` (in z-score units).
    pub fn fit(x: &[f64], dim: usize, y: &[f64], sigma: f64) -> Result<Self, FitError> {
        if dim == 0 || dim > MAX_DIM || !x.len().is_multiple_of(dim) || x.len() / dim != y.len() {
            return Err(FitError::Shape(format!(
                "{} input values of dimension {dim} for {} outputs",
                x.len(),
                y.len()
            )));
        }
        if y.is_empty() {
            return Err(FitError::Empty);
        }
        if !(sigma > 0.0 && sigma.is_finite()) {
            return Err(FitError::BadParameter(format!("sigma = {sigma}")));
        }
        if x.iter().chain(y).any(|v| !v.is_finite()) {
            return Err(FitError::NotFinite);
        }
        let scale = ZScore::fit(x, dim)?;
        let mut xn = vec![0.0; x.len()];
        for (r, o) in x.chunks_exact(dim).zip(xn.chunks_exact_mut(dim)) {
            scale.apply(r, o);
        }
        let y_min = y.iter().copied().fold(f64::INFINITY, f64::min);
        let y_max = y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Ok(Self {
            dim,
            sigma,
            scale,
            xn,
            y: y.to_vec(),
            counts: vec![1.0; y.len()],
            y_min,
            y_max,
        })
    }

    /// Fit like [`Grnn::fit`] (same z-score, from all samples), then merge runs of
    /// consecutive samples that stay within `delta` (z units) of the run's first
    /// sample into one sample at their mean input with their mean output and
    /// their count as multiplicity: yhat = sum n_j Y_j K_j / sum n_j K_j. For
    /// densely sampled time series (1 kHz) this removes near-duplicates: with
    /// delta << sigma the first-order kernel changes cancel about the mean, and
    /// the relative weight change is of order (delta / sigma)^2.
    pub fn fit_merged(
        x: &[f64],
        dim: usize,
        y: &[f64],
        sigma: f64,
        delta: f64,
    ) -> Result<Self, FitError> {
        let full = Self::fit(x, dim, y, sigma)?;
        if delta.is_nan() || delta < 0.0 {
            return Err(FitError::BadParameter(format!("delta = {delta}")));
        }
        let (mut xn, mut ys, mut counts) = (Vec::new(), Vec::new(), Vec::new());
        let mut first: Vec<f64> = Vec::new();
        let mut sum_x = vec![0.0; dim];
        let (mut sum_y, mut n) = (0.0, 0.0);
        let flush = |sum_x: &mut Vec<f64>,
                     sum_y: &mut f64,
                     n: &mut f64,
                     xn: &mut Vec<f64>,
                     ys: &mut Vec<f64>,
                     counts: &mut Vec<f64>| {
            if *n > 0.0 {
                xn.extend(sum_x.iter().map(|v| v / *n));
                ys.push(*sum_y / *n);
                counts.push(*n);
            }
            sum_x.iter_mut().for_each(|v| *v = 0.0);
            *sum_y = 0.0;
            *n = 0.0;
        };
        for (r, &yv) in full.xn.chunks_exact(dim).zip(y) {
            if n == 0.0 || dist2(r, &first) > delta * delta {
                flush(
                    &mut sum_x,
                    &mut sum_y,
                    &mut n,
                    &mut xn,
                    &mut ys,
                    &mut counts,
                );
                first = r.to_vec();
            }
            for (s, v) in sum_x.iter_mut().zip(r) {
                *s += v;
            }
            sum_y += yv;
            n += 1.0;
        }
        flush(
            &mut sum_x,
            &mut sum_y,
            &mut n,
            &mut xn,
            &mut ys,
            &mut counts,
        );
        let y_min = ys.iter().copied().fold(f64::INFINITY, f64::min);
        let y_max = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Ok(Self {
            xn,
            y: ys,
            counts,
            y_min,
            y_max,
            ..full
        })
    }

    /// Fit a two-input network (rows [x0, x1]).
    pub fn fit2(x: &[[f64; 2]], y: &[f64], sigma: f64) -> Result<Self, FitError> {
        let flat: Vec<f64> = x.iter().flatten().copied().collect();
        Self::fit(&flat, 2, y, sigma)
    }

    /// The same network with another spread.
    pub fn with_sigma(&self, sigma: f64) -> Result<Self, FitError> {
        if !(sigma > 0.0 && sigma.is_finite()) {
            return Err(FitError::BadParameter(format!("sigma = {sigma}")));
        }
        Ok(Self {
            sigma,
            ..self.clone()
        })
    }

    /// Input dimension.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Spread sigma (z-score units).
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// Number of training samples.
    pub fn len(&self) -> usize {
        self.y.len()
    }

    /// Always false for a fitted network.
    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }

    /// The input scaling.
    pub fn scaler(&self) -> &ZScore {
        &self.scale
    }

    /// Scaled training inputs (row-major, `dim` per row).
    pub fn scaled_inputs(&self) -> &[f64] {
        &self.xn
    }

    /// Training outputs.
    pub fn outputs(&self) -> &[f64] {
        &self.y
    }

    /// Multiplicity of each training sample (all 1 unless merged).
    pub fn counts(&self) -> &[f64] {
        &self.counts
    }

    /// Sum of the multiplicities (the number of original samples).
    pub fn total_count(&self) -> f64 {
        self.counts.iter().sum()
    }

    /// Smallest and largest training output: every prediction lies in this range
    /// (it is a convex combination of the training outputs).
    pub fn output_range(&self) -> (f64, f64) {
        (self.y_min, self.y_max)
    }

    /// Scale an input row (length `dim`) into z-score units.
    pub fn scale_input(&self, x: &[f64]) -> [f64; MAX_DIM] {
        let mut u = [0.0; MAX_DIM];
        self.scale.apply(x, &mut u[..self.dim]);
        u
    }

    /// Prediction at `x` (length `dim`, original units): the direct sum over all
    /// training samples.
    pub fn predict(&self, x: &[f64]) -> f64 {
        let u = self.scale_input(x);
        self.predict_scaled(&u[..self.dim])
    }

    /// Prediction at the scaled input `u` (direct sum, one `exp` per sample).
    pub fn predict_scaled(&self, u: &[f64]) -> f64 {
        let c = -0.5 / (self.sigma * self.sigma);
        let (mut m, mut s0, mut sy) = (f64::INFINITY, 0.0, 0.0);
        for ((r, &y), &cnt) in self
            .xn
            .chunks_exact(self.dim)
            .zip(&self.y)
            .zip(&self.counts)
        {
            let d2 = dist2(u, r);
            if d2 < m {
                // Re-reference the sums to the new nearest sample.
                let f = if m.is_finite() {
                    (c * (m - d2)).exp()
                } else {
                    0.0
                };
                s0 *= f;
                sy *= f;
                m = d2;
            }
            let w = cnt * (c * (d2 - m)).exp();
            s0 += w;
            sy += w * y;
        }
        sy / s0
    }

    /// Prediction and its gradient with respect to the original (unscaled) inputs
    /// at `x` (direct sum). `grad` must have length `dim`.
    pub fn predict_with_gradient(&self, x: &[f64], grad: &mut [f64]) -> f64 {
        let d = self.dim;
        let u = self.scale_input(x);
        let u = &u[..d];
        let c = -0.5 / (self.sigma * self.sigma);
        let (mut m, mut s0, mut sy) = (f64::INFINITY, 0.0, 0.0);
        let mut sa = [0.0; MAX_DIM];
        let mut say = [0.0; MAX_DIM];
        for ((r, &y), &cnt) in self.xn.chunks_exact(d).zip(&self.y).zip(&self.counts) {
            let d2 = dist2(u, r);
            if d2 < m {
                let f = if m.is_finite() {
                    (c * (m - d2)).exp()
                } else {
                    0.0
                };
                s0 *= f;
                sy *= f;
                for k in 0..d {
                    sa[k] *= f;
                    say[k] *= f;
                }
                m = d2;
            }
            let w = cnt * (c * (d2 - m)).exp();
            s0 += w;
            sy += w * y;
            for k in 0..d {
                let a = w * (u[k] - r[k]);
                sa[k] += a;
                say[k] += a * y;
            }
        }
        let yhat = sy / s0;
        let inv_s2 = 1.0 / (self.sigma * self.sigma);
        for k in 0..d {
            // d yhat / d u_k = -(E[a_k y] - yhat E[a_k]) / sigma^2; chain rule to x_k.
            grad[k] = -(say[k] - yhat * sa[k]) / s0 * inv_s2 / self.scale.std[k];
        }
        yhat
    }

    /// Predictions at many row-major inputs (direct sums, in parallel).
    pub fn predict_many(&self, x: &[f64]) -> Vec<f64> {
        x.par_chunks_exact(self.dim)
            .map(|r| self.predict(r))
            .collect()
    }
}

/// Squared Euclidean distance.
#[inline]
pub(crate) fn dist2(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(p, q)| (p - q) * (p - q)).sum()
}

/// Accuracy of a prediction against the truth (docs/model.md section 9).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Scores {
    /// VAcc, relative: mean over samples of (1 - |VT - VP| / |VT|) * 100 %, skipping
    /// |VT| < 5 % of max |VT|.
    pub vacc_rel_pct: f64,
    /// VAcc, mean-normalised: (1 - sum |VT - VP| / sum |VT|) * 100 %.
    pub vacc_mean_pct: f64,
    /// Root-mean-square error, in the unit of the output.
    pub rmse: f64,
}

/// VAcc (relative, eq. 26 as reconstructed): mean of (1 - |VT - VP| / |VT|) * 100 %
/// over the samples with |VT| >= 5 % of max |VT|. NaN if `truth` is empty or all 0.
pub fn vacc_relative_pct(truth: &[f64], pred: &[f64]) -> f64 {
    let max = truth.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (mut s, mut n) = (0.0, 0usize);
    for (t, p) in truth.iter().zip(pred) {
        if t.abs() >= 0.05 * max && *t != 0.0 {
            s += 1.0 - (t - p).abs() / t.abs();
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        100.0 * s / n as f64
    }
}

/// VAcc, mean-normalised: (1 - sum |VT - VP| / sum |VT|) * 100 %.
pub fn vacc_mean_normalised_pct(truth: &[f64], pred: &[f64]) -> f64 {
    let (mut e, mut a) = (0.0, 0.0);
    for (t, p) in truth.iter().zip(pred) {
        e += (t - p).abs();
        a += t.abs();
    }
    100.0 * (1.0 - e / a)
}

/// Root-mean-square error.
pub fn rmse(truth: &[f64], pred: &[f64]) -> f64 {
    let s: f64 = truth.iter().zip(pred).map(|(t, p)| (t - p) * (t - p)).sum();
    (s / truth.len() as f64).sqrt()
}

/// All three scores.
pub fn score(truth: &[f64], pred: &[f64]) -> Scores {
    Scores {
        vacc_rel_pct: vacc_relative_pct(truth, pred),
        vacc_mean_pct: vacc_mean_normalised_pct(truth, pred),
        rmse: rmse(truth, pred),
    }
}

/// The sigma grid the cross-validation searches by default (z-score units).
pub const DEFAULT_SIGMAS: [f64; 13] = [
    0.01, 0.015, 0.02, 0.03, 0.04, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 1.0,
];

/// Result of a k-fold cross-validation of sigma.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CvResult {
    /// The sigma with the best mean fold VAcc (relative).
    pub sigma: f64,
    /// (sigma, mean fold VAcc relative %, mean fold RMSE) for every candidate.
    pub table: Vec<(f64, f64, f64)>,
}

/// k-fold cross-validation of sigma for a GRNN on row-major inputs `x` of
/// dimension `dim`: the folds are contiguous chunks of a seeded permutation, the
/// z-score is refitted on each training part, and the criterion is the mean over
/// folds of the relative VAcc (ties: the smaller RMSE).
pub fn cv_sigma(
    x: &[f64],
    dim: usize,
    y: &[f64],
    sigmas: &[f64],
    k: usize,
    shuffle: Shuffle,
    seed: u32,
) -> Result<CvResult, FitError> {
    if sigmas.is_empty() {
        return Err(FitError::BadParameter("no sigma candidates".into()));
    }
    let n = y.len();
    if k < 2 || n < k {
        return Err(FitError::BadParameter(format!("{k} folds of {n} samples")));
    }
    let folds = k_folds(shuffle, seed, n, k);
    let pick = |idx: &[usize]| -> (Vec<f64>, Vec<f64>) {
        let mut xs = Vec::with_capacity(idx.len() * dim);
        let mut ys = Vec::with_capacity(idx.len());
        for &i in idx {
            xs.extend_from_slice(&x[i * dim..(i + 1) * dim]);
            ys.push(y[i]);
        }
        (xs, ys)
    };
    // Per fold: the network fitted on the other folds (with the first sigma) and
    // the test part.
    let parts: Vec<(Grnn, Vec<f64>, Vec<f64>)> = (0..k)
        .map(|f| {
            let train: Vec<usize> = (0..k)
                .filter(|&g| g != f)
                .flat_map(|g| folds[g].iter().copied())
                .collect();
            let (xt, yt) = pick(&train);
            let (xv, yv) = pick(&folds[f]);
            Ok((Grnn::fit(&xt, dim, &yt, sigmas[0])?, xv, yv))
        })
        .collect::<Result<_, FitError>>()?;
    let table: Vec<(f64, f64, f64)> = sigmas
        .par_iter()
        .map(|&s| {
            let (mut va, mut rm) = (0.0, 0.0);
            for (net, xv, yv) in &parts {
                let net = net.with_sigma(s).expect("positive sigma");
                let p: Vec<f64> = xv.chunks_exact(dim).map(|r| net.predict(r)).collect();
                va += vacc_relative_pct(yv, &p);
                rm += rmse(yv, &p);
            }
            (s, va / k as f64, rm / k as f64)
        })
        .collect();
    let best = table
        .iter()
        .copied()
        .fold(None::<(f64, f64, f64)>, |b, c| match b {
            Some(b) if b.1 > c.1 || (b.1 == c.1 && b.2 <= c.2) => Some(b),
            _ => Some(c),
        })
        .expect("non-empty");
    Ok(CvResult {
        sigma: best.0,
        table,
    })
}
