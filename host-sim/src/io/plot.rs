//! PNG figures for the reports: stacked panels of line or point series.
//!
//! Text is drawn with the DejaVu Sans font shipped in `assets/` (registered
//! once through plotters' `ab_glyph` backend), so plots need no system font
//! libraries.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

static FONT: Once = Once::new();
const FONT_BYTES: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

pub(crate) fn ensure_font() {
    FONT.call_once(|| {
        // The embedded font is a valid TTF; a failure would only lose text.
        let _ = register_font("sans-serif", FontStyle::Normal, FONT_BYTES);
    });
}

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// A solid line.
    Line,
    /// A dashed line (references, reference models).
    Dashed,
    /// A line of short dashes, finer than [`Style::Dashed`].
    Dotted,
    /// Small dots (scatter plots, measurements).
    Points,
}

/// One curve.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// (x, y) points.
    pub points: Vec<(f64, f64)>,
    /// Drawing style.
    pub style: Style,
    /// Line width (or dot radius), pixels.
    pub width: u32,
    /// Palette index of its colour ([`color`]); by default its place in the panel.
    pub color: Option<usize>,
}

impl Series {
    fn new(label: impl Into<String>, points: Vec<(f64, f64)>, style: Style) -> Self {
        Self {
            label: label.into(),
            points,
            style,
            width: 2,
            color: None,
        }
    }

    /// A solid line.
    pub fn line(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self::new(label, points, Style::Line)
    }

    /// A dashed line.
    pub fn dashed(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self::new(label, points, Style::Dashed)
    }

    /// A scatter of points.
    pub fn points(label: impl Into<String>, points: Vec<(f64, f64)>) -> Self {
        Self::new(label, points, Style::Points)
    }

    /// The same series drawn in `style`.
    pub fn styled(mut self, style: Style) -> Self {
        self.style = style;
        self
    }

    /// The same series with line width (or dot radius) `width` pixels.
    pub fn width(mut self, width: u32) -> Self {
        self.width = width.max(1);
        self
    }

    /// The same series in the palette's colour `i` (the same quantity in the
    /// same colour on every panel of a figure).
    pub fn colored(mut self, i: usize) -> Self {
        self.color = Some(i);
        self
    }
}

/// One panel (axes) of a figure.
#[derive(Clone, Debug, Default)]
pub struct Panel {
    /// Panel title.
    pub title: String,
    /// x-axis label.
    pub x_label: String,
    /// y-axis label.
    pub y_label: String,
    /// The curves, drawn in this order (the last on top).
    pub series: Vec<Series>,
}

impl Panel {
    /// A panel with labels and no series yet.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            series: Vec::new(),
        }
    }

    /// Add a series.
    pub fn with(mut self, s: Series) -> Self {
        self.series.push(s);
        self
    }
}

/// Colour of the i-th series (a palette readable in print).
pub fn color(i: usize) -> RGBColor {
    const P: [RGBColor; 8] = [
        RGBColor(31, 119, 180),
        RGBColor(214, 39, 40),
        RGBColor(44, 160, 44),
        RGBColor(255, 127, 14),
        RGBColor(148, 103, 189),
        RGBColor(23, 190, 207),
        RGBColor(140, 86, 75),
        RGBColor(127, 127, 127),
    ];
    P[i % P.len()]
}

fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if !lo.is_finite() {
        return (0.0, 1.0);
    }
    let span = (hi - lo).max(1e-12 * hi.abs().max(1.0));
    (lo - 0.05 * span, hi + 0.05 * span)
}

/// A figure that could not be drawn or written.
#[derive(Debug, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct PlotError {
    /// The PNG file.
    pub path: PathBuf,
    /// What the plotting backend reported.
    pub message: String,
}

/// Legend text size, px.
const LEGEND_FONT: u32 = 13;
/// Height of one legend row, px.
const LEGEND_ROW: i32 = 18;
/// Inner padding of the legend box, px.
const LEGEND_PAD: i32 = 6;
/// Length of a legend's line sample, px.
const LEGEND_SAMPLE: i32 = 24;
/// Clearance kept between the legend box and any drawn data, px.
const LEGEND_CLEARANCE: i32 = 3;

