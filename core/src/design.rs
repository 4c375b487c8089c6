//! MPC design: prediction model, zero-order hold, augmented model and gains
//! (docs/model.md sections 6.2 and 6.3, the paper's eq. 9-12 and 28-40).
//!
//! The design runs in f64 with nalgebra on fixed-size matrices: no allocation, so
//! the firmware can re-design on the board after a parameter change. Only the
//! gains it returns are used per tick (see [`crate::mpc`]).
//!
//! Horizons are bounded by [`MAX_NP`] and [`MAX_NC`]; the matrices are stored at
//! that size and only the leading `np x nc` block is meaningful.

use nalgebra::{SMatrix, SVector};

use crate::params::PlantParams;

/// Largest prediction horizon the design accepts.
pub const MAX_NP: usize = 32;
/// Largest control horizon the design accepts.
pub const MAX_NC: usize = 8;

/// 3x3 matrix.
pub type Mat3 = SMatrix<f64, 3, 3>;
/// 3-vector.
pub type Vec3 = SVector<f64, 3>;
/// 4x4 matrix.
pub type Mat4 = SMatrix<f64, 4, 4>;
/// 4-vector.
pub type Vec4 = SVector<f64, 4>;

/// Why a design was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DesignError {
    /// `np` is 0, larger than [`MAX_NP`], or smaller than `nc`.
    PredictionHorizon,
    /// `nc` is 0 or larger than [`MAX_NC`].
    ControlHorizon,
    /// The sample time is not finite and positive.
    SampleTime,
    /// The input weight `r_w` is not finite and positive.
    InputWeight,
    /// The physical parameters give a non-finite or degenerate model.
    Model,
    /// The Hessian `Phi^T Phi + r_w I` could not be factorised.
    Singular,
    /// A constraint or share of the constrained MPC is out of range
    /// (acceleration limit not finite and > 0, a share outside [0, 1]).
    Constraint,
}

impl DesignError {
    /// A short human-readable reason.
    pub fn as_str(&self) -> &'static str {
        match self {
            Self::PredictionHorizon => "prediction horizon must satisfy nc <= np <= 32",
            Self::ControlHorizon => "control horizon must satisfy 1 <= nc <= 8",
            Self::SampleTime => "sample time must be finite and > 0",
            Self::InputWeight => "input weight r_w must be finite and > 0",
            Self::Model => "plant parameters give a degenerate prediction model",
            Self::Singular => "MPC Hessian is singular",
            Self::Constraint => "cmpc: a_max must be finite and > 0, load_ff and preview in [0, 1]",
        }
    }
}

/// Horizons, sample time and input weight of one MPC design.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MpcParams {
    /// Prediction horizon Np.
    pub np: usize,
    /// Control horizon Nc.
    pub nc: usize,
    /// MPC sample time Ts, s.
    pub ts_s: f64,
    /// Input weight r_w (R-bar = r_w I).
    pub rw: f64,
}

impl MpcParams {
    /// Check the parameters against the design's bounds.
    pub fn validate(&self) -> Result<(), DesignError> {
        if self.nc == 0 || self.nc > MAX_NC {
            return Err(DesignError::ControlHorizon);
        }
        if self.np == 0 || self.np > MAX_NP || self.np < self.nc {
            return Err(DesignError::PredictionHorizon);
        }
        if !(self.ts_s.is_finite() && self.ts_s > 0.0) {
            return Err(DesignError::SampleTime);
        }
        if !(self.rw.is_finite() && self.rw > 0.0) {
            return Err(DesignError::InputWeight);
        }
        Ok(())
    }
}

/// Continuous-time prediction model of section 6.2: x = [y, y', y'' - B2 u].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PredictionModel {
    /// b1 = (AA1^2 + AA2^2) k / (2 pi a l), N/m.
    pub b1_npm: f64,
    /// b2 = (AA1 AP1 + AA2 AP2) k / (2 pi a l), N/m.
    pub b2_npm: f64,
    /// Hose creep time constant T1, s.
    pub t1_s: f64,
    /// Hose lead time constant T2, s.
    pub t2_s: f64,
    /// Input gain of the second state, B2 = b2 T1 / (m T2), 1/s^2.
    pub b2_gain: f64,
    /// Continuous state matrix Ac.
    pub ac: Mat3,
    /// Continuous input matrix Bc.
    pub bc: Vec3,
}

