//! Back-propagation network (the paper's Fig. 9 "BP"): a small multilayer
//! perceptron d-H-1 with tanh hidden units and a linear output, z-score inputs and
//! standardised output, trained full-batch on the mean squared error with Adam
//! from a seeded Xavier initialisation.

use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::model::hose::net::{FitError, ZScore};

/// Hyper-parameters of [`Mlp`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MlpOptions {
    /// Hidden units.
    pub hidden: usize,
    /// Full-batch Adam steps.
    pub epochs: usize,
    /// Adam learning rate.
    pub learning_rate: f64,
    /// Seed of the initial weights.
    pub seed: u64,
}

impl Default for MlpOptions {
    fn default() -> Self {
        Self {
            hidden: 10,
            epochs: 3000,
            learning_rate: 0.01,
            seed: 7,
        }
    }
}

/// A trained MLP.
#[derive(Clone, Debug, PartialEq)]
pub struct Mlp {
    dim: usize,
    hidden: usize,
    scale: ZScore,
    y_mean: f64,
    y_std: f64,
    /// Parameters: W1 (hidden x dim), b1 (hidden), w2 (hidden), b2.
    p: Vec<f64>,
}

impl Mlp {
    /// Train on row-major inputs `x` (dimension `dim`) and outputs `y`.
    pub fn fit(x: &[f64], dim: usize, y: &[f64], o: &MlpOptions) -> Result<Self, FitError> {
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
        if o.hidden == 0 || o.learning_rate.is_nan() || o.learning_rate <= 0.0 {
            return Err(FitError::BadParameter(
                "hidden units and learning rate must be positive".into(),
            ));
        }
        let scale = ZScore::fit(x, dim)?;
        let mut xn = vec![0.0; x.len()];
        for (r, out) in x.chunks_exact(dim).zip(xn.chunks_exact_mut(dim)) {
            scale.apply(r, out);
        }
        let y_mean = y.iter().sum::<f64>() / n as f64;
        let y_std = (y.iter().map(|v| (v - y_mean) * (v - y_mean)).sum::<f64>() / n as f64)
            .sqrt()
            .max(1e-12);
        let yn: Vec<f64> = y.iter().map(|v| (v - y_mean) / y_std).collect();
        let h = o.hidden;
        let n_p = h * dim + h + h + 1;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(o.seed);
        let mut p = vec![0.0; n_p];
        let n1 = Normal::new(0.0, (2.0 / (dim + h) as f64).sqrt()).expect("valid");
        let n2 = Normal::new(0.0, (2.0 / (h + 1) as f64).sqrt()).expect("valid");
        for v in p.iter_mut().take(h * dim) {
            *v = n1.sample(&mut rng);
        }
        for v in p.iter_mut().skip(h * dim + h).take(h) {
            *v = n2.sample(&mut rng);
        }
        let mut net = Self {
            dim,
            hidden: h,
            scale,
            y_mean,
            y_std,
            p,
        };
        let (b1_0, w2_0, b2_0) = (h * dim, h * dim + h, h * dim + 2 * h);
        let (beta1, beta2, eps) = (0.9, 0.999, 1e-8);
        let mut m = vec![0.0; n_p];
        let mut v = vec![0.0; n_p];
        let mut g = vec![0.0; n_p];
        let mut a = vec![0.0; h];
        for epoch in 1..=o.epochs {
            g.iter_mut().for_each(|q| *q = 0.0);
            for (r, &t) in xn.chunks_exact(dim).zip(&yn) {
                let mut out = net.p[b2_0];
                for (j, aj) in a.iter_mut().enumerate() {
                    let z = net.p[b1_0 + j]
                        + r.iter()
                            .zip(&net.p[j * dim..(j + 1) * dim])
                            .map(|(x, w)| x * w)
                            .sum::<f64>();
                    *aj = z.tanh();
                    out += net.p[w2_0 + j] * *aj;
                }
                let e = 2.0 * (out - t) / n as f64;
                g[b2_0] += e;
                for j in 0..h {
                    g[w2_0 + j] += e * a[j];
                    let dz = e * net.p[w2_0 + j] * (1.0 - a[j] * a[j]);
                    g[b1_0 + j] += dz;
                    for q in 0..dim {
                        g[j * dim + q] += dz * r[q];
                    }
                }
            }
            let c1 = 1.0 - beta1_pow(beta1, epoch);
            let c2 = 1.0 - beta1_pow(beta2, epoch);
            for i in 0..n_p {
                m[i] = beta1 * m[i] + (1.0 - beta1) * g[i];
                v[i] = beta2 * v[i] + (1.0 - beta2) * g[i] * g[i];
                net.p[i] -= o.learning_rate * (m[i] / c1) / ((v[i] / c2).sqrt() + eps);
            }
        }
        Ok(net)
    }

    /// Prediction at `x` (original units, length `dim`).
    pub fn predict(&self, x: &[f64]) -> f64 {
        let (d, h) = (self.dim, self.hidden);
        let mut u = vec![0.0; d];
        self.scale.apply(x, &mut u);
        let mut out = self.p[h * d + 2 * h];
        for j in 0..h {
            let z = self.p[h * d + j]
                + u.iter()
                    .zip(&self.p[j * d..(j + 1) * d])
                    .map(|(x, w)| x * w)
                    .sum::<f64>();
            out += self.p[h * d + h + j] * z.tanh();
        }
        self.y_mean + self.y_std * out
    }
}

fn beta1_pow(b: f64, e: usize) -> f64 {
    b.powi(e.min(i32::MAX as usize) as i32)
}
