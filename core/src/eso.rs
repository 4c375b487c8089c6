//! Extended state observer (docs/model.md section 6.5, the paper's eq. 42-44).
//!
//! ```text
//! e   = z1 - y
//! z1 += h (z2 - beta1 e)
//! z2 += h (z3 - beta2 fal(e, alpha1, delta) + b0 u)
//! z3 += h (-beta3 fal(e, alpha2, delta))         (right-hand sides use the old z)
//! ```
//!
//! [`EsoFixed`] is the observer the controller runs: states in the Q formats of
//! [`crate::fxp`], constants `h`, `h beta_i` and `h b0` precomputed with 31
//! significant bits, `fal` by integer log2/exp2 (no floating-point pow).
//! [`EsoF64`] is the binary64 reference it is tested against.
//!
//! ## Error bound of the fixed-point observer
//! Per update the fixed-point observer departs from the f64 one by its rounding:
//! the input y quantised to Q4.28 (<= 1.9e-9 m), two roundings in z1
//! (<= 3.7e-9 m), three in z2 plus the fal error times `h beta2`
//! (<= 1.0e-7 m/s) and one in z3 plus `h beta3` times the fal error
//! (<= 7.7e-6 m/s^2). These local errors pass through the observer's own
//! error dynamics, which are contracting (linear-zone poles -1.55 and
//! -14.2 +- 34.2j rad/s for the paper's gains). [`EsoFixedGains::error_bound`]
//! sums the l1 norm of that linear-zone error response over the local
//! rounding bounds and doubles it for the nonlinear zone, where fal's slope is
//! lower; the paper-scenario tests (crate `dca-tests`) check the fixed-point
//! observer against [`EsoF64`] on the same inputs against that bound.

use crate::fxp::{self, Acc, Coeff, Fal, Pos, Vel, ACC_FRAC, POS_FRAC, VEL_FRAC};

/// Observer parameters (physical, f64).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EsoParams {
    /// Position error gain beta1, 1/s.
    pub beta1: f64,
    /// Velocity gain beta2.
    pub beta2: f64,
    /// Disturbance gain beta3.
    pub beta3: f64,
    /// Input gain b0 of the observer model, 1/s (u in m/s, z3 in m/s^2).
    pub b0: f64,
    /// Observer step h, s.
    pub h_s: f64,
    /// fal exponent of the z2 correction.
    pub alpha1: f64,
    /// fal exponent of the z3 correction.
    pub alpha2: f64,
    /// fal linear-zone half width, m.
    pub delta_m: f64,
}

impl EsoParams {
    /// The paper's Table 2 values with Han's usual exponents (docs/model.md 6.5).
    pub const PAPER: Self = Self {
        beta1: 30.0,
        beta2: 100.0,
        beta3: 40.0,
        b0: 0.02,
        h_s: 0.006,
        alpha1: 0.5,
        alpha2: 0.25,
        delta_m: 0.005,
    };
}

/// Why observer parameters were refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EsoError {
    /// A gain or the step is not finite, or a product `h beta` is out of range.
    Gain,
    /// alpha outside (0, 1] or delta outside (0, 8) m.
    Fal,
}

/// Precomputed constants of the fixed-point observer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EsoFixedGains {
    h: Coeff,
    hb1: Coeff,
    hb2: Coeff,
    hb3: Coeff,
    hb0: Coeff,
    fal1: Fal,
    fal2: Fal,
}

impl EsoFixedGains {
    /// Precompute the constants for `p`.
    pub fn new(p: &EsoParams) -> Result<Self, EsoError> {
        let ok = [p.beta1, p.beta2, p.beta3, p.b0, p.h_s]
            .iter()
            .all(|v| v.is_finite())
            && p.h_s > 0.0
            && p.h_s < 1.0;
        if !ok {
            return Err(EsoError::Gain);
        }
        let c = |v: f64| match Coeff::from_f64(v) {
            Some(k) if v.abs() < 1.0e4 => Ok(k),
            _ => Err(EsoError::Gain),
        };
        Ok(Self {
            h: c(p.h_s)?,
            hb1: c(p.h_s * p.beta1)?,
            hb2: c(p.h_s * p.beta2)?,
            hb3: c(p.h_s * p.beta3)?,
            hb0: c(p.h_s * p.b0)?,
            fal1: Fal::new(p.alpha1, p.delta_m).ok_or(EsoError::Fal)?,
            fal2: Fal::new(p.alpha2, p.delta_m).ok_or(EsoError::Fal)?,
        })
    }

