//! Radial basis function network (the paper's Fig. 9 "RBF"): k-means centres in
//! z-score input space, one common Gaussian width, output weights (and a bias)
//! by regularised least squares.

use rand::{Rng, SeedableRng};

use crate::model::hose::net::{dist2, FitError, ZScore};

/// Hyper-parameters of [`Rbf`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RbfOptions {
    /// Number of centres.
    pub centres: usize,
    /// Width as a multiple of the mean distance from a centre to its nearest
    /// neighbour centre.
    pub width_factor: f64,
    /// Lloyd iterations of k-means.
    pub iterations: usize,
    /// Ridge regularisation, relative to the mean diagonal of the normal matrix.
    pub ridge: f64,
    /// Seed of the k-means++ initialisation.
    pub seed: u64,
}

impl Default for RbfOptions {
    fn default() -> Self {
        Self {
            centres: 40,
            width_factor: 1.0,
            iterations: 50,
            ridge: 1e-8,
            seed: 7,
        }
    }
}

/// A fitted RBF network.
#[derive(Clone, Debug, PartialEq)]
pub struct Rbf {
    dim: usize,
    scale: ZScore,
    centres: Vec<f64>,
    width: f64,
    /// Output weights, the bias last.
    weights: Vec<f64>,
}

impl Rbf {
    /// Fit to row-major inputs `x` (dimension `dim`) and outputs `y`.
    pub fn fit(x: &[f64], dim: usize, y: &[f64], o: &RbfOptions) -> Result<Self, FitError> {
        if dim == 0 || x.len() != dim * y.len() {
            return Err(FitError::Shape(format!(
                "{} inputs for {} outputs",
                x.len(),
                y.len()
            )));
        }
        let n = y.len();
        if n == 0 {
            return Err(FitError::Empty);
        }
        if x.iter().chain(y).any(|v| !v.is_finite()) {
            return Err(FitError::NotFinite);
        }
        let k = o.centres.min(n);
        if k == 0 || o.width_factor.is_nan() || o.width_factor <= 0.0 {
            return Err(FitError::BadParameter(
                "centres and width must be positive".into(),
            ));
        }
        let scale = ZScore::fit(x, dim)?;
        let mut xn = vec![0.0; x.len()];
        for (r, out) in x.chunks_exact(dim).zip(xn.chunks_exact_mut(dim)) {
            scale.apply(r, out);
        }
        let centres = kmeans(&xn, dim, k, o.iterations, o.seed);
        // Width: mean nearest-neighbour distance between centres.
        let mut nn = 0.0;
        for i in 0..k {
            let ci = &centres[i * dim..(i + 1) * dim];
            let m = (0..k)
                .filter(|&j| j != i)
                .map(|j| dist2(ci, &centres[j * dim..(j + 1) * dim]))
                .fold(f64::INFINITY, f64::min);
            nn += if m.is_finite() { m.sqrt() } else { 1.0 };
        }
        let width = o.width_factor * (nn / k as f64).max(1e-6);
        // Normal equations of the least-squares fit of [phi, 1] w = y.
        let m = k + 1;
        let mut a = vec![0.0; m * m];
        let mut b = vec![0.0; m];
        let mut phi = vec![0.0; m];
        let net = Self {
            dim,
            scale,
            centres,
            width,
            weights: vec![0.0; m],
        };
        for (r, &yv) in xn.chunks_exact(dim).zip(y) {
            net.features(r, &mut phi);
            for i in 0..m {
                b[i] += phi[i] * yv;
                for j in 0..=i {
                    a[i * m + j] += phi[i] * phi[j];
                }
            }
        }
        let mean_diag = (0..m).map(|i| a[i * m + i]).sum::<f64>() / m as f64;
        for i in 0..m {
            a[i * m + i] += o.ridge * mean_diag;
            for j in 0..i {
                a[j * m + i] = a[i * m + j];
            }
        }
        let weights = cholesky_solve(&mut a, &b, m)
            .ok_or_else(|| FitError::BadParameter("singular RBF normal equations".into()))?;
        Ok(Self { weights, ..net })
    }

