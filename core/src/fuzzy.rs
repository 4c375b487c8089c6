//! Fuzzy gain scheduling for the PID (the paper's "fuzzy-PID" baseline), f32.
//!
//! Mamdani inference on the error e = r - Xo and its rate ec = de/dt, once per
//! PID tick, gives increments of Kp, Ki and Kd around the base gains:
//!
//! * Inputs are normalised to the universe [-3, 3]: `3 e / e_span_m`,
//!   `3 ec / ec_span_mps`, saturated at the ends.
//! * Seven triangular sets NB, NM, NS, ZO, PS, PM, PB centred on -3..3, each
//!   one unit wide at its base on either side (a partition of unity), so at
//!   most two sets per input and four rules fire.
//! * Rule strength = min(mu_e, mu_ec); implication = min (clipping);
//!   aggregation = max; defuzzification = centroid of the aggregated set,
//!   sampled on 49 points of the output universe [-3, 3] (step 1/8, exact in
//!   binary so the sum is the same on every target).
//! * Output: dK = centroid / 3 * dk_max; K = K0 + dK, then Kp, Ki, Kd >= 0.
//!
//! ## Rule base
//! Rows are e (NB..PB), columns ec (NB..PB). e > 0 means the piston is short of
//! the reference; e ec > 0 means the error is growing, e ec < 0 that it is
//! closing. Every table is point-symmetric, dK(-e, -ec) = dK(e, ec), because
//! the actuator is controlled the same way in both directions.
//!
//! * Kp: larger when the error is large or growing (fast correction), smaller
//!   when a large error is closing fast (brake before the overshoot).
//! * Ki: small for large errors (no windup during moves), large near the
//!   target while the error is slow (remove the steady-state error of a held
//!   load), reduced when the error closes fast.
//! * Kd: largest near the target with a fast-changing error (damping of the
//!   hydraulic mode after load steps), small during large moves (noise and the
//!   lag of a long stroke).

use crate::mpc::Limits;
use crate::pid::{Pid, PidOutput, PidParams};

/// Linguistic terms, as their centre on the universe [-3, 3].
const NB: i8 = -3;
const NM: i8 = -2;
const NS: i8 = -1;
const ZO: i8 = 0;
const PS: i8 = 1;
const PM: i8 = 2;
const PB: i8 = 3;

/// dKp rules: rows e NB..PB, columns ec NB..PB.
#[rustfmt::skip]
pub const RULES_KP: [[i8; 7]; 7] = [
    [PB, PB, PM, PM, PS, ZO, ZO],
    [PB, PM, PM, PS, PS, ZO, NS],
    [PM, PM, PS, PS, ZO, NS, NS],
    [PS, PS, ZO, ZO, ZO, PS, PS],
    [NS, NS, ZO, PS, PS, PM, PM],
    [NS, ZO, PS, PS, PM, PM, PB],
    [ZO, ZO, PS, PM, PM, PB, PB],
];

/// dKi rules: rows e NB..PB, columns ec NB..PB.
#[rustfmt::skip]
pub const RULES_KI: [[i8; 7]; 7] = [
    [NB, NB, NB, NM, NM, NS, NS],
    [NB, NM, NM, NS, NS, ZO, ZO],
    [NM, NS, NS, ZO, ZO, PS, PS],
    [NS, ZO, PS, PM, PS, ZO, NS],
    [PS, PS, ZO, ZO, NS, NS, NM],
    [ZO, ZO, NS, NS, NM, NM, NB],
    [NS, NS, NM, NM, NB, NB, NB],
];

/// dKd rules: rows e NB..PB, columns ec NB..PB.
#[rustfmt::skip]
pub const RULES_KD: [[i8; 7]; 7] = [
    [NS, NS, NM, NB, NM, NS, NS],
    [ZO, NS, NS, NM, NS, NS, ZO],
    [PS, ZO, NS, NS, NS, ZO, PS],
    [PB, PM, PS, ZO, PS, PM, PB],
    [PS, ZO, NS, NS, NS, ZO, PS],
    [ZO, NS, NS, NM, NS, NS, ZO],
    [NS, NS, NM, NB, NM, NS, NS],
];