impl PredictionModel {
    /// The model of eq. 9-12 from physical parameters, hose linearised at `p_nom_pa`.
    pub fn new(p: &PlantParams) -> Result<Self, DesignError> {
        let lin = p.hose_linearisation(p.p_nom_pa);
        let g = 2.0 * core::f64::consts::PI * p.hose_radius_m * p.hose_length_m;
        let b1 = (p.aa1_m2 * p.aa1_m2 + p.aa2_m2 * p.aa2_m2) * lin.k_papm / g;
        let b2 = (p.aa1_m2 * p.ap1_m2 + p.aa2_m2 * p.ap2_m2) * lin.k_papm / g;
        let (m, t1, t2) = (p.m_kg, lin.t1_s, lin.t2_s);
        let b2_gain = b2 * t1 / (m * t2);
        let b3_gain = b2 * (t2 - t1) / (m * t2 * t2);
        #[rustfmt::skip]
        let ac = Mat3::new(
            0.0, 1.0, 0.0,
            0.0, 0.0, 1.0,
            -b1 / (m * t2), -b1 * t1 / (m * t2), -1.0 / t2,
        );
        let bc = Vec3::new(0.0, b2_gain, b3_gain);
        let finite = ac.iter().chain(bc.iter()).all(|v| v.is_finite());
        if !(finite && m > 0.0 && t2 > 0.0 && b1 > 0.0) {
            return Err(DesignError::Model);
        }
        Ok(Self {
            b1_npm: b1,
            b2_npm: b2,
            t1_s: t1,
            t2_s: t2,
            b2_gain,
            ac,
            bc,
        })
    }

    /// Zero-order-hold discretisation at `ts_s`:
    /// `expm([[Ac, Bc], [0, 0]] Ts) = [[Ad, Bd], [0, 1]]`.
    pub fn discretise(&self, ts_s: f64) -> (Mat3, Vec3) {
        let mut m = Mat4::zeros();
        m.fixed_view_mut::<3, 3>(0, 0).copy_from(&(self.ac * ts_s));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&(self.bc * ts_s));
        let e = expm4(&m);
        (
            e.fixed_view::<3, 3>(0, 0).into_owned(),
            e.fixed_view::<3, 1>(0, 3).into_owned(),
        )
    }
}

/// Matrix exponential of a 4x4 matrix: scaling and squaring with a Taylor series.
///
/// The matrix is scaled by 2^-s until its infinity norm is at most 1/2, the
/// series is summed to 18 terms (truncation below 1e-22 relative) and the result
/// squared s times. Only +, *, / are used, so the result is bit-identical on
/// every IEEE-754 target.
pub fn expm4(a: &Mat4) -> Mat4 {
    let norm = (0..4)
        .map(|i| (0..4).map(|j| a[(i, j)].abs()).sum::<f64>())
        .fold(0.0, f64::max);
    let mut s = 0u32;
    let mut scale = 1.0;
    while norm * scale > 0.5 && s < 1000 {
        scale *= 0.5;
        s += 1;
    }
    let x = a * scale;
    let mut term = Mat4::identity();
    let mut sum = Mat4::identity();
    for k in 1..=18 {
        term = term * x / (k as f64);
        sum += term;
    }
    for _ in 0..s {
        sum = sum * sum;
    }
    sum
}

/// A complete MPC design: the matrices of section 6.3 and the gains.
#[derive(Clone, Debug, PartialEq)]
pub struct MpcDesign {
    /// The parameters the design was made with.
    pub params: MpcParams,
    /// The continuous model.
    pub model: PredictionModel,
    /// Discrete state matrix Ad.
    pub ad: Mat3,
    /// Discrete input matrix Bd.
    pub bd: Vec3,
    /// Augmented state matrix A = [[Ad, 0], [Cc Ad, 1]].
    pub a: Mat4,
    /// Augmented input matrix B = [Bd; Cc Bd].
    pub b: Vec4,
    /// Augmented output matrix C = [0, 0, 0, 1].
    pub c: SMatrix<f64, 1, 4>,
    /// F = [C A; C A^2; ...; C A^Np]; rows beyond `np` are zero.
    pub f: SMatrix<f64, MAX_NP, 4>,
    /// Phi(i, j) = C A^(i-j) B for i >= j; outside `np x nc` zero.
    pub phi: SMatrix<f64, MAX_NP, MAX_NC>,
    /// State-increment gain Kx (first three entries of Kmpc).
    pub kx: [f64; 3],
    /// Output gain Kmpc\[3\].
    pub ky_state: f64,
    /// Reference gain Ky = first element of H^-1 Phi^T [1 ... 1]^T.
    pub ky: f64,
}

