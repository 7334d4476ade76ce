//! Charts of `analyze --plot`, the bake's previews and `bench --sweep --plot`: PNG or SVG by
//! the file's extension, written atomically (cargo feature `plot`).
//!
//! Labels use DejaVu Sans embedded in the binary (the `dejavu` crate), so a chart renders the
//! same on a server without fonts (SVG names the family and leaves drawing text to the viewer).

use plotters::coord::Shift;
use plotters::prelude::*;
use quatcurve_eval::io::{write_atomic, IoError};
use std::path::Path;

/// One line of the chart: `|omega|` and `|alpha|` of one curve at `times`.
pub struct Series {
    /// The legend's text.
    pub label: String,
    /// Sample times.
    pub times: Vec<f64>,
    /// `|omega|` at each time (rad/s).
    pub omega: Vec<f64>,
    /// `|alpha|` at each time (rad/s^2).
    pub alpha: Vec<f64>,
}

const FONT: &str = "sans-serif";

/// One line of a [`log_log`] chart.
pub struct Line {
    /// The legend's text.
    pub label: String,
    /// `(x, y)` points, both positive.
    pub points: Vec<(f64, f64)>,
}

/// A log-log chart of `lines` to `path` (`.png` or `.svg`).
///
/// # Errors
/// As [`rates`].
pub fn log_log(path: &Path, title: &str, x: &str, y: &str, lines: &[Line]) -> Result<(), PlotError> {
    render(path, (1000, 640), &LogLog { title, x, y, lines })
}

struct LogLog<'a> {
    title: &'a str,
    x: &'a str,
    y: &'a str,
    lines: &'a [Line],
}

impl Figure for LogLog<'_> {
    fn draw<B: DrawingBackend>(&self, root: DrawingArea<B, Shift>) -> Result<(), DrawingAreaErrorKind<B::ErrorType>> {
        root.fill(&WHITE)?;
        let bounds = |pick: fn(&(f64, f64)) -> f64| {
            let values =
                self.lines.iter().flat_map(|l| l.points.iter().map(pick)).filter(|v| *v > 0.0 && v.is_finite());
            let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(a, b), v| (a.min(v), b.max(v)));
            if lo <= hi {
                (lo / 1.5, hi * 1.5)
            } else {
                (1.0, 10.0)
            }
        };
        let ((x0, x1), (y0, y1)) = (bounds(|p| p.0), bounds(|p| p.1));
        let mut chart = ChartBuilder::on(&root)
            .caption(self.title, (FONT, 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
        let powers = |v: &f64| format!("{v:.0e}");
        chart
            .configure_mesh()
            .x_desc(self.x)
            .y_desc(self.y)
            .x_label_formatter(&powers)
            .y_label_formatter(&powers)
            .label_style((FONT, 13))
            .light_line_style(WHITE.mix(0.0))
            .bold_line_style(BLACK.mix(0.08))
            .draw()?;
        for (i, line) in self.lines.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(line.points.iter().copied(), color.stroke_width(2)).point_size(3))?
                .label(&line.label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .label_font((FONT, 13))
            .position(SeriesLabelPosition::LowerRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        root.present()
    }
}

/// Draws a skeleton (a line from each joint to its parent) at the clip's frames `picks`
/// (`preview_frames` in `quatcurve::bake::texture`), given the model texture rows of those frames
/// alone, front view (x, y) beside side view (z, y), one colour per frame, to `path` (`.png`
/// or `.svg`).
///
/// # Errors
/// As [`rates`].
pub fn skeleton(
    path: &Path,
    title: &str,
    model: &[f32],
    picks: &[usize],
    animation: &quatcurve_anim::Animation,
) -> Result<(), PlotError> {
    let joints = animation.joints.len();
    let picks = picks.to_vec();
    // `k`: the frame's place in `picks` (and its row in `model`).
    let at = |k: usize, j: usize| quatcurve_eval::skeleton::position(model, joints, k, j).map(f64::from);
    // Bones of every picked frame: (frame's place in picks, from, to).
    let bones: Vec<(usize, [f64; 3], [f64; 3])> = (0..picks.len())
        .flat_map(|k| {
            animation
                .joints
                .iter()
                .enumerate()
                .filter_map(move |(j, joint)| joint.parent.map(|p| (k, at(k, p), at(k, j))))
        })
        .collect();
    let points = || {
        bones
            .iter()
            .flat_map(|(_, a, b)| [*a, *b])
            .chain((0..joints).flat_map(|j| (0..picks.len()).map(move |k| at(k, j))))
    };
    let range = |axis: usize| {
        points()
            .map(|p| p[axis])
            .filter(|v| v.is_finite())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)))
    };
    let ranges = [range(0), range(1), range(2)];
    // One scale for every axis, so the skeleton keeps its proportions.
    let half = ranges.iter().map(|(a, b)| b - a).fold(1e-6, f64::max) * 0.55;
    let centre =
        |axis: usize| if ranges[axis].0 <= ranges[axis].1 { 0.5 * (ranges[axis].0 + ranges[axis].1) } else { 0.0 };
    let window = |axis: usize| (centre(axis) - half)..(centre(axis) + half);
    render(path, (1200, 640), &Skeleton { title, bones, picks, windows: [window(0), window(1), window(2)] })
}