    /// The bound of the module documentation: `[z1 m, z2 m/s, z3 m/s^2]` that
    /// the fixed-point observer stays within from [`EsoF64`] on the same inputs,
    /// for observer gains whose linear-zone error dynamics are stable.
    ///
    /// Computed in f64 from the parameters: the l1 norm of the linear-zone
    /// error impulse response (up to 20 000 steps) applied to the per-update
    /// rounding bounds, times 2 for the nonlinear zone. Returns `None` when the
    /// linear-zone error dynamics do not decay.
    pub fn error_bound(p: &EsoParams) -> Option<[f64; 3]> {
        let h = p.h_s;
        let lin1 = libm::pow(p.delta_m, p.alpha1 - 1.0);
        let lin2 = libm::pow(p.delta_m, p.alpha2 - 1.0);
        // Error dynamics e_{k+1} = M e_k with e = z - z_true (y exact).
        let m = [
            [1.0 - h * p.beta1, h, 0.0],
            [-h * p.beta2 * lin1, 1.0, h],
            [-h * p.beta3 * lin2, 0.0, 1.0],
        ];
        // Local rounding bound per update (see the module documentation):
        // half-LSB roundings plus the fal error (relative 1e-6) at |fal| <= 3.
        let lsb = |f: u32| libm::exp2(-(f as f64));
        let fal_err = 3.0e-6;
        let local = [
            0.5 * lsb(POS_FRAC) * (1.0 + h * p.beta1.abs()) + lsb(POS_FRAC),
            1.5 * lsb(VEL_FRAC) + h * p.beta2.abs() * fal_err,
            0.5 * lsb(ACC_FRAC) + h * p.beta3.abs() * fal_err,
        ];
        let mut bound = [0.0f64; 3];
        // Response to a unit local error in each state, summed in absolute value.
        for (src, &loc) in local.iter().enumerate() {
            let mut x = [0.0f64; 3];
            x[src] = 1.0;
            let mut last = f64::MAX;
            for k in 0..20_000 {
                for (b, xi) in bound.iter_mut().zip(x.iter()) {
                    *b += xi.abs() * loc;
                }
                let mut n = [0.0f64; 3];
                for (i, row) in m.iter().enumerate() {
                    n[i] = row[0] * x[0] + row[1] * x[1] + row[2] * x[2];
                }
                x = n;
                let size = x[0].abs() + x[1].abs() + x[2].abs();
                if k % 1000 == 999 {
                    if size > last {
                        return None;
                    }
                    last = size;
                }
            }
            if x.iter().any(|v| v.abs() > 1e-6) {
                return None;
            }
        }
        Some([2.0 * bound[0], 2.0 * bound[1], 2.0 * bound[2]])
    }
}

/// Fixed-point observer state.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EsoFixed {
    /// Estimated position z1.
    pub z1: Pos,
    /// Estimated velocity z2.
    pub z2: Vel,
    /// Estimated total disturbance (acceleration) z3.
    pub z3: Acc,
}

impl EsoFixed {
    /// One observer update with measurement `y` and input `u` (old z on the right).
    #[inline]
    pub fn update(&mut self, g: &EsoFixedGains, y: Pos, u: Vel) {
        let e = self.z1.saturating_sub(y);
        let (f1, f2) = Fal::eval_pair(&g.fal1, &g.fal2, e);
        let (f1, f2) = (f1.to_bits(), f2.to_bits());
        let (z1, z2, z3) = (self.z1.to_bits(), self.z2.to_bits(), self.z3.to_bits());
        let d1 = g.h.mul(z2, VEL_FRAC, POS_FRAC) - g.hb1.mul(e.to_bits(), POS_FRAC, POS_FRAC);
        let d2 = g.h.mul(z3, ACC_FRAC, VEL_FRAC) - g.hb2.mul(f1, POS_FRAC, VEL_FRAC)
            + g.hb0.mul(u.to_bits(), VEL_FRAC, VEL_FRAC);
        let d3 = -g.hb3.mul(f2, POS_FRAC, ACC_FRAC);
        self.z1 = Pos::from_bits(fxp::sat32(z1 as i64 + d1));
        self.z2 = Vel::from_bits(fxp::sat32(z2 as i64 + d2));
        self.z3 = Acc::from_bits(fxp::sat32(z3 as i64 + d3));
    }

    /// The state as `[z1 m, z2 m/s, z3 m/s^2]` in f32 (nearest, ties to even:
    /// the values of `to_num::<f32>()`).
    #[inline]
    pub fn to_f32(&self) -> [f32; 3] {
        [
            fxp::q_to_f32::<{ POS_FRAC as i32 }>(self.z1.to_bits()),
            fxp::q_to_f32::<{ VEL_FRAC as i32 }>(self.z2.to_bits()),
            fxp::q_to_f32::<{ ACC_FRAC as i32 }>(self.z3.to_bits()),
        ]
    }
}