/// Fuzzy PID parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FuzzyParams {
    /// Base gains and sample time.
    pub base: PidParams,
    /// Error that maps to the end of the universe (PB), m.
    pub e_span_m: f32,
    /// Error rate that maps to the end of the universe (PB), m/s.
    pub ec_span_mps: f32,
    /// Largest Kp increment, 1/s.
    pub dkp_max: f32,
    /// Largest Ki increment, 1/s^2.
    pub dki_max: f32,
    /// Largest Kd increment.
    pub dkd_max: f32,
}

impl FuzzyParams {
    /// Defaults around the paper's PI gains (Table 2), Kd scheduled from 0.02.
    pub const PAPER: Self = Self {
        base: PidParams {
            kp: 2.7,
            ki: 0.05,
            kd: 0.02,
            ts_s: 0.1,
        },
        e_span_m: 0.02,
        ec_span_mps: 0.1,
        dkp_max: 1.0,
        dki_max: 0.05,
        dkd_max: 0.02,
    };

    /// True when every parameter is finite, spans positive, increments >= 0.
    pub fn is_valid(&self) -> bool {
        self.base.is_valid()
            && [self.e_span_m, self.ec_span_mps]
                .iter()
                .all(|v| v.is_finite() && *v > 0.0)
            && [self.dkp_max, self.dki_max, self.dkd_max]
                .iter()
                .all(|v| v.is_finite() && *v >= 0.0)
    }
}

/// Membership of `x` in the triangular set centred on `c` (unit half-width).
fn membership(x: f32, c: f32) -> f32 {
    let d = 1.0 - (x - c).abs();
    if d > 0.0 {
        d
    } else {
        0.0
    }
}

/// The (at most two) sets an input in [-3, 3] belongs to: (row index, degree).
fn fuzzify(x: f32) -> [(usize, f32); 2] {
    // x in [-3, 3]: lower centre index 0..=5, upper = lower + 1.
    let lo = libm::floorf(x + 3.0);
    let lo = if lo < 0.0 {
        0
    } else if lo > 5.0 {
        5
    } else {
        lo as usize
    };
    let c_lo = lo as f32 - 3.0;
    [
        (lo, membership(x, c_lo)),
        (lo + 1, membership(x, c_lo + 1.0)),
    ]
}

/// Mamdani inference of one table: centroid on [-3, 3].
pub fn infer(table: &[[i8; 7]; 7], e_n: f32, ec_n: f32) -> f32 {
    infer_sets(table, &fuzzify(e_n), &fuzzify(ec_n))
}

/// Membership degrees b/8, b = 0..=8, of the sample points in a triangle.
const EIGHTHS: [f32; 9] = [0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, 1.0];

/// [`infer`] from the fuzzified inputs (the same numbers as clipping the four
/// rules at every sample point and taking the largest, computed with less work):
///
/// * rules with the same output centre c clip the same triangle m(x, c), and
///   max_r min(m, w_r) = min(m, max_r w_r): one strength per centre suffices;
/// * the sample point x = a - 3 + b/8 (b = 0..7) is inside the triangles of the
///   centres a - 3 (m = 1 - b/8) and a - 2 (m = b/8) only, and both degrees are
///   exact in binary, as in the direct evaluation;
/// * where both strengths are 0 the aggregated degree is 0, and adding 0 x to
///   the numerator and 0 to the denominator leaves them unchanged (neither is
///   ever -0), so those 8 points are skipped.
///
/// The sums are formed in the same order with the same operands, so the
/// result is bit-identical to the direct evaluation.
fn infer_sets(table: &[[i8; 7]; 7], fe: &[(usize, f32); 2], fc: &[(usize, f32); 2]) -> f32 {
    // Strength per output centre c (index c + 3); index 7 stays 0.
    let mut strength = [0.0f32; 8];
    for &(i, mu_e) in fe {
        for &(j, mu_c) in fc {
            let w = if mu_e < mu_c { mu_e } else { mu_c };
            // i, j <= 6 (fuzzify); the masks only spare the bounds checks.
            let s = &mut strength[(table[i.min(6)][j.min(6)] + 3) as usize & 7];
            if w > *s {
                *s = w;
            }
        }
    }
    let (mut num, mut den) = (0.0f32, 0.0f32);
    for a in 0..7 {
        let (s_lo, s_hi) = (strength[a], strength[a + 1]);
        if !(s_lo > 0.0 || s_hi > 0.0) {
            continue;
        }
        // The last segment is the single point x = 3.
        let points = if a == 6 { 1 } else { 8 };
        // Every degree and strength is +0 or positive, where the order of the
        // bit patterns is the order of the values: min and max on the bits.
        let (s_lo, s_hi) = (s_lo.to_bits(), s_hi.to_bits());
        for b in 0..points {
            let x = (8 * a + b) as f32 * 0.125 - 3.0;
            let (m_lo, m_hi) = (EIGHTHS[8 - b].to_bits(), EIGHTHS[b].to_bits());
            let mu = f32::from_bits(m_lo.min(s_lo).max(m_hi.min(s_hi)));
            num += mu * x;
            den += mu;
        }
    }
    if den > 0.0 {
        num / den
    } else {
        0.0
    }
}

