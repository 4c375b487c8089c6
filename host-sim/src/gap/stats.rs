//! Residual statistics: noise level, whiteness and residual-input
//! correlation tests (as MATLAB's `resid`, 99 % bounds), frequency bands.

use rustfft::{num_complex::Complex, FftPlanner};

/// Two-sided 99 % quantile of the standard normal distribution (the per-lag
/// correlation bound).
pub const Z99: f64 = 2.575_829_303_549_054;
/// One-sided 99 % quantile of the standard normal distribution.
pub const Z99_ONE_SIDED: f64 = 2.326_347_874_040_841;

/// Median of a slice (NaN-free; 0 for an empty slice).
pub fn median(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut s = v.to_vec();
    s.sort_by(|a, b| a.total_cmp(b));
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// Median absolute value of a zero-mean normal variable per unit of its
/// standard deviation.
pub const MAD_PER_SIGMA: f64 = 0.674_489_750_196_081_7;

/// Robust standard deviation of zero-centred values from their absolute
/// values `abs` (NaN-free): their median over [`MAD_PER_SIGMA`].
pub fn mad_sigma(abs: &[f64]) -> f64 {
    median(abs) / MAD_PER_SIGMA
}

/// White measurement-noise level of a sampled signal, from the median
/// absolute second difference (robust to the signal's own smooth motion and
/// to a minority of steps): sigma = MAD(d2) / (0.6745 sqrt 6).
pub fn noise_sigma(x: &[f64]) -> f64 {
    if x.len() < 3 {
        return 0.0;
    }
    let d2: Vec<f64> = x
        .windows(3)
        .map(|w| (w[2] - 2.0 * w[1] + w[0]).abs())
        .collect();
    median(&d2) / (MAD_PER_SIGMA * 6f64.sqrt())
}

/// Mean of a slice.
pub fn mean(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        v.iter().sum::<f64>() / v.len() as f64
    }
}

/// Root mean square of a slice.
pub fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        0.0
    } else {
        (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
    }
}

/// Normalised autocorrelation of `e` at lags 1..=max_lag.
pub fn autocorrelation(e: &[f64], max_lag: usize) -> Vec<f64> {
    let m = mean(e);
    let c0: f64 = e.iter().map(|x| (x - m) * (x - m)).sum();
    if c0 <= 0.0 {
        return vec![0.0; max_lag];
    }
    (1..=max_lag)
        .map(|k| {
            if k >= e.len() {
                return 0.0;
            }
            (0..e.len() - k)
                .map(|i| (e[i] - m) * (e[i + k] - m))
                .sum::<f64>()
                / c0
        })
        .collect()
}

/// Normalised cross-correlation of input `u` leading residual `e` at lags
/// 0..=max_lag (r(k) = sum u(t) e(t + k) / sqrt(sum u^2 sum e^2)).
pub fn cross_correlation(u: &[f64], e: &[f64], max_lag: usize) -> Vec<f64> {
    let n = u.len().min(e.len());
    let (mu, me) = (mean(&u[..n]), mean(&e[..n]));
    let su: f64 = u[..n].iter().map(|x| (x - mu) * (x - mu)).sum();
    let se: f64 = e[..n].iter().map(|x| (x - me) * (x - me)).sum();
    if su <= 0.0 || se <= 0.0 {
        return vec![0.0; max_lag + 1];
    }
    let s = (su * se).sqrt();
    (0..=max_lag)
        .map(|k| {
            if k >= n {
                return 0.0;
            }
            (0..n - k)
                .map(|i| (u[i] - mu) * (e[i + k] - me))
                .sum::<f64>()
                / s
        })
        .collect()
}

/// 99 % quantile of the chi-square distribution with `m` degrees of freedom
/// (Wilson-Hilferty approximation; within 0.5 % for m >= 5).
pub fn chi2_99(m: usize) -> f64 {
    let m = m.max(1) as f64;
    let a = 2.0 / (9.0 * m);
    m * (1.0 - a + Z99_ONE_SIDED * a.sqrt()).powi(3)
}

/// Result of a correlation test.
#[derive(Clone, Debug, PartialEq)]
pub struct CorrTest {
    /// Largest |correlation| over the lags tested.
    pub max_abs: f64,
    /// The per-lag 99 % bound z99 / sqrt(N) for white, independent residuals
    /// (what MATLAB's `resid` draws).
    pub bound: f64,
    /// Portmanteau statistic Q = N sum r_k^2 over the lags tested.
    pub q: f64,
    /// Its 99 % quantile under the null hypothesis (chi-square, one degree of
    /// freedom per lag).
    pub q_limit: f64,
}

impl CorrTest {
    /// The residuals look white / independent of the input at the 99 % level.
    pub fn passes(&self) -> bool {
        self.q <= self.q_limit
    }
}

/// Whiteness test of `e` at lags 1..=max_lag.
pub fn whiteness(e: &[f64], max_lag: usize) -> CorrTest {
    test_of(&autocorrelation(e, max_lag), e.len())
}

