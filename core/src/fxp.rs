//! Fixed-point arithmetic for the ESO: Q formats, scaled constants, log2/exp2.
//!
//! Every signal is an `i32` with an explicit number of fractional bits, carried
//! by a type from the `fixed` crate so the scaling is visible in every
//! signature. Products go through `i64` and are rounded to nearest (ties
//! upwards) when shifted back, then saturated. Only integer operations are
//! used, so results are bit-identical on every target.
//!
//! | type | Q format | range | resolution | physical range it carries |
//! |------|----------|-------|------------|---------------------------|
//! | [`Pos`] | Q4.28 (I4F28) | +-8 m | 3.7e-9 m | stroke -0.01..0.11 m; ESO error; fal outputs (m^alpha, <= 2.9) |
//! | [`Vel`] | Q8.24 (I8F24) | +-128 m/s | 6.0e-8 m/s | piston speeds <= 0.2 m/s, commands <= 0.1 m/s |
//! | [`Acc`] | Q16.16 (I16F16) | +-32768 m/s^2 | 1.5e-5 m/s^2 | piston accelerations <= ~50 m/s^2 |
//! | log2 (`i32`, [`LOG2_FRAC`]) | Q8.24 | +-128 | 6.0e-8 | log2 of a `Pos` magnitude, -28..3 |
//!
//! The ranges leave two orders of magnitude of headroom above the physical
//! signals, so saturation only happens on absurd inputs (and then it is
//! defined, not a wrap-around).

use fixed::types::{I16F16, I4F28, I8F24};

/// Position, error and fal output: Q4.28, metres (or m^alpha for fal).
pub type Pos = I4F28;
/// Velocity: Q8.24, m/s.
pub type Vel = I8F24;
/// Acceleration: Q16.16, m/s^2.
pub type Acc = I16F16;

/// Fractional bits of [`Pos`].
pub const POS_FRAC: u32 = 28;
/// Fractional bits of [`Vel`].
pub const VEL_FRAC: u32 = 24;
/// Fractional bits of [`Acc`].
pub const ACC_FRAC: u32 = 16;
/// Fractional bits of a base-2 logarithm.
pub const LOG2_FRAC: u32 = 24;

/// Saturate an `i64` to the `i32` range.
#[inline]
pub fn sat32(x: i64) -> i32 {
    if x > i32::MAX as i64 {
        i32::MAX
    } else if x < i32::MIN as i64 {
        i32::MIN
    } else {
        x as i32
    }
}

/// Arithmetic shift of an `i64` by `sh` bits: right with round-to-nearest
/// (ties upwards) when `sh > 0`, left with saturation when `sh < 0`.
pub fn shift_round(p: i64, sh: i32) -> i64 {
    if sh > 0 {
        if sh >= 63 {
            // |p| < 2^62: the rounded result is 0 (or -1 for tiny negatives: 0 is nearer).
            return 0;
        }
        // (p + 2^(sh-1)) >> sh, computed as ((p >> (sh-1)) + 1) >> 1: with
        // p = q 2^(sh-1) + rest (0 <= rest < 2^(sh-1)) both are
        // floor((q + 1)/2), and this form needs no 64-bit constant.
        ((p >> (sh - 1)) + 1) >> 1
    } else if sh < 0 {
        let l = (-sh) as u32;
        if l >= 62 {
            return if p > 0 {
                i64::MAX
            } else if p < 0 {
                i64::MIN
            } else {
                0
            };
        }
        p.saturating_mul(1i64 << l)
    } else {
        p
    }
}

/// `2^e` as an `f32`, for `-126 <= e <= 127`.
const fn pow2_f32(e: i32) -> f32 {
    f32::from_bits(((127 + e) as u32) << 23)
}

