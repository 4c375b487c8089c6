//! Numbers in messages, written so that a person can read them: `1e308`
//! rather than a 309-digit integer, `1e-10` rather than
//! `0.0000000001` or `9.999999999999999e-11`.

use std::fmt;

/// A number as messages show it ([`fmt::Display`]): the shortest form that
/// reads back as the same value, rounded to 6 significant digits when that
/// form has more than 8 (a computed bound, not a value someone typed); plain
/// from 1e-4 to below 1e6, with an exponent outside (`1e308`, `2.5e-7`);
/// `NaN`, `inf` and `-inf` as such.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        if v.is_nan() {
            return f.write_str("NaN");
        }
        if v.is_infinite() {
            return f.write_str(if v > 0.0 { "inf" } else { "-inf" });
        }
        if v == 0.0 {
            return f.write_str("0");
        }
        let shortest = format!("{v:e}");
        let digits = |s: &str| {
            s.split('e')
                .next()
                .unwrap_or("")
                .bytes()
                .filter(u8::is_ascii_digit)
                .count()
        };
        let text = if digits(&shortest) > 8 {
            trim_mantissa(&format!("{v:.5e}"))
        } else {
            shortest
        };
        let exp: i32 = text
            .split_once('e')
            .and_then(|(_, e)| e.parse().ok())
            .unwrap_or(0);
        if (-4..6).contains(&exp) {
            // Plain: the (possibly rounded) value's shortest form.
            let rounded: f64 = text.parse().unwrap_or(v);
            write!(f, "{rounded}")
        } else {
            f.write_str(&text)
        }
    }
}

/// `1.50000e-10` -> `1.5e-10`, `1.00000e3` -> `1e3`.
fn trim_mantissa(s: &str) -> String {
    match s.split_once('e') {
        Some((m, e)) if m.contains('.') => {
            format!("{}e{e}", m.trim_end_matches('0').trim_end_matches('.'))
        }
        _ => s.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn readable_forms() {
        for (v, want) in [
            (1e308, "1e308"),
            (-1e308, "-1e308"),
            (1e303, "1e303"),
            (f64::MAX, "1.79769e308"),
            (9.999999999999999e-11, "1e-10"),
            (1e-300, "1e-300"),
            (0.0, "0"),
            (-5.0, "-5"),
            (0.05, "0.05"),
            (0.001, "0.001"),
            (0.0001, "0.0001"),
            (0.00005, "5e-5"),
            (0.1 + 0.2, "0.3"),
            (123456.0, "123456"),
            (1_000_000.0, "1e6"),
            (1_234_567.0, "1.234567e6"),
            (3600.0, "3600"),
            (f64::NAN, "NaN"),
            (f64::INFINITY, "inf"),
            (f64::NEG_INFINITY, "-inf"),
        ] {
            assert_eq!(Num(v).to_string(), want, "{v:e}");
        }
    }

    /// Whatever the value, the text is short.
    #[test]
    fn never_long() {
        for bits in [
            0u64,
            1,
            0x7fef_ffff_ffff_ffff,
            0x3ff0_0000_0000_0001,
            0x8000_0000_0000_0001,
        ] {
            let v = f64::from_bits(bits);
            assert!(Num(v).to_string().len() <= 14, "{v:e}: {}", Num(v));
        }
    }
}