/// Independence test of `e` from `u` at lags 0..=max_lag.
pub fn independence(u: &[f64], e: &[f64], max_lag: usize) -> CorrTest {
    test_of(&cross_correlation(u, e, max_lag), e.len())
}

fn test_of(r: &[f64], n: usize) -> CorrTest {
    let n = n.max(1) as f64;
    CorrTest {
        max_abs: r.iter().map(|x| x.abs()).fold(0.0, f64::max),
        bound: Z99 / n.sqrt(),
        q: n * r.iter().map(|x| x * x).sum::<f64>(),
        q_limit: chi2_99(r.len()),
    }
}

/// Frequency bands the gap is split into, Hz (upper edges; the last is Nyquist).
pub const BANDS_HZ: [(f64, f64); 4] = [(0.0, 0.5), (0.5, 5.0), (5.0, 50.0), (50.0, f64::INFINITY)];

/// Share of the residual's power (mean removed) in each of [`BANDS_HZ`],
/// from the periodogram of the whole record (Hann window).
pub fn band_shares(e: &[f64], dt_s: f64) -> [f64; 4] {
    let n = e.len();
    if n < 8 {
        return [0.0; 4];
    }
    let m = mean(e);
    let mut buf: Vec<Complex<f64>> = e
        .iter()
        .enumerate()
        .map(|(i, x)| {
            let w = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / n as f64).cos();
            Complex::new((x - m) * w, 0.0)
        })
        .collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    let mut p = [0.0f64; 4];
    for (k, c) in buf.iter().enumerate().take(n / 2 + 1).skip(1) {
        let f = k as f64 / (n as f64 * dt_s);
        let i = BANDS_HZ
            .iter()
            .position(|(lo, hi)| f >= *lo && f < *hi)
            .unwrap_or(3);
        p[i] += c.norm_sqr();
    }
    let total: f64 = p.iter().sum();
    if total > 0.0 {
        p.map(|x| x / total)
    } else {
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, StandardNormal};

    fn white(n: usize, seed: u64) -> Vec<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        (0..n)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                z
            })
            .collect()
    }

    #[test]
    fn noise_sigma_under_smooth_motion_and_steps() {
        let e = white(5000, 1);
        let x: Vec<f64> = (0..5000)
            .map(|i| {
                let t = i as f64 * 1e-3;
                // 50 mm over a few seconds, a step, and 10 um of noise.
                0.05 * (1.0 - (-t).exp()) + if t > 3.0 { 0.002 } else { 0.0 } + 10e-6 * e[i]
            })
            .collect();
        let s = noise_sigma(&x);
        assert!((s - 10e-6).abs() < 1e-6, "{s:e}");
    }

    #[test]
    fn whiteness_passes_noise_and_fails_a_drift() {
        let e = white(4000, 2);
        assert!(whiteness(&e, 50).passes());
        let drift: Vec<f64> = e
            .iter()
            .enumerate()
            .map(|(i, x)| x + 3.0 * (i as f64 * 0.003).sin())
            .collect();
        let t = whiteness(&drift, 50);
        assert!(!t.passes(), "{t:?}");
    }

    #[test]
    fn independence_detects_a_lagged_dependence() {
        let u = white(4000, 3);
        let n = white(4000, 4);
        assert!(independence(&u, &n, 30).passes());
        let e: Vec<f64> = (0..4000)
            .map(|i| n[i] + if i >= 5 { 0.5 * u[i - 5] } else { 0.0 })
            .collect();
        assert!(!independence(&u, &e, 30).passes());
    }

    #[test]
    fn chi2_quantile() {
        // Tabulated 99 % quantiles: 15.09 (5), 23.21 (10), 50.89 (30), 76.15 (50).
        for (m, q) in [(5, 15.086), (10, 23.209), (30, 50.892), (50, 76.154)] {
            assert!((chi2_99(m) / q - 1.0).abs() < 0.005, "{m}: {}", chi2_99(m));
        }
    }

    #[test]
    fn white_noise_passes_at_the_expected_rate() {
        let passed = (0..200)
            .filter(|s| whiteness(&white(2000, 100 + s), 20).passes())
            .count();
        // 99 % expected: 198 of 200; allow sampling spread.
        assert!(passed >= 193, "{passed} of 200");
    }

    #[test]
    fn band_shares_locate_a_tone() {
        let e: Vec<f64> = (0..8000)
            .map(|i| (2.0 * std::f64::consts::PI * 12.0 * i as f64 * 1e-3).sin())
            .collect();
        let b = band_shares(&e, 1e-3);
        assert!(b[2] > 0.95, "{b:?}");
        let slow: Vec<f64> = (0..8000).map(|i| (i as f64 * 1e-3 * 0.2).sin()).collect();
        assert!(band_shares(&slow, 1e-3)[0] > 0.9);
    }
}
