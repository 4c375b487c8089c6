//! Small, allocation-free decimal text for the serial console and the telemetry
//! stream: number parsing and formatting without `core::fmt`'s float machinery
//! (which would cost several KiB of the firmware's flash budget).
//!
//! * [`parse_f64`] reads a decimal number (`-12.5`, `0.006`, `1.2e-13`) and is
//!   exact: it only accepts what it can round correctly (Clinger's fast path: at
//!   most 15 significant digits and a power of ten within 10^+-22 after
//!   normalisation) and refuses the rest instead of guessing.
//! * [`Buf`] is a fixed-capacity text buffer with [`Buf::push_f64`] (9
//!   significant digits, positional or scientific), [`Buf::push_fixed`]
//!   (a fixed number of decimals, for the run-log columns) and integers.

/// Why a number was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NumError {
    /// Not a decimal number (empty, stray characters, no digits).
    Syntax,
    /// More than 15 significant digits, or a magnitude this parser cannot round
    /// exactly (beyond about 1e+-22 after normalisation).
    Precision,
}

impl NumError {
    /// A short human-readable reason.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Syntax => "not a number",
            Self::Precision => "number has too many digits or is too large or too small",
        }
    }
}

/// Powers of ten that are exact in binary64.
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// Largest significand accepted: 15 decimal digits (< 2^53, so exact in f64).
const MAX_SIGNIFICAND: u64 = 999_999_999_999_999;

/// Parse a decimal number: optional sign, digits with an optional point, an
/// optional exponent (`e`/`E`, optional sign, up to 3 digits). No spaces, no
/// `inf`/`nan`, no hexadecimal.
///
/// The result is the correctly rounded binary64 value. Leading zeros and
/// trailing zeros after the point do not count as significant digits.
pub fn parse_f64(s: &str) -> Result<f64, NumError> {
    let b = s.as_bytes();
    let mut i = 0;
    let neg = match b.first() {
        Some(b'-') => {
            i = 1;
            true
        }
        Some(b'+') => {
            i = 1;
            false
        }
        _ => false,
    };
    let mut mant: u64 = 0;
    let mut digits = 0u32; // significant digits kept in `mant`
    let mut exp10: i32 = 0; // value = mant * 10^exp10
    let mut any_digit = false;
    let mut seen_point = false;
    let mut trailing_zeros = 0u32; // zeros not yet multiplied into `mant`
    while i < b.len() {
        let c = b[i];
        match c {
            b'0'..=b'9' => {
                any_digit = true;
                let d = (c - b'0') as u64;
                if seen_point {
                    exp10 -= 1;
                }
                if d == 0 {
                    // Defer zeros: they only count if a non-zero digit follows.
                    if mant != 0 {
                        trailing_zeros += 1;
                    }
                } else {
                    digits += trailing_zeros + 1;
                    if digits > 15 {
                        return Err(NumError::Precision);
                    }
                    for _ in 0..trailing_zeros {
                        mant *= 10;
                    }
                    trailing_zeros = 0;
                    mant = mant * 10 + d;
                }
            }
            b'.' if !seen_point => seen_point = true,
            b'e' | b'E' => break,
            _ => return Err(NumError::Syntax),
        }
        i += 1;
    }
    if !any_digit {
        return Err(NumError::Syntax);
    }
    // Zeros deferred at the end of the significand scale it instead.
    exp10 += trailing_zeros as i32;
    if i < b.len() {
        // Exponent part.
        i += 1;
        let mut eneg = false;
        match b.get(i) {
            Some(b'-') => {
                eneg = true;
                i += 1;
            }
            Some(b'+') => i += 1,
            _ => {}
        }
        let start = i;
        let mut e: i32 = 0;
        while i < b.len() {
            let c = b[i];
            if !c.is_ascii_digit() || i - start >= 3 {
                return Err(NumError::Syntax);
            }
            e = e * 10 + (c - b'0') as i32;
            i += 1;
        }
        if i == start {
            return Err(NumError::Syntax);
        }
        exp10 += if eneg { -e } else { e };
    }
    debug_assert!(mant <= MAX_SIGNIFICAND);
    let m = mant as f64;
    let v = if mant == 0 {
        0.0
    } else if exp10 >= 0 {
        // Move powers of ten into the significand while it stays exact.
        let mut m_int = mant;
        let mut e = exp10;
        while e > 22 {
            match m_int.checked_mul(10) {
                Some(x) if x <= MAX_SIGNIFICAND => {
                    m_int = x;
                    e -= 1;
                }
                _ => return Err(NumError::Precision),
            }
        }
        m_int as f64 * POW10[e as usize]
    } else if exp10 >= -22 {
        m / POW10[(-exp10) as usize]
    } else {
        return Err(NumError::Precision);
    };
    Ok(if neg { -v } else { v })
}