/// A Q value with `FRAC` fractional bits as the nearest `f32` (ties to even):
/// the same value as the `fixed` types' `to_num::<f32>()`, for `FRAC <= 32`.
///
/// The integer-to-float conversion rounds once (to nearest, ties to even) and
/// the scaling by a power of two is exact, so this is one `vcvt` and one `vmul`
/// on a Cortex-M4 instead of a software conversion.
#[inline]
pub fn q_to_f32<const FRAC: i32>(bits: i32) -> f32 {
    bits as f32 * pow2_f32(-FRAC)
}

/// A finite `f32` to a Q value with `FRAC` fractional bits, rounded to nearest
/// (ties to even) and saturated to the `i32` range: the same value as the
/// `fixed` types' `saturating_from_num`, for `FRAC <= 32`. NaN gives 0 (where
/// `saturating_from_num` panics).
///
/// The scaling by 2^FRAC is exact (it can only overflow to infinity, which
/// saturates); below 2^23 adding and removing 2^23 rounds to an integer in the
/// default rounding mode (ties to even); from 2^23 on every `f32` is an integer.
#[inline]
pub fn f32_to_q<const FRAC: i32>(x: f32) -> i32 {
    const TWO_23: f32 = 8_388_608.0;
    let s = x * pow2_f32(FRAC);
    let a = s.abs();
    let r = if a < TWO_23 {
        ((a + TWO_23) - TWO_23).copysign(s)
    } else {
        s
    };
    // `as` saturates at the i32 range.
    r as i32
}

/// A real constant as a normalised mantissa and a binary exponent:
/// `value = mant * 2^-shift`, `2^30 <= |mant| < 2^31` (or `mant = 0`).
///
/// It keeps 31 significant bits whatever the constant's magnitude, which is
/// what the ESO's products `h beta_i` (1e-4 .. 1) need.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Coeff {
    mant: i32,
    shift: i32,
}

impl Coeff {
    /// The zero constant.
    pub const ZERO: Self = Self { mant: 0, shift: 0 };

    /// Round a finite `f64` to the nearest representable constant.
    ///
    /// Returns `None` for non-finite values and for magnitudes of 2^60 or more.
    pub fn from_f64(c: f64) -> Option<Self> {
        if !c.is_finite() || c.abs() >= 1.152_921_504_606_847e18 {
            return None;
        }
        if c == 0.0 {
            return Some(Self::ZERO);
        }
        // c = f 2^e with 0.5 <= |f| < 1, so f 2^31 has 31 significant bits.
        let (f, e) = libm::frexp(c);
        let mut mant = libm::round(f * 2_147_483_648.0) as i64;
        let mut shift = 31 - e;
        if mant.abs() >= 1i64 << 31 {
            mant /= 2;
            shift -= 1;
        }
        // Constants below 2^-90 are zero for every product the ESO forms.
        if shift > 120 {
            return Some(Self::ZERO);
        }
        Some(Self {
            mant: mant as i32,
            shift,
        })
    }

    /// The constant as an `f64` (exact).
    pub fn to_f64(self) -> f64 {
        self.mant as f64 * libm::exp2(-(self.shift as f64))
    }

    /// `self * x` where `x` has `fin` fractional bits; the result has `fout`
    /// fractional bits, rounded to nearest, not yet saturated.
    #[inline]
    pub fn mul(self, x: i32, fin: u32, fout: u32) -> i64 {
        let p = self.mant as i64 * x as i64;
        shift_round(p, self.shift + fin as i32 - fout as i32)
    }
}

/// 2^(2^-i) in Q30 for i = 1..=24, computed at compile time with exact integer
/// square roots in Q62 and rounded once to Q30.
const EXP2_TABLE: [u64; 24] = exp2_table();

const fn exp2_table() -> [u64; 24] {
    let mut t62 = [0u128; 24];
    // 2^(1/2) in Q62 = isqrt(2 * 2^124).
    t62[0] = (2u128 << 124).isqrt();
    let mut i = 1;
    while i < 24 {
        t62[i] = (t62[i - 1] << 62).isqrt();
        i += 1;
    }
    let mut out = [0u64; 24];
    let mut i = 0;
    while i < 24 {
        out[i] = ((t62[i] + (1u128 << 31)) >> 32) as u64;
        i += 1;
    }
    out
}