impl MpcDesign {
    /// Design the MPC of section 6.3 for the given plant and parameters.
    pub fn new(plant: &PlantParams, params: MpcParams) -> Result<Self, DesignError> {
        params.validate()?;
        let model = PredictionModel::new(plant)?;
        let (ad, bd) = model.discretise(params.ts_s);
        let cc = nalgebra::RowVector3::new(1.0, 0.0, 0.0);

        let mut a = Mat4::zeros();
        a.fixed_view_mut::<3, 3>(0, 0).copy_from(&ad);
        a.fixed_view_mut::<1, 3>(3, 0).copy_from(&(cc * ad));
        a[(3, 3)] = 1.0;
        let mut b = Vec4::zeros();
        b.fixed_view_mut::<3, 1>(0, 0).copy_from(&bd);
        b[3] = (cc * bd)[0];
        let c = SMatrix::<f64, 1, 4>::new(0.0, 0.0, 0.0, 1.0);

        let (np, nc) = (params.np, params.nc);
        // cab[i] = C A^i B for i = 0..np, and the rows C A^(i+1) of F.
        let mut f = SMatrix::<f64, MAX_NP, 4>::zeros();
        let mut cab = [0.0f64; MAX_NP];
        let mut c_ai = c; // C A^i
        for (i, cab_i) in cab.iter_mut().take(np).enumerate() {
            *cab_i = (c_ai * b)[0];
            c_ai *= a;
            f.fixed_view_mut::<1, 4>(i, 0).copy_from(&c_ai);
        }
        let mut phi = SMatrix::<f64, MAX_NP, MAX_NC>::zeros();
        for i in 0..np {
            for j in 0..=i.min(nc - 1) {
                phi[(i, j)] = cab[i - j];
            }
        }

        // H = Phi^T Phi + r_w I on the nc x nc block; identity on the unused
        // diagonal keeps the padded matrix positive definite without coupling.
        let mut h = phi.transpose() * phi;
        for i in 0..MAX_NC {
            h[(i, i)] += if i < nc { params.rw } else { 1.0 };
        }
        // Right-hand sides: Phi^T F (4 columns) and Phi^T 1 (the reference).
        let mut rhs = SMatrix::<f64, MAX_NC, 5>::zeros();
        rhs.fixed_view_mut::<MAX_NC, 4>(0, 0)
            .copy_from(&(phi.transpose() * f));
        let mut ones = SVector::<f64, MAX_NP>::zeros();
        for i in 0..np {
            ones[i] = 1.0;
        }
        rhs.fixed_view_mut::<MAX_NC, 1>(0, 4)
            .copy_from(&(phi.transpose() * ones));
        let chol = nalgebra::Cholesky::new(h).ok_or(DesignError::Singular)?;
        let sol = chol.solve(&rhs);
        let kx = [sol[(0, 0)], sol[(0, 1)], sol[(0, 2)]];
        let (ky_state, ky) = (sol[(0, 3)], sol[(0, 4)]);
        if !(kx.iter().all(|v| v.is_finite()) && ky.is_finite() && ky_state.is_finite()) {
            return Err(DesignError::Singular);
        }
        Ok(Self {
            params,
            model,
            ad,
            bd,
            a,
            b,
            c,
            f,
            phi,
            kx,
            ky_state,
            ky,
        })
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    fn rel_close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * b.abs()
    }

    #[test]
    fn prediction_model_numbers_of_section_6_2() {
        let m = PredictionModel::new(&PlantParams::NOMINAL).unwrap();
        assert!(rel_close(m.b1_npm, 3.62384751e5, 1e-8));
        assert!(rel_close(m.b2_npm, 5.65929449e5, 1e-8));
        assert!(rel_close(m.ac[(2, 0)], -6.454682e4, 1e-6));
        assert!(rel_close(m.ac[(2, 1)], -1.936405e4, 1e-6));
        assert!(rel_close(m.ac[(2, 2)], -8.905841, 1e-6));
        assert!(rel_close(m.bc[1], 3.0240465e4, 1e-7));
        assert!(rel_close(m.bc[2], -1.6851522e5, 1e-7));
    }

    #[test]
    fn expm_of_diagonal_and_nilpotent() {
        let d = Mat4::from_diagonal(&Vec4::new(-1.0, 0.5, 2.0, -30.0));
        let e = expm4(&d);
        for (i, v) in [-1.0f64, 0.5, 2.0, -30.0].iter().enumerate() {
            assert!(rel_close(e[(i, i)], libm::exp(*v), 1e-13));
        }
        let mut n = Mat4::zeros();
        n[(0, 1)] = 3.0;
        let e = expm4(&n);
        assert_eq!(e[(0, 1)], 3.0);
        assert_eq!(e[(0, 0)], 1.0);
    }

    #[test]
    fn invalid_parameters_are_refused() {
        let p = PlantParams::NOMINAL;
        let ok = MpcParams {
            np: 6,
            nc: 2,
            ts_s: 0.1,
            rw: 33.0,
        };
        assert!(MpcDesign::new(&p, ok).is_ok());
        let bad = [
            (MpcParams { np: 1, ..ok }, DesignError::PredictionHorizon),
            (MpcParams { np: 33, ..ok }, DesignError::PredictionHorizon),
            (MpcParams { nc: 0, ..ok }, DesignError::ControlHorizon),
            (
                MpcParams {
                    nc: 9,
                    np: 20,
                    ..ok
                },
                DesignError::ControlHorizon,
            ),
            (MpcParams { ts_s: 0.0, ..ok }, DesignError::SampleTime),
            (
                MpcParams {
                    ts_s: f64::NAN,
                    ..ok
                },
                DesignError::SampleTime,
            ),
            (MpcParams { rw: -1.0, ..ok }, DesignError::InputWeight),
            (
                MpcParams {
                    rw: f64::INFINITY,
                    ..ok
                },
                DesignError::InputWeight,
            ),
        ];
        for (params, err) in bad {
            assert_eq!(MpcDesign::new(&p, params).unwrap_err(), err, "{params:?}");
        }
        let broken = PlantParams {
            m_kg: 0.0,
            ..PlantParams::NOMINAL
        };
        assert_eq!(MpcDesign::new(&broken, ok).unwrap_err(), DesignError::Model);
    }
}
