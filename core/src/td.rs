//! Han's tracking differentiator (docs/model.md section 6.6), f32.
//!
//! ```text
//! fhan(x1, x2, r, h0): d = r h0; d0 = h0 d; y = x1 + h0 x2; a0 = sqrt(d^2 + 8 r |y|)
//!    a = x2 + (a0 - d)/2 sign(y)  if |y| > d0  else  x2 + y/h0
//!    fhan = -r sign(a)            if |a| > d   else  -r a/d
//! v1 += h v2 ;  v2 += h fhan(v1 - r_cmd, v2, r, h0)   (old values on the right)
//! ```

/// Parameters of the tracking differentiator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TdParams {
    /// Acceleration limit r (Table 2 "b"), m/s^2.
    pub r_mps2: f32,
    /// Filter factor h0 (Table 2 "h0"), s.
    pub h0_s: f32,
    /// Update period h, s.
    pub h_s: f32,
}

impl TdParams {
    /// The paper's values (docs/model.md section 6.6).
    pub const PAPER: Self = Self {
        r_mps2: 8.0,
        h0_s: 0.005,
        h_s: 0.006,
    };

    /// True when every parameter is finite and positive.
    pub fn is_valid(&self) -> bool {
        [self.r_mps2, self.h0_s, self.h_s]
            .iter()
            .all(|v| v.is_finite() && *v > 0.0)
    }
}

fn sign(x: f32) -> f32 {
    if x > 0.0 {
        1.0
    } else if x < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Han's time-optimal synthesis function.
pub fn fhan(x1: f32, x2: f32, r: f32, h0: f32) -> f32 {
    let d = r * h0;
    let d0 = h0 * d;
    let y = x1 + h0 * x2;
    let a0 = libm::sqrtf(d * d + 8.0 * r * y.abs());
    let a = if y.abs() > d0 {
        x2 + (a0 - d) / 2.0 * sign(y)
    } else {
        x2 + y / h0
    };
    if a.abs() > d {
        -r * sign(a)
    } else {
        -r * a / d
    }
}

/// Tracking differentiator state: v1 follows the command, v2 is its rate.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Td {
    /// Smoothed reference, m.
    pub v1_m: f32,
    /// Its rate, m/s.
    pub v2_mps: f32,
}

impl Td {
    /// One update towards `r_cmd_m`.
    pub fn update(&mut self, p: &TdParams, r_cmd_m: f32) {
        let v1 = self.v1_m + p.h_s * self.v2_mps;
        let v2 = self.v2_mps + p.h_s * fhan(self.v1_m - r_cmd_m, self.v2_mps, p.r_mps2, p.h0_s);
        self.v1_m = v1;
        self.v2_mps = v2;
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    #[test]
    fn check_vector_of_section_6_6() {
        let mut td = Td::default();
        for _ in 0..10 {
            td.update(&TdParams::PAPER, 0.05);
        }
        assert!((td.v1_m - 0.01296).abs() < 1e-6, "{}", td.v1_m);
        assert!((td.v2_mps - 0.48).abs() < 1e-5, "{}", td.v2_mps);
    }

    #[test]
    fn settles_on_the_command() {
        let mut td = Td::default();
        for _ in 0..200 {
            td.update(&TdParams::PAPER, 0.05);
        }
        assert!((td.v1_m - 0.05).abs() < 1e-5, "{}", td.v1_m);
        assert!(td.v2_mps.abs() < 1e-3);
    }

    #[test]
    fn fhan_linear_and_bang_bang_zones() {
        // Far away: full acceleration towards the target.
        assert_eq!(fhan(-1.0, 0.0, 8.0, 0.005), 8.0);
        assert_eq!(fhan(1.0, 0.0, 8.0, 0.005), -8.0);
        assert_eq!(fhan(0.0, 0.0, 8.0, 0.005), 0.0);
    }
}