fn normalise(x: f32, span: f32) -> f32 {
    let v = 3.0 * x / span;
    if v > 3.0 {
        3.0
    } else if v >= -3.0 {
        v
    } else {
        -3.0
    }
}

fn non_negative(x: f32) -> f32 {
    if x > 0.0 {
        x
    } else {
        0.0
    }
}

/// Fuzzy PID state: the PID plus the previous error for ec.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FuzzyPid {
    /// The PID whose gains are scheduled.
    pub pid: Pid,
    /// Error at the previous tick, m.
    pub e_prev_m: f32,
    /// Gains used at the last tick.
    pub gains: Option<PidParams>,
}

impl FuzzyPid {
    /// Start from rest with the power piston at `u0_m`.
    pub fn new(u0_m: f32) -> Self {
        Self {
            pid: Pid::new(u0_m),
            ..Self::default()
        }
    }

    /// The gains the rule base gives for error `e_m` and error rate `ec_mps`.
    pub fn schedule(p: &FuzzyParams, e_m: f32, ec_mps: f32) -> PidParams {
        let fe = fuzzify(normalise(e_m, p.e_span_m));
        let fc = fuzzify(normalise(ec_mps, p.ec_span_mps));
        let b = &p.base;
        PidParams {
            kp: non_negative(b.kp + infer_sets(&RULES_KP, &fe, &fc) / 3.0 * p.dkp_max),
            ki: non_negative(b.ki + infer_sets(&RULES_KI, &fe, &fc) / 3.0 * p.dki_max),
            kd: non_negative(b.kd + infer_sets(&RULES_KD, &fe, &fc) / 3.0 * p.dkd_max),
            ts_s: b.ts_s,
        }
    }