/// Base-2 logarithm of a positive Q4.28 value, in Q8.24.
///
/// Normalises to a mantissa in [1, 2) (Q30) and extracts 24 fraction bits by
/// repeated squaring. Absolute error below 2^-23 (measured: see tests).
/// Returns `None` for `x <= 0`.
pub fn log2_pos(x: Pos) -> Option<i32> {
    let raw = x.to_bits();
    if raw <= 0 {
        return None;
    }
    Some(log2_raw(raw))
}

/// [`log2_pos`] of a raw Q4.28 value `raw > 0`.
///
/// The mantissa m stays within [2^30, 2^31) at the top of every iteration, so
/// the square is a 32 x 32 -> 64-bit multiply (one `umlal` on a Cortex-M) and
/// the halving step is taken without a branch: the loop's instruction count
/// does not depend on the data.
#[inline]
fn log2_raw(raw: i32) -> i32 {
    let n = 31 - raw.leading_zeros() as i32; // position of the leading one, 0..=30
    let mut m: u32 = (raw as u32) << (30 - n); // [2^30, 2^31): mantissa in Q30
    let mut frac: u32 = 0;
    let mut i = 0;
    while i < LOG2_FRAC {
        // m^2 in Q30 rounded is (m^2 + 2^29) >> 30; when that reaches 2.0
        // (2^31) it is halved with rounding: ((q >> 30) + 1) >> 1 =
        // ((q + 2^30) >> 30) >> 1 with q = m^2 + 2^29 (both are
        // floor((q + 2^30) / 2^31)). m stays in [2^30, 2^31): q < 2^62, so
        // `big` is the bit q >> 61 and (q + 2^30) >> 30 fits in 32 bits.
        let q = m as u64 * m as u64 + (1 << 29);
        let big = (q >> 61) as u32;
        m = (((q + ((big as u64) << 30)) >> 30) as u32) >> big;
        // The fraction bits arrive most significant first.
        frac = (frac << 1) | big;
        i += 1;
    }
    ((n - POS_FRAC as i32) << LOG2_FRAC) + frac as i32
}

/// 2^v for `v` in Q8.24, as a Q4.28 value (saturated to its range).
///
/// The running product r stays in [2^30, 2^31) (a product of factors in
/// [1, 2) whose exponents sum to less than 1), so every step is a 32 x 32 ->
/// 64-bit multiply. Only the set fraction bits cost a multiply; they are taken
/// most significant first (the order of the rounded products matters), found
/// with a count of leading zeros.
pub fn exp2_to_pos(v: i32) -> Pos {
    let ip = v >> LOG2_FRAC; // floor
    let mut bits = (v & ((1 << LOG2_FRAC) - 1)) as u32;
    let mut r: u32 = 1 << 30; // 1.0 in Q30
    while bits != 0 {
        let lz = bits.leading_zeros(); // 8..=31: bit 31 - lz, table entry lz - 8
                                       // (r t + 2^29) >> 30 < 2^31: fits in u32.
        r = ((r as u64 * EXP2_BY_LZ[(lz & 31) as usize] as u64 + (1 << 29)) >> 30) as u32;
        bits &= !(1 << (31 - lz));
    }
    // r in [2^30, 2^31) is 2^fp in Q30; scale by 2^ip into Q28.
    let out = shift_round(r as i64, 30 - POS_FRAC as i32 - ip);
    Pos::from_bits(sat32(out))
}

/// [`EXP2_TABLE`] as `u32` (every entry is below 2^31), indexed by the leading
/// zeros of the 24-bit fraction bit it belongs to: entry `8 + i` is 2^(2^-(i+1)).
const EXP2_BY_LZ: [u32; 32] = {
    let mut out = [0u32; 32];
    let mut i = 0;
    while i < 24 {
        assert!(EXP2_TABLE[i] < 1 << 31);
        out[8 + i] = EXP2_TABLE[i] as u32;
        i += 1;
    }
    out
};