/// Draw `panels` stacked vertically into a PNG of `width` x (`panel_height` x n).
///
/// Each panel's legend goes where it covers no data: the first of its axes'
/// corners, then edge middles, that the drawn curves leave free; when some
/// panel has no such room, every panel's legend goes to the right of its
/// axes (all axes keep one width, so the time axes of stacked panels stay
/// aligned).
pub fn save(path: &Path, panels: &[Panel], width: u32, panel_height: u32) -> Result<(), PlotError> {
    ensure_font();
    let n = panels.len().max(1) as u32;
    let size = (width, panel_height * n);
    let err = |e: String| PlotError {
        path: path.to_path_buf(),
        message: e,
    };
    // First in memory: does every legend find room inside its axes?
    let mut buffer = vec![0u8; size.0 as usize * size.1 as usize * 3];
    let inside = {
        let root = BitMapBackend::with_buffer(&mut buffer, size).into_drawing_area();
        draw(&root, panels, Legends::Inside).map_err(err)?
    };
    let legends = if inside {
        Legends::Inside
    } else {
        let root = BitMapBackend::with_buffer(&mut buffer, size).into_drawing_area();
        let widest = panels
            .iter()
            .map(|p| Legend::of(&root, p).map(|l| l.size().0))
            .collect::<Result<Vec<_>, _>>()
            .map_err(err)?
            .into_iter()
            .max()
            .unwrap_or(0);
        Legends::Right(widest.max(0) as u32)
    };
    let root = BitMapBackend::new(path, size).into_drawing_area();
    draw(&root, panels, legends).map_err(err)?;
    root.present().map_err(|e| err(e.to_string()))?;
    Ok(())
}

/// Where the legends go.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Legends {
    /// Inside the axes, where no data is drawn; a panel without such room
    /// gets none (the caller then draws again with `Right`).
    Inside,
    /// To the right of the axes, in a strip this many pixels wide.
    Right(u32),
}

fn font() -> TextStyle<'static> {
    ("sans-serif", LEGEND_FONT).into_font().into()
}

/// The labelled series of a panel, in legend order.
fn labelled(panel: &Panel) -> impl Iterator<Item = (usize, &Series)> {
    panel
        .series
        .iter()
        .enumerate()
        .filter(|(_, s)| !s.label.is_empty())
}

/// A panel's legend laid out in `cols` columns, filled row by row.
#[derive(Clone, Debug)]
struct Legend {
    /// Text width of each entry, px.
    text: Vec<i32>,
    /// Columns.
    cols: usize,
}

impl Legend {
    /// Gap between columns, px.
    const COL_GAP: i32 = 12;