    /// One tick: schedule the gains, then run the PID with them.
    pub fn tick(&mut self, p: &FuzzyParams, lim: &Limits, y_m: f32, r_m: f32) -> PidOutput {
        let e = r_m - y_m;
        let ec = if self.pid.started {
            (e - self.e_prev_m) / p.base.ts_s
        } else {
            0.0
        };
        let g = Self::schedule(p, e, ec);
        self.e_prev_m = e;
        self.gains = Some(g);
        self.pid.tick(&g, lim, y_m, r_m)
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    /// The direct evaluation: four clipped rules at each of the 49 points.
    fn infer_reference(table: &[[i8; 7]; 7], e_n: f32, ec_n: f32) -> f32 {
        let (fe, fc) = (fuzzify(e_n), fuzzify(ec_n));
        let mut rules = [(0.0f32, 0.0f32); 4];
        let mut k = 0;
        for &(i, mu_e) in &fe {
            for &(j, mu_c) in &fc {
                let w = if mu_e < mu_c { mu_e } else { mu_c };
                rules[k] = (w, table[i][j] as f32);
                k += 1;
            }
        }
        let (mut num, mut den) = (0.0f32, 0.0f32);
        for n in 0..49 {
            let x = n as f32 * 0.125 - 3.0;
            let mut mu = 0.0f32;
            for &(w, c) in &rules {
                let m = membership(x, c);
                let clipped = if m < w { m } else { w };
                if clipped > mu {
                    mu = clipped;
                }
            }
            num += mu * x;
            den += mu;
        }
        if den > 0.0 {
            num / den
        } else {
            0.0
        }
    }

    #[test]
    fn inference_is_bit_identical_to_the_direct_evaluation() {
        // A fine grid (every sample point and halfway between), an irregular
        // sweep and values next to the set boundaries.
        let mut inputs = [0.0f32; 97 + 438 + 6];
        for (i, v) in inputs.iter_mut().enumerate().take(97) {
            *v = i as f32 * 0.0625 - 3.0;
        }
        for (i, v) in inputs[97..97 + 438].iter_mut().enumerate() {
            *v = -3.0 + i as f32 * 0.0137;
        }
        inputs[97 + 438..].copy_from_slice(&[
            -2.999_999_8,
            2.999_999_8,
            -0.0,
            1e-7,
            -1e-7,
            0.999_999_94,
        ]);
        for t in [&RULES_KP, &RULES_KI, &RULES_KD] {
            for &e in &inputs {
                for &ec in inputs.iter().step_by(7) {
                    let (got, want) = (infer(t, e, ec), infer_reference(t, e, ec));
                    assert_eq!(got.to_bits(), want.to_bits(), "({e}, {ec})");
                }
            }
        }
    }

    #[test]
    fn tables_are_point_symmetric() {
        for t in [&RULES_KP, &RULES_KI, &RULES_KD] {
            for i in 0..7 {
                for j in 0..7 {
                    assert_eq!(t[i][j], t[6 - i][6 - j], "({i},{j})");
                }
            }
        }
    }

    #[test]
    fn fuzzification_is_a_partition_of_unity() {
        let mut x = -3.0f32;
        while x <= 3.0 {
            let f = fuzzify(x);
            assert!((f[0].1 + f[1].1 - 1.0).abs() < 1e-6, "{x}");
            x += 0.037;
        }
        assert_eq!(fuzzify(3.0)[1], (6, 1.0));
        assert_eq!(fuzzify(-3.0)[0], (0, 1.0));
    }

    #[test]
    fn single_rule_gives_its_centre() {
        // Exactly on the centres: one rule fires fully; a clipped triangle's
        // centroid is its centre except at the universe's edges.
        for i in 1..6 {
            for j in 0..7 {
                let want = RULES_KP[i][j] as f32;
                if want.abs() < 3.0 {
                    let got = infer(&RULES_KP, i as f32 - 3.0, j as f32 - 3.0);
                    assert!((got - want).abs() < 1e-5, "({i},{j}): {got}");
                }
            }
        }
    }

    #[test]
    fn schedule_follows_the_rules_at_the_corners() {
        let p = FuzzyParams::PAPER;
        // Large positive error, growing: Kp up, Ki down, Kd down.
        let g = FuzzyPid::schedule(&p, 1.0, 1.0);
        assert!(g.kp > p.base.kp + 0.5 * p.dkp_max);
        assert!(g.ki < p.base.ki);
        assert!(g.kd < p.base.kd);
        // On target, still: Ki up, Kp nominal.
        let g = FuzzyPid::schedule(&p, 0.0, 0.0);
        assert!(g.ki > p.base.ki);
        assert!((g.kp - p.base.kp).abs() < 1e-6);
        // Gains never negative whatever the increments.
        let harsh = FuzzyParams {
            dkp_max: 100.0,
            dki_max: 100.0,
            dkd_max: 100.0,
            ..p
        };
        for (e, ec) in [(1.0, -1.0), (-1.0, 1.0), (0.0, 1.0), (0.01, 0.0)] {
            let g = FuzzyPid::schedule(&harsh, e, ec);
            assert!(g.kp >= 0.0 && g.ki >= 0.0 && g.kd >= 0.0);
        }
    }

    #[test]
    fn tick_moves_towards_the_reference() {
        let lim = Limits::from_plant(&crate::params::PlantParams::NOMINAL);
        let mut f = FuzzyPid::new(0.0);
        let out = f.tick(&FuzzyParams::PAPER, &lim, 0.0, 0.01);
        assert!(out.v_cmd_mps > 0.0);
        let out = f.tick(&FuzzyParams::PAPER, &lim, 0.02, 0.01);
        assert!(out.v_cmd_mps < 0.0);
    }
}