/// Han's fal function, precomputed for one exponent and linear-zone width.
///
/// `fal(e) = e / delta^(1-alpha)` for `|e| <= delta`, `|e|^alpha sign(e)` otherwise.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fal {
    /// Exponent alpha in Q2.30, 0 < alpha <= 1.
    alpha_q30: i32,
    /// Linear-zone half width delta.
    delta: Pos,
    /// Linear-zone slope delta^(alpha - 1).
    slope: Coeff,
}

impl Fal {
    /// Precompute fal for `alpha` in (0, 1] and `delta` in (0, 8) m.
    pub fn new(alpha: f64, delta_m: f64) -> Option<Self> {
        if !(alpha > 0.0 && alpha <= 1.0 && delta_m > 0.0 && delta_m < 7.9) {
            return None;
        }
        // delta_m * 2^28 < 2^31 here, and below 2^52 adding and removing 2^52
        // rounds to an integer (ties to even): `Pos::checked_from_num(delta_m)`
        // without the generic conversion code.
        const TWO_52: f64 = 4_503_599_627_370_496.0;
        let delta =
            Pos::from_bits(((delta_m * (1u32 << POS_FRAC) as f64 + TWO_52) - TWO_52) as i32);
        if delta.to_bits() <= 0 {
            return None;
        }
        let alpha_q30 = libm::round(alpha * 1_073_741_824.0) as i32;
        // The slope delta^(alpha - 1) is delta^alpha / delta, with delta^alpha from the
        // same fixed-point power the outer branch evaluates: both branches give the
        // same value at the quantised delta, and no f64 `pow` (3 KB of flash on the
        // board) is linked. Both operands as f64 are exact (Q4.28 bits below 2^31).
        let mut fal = Self {
            alpha_q30,
            delta,
            slope: Coeff::ZERO,
        };
        let at_delta = fal.power(delta, log2_raw(delta.to_bits()));
        fal.slope = Coeff::from_f64(at_delta.to_bits() as f64 / delta.to_bits() as f64)?;
        Some(fal)
    }

    /// fal(e) for an error in Q4.28; result in Q4.28 (m^alpha).
    pub fn eval(&self, e: Pos) -> Pos {
        let ae = e.saturating_abs();
        if ae <= self.delta {
            return self.linear(e);
        }
        // ae > delta > 0, so the logarithm exists.
        self.power(e, log2_raw(ae.to_bits()))
    }

    /// `(a.eval(e), b.eval(e))`, with the logarithm of |e| taken at most once.
    #[inline]
    pub fn eval_pair(a: &Self, b: &Self, e: Pos) -> (Pos, Pos) {
        let ae = e.saturating_abs();
        let (lin_a, lin_b) = (ae <= a.delta, ae <= b.delta);
        // Only used where ae > delta > 0: the logarithm exists.
        let l = if lin_a && lin_b {
            0
        } else {
            log2_raw(ae.to_bits())
        };
        let fa = if lin_a { a.linear(e) } else { a.power(e, l) };
        let fb = if lin_b { b.linear(e) } else { b.power(e, l) };
        (fa, fb)
    }

    /// The linear zone: `e delta^(alpha - 1)`.
    #[inline]
    fn linear(&self, e: Pos) -> Pos {
        Pos::from_bits(sat32(self.slope.mul(e.to_bits(), POS_FRAC, POS_FRAC)))
    }