    fn of<DB: DrawingBackend>(
        area: &DrawingArea<DB, Shift>,
        panel: &Panel,
    ) -> Result<Self, String> {
        let text = labelled(panel)
            .map(|(_, s)| {
                area.estimate_text_size(&s.label, &font())
                    .map(|(w, _)| w as i32)
                    .map_err(|e| e.to_string())
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Self { text, cols: 1 })
    }

    fn is_empty(&self) -> bool {
        self.text.is_empty()
    }

    fn with_cols(&self, cols: usize) -> Self {
        Self {
            text: self.text.clone(),
            cols: cols.clamp(1, self.text.len().max(1)),
        }
    }

    fn rows(&self) -> usize {
        self.text.len().div_ceil(self.cols)
    }

    /// Width of one column (every column as wide as the widest entry), px.
    fn col_width(&self) -> i32 {
        LEGEND_SAMPLE + 6 + self.text.iter().copied().max().unwrap_or(0)
    }

    /// Width and height of the box, px.
    fn size(&self) -> (i32, i32) {
        let cols = self.cols as i32;
        (
            2 * LEGEND_PAD + cols * self.col_width() + (cols - 1) * Self::COL_GAP,
            2 * LEGEND_PAD + self.rows() as i32 * LEGEND_ROW,
        )
    }

    /// Offset of entry `k`'s row within the box: left end of its sample,
    /// middle of its row.
    fn entry(&self, k: usize) -> (i32, i32) {
        let (row, col) = ((k / self.cols) as i32, (k % self.cols) as i32);
        (
            LEGEND_PAD + col * (self.col_width() + Self::COL_GAP),
            LEGEND_PAD + row * LEGEND_ROW + LEGEND_ROW / 2,
        )
    }
}

/// Draw every panel; with `Legends::Inside`, whether every legend found room.
fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    panels: &[Panel],
    legends: Legends,
) -> Result<bool, String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    root.fill(&WHITE).map_err(|x| e(&x))?;
    let mut all_placed = true;
    let areas = root.split_evenly((panels.len().max(1), 1));
    for (panel, area) in panels.iter().zip(areas.iter()) {
        let (w, _) = area.dim_in_pixel();
        let (axes, strip) = match legends {
            Legends::Inside => (area.clone(), None),
            Legends::Right(lw) => {
                let (a, b) = area.split_horizontally(w.saturating_sub(lw + 8));
                (a, Some(b))
            }
        };
        let (x0, x1) = range(
            panel
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.0)),
        );
        let (y0, y1) = range(
            panel
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.1)),
        );
        let mut chart = ChartBuilder::on(&axes)
            .caption(&panel.title, ("sans-serif", 18))
            .margin(8)
            .x_label_area_size(36)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_desc(panel.x_label.as_str())
            .y_desc(panel.y_label.as_str())
            .label_style(("sans-serif", 13))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|x| e(&x))?;
        for (i, s) in panel.series.iter().enumerate() {
            let c = color(s.color.unwrap_or(i));
            let w = s.width;
            let pts = s
                .points
                .iter()
                .copied()
                .filter(|p| p.0.is_finite() && p.1.is_finite());
            match s.style {
                Style::Line => chart
                    .draw_series(LineSeries::new(pts, c.stroke_width(w)))
                    .map(|_| ()),
                Style::Dashed | Style::Dotted => {
                    let (dash, gap) = dashes(s);
                    chart
                        .draw_series(DashedLineSeries::new(pts, dash, gap, c.stroke_width(w)))
                        .map(|_| ())
                }
                Style::Points => chart
                    .draw_series(pts.map(|p| Circle::new(p, w, c.filled())))
                    .map(|_| ()),
            }
            .map_err(|x| e(&x))?;
        }
        let legend = Legend::of(root, panel)?;
        if legend.is_empty() {
            continue;
        }
        let (xr, yr) = chart.plotting_area().get_pixel_range();
        let placed = match strip {
            Some(strip) => {
                let (sx, _) = strip.get_pixel_range();
                Some((legend, (sx.start + 4, yr.start)))
            }
            None => {
                let mut grid = Occupancy::new(xr.clone(), yr.clone());
                for s in &panel.series {
                    let pixels: Vec<(i32, i32)> = s
                        .points
                        .iter()
                        .filter(|p| p.0.is_finite() && p.1.is_finite())
                        .map(|p| chart.backend_coord(p))
                        .collect();
                    let r = s.width as i32 / 2 + LEGEND_CLEARANCE;
                    match s.style {
                        Style::Points => pixels.iter().for_each(|p| grid.mark(*p, r + 1)),
                        _ => pixels
                            .windows(2)
                            .for_each(|w| grid.mark_segment(w[0], w[1], r)),
                    }
                }
                // One column, else as few more as find room.
                (1..=legend.text.len()).find_map(|cols| {
                    let l = legend.with_cols(cols);
                    grid.free_spot(l.size()).map(|at| (l, at))
                })
            }
        };
        match placed {
            Some((legend, at)) => draw_legend(root, panel, &legend, at)?,
            None => all_placed = false,
        }
    }
    Ok(all_placed)
}