struct Skeleton<'a> {
    title: &'a str,
    /// (frame's place in `picks`, parent position, joint position).
    bones: Vec<(usize, [f64; 3], [f64; 3])>,
    picks: Vec<usize>,
    windows: [std::ops::Range<f64>; 3],
}

impl Figure for Skeleton<'_> {
    fn draw<B: DrawingBackend>(&self, root: DrawingArea<B, Shift>) -> Result<(), DrawingAreaErrorKind<B::ErrorType>> {
        let Skeleton { title, bones, picks, windows: [x, y, z] } = self;
        root.fill(&WHITE)?;
        let root = root.titled(title, (FONT, 18))?;
        let panels = root.split_evenly((1, 2));
        for (panel, (name, horizontal, h_range)) in
            panels.iter().zip([("front (x, y)", 0, x.clone()), ("side (z, y)", 2, z.clone())])
        {
            let mut chart = ChartBuilder::on(panel)
                .caption(name, (FONT, 15))
                .margin(10)
                .x_label_area_size(30)
                .y_label_area_size(45)
                .build_cartesian_2d(h_range, y.clone())?;
            chart
                .configure_mesh()
                .label_style((FONT, 12))
                .light_line_style(WHITE.mix(0.0))
                .bold_line_style(BLACK.mix(0.08))
                .draw()?;
            for (k, &frame) in picks.iter().enumerate() {
                let color = Palette99::pick(k).to_rgba();
                chart
                    .draw_series(bones.iter().filter(|b| b.0 == k).map(|(_, a, b)| {
                        PathElement::new(vec![(a[horizontal], a[1]), (b[horizontal], b[1])], color.stroke_width(2))
                    }))?
                    .label(format!("frame {frame}"))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            }
            chart
                .configure_series_labels()
                .label_font((FONT, 12))
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()?;
        }
        root.present()
    }
}

/// A chart that can draw itself on any plotters backend.
trait Figure {
    fn draw<B: DrawingBackend>(&self, root: DrawingArea<B, Shift>) -> Result<(), DrawingAreaErrorKind<B::ErrorType>>;
}

/// Draws `figure` on the backend `path`'s extension names (`.png` or `.svg`) and writes the
/// file atomically.
fn render(path: &Path, size: (u32, u32), figure: &impl Figure) -> Result<(), PlotError> {
    let at = |error: PlotError| PlotError::At { path: path.display().to_string(), error: Box::new(error) };
    let drawn = |e: DrawingAreaErrorKind<_>| at(PlotError::Draw(Box::new(e)));
    // Both backends measure text with it. Registering twice is harmless; a font that does not
    // parse is a build defect.
    plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular())
        .map_err(|_| at(PlotError::Font))?;
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("svg") => {
            let mut text = String::new();
            figure
                .draw(SVGBackend::with_string(&mut text, size).into_drawing_area())
                .map_err(|e| at(PlotError::Draw(Box::new(e))))?;
            Ok(write_atomic(path, |w| w.write_all(text.as_bytes()))?)
        }
        Some("png") => {
            let mut pixels = vec![0u8; (size.0 * size.1 * 3) as usize];
            figure.draw(BitMapBackend::with_buffer(&mut pixels, size).into_drawing_area()).map_err(drawn)?;
            Ok(write_atomic(path, |w| {
                use image::ImageEncoder;
                image::codecs::png::PngEncoder::new(w)
                    .write_image(&pixels, size.0, size.1, image::ColorType::Rgb8)
                    .map_err(std::io::Error::other)
            })?)
        }
        _ => Err(at(PlotError::Extension)),
    }
}