    /// Outside the linear zone: `|e|^alpha sign(e)` from `l = log2 |e|` (Q8.24).
    #[inline]
    fn power(&self, e: Pos, l: i32) -> Pos {
        let v = shift_round(l as i64 * self.alpha_q30 as i64, 30);
        let mag = exp2_to_pos(sat32(v));
        if e.is_negative() {
            -mag
        } else {
            mag
        }
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    #[test]
    fn coeff_round_trip_keeps_31_bits() {
        for c in [
            0.18,
            0.6,
            0.24,
            1.2e-4,
            0.006,
            1.0,
            -3.5,
            14.142135623730951,
            1e-9,
            123456.0,
        ] {
            let k = Coeff::from_f64(c).unwrap();
            let err = ((k.to_f64() - c) / c).abs();
            assert!(err <= 2f64.powi(-31), "{c}: {err:e}");
        }
        assert_eq!(Coeff::from_f64(0.0), Some(Coeff::ZERO));
        assert_eq!(Coeff::from_f64(f64::NAN), None);
        assert_eq!(Coeff::from_f64(f64::INFINITY), None);
        assert_eq!(Coeff::from_f64(1e30), None);
    }

    #[test]
    fn coeff_mul_rounds_to_nearest_and_saturates_left_shifts() {
        let half = Coeff::from_f64(0.5).unwrap();
        // 3 * 0.5 = 1.5 -> 2 (ties upwards), -3 * 0.5 = -1.5 -> -1.
        assert_eq!(half.mul(3, 0, 0), 2);
        assert_eq!(half.mul(-3, 0, 0), -1);
        let big = Coeff::from_f64(1e15).unwrap();
        assert_eq!(big.mul(i32::MAX, 0, 30), i64::MAX);
        assert_eq!(big.mul(i32::MIN, 0, 30), i64::MIN);
    }

    /// The first implementation of `log2_pos` (64-bit, branching): the
    /// optimised one must give the same bits.
    fn log2_reference(x: Pos) -> Option<i32> {
        let raw = x.to_bits();
        if raw <= 0 {
            return None;
        }
        let n = 31 - raw.leading_zeros() as i32;
        let mut m: u64 = (raw as u64) << (30 - n);
        let mut frac: i32 = 0;
        let mut i = 1;
        while i <= LOG2_FRAC as i32 {
            m = (m * m + (1u64 << 29)) >> 30;
            if m >= 1u64 << 31 {
                m = (m + 1) >> 1;
                frac |= 1 << (LOG2_FRAC as i32 - i);
            }
            i += 1;
        }
        Some(((n - POS_FRAC as i32) << LOG2_FRAC) + frac)
    }

    /// The first implementation of `exp2_to_pos` (a 64-bit multiply per set bit).
    fn exp2_reference(v: i32) -> Pos {
        let ip = v >> LOG2_FRAC;
        let fp = v & ((1 << LOG2_FRAC) - 1);
        let mut r: u64 = 1 << 30;
        for i in 0..LOG2_FRAC as usize {
            if fp & (1 << (LOG2_FRAC as usize - 1 - i)) != 0 {
                r = (r * EXP2_TABLE[i] + (1 << 29)) >> 30;
            }
        }
        let sh = 30 - POS_FRAC as i32 - ip;
        let out = if sh > 0 {
            if sh >= 63 {
                0
            } else {
                (r as i64 + (1i64 << (sh - 1))) >> sh
            }
        } else {
            shift_round(r as i64, sh)
        };
        Pos::from_bits(sat32(out))
    }

    /// Odd strides through the whole i32 range, plus the ends.
    fn sweep(stride: u32) -> impl Iterator<Item = i32> {
        (0..=u32::MAX / stride)
            .map(move |i| i.wrapping_mul(stride) as i32)
            .chain([i32::MIN, -1, 0, 1, i32::MAX])
    }

    #[test]
    fn log2_and_exp2_are_bit_identical_to_the_reference() {
        for v in sweep(65_537) {
            let x = Pos::from_bits(v);
            assert_eq!(log2_pos(x), log2_reference(x), "log2 {v}");
            assert_eq!(exp2_to_pos(v), exp2_reference(v), "exp2 {v}");
        }
        // Every fraction bit pattern of exp2 at one integer part.
        for fp in (0..1 << 24).step_by(97) {
            let v = (-3 << 24) | fp;
            assert_eq!(exp2_to_pos(v), exp2_reference(v), "exp2 {v}");
        }
        // Mantissas next to 2.0, where the halving step of log2 rounds.
        for raw in (i32::MAX - 5_000..=i32::MAX).chain((1 << 30) - 5_000..(1 << 30) + 5_000) {
            let x = Pos::from_bits(raw);
            assert_eq!(log2_pos(x), log2_reference(x), "log2 {raw}");
        }
    }

    #[test]
    fn shift_round_matches_add_then_shift() {
        for p in sweep(1_000_003).map(|v| (v as i64) << 30 | (v as u32 as i64 & 0x3fff_ffff)) {
            for sh in 1..63 {
                assert_eq!(
                    shift_round(p, sh),
                    (p + (1i64 << (sh - 1))) >> sh,
                    "{p} {sh}"
                );
            }
        }
    }

    #[test]
    fn fal_delta_rounds_as_fixed_does_and_the_branches_meet() {
        // Random deltas, and exact ties at the Q4.28 resolution.
        let mut x: u64 = 0x853C_49E6_748F_EA9B;
        for i in 0..20_000u32 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let d = if i % 2 == 0 {
                (x >> 11) as f64 / (1u64 << 53) as f64 * 7.9
            } else {
                ((x % (1 << 31)) as f64 + 0.5) / (1u64 << POS_FRAC) as f64
            };
            if let Some(f) = Fal::new(0.5, d) {
                assert_eq!(Some(f.delta), Pos::checked_from_num(d), "{d:e}");
                // The slope is delta^-1/2 to the precision of the fixed-point power
                // (its result has at least 2^14 counts at the smallest delta)...
                let slope = libm::pow(f.delta.to_num::<f64>(), -0.5);
                let rel = (f.slope.to_f64() - slope).abs() / slope;
                assert!(rel <= 1e-4, "{d:e}: slope off by {rel:e}");
                // ...and the two branches meet at delta to one count.
                let at = f.power(f.delta, log2_raw(f.delta.to_bits()));
                let lin = f.linear(f.delta);
                assert!(
                    (at.to_bits() - lin.to_bits()).abs() <= 1,
                    "{d:e}: {at} vs {lin}"
                );
            }
        }
    }

