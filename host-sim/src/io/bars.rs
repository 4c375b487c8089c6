//! PNG bar charts for the reports: named categories along the x axis, one
//! bar per series in each (for example each candidate effect's gap shrink on
//! the fit and on the check runs).

use std::path::Path;

use plotters::prelude::*;

use super::plot::{color, ensure_font, PlotError};

/// A grouped bar chart: `categories` along x, for each a bar of every
/// series' value (`series[j].1[i]` for category `i`).
#[derive(Clone, Debug, PartialEq)]
pub struct Bars {
    /// Title above the chart.
    pub title: String,
    /// Quantity and unit of the y axis.
    pub y_label: String,
    /// Names along the x axis.
    pub categories: Vec<String>,
    /// Each series' label and its value per category (NaN: no bar).
    pub series: Vec<(String, Vec<f64>)>,
}

/// Draw `bars` into a PNG of `width` x `height`; the y axis spans the
/// values and zero, with a band above the highest bar for the legend.
pub fn save_bars(path: &Path, bars: &Bars, width: u32, height: u32) -> Result<(), PlotError> {
    ensure_font();
    let err = |e: &dyn std::fmt::Display| PlotError {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let root = BitMapBackend::new(path, (width, height)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let values = bars.series.iter().flat_map(|s| s.1.iter().copied());
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((0.0_f64, 0.0_f64), |(a, b), v| (a.min(v), b.max(v)));
    let span = (hi - lo).max(1e-9);
    let n = bars.categories.len().max(1);
    let names = bars.categories.clone();
    let mut chart = ChartBuilder::on(&root)
        .caption(&bars.title, ("sans-serif", 18))
        .margin(8)
        .x_label_area_size(56)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..n as f64, (lo - 0.05 * span)..(hi + 0.3 * span))
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(2 * n + 1)
        .x_label_formatter(&|x| {
            // Names at the categories' centres (k + 0.5), nothing elsewhere.
            let k = (x - 0.5).round();
            if (x - 0.5 - k).abs() < 1e-6 && k >= 0.0 {
                names.get(k as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        })
        .y_desc(bars.y_label.as_str())
        .label_style(("sans-serif", 13))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| err(&e))?;
    let m = bars.series.len().max(1) as f64;
    let w = 0.8 / m;
    for (j, (label, vals)) in bars.series.iter().enumerate() {
        let c = color(j);
        let rects = vals
            .iter()
            .enumerate()
            .filter(|(_, v)| v.is_finite())
            .map(|(i, &v)| {
                let x0 = i as f64 + 0.1 + j as f64 * w;
                Rectangle::new([(x0, 0.0), (x0 + w, v)], c.filled())
            });
        chart
            .draw_series(rects)
            .map_err(|e| err(&e))?
            .label(label.as_str())
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], c.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(RGBColor(200, 200, 200))
        .label_font(("sans-serif", 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png_with_named_bars() {
        let dir = std::env::temp_dir().join(format!("dca-bars-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("b.png");
        let bars = Bars {
            title: "t".into(),
            y_label: "gap shrink [%]".into(),
            categories: vec!["leakage".into(), "friction".into()],
            series: vec![
                ("fit".into(), vec![90.0, -20.0]),
                ("check".into(), vec![80.0, f64::NAN]),
            ],
        };
        save_bars(&path, &bars, 600, 300).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert!(bytes.len() > 2000, "{} bytes", bytes.len());
        std::fs::remove_dir_all(&dir).ok();
    }
}