/// Why a chart could not be drawn or written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum PlotError {
    /// What went wrong with the chart at `path`.
    #[error("{path}: {error}")]
    At {
        /// The chart's file.
        path: String,
        /// What went wrong.
        error: Box<PlotError>,
    },
    /// A file name that ends in neither `.png` nor `.svg`.
    #[error("a plot must end in .png or .svg")]
    Extension,
    /// The embedded font does not load (a build defect).
    #[error("the embedded font does not load")]
    Font,
    /// plotters could not draw the chart.
    #[error("{0}")]
    Draw(Box<dyn std::error::Error + Send + Sync>),
    /// The file could not be written.
    #[error(transparent)]
    Write(#[from] IoError),
}

/// Draws `|omega|` (top) and `|alpha|` (bottom) against time, one line per series, the key
/// times marked by vertical rules, to `path` (`.png` or `.svg`).
///
/// # Errors
/// A message naming the file: an unknown extension, a drawing or writing failure.
pub fn rates(path: &Path, title: &str, series: &[Series], keys: &[f64]) -> Result<(), PlotError> {
    render(path, (1000, 640), &Rates { title, series, keys })
}

struct Rates<'a> {
    title: &'a str,
    series: &'a [Series],
    keys: &'a [f64],
}

impl Figure for Rates<'_> {
    fn draw<B: DrawingBackend>(&self, root: DrawingArea<B, Shift>) -> Result<(), DrawingAreaErrorKind<B::ErrorType>> {
        let Rates { title, series, keys } = *self;
        root.fill(&WHITE)?;
        let root = root.titled(title, (FONT, 20))?;
        let panels = root.split_evenly((2, 1));
        let (t0, t1) = series
            .iter()
            .flat_map(|s| [s.times.first(), s.times.last()])
            .flatten()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| (a.min(t), b.max(t)));
        let (t0, t1) = if t0 < t1 { (t0, t1) } else { (0.0, 1.0) };
        for (panel, (name, pick)) in panels.iter().zip([("|omega| (rad/s)", 0), ("|alpha| (rad/s^2)", 1)]) {
            let values = |s: &Series| if pick == 0 { s.omega.clone() } else { s.alpha.clone() };
            let top = series.iter().flat_map(values).filter(|v| v.is_finite()).fold(0.0f64, f64::max);
            let top = if top > 0.0 { 1.05 * top } else { 1.0 };
            let mut chart = ChartBuilder::on(panel)
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(60)
                .build_cartesian_2d(t0..t1, 0.0..top)?;
            // No vertical grid: the vertical rules are the key times.
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_desc("time (s)")
                .y_desc(name)
                .label_style((FONT, 14))
                .light_line_style(WHITE.mix(0.0))
                .bold_line_style(BLACK.mix(0.08))
                .draw()?;
            let rule = BLACK.mix(0.45);
            chart
                .draw_series(keys.iter().map(|&k| PathElement::new(vec![(k, 0.0), (k, top)], rule)))?
                .label("key times")
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], rule));
            for (i, s) in series.iter().enumerate() {
                let color = Palette99::pick(i).to_rgba();
                let style = color.stroke_width(2);
                chart
                    .draw_series(LineSeries::new(s.times.iter().copied().zip(values(s)), style))?
                    .label(&s.label)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2)));
            }
            chart
                .configure_series_labels()
                .label_font((FONT, 14))
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()?;
        }
        root.present()
    }
}