    #[test]
    fn fal_pair_equals_two_evaluations() {
        let a = Fal::new(0.5, 0.005).unwrap();
        let b = Fal::new(0.25, 0.01).unwrap();
        for e in sweep(40_009) {
            let e = Pos::from_bits(e);
            assert_eq!(Fal::eval_pair(&a, &b, e), (a.eval(e), b.eval(e)), "{e}");
            assert_eq!(Fal::eval_pair(&b, &a, e), (b.eval(e), a.eval(e)), "{e}");
        }
    }

    #[test]
    fn float_conversions_equal_the_fixed_crate() {
        use fixed::types::{I16F16, I8F24};
        for v in sweep(3_001) {
            assert_eq!(
                q_to_f32::<28>(v).to_bits(),
                Pos::from_bits(v).to_num::<f32>().to_bits()
            );
            assert_eq!(
                q_to_f32::<24>(v).to_bits(),
                I8F24::from_bits(v).to_num::<f32>().to_bits()
            );
            assert_eq!(
                q_to_f32::<16>(v).to_bits(),
                I16F16::from_bits(v).to_num::<f32>().to_bits()
            );
        }
        let specials = [
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.5,
            2.5,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ];
        let fs = sweep(3_001)
            .map(|v| f32::from_bits(v as u32))
            .chain(specials)
            .filter(|x| !x.is_nan());
        for x in fs {
            assert_eq!(
                f32_to_q::<28>(x),
                Pos::saturating_from_num(x).to_bits(),
                "{x:e}"
            );
            assert_eq!(
                f32_to_q::<24>(x),
                I8F24::saturating_from_num(x).to_bits(),
                "{x:e}"
            );
            // Ties at the resolution of the format.
            let t = (x.to_bits() as i32 >> 8) as f32 + 0.5;
            assert_eq!(
                f32_to_q::<0>(t),
                fixed::types::I32F0::saturating_from_num(t).to_bits(),
                "{t:e}"
            );
        }
        assert_eq!(f32_to_q::<28>(f32::NAN), 0);
    }

