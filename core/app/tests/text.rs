//! Number parsing and formatting of the console (dca_app::text).

use dca_app::text::{parse_f64, parse_u32, Buf, NumError};

#[test]
fn parses_exactly_like_std_within_the_fast_path() {
    for s in [
        "0",
        "-0",
        "1",
        "+2.5",
        "-12.5",
        "0.006",
        "33",
        "1.2e-13",
        "4.91e-4",
        "1e22",
        "1e25",
        "123456789012345",
        "0.000123456789012345",
        "2441.40625",
        "10.05",
        "1.50",
        "7E3",
        "1e-22",
        "-3.5e+2",
        ".5",
        "5.",
    ] {
        let want: f64 = s.parse().unwrap();
        let got = parse_f64(s).unwrap_or_else(|e| panic!("{s}: {e:?}"));
        assert_eq!(got.to_bits(), want.to_bits(), "{s}");
    }
}

#[test]
fn refuses_what_it_cannot_round_or_read() {
    for s in [
        "", "-", ".", "e5", "1e", "1e+", "1.2.3", "1,5", "nan", "inf", "0x10", "1 2", "--1",
        "1e1234",
    ] {
        assert_eq!(parse_f64(s), Err(NumError::Syntax), "{s}");
    }
    for s in ["1234567890123456", "1e-23", "1e400", "0.1234567890123456"] {
        assert_eq!(parse_f64(s), Err(NumError::Precision), "{s}");
    }
}

#[test]
fn parses_small_unsigned_integers_only() {
    assert_eq!(parse_u32("100"), Some(100));
    assert_eq!(parse_u32("0"), Some(0));
    for s in ["", "-1", "1.0", "1234567890", "1e3", " 1"] {
        assert_eq!(parse_u32(s), None, "{s}");
    }
}

fn sig(v: f64, n: u32) -> String {
    let mut b: Buf<40> = Buf::new();
    b.push_sig(v, n);
    b.as_str().to_string()
}

#[test]
fn formats_significant_digits_as_typed() {
    let cases: &[(f64, &str)] = &[
        (0.0, "0"),
        (33.0, "33"),
        (0.006, "0.006"),
        (1.2e-13, "1.2e-13"),
        (-2441.40625, "-2441.40625"),
        (100.0, "100"),
        (1e9, "1e9"),
        (123456789.0, "123456789"),
        (0.0001, "0.0001"),
        (0.00001234, "1.234e-5"),
        (9.9999999996, "10"),
        (1.0e22, "1e22"),
        (f64::NAN, "nan"),
        (f64::NEG_INFINITY, "-inf"),
    ];
    for (v, want) in cases {
        assert_eq!(sig(*v, 9), *want, "{v}");
    }
    let mut b: Buf<24> = Buf::new();
    b.push_f32(2.7);
    assert_eq!(b.as_str(), "2.7");
}

#[test]
fn formatted_values_parse_back_to_the_nine_digit_rounding() {
    // Every value printed with 9 digits reads back within half a unit of the
    // ninth digit.
    let mut x = 1.234_567_891e-12_f64;
    for _ in 0..30 {
        let s = sig(x, 9);
        let back = parse_f64(&s).unwrap();
        assert!(((back - x) / x).abs() <= 5.1e-9, "{x} -> {s} -> {back}");
        x *= -7.3;
    }
}

#[test]
fn fixed_decimals_round_half_away_and_mark_overflow() {
    let f = |v: f64, d: u32| {
        let mut b: Buf<40> = Buf::new();
        b.push_fixed(v, d);
        b.as_str().to_string()
    };
    assert_eq!(f(0.05, 6), "0.050000");
    assert_eq!(f(-0.0000012, 7), "-0.0000012");
    assert_eq!(f(-0.00000001, 3), "0.000");
    assert_eq!(f(640127.44, 1), "640127.4");
    assert_eq!(f(2.5, 0), "3");
    assert_eq!(f(1e30, 2), "ovf");
    assert_eq!(f(f64::NAN, 2), "nan");
}

#[test]
fn buffer_drops_what_does_not_fit_and_says_so() {
    let mut b: Buf<4> = Buf::new();
    b.push_str("abc");
    b.push_str("de");
    assert_eq!(b.as_str(), "abc");
    assert!(b.overflowed());
    b.clear();
    b.push_u64(12345);
    assert!(b.overflowed());
    assert_eq!(b.as_str(), "");
}