/// The binary64 reference observer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EsoF64 {
    /// Estimated position, m.
    pub z1: f64,
    /// Estimated velocity, m/s.
    pub z2: f64,
    /// Estimated total disturbance, m/s^2.
    pub z3: f64,
}

/// Han's fal in binary64.
pub fn fal_f64(e: f64, alpha: f64, delta: f64) -> f64 {
    if e.abs() <= delta {
        e / libm::pow(delta, 1.0 - alpha)
    } else {
        libm::pow(e.abs(), alpha) * if e < 0.0 { -1.0 } else { 1.0 }
    }
}

impl EsoF64 {
    /// One observer update (old z on the right).
    pub fn update(&mut self, p: &EsoParams, y: f64, u: f64) {
        let e = self.z1 - y;
        let f1 = fal_f64(e, p.alpha1, p.delta_m);
        let f2 = fal_f64(e, p.alpha2, p.delta_m);
        let z1 = self.z1 + p.h_s * (self.z2 - p.beta1 * e);
        let z2 = self.z2 + p.h_s * (self.z3 - p.beta2 * f1 + p.b0 * u);
        let z3 = self.z3 + p.h_s * (-p.beta3 * f2);
        *self = Self { z1, z2, z3 };
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    const CHECK: [f64; 3] = [5.586132082e-4, 2.402277147e-2, 3.599376713e-2];
    const INPUTS: [(f64, f64); 3] = [(0.0, 0.05), (0.001, 0.05), (0.002, 0.05)];

    #[test]
    fn f64_reference_reproduces_check_vector() {
        let mut eso = EsoF64::default();
        for (y, u) in INPUTS {
            eso.update(&EsoParams::PAPER, y, u);
        }
        for (got, want) in [eso.z1, eso.z2, eso.z3].iter().zip(CHECK) {
            assert!(((got - want) / want).abs() < 1e-9, "{got:e} vs {want:e}");
        }
    }

    #[test]
    fn fixed_point_reproduces_check_vector_within_bound() {
        let g = EsoFixedGains::new(&EsoParams::PAPER).unwrap();
        let bound = EsoFixedGains::error_bound(&EsoParams::PAPER).unwrap();
        let mut eso = EsoFixed::default();
        for (y, u) in INPUTS {
            eso.update(&g, Pos::from_num(y), Vel::from_num(u));
        }
        let z = [
            eso.z1.to_num::<f64>(),
            eso.z2.to_num::<f64>(),
            eso.z3.to_num::<f64>(),
        ];
        for i in 0..3 {
            assert!(
                (z[i] - CHECK[i]).abs() <= bound[i],
                "z{}: {:e} vs {:e} (bound {:e})",
                i + 1,
                z[i],
                CHECK[i],
                bound[i]
            );
        }
    }

    #[test]
    fn bound_is_small_for_paper_gains_and_refused_for_unstable_ones() {
        let b = EsoFixedGains::error_bound(&EsoParams::PAPER).unwrap();
        // Well below the LVDT's 29 um LSB, the speed resolution the MPC needs and
        // the 1 m/s^2 scale of the accelerations.
        assert!(b[0] < 1e-5 && b[1] < 1e-3 && b[2] < 1e-2, "{b:?}");
        let unstable = EsoParams {
            beta1: 400.0,
            ..EsoParams::PAPER
        };
        assert_eq!(EsoFixedGains::error_bound(&unstable), None);
    }

    #[test]
    fn invalid_parameters_are_refused() {
        let bad_h = EsoParams {
            h_s: 0.0,
            ..EsoParams::PAPER
        };
        assert_eq!(EsoFixedGains::new(&bad_h), Err(EsoError::Gain));
        let bad_beta = EsoParams {
            beta2: f64::NAN,
            ..EsoParams::PAPER
        };
        assert_eq!(EsoFixedGains::new(&bad_beta), Err(EsoError::Gain));
        let bad_alpha = EsoParams {
            alpha2: 0.0,
            ..EsoParams::PAPER
        };
        assert_eq!(EsoFixedGains::new(&bad_alpha), Err(EsoError::Fal));
    }

    #[test]
    fn saturates_instead_of_wrapping() {
        let g = EsoFixedGains::new(&EsoParams::PAPER).unwrap();
        let mut eso = EsoFixed::default();
        for _ in 0..10_000 {
            eso.update(&g, Pos::MAX, Vel::MAX);
        }
        let z = eso.to_f32();
        assert!(z.iter().all(|v| v.is_finite()));
        assert!(z[0] > 7.0, "z1 follows a saturated measurement: {z:?}");
    }
}