    fn features(&self, u: &[f64], phi: &mut [f64]) {
        let c = -0.5 / (self.width * self.width);
        let k = self.weights.len() - 1;
        for (j, p) in phi.iter_mut().enumerate().take(k) {
            *p = (c * dist2(u, &self.centres[j * self.dim..(j + 1) * self.dim])).exp();
        }
        phi[k] = 1.0;
    }

    /// Prediction at `x` (original units, length `dim`).
    pub fn predict(&self, x: &[f64]) -> f64 {
        let mut u = vec![0.0; self.dim];
        self.scale.apply(x, &mut u);
        let mut phi = vec![0.0; self.weights.len()];
        self.features(&u, &mut phi);
        phi.iter().zip(&self.weights).map(|(p, w)| p * w).sum()
    }

    /// Number of centres.
    pub fn n_centres(&self) -> usize {
        self.weights.len() - 1
    }
}

/// k-means (Lloyd) with k-means++ initialisation, seeded.
fn kmeans(x: &[f64], dim: usize, k: usize, iterations: usize, seed: u64) -> Vec<f64> {
    let n = x.len() / dim;
    let row = |i: usize| &x[i * dim..(i + 1) * dim];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut c: Vec<f64> = row(rng.random_range(0..n)).to_vec();
    let mut d2: Vec<f64> = (0..n).map(|i| dist2(row(i), &c[..dim])).collect();
    while c.len() < k * dim {
        let total: f64 = d2.iter().sum();
        let pick = if total > 0.0 {
            let mut r = rng.random::<f64>() * total;
            let mut p = n - 1;
            for (i, d) in d2.iter().enumerate() {
                if r < *d {
                    p = i;
                    break;
                }
                r -= d;
            }
            p
        } else {
            rng.random_range(0..n)
        };
        let j = c.len() / dim;
        c.extend_from_slice(row(pick));
        for (i, d) in d2.iter_mut().enumerate() {
            *d = d.min(dist2(row(i), &c[j * dim..(j + 1) * dim]));
        }
    }
    let mut assign = vec![0usize; n];
    for _ in 0..iterations {
        let mut changed = false;
        for (i, a) in assign.iter_mut().enumerate() {
            let best = (0..k)
                .min_by(|&p, &q| {
                    dist2(row(i), &c[p * dim..(p + 1) * dim])
                        .total_cmp(&dist2(row(i), &c[q * dim..(q + 1) * dim]))
                })
                .expect("k > 0");
            if best != *a {
                *a = best;
                changed = true;
            }
        }
        let mut sum = vec![0.0; k * dim];
        let mut cnt = vec![0usize; k];
        for (i, &a) in assign.iter().enumerate() {
            cnt[a] += 1;
            for q in 0..dim {
                sum[a * dim + q] += x[i * dim + q];
            }
        }
        for j in 0..k {
            if cnt[j] > 0 {
                for q in 0..dim {
                    c[j * dim + q] = sum[j * dim + q] / cnt[j] as f64;
                }
            }
        }
        if !changed {
            break;
        }
    }
    c
}

/// Solve the symmetric positive definite system `a x = b` (row-major `m x m`,
/// overwritten by its Cholesky factor). `None` if not positive definite.
pub(crate) fn cholesky_solve(a: &mut [f64], b: &[f64], m: usize) -> Option<Vec<f64>> {
    for j in 0..m {
        let mut s = a[j * m + j];
        for p in 0..j {
            s -= a[j * m + p] * a[j * m + p];
        }
        if s.is_nan() || s <= 0.0 {
            return None;
        }
        let l = s.sqrt();
        a[j * m + j] = l;
        for i in j + 1..m {
            let mut s = a[i * m + j];
            for p in 0..j {
                s -= a[i * m + p] * a[j * m + p];
            }
            a[i * m + j] = s / l;
        }
    }
    let mut z = b.to_vec();
    for i in 0..m {
        for p in 0..i {
            z[i] -= a[i * m + p] * z[p];
        }
        z[i] /= a[i * m + i];
    }
    for i in (0..m).rev() {
        for p in i + 1..m {
            z[i] -= a[p * m + i] * z[p];
        }
        z[i] /= a[i * m + i];
    }
    Some(z)
}