/// Draw a panel's legend box with its top left corner at `at` (pixels).
fn draw_legend<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    panel: &Panel,
    legend: &Legend,
    at: (i32, i32),
) -> Result<(), String> {
    let e = |e: &dyn std::fmt::Display| e.to_string();
    let (x, y) = at;
    let (w, h) = legend.size();
    root.draw(&Rectangle::new(
        [(x, y), (x + w, y + h)],
        WHITE.mix(0.9).filled(),
    ))
    .map_err(|x| e(&x))?;
    root.draw(&Rectangle::new(
        [(x, y), (x + w, y + h)],
        RGBColor(200, 200, 200).stroke_width(1),
    ))
    .map_err(|x| e(&x))?;
    for (k, (i, s)) in labelled(panel).enumerate() {
        let c = color(s.color.unwrap_or(i));
        let (dx, dy) = legend.entry(k);
        let (l, r, cy) = (x + dx, x + dx + LEGEND_SAMPLE, y + dy);
        let stroke = c.stroke_width(s.width.max(2));
        match s.style {
            Style::Line => root.draw(&PathElement::new(vec![(l, cy), (r, cy)], stroke)),
            Style::Dashed | Style::Dotted => {
                let (dash, gap) = dashes(s);
                let (dash, gap) = (dash as i32, gap as i32);
                let mut a = l;
                let mut res = Ok(());
                while a < r && res.is_ok() {
                    res = root.draw(&PathElement::new(
                        vec![(a, cy), ((a + dash).min(r), cy)],
                        stroke,
                    ));
                    a += dash + gap;
                }
                res
            }
            Style::Points => root.draw(&Circle::new(((l + r) / 2, cy), 3, c.filled())),
        }
        .map_err(|x| e(&x))?;
        root.draw(&Text::new(
            s.label.as_str(),
            (r + 6, cy),
            font().pos(Pos::new(HPos::Left, VPos::Center)),
        ))
        .map_err(|x| e(&x))?;
    }
    Ok(())
}

/// Dash and gap lengths of a dashed or dotted series, px.
fn dashes(s: &Series) -> (u32, u32) {
    match s.style {
        Style::Dotted => (2 + s.width, 2 + s.width),
        _ => (6 + 2 * s.width, 4 + s.width),
    }
}

/// Which pixels of the axes the drawn data covers.
struct Occupancy {
    x0: i32,
    y0: i32,
    w: i32,
    h: i32,
    taken: Vec<bool>,
}

impl Occupancy {
    fn new(x: std::ops::Range<i32>, y: std::ops::Range<i32>) -> Self {
        let (w, h) = ((x.end - x.start).max(1), (y.end - y.start).max(1));
        Self {
            x0: x.start,
            y0: y.start,
            w,
            h,
            taken: vec![false; (w * h) as usize],
        }
    }

    /// Mark the square of half-width `r` around `p`.
    fn mark(&mut self, p: (i32, i32), r: i32) {
        let (cx, cy) = (p.0 - self.x0, p.1 - self.y0);
        for y in (cy - r).max(0)..=(cy + r).min(self.h - 1) {
            for x in (cx - r).max(0)..=(cx + r).min(self.w - 1) {
                self.taken[(y * self.w + x) as usize] = true;
            }
        }
    }

    /// Mark the segment from `a` to `b`, `r` pixels either side.
    fn mark_segment(&mut self, a: (i32, i32), b: (i32, i32), r: i32) {
        let n = (b.0 - a.0).abs().max((b.1 - a.1).abs()).max(1);
        for k in 0..=n {
            let f = f64::from(k) / f64::from(n);
            let x = f64::from(a.0) + f * f64::from(b.0 - a.0);
            let y = f64::from(a.1) + f * f64::from(b.1 - a.1);
            self.mark((x.round() as i32, y.round() as i32), r);
        }
    }

    /// The top left corner of the first free place for a `size` box: the
    /// corners, then the middles of the edges, 6 px inside the axes.
    fn free_spot(&self, size: (i32, i32)) -> Option<(i32, i32)> {
        const INSET: i32 = 6;
        let (w, h) = size;
        let (l, r) = (INSET, self.w - INSET - w);
        let (t, b) = (INSET, self.h - INSET - h);
        let (cx, cy) = ((self.w - w) / 2, (self.h - h) / 2);
        [
            (r, t),
            (l, t),
            (r, b),
            (l, b),
            (cx, t),
            (cx, b),
            (r, cy),
            (l, cy),
        ]
        .into_iter()
        .find(|&(x, y)| x >= 0 && y >= 0 && self.is_free(x, y, w, h))
        .map(|(x, y)| (x + self.x0, y + self.y0))
    }