/// Parse an unsigned decimal integer (digits only, at most 9 of them).
pub fn parse_u32(s: &str) -> Option<u32> {
    if s.is_empty() || s.len() > 9 || !s.bytes().all(|c| c.is_ascii_digit()) {
        return None;
    }
    Some(s.bytes().fold(0u32, |a, c| a * 10 + (c - b'0') as u32))
}

/// A fixed-capacity text buffer. Writes past the capacity are dropped and
/// remembered ([`Buf::overflowed`]), never a panic.
#[derive(Clone, Debug)]
pub struct Buf<const N: usize> {
    data: [u8; N],
    len: usize,
    overflow: bool,
}

impl<const N: usize> Default for Buf<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> Buf<N> {
    /// An empty buffer.
    pub const fn new() -> Self {
        Self {
            data: [0; N],
            len: 0,
            overflow: false,
        }
    }

    /// The text written so far.
    pub fn as_str(&self) -> &str {
        // Only whole UTF-8 strings and ASCII bytes are ever written, and a string
        // that does not fit is dropped whole.
        core::str::from_utf8(self.as_bytes()).unwrap_or("")
    }

    /// The bytes written so far.
    pub fn as_bytes(&self) -> &[u8] {
        // len <= N always; `get` spares the panic path.
        self.data.get(..self.len).unwrap_or(&[])
    }

    /// Bytes written.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing has been written.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// True when a write did not fit.
    pub fn overflowed(&self) -> bool {
        self.overflow
    }

