//! What the parts share: piecewise-linear maps through knots (the general
//! families' shapes) and the serde default of a factor of 1.

/// The serde default of a factor or an exponent that is 1 unless given.
pub(super) fn one() -> f64 {
    1.0
}

/// The segment of the knots `xs` (increasing) that `x` falls in: `i` for
/// `xs[i] < x <= xs[i + 1]`, the first and the last extended beyond.
pub(crate) fn segment(xs: &[f64], x: f64) -> usize {
    xs[1..xs.len() - 1].iter().take_while(|k| x > **k).count()
}

/// Linear interpolation of `ys` over the knots `xs` (increasing): flat
/// beyond the last knot when `flat`, else extended along the last segment;
/// extended along the first below the first knot.
pub(super) fn interp(xs: &[f64], ys: &[f64], x: f64, flat: bool) -> f64 {
    let last = xs.len() - 1;
    if x >= xs[last] && flat {
        return ys[last];
    }
    let i = segment(xs, x);
    let w = (x - xs[i]) / (xs[i + 1] - xs[i]);
    ys[i] + w * (ys[i + 1] - ys[i])
}