    fn is_free(&self, x: i32, y: i32, w: i32, h: i32) -> bool {
        if x + w > self.w || y + h > self.h {
            return false;
        }
        (y..y + h).all(|yy| {
            let row = (yy * self.w) as usize;
            !self.taken[row + x as usize..row + (x + w) as usize]
                .iter()
                .any(|t| *t)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png_with_text() {
        let dir = std::env::temp_dir().join(format!("dca-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.png");
        let sine: Vec<(f64, f64)> = (0..200)
            .map(|i| (i as f64 * 0.01, (i as f64 * 0.05).sin()))
            .collect();
        let panel = Panel::new("test", "t [s]", "y [-]")
            .with(Series::line("sine", sine.clone()))
            .with(Series::dashed(
                "ref",
                sine.iter().map(|p| (p.0, 0.5 * p.1)).collect(),
            ))
            .with(Series::points(
                "pts",
                sine.iter().step_by(10).copied().collect(),
            ));
        save(&path, &[panel.clone(), panel], 640, 240).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert!(bytes.len() > 5_000, "{} bytes", bytes.len());
        if std::env::var_os("DCA_KEEP_PLOT").is_none() {
            std::fs::remove_dir_all(&dir).ok();
        }
    }

    /// A legend goes to the first corner the data leaves free, never over it.
    #[test]
    fn the_legend_takes_a_free_corner() {
        // A rising line from the lower left to the upper right (pixel y
        // grows downwards): the upper right corner is taken, the upper left
        // is free.
        let mut g = Occupancy::new(0..200, 0..100);
        g.mark_segment((0, 99), (199, 0), 3);
        let (x, y) = g.free_spot((60, 30)).expect("room");
        assert_eq!((x, y), (6, 6));
        // Data everywhere but the lower right: found there.
        let mut g = Occupancy::new(10..210, 20..120);
        for y in (20..120).step_by(4) {
            g.mark_segment((10, y), (if y < 80 { 209 } else { 100 }, y), 2);
        }
        let (x, y) = g.free_spot((60, 30)).expect("room");
        assert!(x >= 100 + 3 && y + 30 <= 120, "{x}, {y}");
        assert!(g.is_free(x - 10, y - 20, 60, 30));
        // No room at all.
        let mut g = Occupancy::new(0..200, 0..100);
        for y in (0..100).step_by(5) {
            g.mark_segment((0, y), (199, y), 2);
        }
        assert_eq!(g.free_spot((60, 30)), None);
    }

    /// Where one panel has no room inside its axes, every legend of the
    /// figure goes to the right of its axes.
    #[test]
    fn a_full_panel_sends_the_legends_outside() {
        ensure_font();
        let (w, h) = (600u32, 400u32);
        let mut buf = vec![0u8; (w * h * 3) as usize];
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let quiet = Panel::new("quiet", "t [s]", "y [-]")
            .with(Series::line("a line", vec![(0.0, 0.0), (1.0, 0.1)]))
            .with(Series::line("", vec![(0.0, 1.0), (0.0, 1.0)]));
        // A fast sine fills the axes from edge to edge.
        let busy: Vec<(f64, f64)> = (0..4000)
            .map(|i| (i as f64 * 2.5e-4, (i as f64 * 0.2).sin()))
            .collect();
        let busy = Panel::new("busy", "t [s]", "y [-]").with(Series::line("a sine", busy));
        assert!(draw(&root, std::slice::from_ref(&quiet), Legends::Inside).unwrap());
        assert!(!draw(&root, &[quiet.clone(), busy.clone()], Legends::Inside).unwrap());
        assert!(draw(&root, &[quiet, busy], Legends::Right(120)).unwrap());
    }
}