    /// Empty the buffer.
    pub fn clear(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Append a string (whole or not at all).
    pub fn push_str(&mut self, s: &str) {
        self.push_bytes(s.as_bytes());
    }

    /// Append ASCII bytes (whole or not at all).
    fn push_bytes(&mut self, b: &[u8]) {
        match self.data.get_mut(self.len..self.len + b.len()) {
            Some(dst) => {
                for (d, s) in dst.iter_mut().zip(b) {
                    *d = *s;
                }
                self.len += b.len();
            }
            None => self.overflow = true,
        }
    }

    /// Append one ASCII byte.
    pub fn push_byte(&mut self, c: u8) {
        debug_assert!(c.is_ascii());
        if self.len >= N {
            self.overflow = true;
            return;
        }
        self.data[self.len] = c;
        self.len += 1;
    }

    /// Append an unsigned integer in decimal.
    pub fn push_u64(&mut self, mut v: u64) {
        // The digits, least significant in the last byte (u64: at most 20).
        let mut tmp = [0u8; 20];
        let mut n = 0;
        for slot in tmp.iter_mut().rev() {
            let (q, r) = div_rem(v, 10);
            *slot = b'0' + r as u8;
            n += 1;
            v = q;
            if v == 0 {
                break;
            }
        }
        self.push_bytes(tmp.get(tmp.len() - n..).unwrap_or(&[]));
    }

    /// Append a signed integer in decimal.
    pub fn push_i64(&mut self, v: i64) {
        if v < 0 {
            self.push_byte(b'-');
        }
        self.push_u64(v.unsigned_abs());
    }

    /// Append `v` with exactly `decimals` digits after the point (at most 9),
    /// rounded half away from zero; `nan`, `inf` and `-inf` for non-finite
    /// values, and `ovf` beyond +-9.2e18 / 10^decimals.
    pub fn push_fixed(&mut self, v: f64, decimals: u32) {
        if !v.is_finite() {
            self.push_nonfinite(v);
            return;
        }
        let decimals = decimals.min(9);
        let scale = POW10[decimals as usize];
        let scaled = libm::round(libm::fabs(v) * scale);
        if scaled >= 9.2e18 {
            self.push_str("ovf");
            return;
        }
        let n = scaled as u64;
        let p = 10u32.pow(decimals);
        if v < 0.0 && n != 0 {
            self.push_byte(b'-');
        }
        let (int, mut frac) = div_rem(n, p);
        self.push_u64(int);
        if decimals > 0 {
            self.push_byte(b'.');
            let mut div = p / 10;
            while div > 0 {
                self.push_byte(b'0' + (frac / div) as u8);
                frac %= div;
                div /= 10;
            }
        }
    }

    fn push_nonfinite(&mut self, v: f64) {
        if v.is_nan() {
            self.push_str("nan");
        } else if v > 0.0 {
            self.push_str("inf");
        } else {
            self.push_str("-inf");
        }
    }

    /// Append a binary64 value with up to 9 significant digits (see
    /// [`Buf::push_sig`]).
    pub fn push_f64(&mut self, v: f64) {
        self.push_sig(v, 9);
    }

    /// Append a binary32 value with up to 7 significant digits, so that a value
    /// typed with at most 7 digits prints as typed (see [`Buf::push_sig`]).
    pub fn push_f32(&mut self, v: f32) {
        self.push_sig(v as f64, 7);
    }

    /// Append `v` rounded to `sig` (1 ..= 9) significant digits, trailing zeros
    /// dropped: positional for 1e-4 <= |v| < 1e9, scientific (`1.2e-13`)
    /// otherwise; `nan`, `inf`, `-inf` for non-finite values.
    pub fn push_sig(&mut self, v: f64, sig: u32) {
        if !v.is_finite() {
            self.push_nonfinite(v);
            return;
        }
        if v == 0.0 {
            self.push_byte(b'0');
            return;
        }
        if v < 0.0 {
            self.push_byte(b'-');
        }
        let n = sig.clamp(1, 9) as i32;
        let lo = 10u64.pow(n as u32 - 1);
        let hi = lo * 10;
        let a = libm::fabs(v);
        // Decimal exponent e with 10^e <= a < 10^(e+1) (first guess; the
        // rounding below corrects it by one where needed).
        let mut e = decimal_exponent(a);
        let mut digits = scaled_digits(a, n - 1 - e);
        if digits >= hi {
            e += 1;
            digits = scaled_digits(a, n - 1 - e);
        } else if digits < lo {
            e -= 1;
            digits = scaled_digits(a, n - 1 - e);
        }
        if digits >= hi {
            // 9.999...5 rounded up to the next power of ten.
            digits = div_rem(digits, 10).0;
            e += 1;
        }
        let mut d = [0u8; 9];
        let n = n as usize;
        let mut x = digits;
        for k in (0..n).rev() {
            let (q, r) = div_rem(x, 10);
            d[k] = b'0' + r as u8;
            x = q;
        }
        let mut last = n;
        while last > 1 && d[last - 1] == b'0' {
            last -= 1;
        }
        let sig = &d[..last];
        if (-4..9).contains(&e) {
            if e < 0 {
                self.push_str("0.");
                for _ in 0..(-e - 1) {
                    self.push_byte(b'0');
                }
                for &c in sig {
                    self.push_byte(c);
                }
            } else {
                let int_len = (e + 1) as usize;
                for k in 0..int_len.max(sig.len()) {
                    if k == int_len {
                        self.push_byte(b'.');
                    }
                    self.push_byte(if k < sig.len() { sig[k] } else { b'0' });
                }
            }
        } else {
            self.push_byte(sig[0]);
            if sig.len() > 1 {
                self.push_byte(b'.');
                for &c in &sig[1..] {
                    self.push_byte(c);
                }
            }
            self.push_byte(b'e');
            self.push_i64(e as i64);
        }
    }
}

/// `(n / d, n % d)` for `0 < d < 2^31`, with 32-bit divisions only (the
/// firmware then links no 64-bit division routine; the Cortex-M4 divides 32-bit
/// numbers in hardware). Exact: a long division of the low word, one bit at a
/// time, after a hardware division of the high word.
pub(crate) fn div_rem(n: u64, d: u32) -> (u64, u32) {
    let (hi, lo) = ((n >> 32) as u32, n as u32);
    if hi == 0 {
        return ((lo / d) as u64, lo % d);
    }
    let (q_hi, mut r) = (hi / d, hi % d);
    let mut q_lo = 0u32;
    for i in (0..32).rev() {
        // r < d < 2^31, so 2r + 1 fits.
        r = (r << 1) | ((lo >> i) & 1);
        q_lo <<= 1;
        if r >= d {
            r -= d;
            q_lo |= 1;
        }
    }
    (((q_hi as u64) << 32) | q_lo as u64, r)
}

/// floor(log10(a)) for finite a > 0, by comparison with exact powers of ten
/// (exact for 1e-22 <= a < 1e23, within one outside; no `log10`).
fn decimal_exponent(a: f64) -> i32 {
    let mut e = 0i32;
    let mut x = a;
    while x >= 1e22 {
        x /= 1e22;
        e += 22;
    }
    while x < 1e-22 {
        x *= 1e22;
        e -= 22;
    }
    if x >= 1.0 {
        let k = POW10.iter().rposition(|p| x >= *p).unwrap_or(0);
        e + k as i32
    } else {
        let k = POW10.iter().position(|p| x * p >= 1.0).unwrap_or(22);
        e - k as i32
    }
}

/// round(a * 10^p) as an integer, with an exact power of ten where possible.
///
/// Beyond 10^22 the scaling is done in steps of 10^22 (one step up to 10^44,
/// as the exponent range of f32 values needs; more for tiny f64 values).
fn scaled_digits(a: f64, p: i32) -> u64 {
    let mut s = a;
    let mut k = p.unsigned_abs();
    while k > 22 {
        s = if p >= 0 { s * POW10[22] } else { s / POW10[22] };
        k -= 22;
    }
    let pk = POW10[k.min(22) as usize];
    let s = if p >= 0 { s * pk } else { s / pk };
    libm::round(s) as u64
}

impl<const N: usize> core::fmt::Write for Buf<N> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        self.push_str(s);
        if self.overflow {
            Err(core::fmt::Error)
        } else {
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiny_and_huge_values_print_instead_of_panicking() {
        // Scalings beyond 10^44 once indexed past the power table (a panic
        // for, e.g., a subnormal f32 setting or HIL sample shown by `get` or
        // `status`).
        for (v, sig, want) in [
            (1e-40f64, 7, "1e-40"),
            (1e-300, 9, "1e-300"),
            (4.9e-324, 9, "4.94065646e-324"),
            (1.5e300, 9, "1.5e300"),
            (f64::MAX, 9, "1.79769313e308"),
        ] {
            let mut b: Buf<64> = Buf::new();
            b.push_sig(v, sig);
            assert_eq!(b.as_str(), want);
        }
        let mut b: Buf<64> = Buf::new();
        b.push_f32(f32::from_bits(1));
        assert_eq!(b.as_str(), "1.401298e-45");
    }

    #[test]
    fn div_rem_equals_64_bit_division() {
        let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
        let mut values = [0u64; 2_000];
        for (i, v) in values.iter_mut().enumerate() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            *v = match i % 4 {
                0 => x,
                1 => x >> (x % 64),
                2 => (x % 3) << 32 | (x >> 32),
                _ => [0, 1, u32::MAX as u64, 1 << 32, u64::MAX, u64::MAX - 1][i / 4 % 6],
            };
        }
        for &n in &values {
            for d in [
                1u32,
                2,
                3,
                7,
                10,
                1000,
                65_535,
                65_536,
                999_999_937,
                1 << 30,
                i32::MAX as u32,
            ] {
                let (q, r) = div_rem(n, d);
                assert_eq!((q, r as u64), (n / d as u64, n % d as u64), "{n} / {d}");
            }
        }
    }
}