    #[test]
    fn exp2_table_matches_libm() {
        for (i, &t) in EXP2_TABLE.iter().enumerate() {
            let want = libm::exp2(libm::exp2(-((i + 1) as f64))) * 2f64.powi(30);
            assert!((t as f64 - want).abs() <= 0.5, "entry {i}: {t} vs {want}");
        }
    }

    #[test]
    fn log2_over_the_pos_range() {
        let mut worst = 0.0f64;
        let mut raw: i32 = 1;
        while raw < i32::MAX / 2 {
            for r in [raw, raw + raw / 3, raw + raw / 7 * 5] {
                let x = Pos::from_bits(r);
                let got = log2_pos(x).unwrap() as f64 / 2f64.powi(24);
                let want = libm::log2(x.to_num::<f64>());
                worst = worst.max((got - want).abs());
            }
            raw = raw.saturating_mul(2);
        }
        assert!(worst < 2f64.powi(-23), "log2 error {worst:e}");
        assert_eq!(log2_pos(Pos::ZERO), None);
        assert_eq!(log2_pos(Pos::from_num(-1)), None);
    }

    #[test]
    fn exp2_relative_error() {
        let mut worst = 0.0f64;
        let mut v = -20i32 << 24;
        while v < 2 << 24 {
            let got = exp2_to_pos(v).to_num::<f64>();
            let want = libm::exp2(v as f64 / 2f64.powi(24));
            // Relative error beyond one LSB of the Q28 output.
            let err = ((got - want).abs() - 2f64.powi(-28)).max(0.0) / want;
            worst = worst.max(err);
            v += 1_234_567;
        }
        assert!(worst < 4e-8, "exp2 relative error {worst:e}");
        // Saturation instead of wrap-around.
        assert_eq!(exp2_to_pos(10 << 24), Pos::MAX);
    }

    #[test]
    fn fal_matches_f64_reference() {
        for &(alpha, delta) in &[(0.5, 0.005), (0.25, 0.005), (0.75, 0.01), (1.0, 0.002)] {
            let fal = Fal::new(alpha, delta).unwrap();
            let mut worst = 0.0f64;
            let mut e = -2.5f64;
            while e < 2.5 {
                let q = Pos::from_num(e);
                let ef = q.to_num::<f64>();
                let want = if ef.abs() <= delta {
                    ef / libm::pow(delta, 1.0 - alpha)
                } else {
                    libm::pow(ef.abs(), alpha) * ef.signum()
                };
                let got = fal.eval(q).to_num::<f64>();
                // Relative error beyond one LSB of the Q28 output.
                let err = ((got - want).abs() - 2f64.powi(-28)).max(0.0);
                worst = worst.max(err / want.abs().max(1e-9));
                e += 0.000_731;
            }
            assert!(worst < 1e-6, "alpha {alpha}: {worst:e}");
        }
        assert!(Fal::new(0.0, 0.005).is_none());
        assert!(Fal::new(1.5, 0.005).is_none());
        assert!(Fal::new(0.5, 0.0).is_none());
        assert!(Fal::new(0.5, f64::NAN).is_none());
    }

    #[test]
    fn fal_is_odd_and_saturates() {
        let fal = Fal::new(0.5, 0.005).unwrap();
        for e in [0.001, 0.004, 0.006, 0.3, 7.0] {
            let p = fal.eval(Pos::from_num(e));
            let n = fal.eval(Pos::from_num(-e));
            assert_eq!(p, -n);
        }
        // Extreme inputs stay finite and ordered.
        assert!(fal.eval(Pos::MAX) > Pos::from_num(2.8));
        assert!(fal.eval(Pos::MIN) < Pos::from_num(-2.8));
    }
}
