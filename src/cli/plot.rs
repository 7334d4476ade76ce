//! Charts of `analyze --plot`: PNG or SVG by the file's extension, written atomically.
//!
//! Labels use DejaVu Sans embedded in the binary (the `dejavu` crate), so a chart renders the
//! same on a server without fonts (SVG names the family and leaves drawing text to the viewer).

use plotters::coord::Shift;
use plotters::prelude::*;
use quatcurve::io::write_atomic;
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

const SIZE: (u32, u32) = (1000, 640);
const FONT: &str = "sans-serif";

/// Draws `|omega|` (top) and `|alpha|` (bottom) against time, one line per series, the key
/// times marked by vertical rules, to `path` (`.png` or `.svg`).
///
/// # Errors
/// A message naming the file: an unknown extension, a drawing or writing failure.
pub fn rates(path: &Path, title: &str, series: &[Series], keys: &[f64]) -> Result<(), String> {
    let fail = |e: &dyn std::fmt::Display| format!("{}: {e}", path.display());
    // Both backends measure text with it. Registering twice is harmless; a font that does not
    // parse is a build defect.
    plotters::style::register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).map_err(|_| fail(&"the embedded font does not load"))?;
    match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
        Some("svg") => {
            let mut text = String::new();
            draw(SVGBackend::with_string(&mut text, SIZE).into_drawing_area(), title, series, keys).map_err(|e| fail(&e))?;
            write_atomic(path, |w| w.write_all(text.as_bytes())).map_err(|e| e.to_string())
        }
        Some("png") => {
            let mut pixels = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
            draw(BitMapBackend::with_buffer(&mut pixels, SIZE).into_drawing_area(), title, series, keys).map_err(|e| fail(&e))?;
            write_atomic(path, |w| {
                use image::ImageEncoder;
                image::codecs::png::PngEncoder::new(w)
                    .write_image(&pixels, SIZE.0, SIZE.1, image::ColorType::Rgb8)
                    .map_err(std::io::Error::other)
            })
            .map_err(|e| e.to_string())
        }
        _ => Err(format!("{}: a plot must end in .png or .svg", path.display())),
    }
}

fn draw<B: DrawingBackend>(root: DrawingArea<B, Shift>, title: &str, series: &[Series], keys: &[f64]) -> Result<(), DrawingAreaErrorKind<B::ErrorType>> {
    root.fill(&WHITE)?;
    let root = root.titled(title, (FONT, 20))?;
    let panels = root.split_evenly((2, 1));
    let (t0, t1) = series.iter().flat_map(|s| [s.times.first(), s.times.last()]).flatten().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &t| (a.min(t), b.max(t)));
    let (t0, t1) = if t0 < t1 { (t0, t1) } else { (0.0, 1.0) };
    for (panel, (name, pick)) in panels.iter().zip([("|omega| (rad/s)", 0), ("|alpha| (rad/s^2)", 1)]) {
        let values = |s: &Series| if pick == 0 { s.omega.clone() } else { s.alpha.clone() };
        let top = series.iter().flat_map(values).filter(|v| v.is_finite()).fold(0.0f64, f64::max);
        let top = if top > 0.0 { 1.05 * top } else { 1.0 };
        let mut chart = ChartBuilder::on(panel).margin(10).x_label_area_size(35).y_label_area_size(60).build_cartesian_2d(t0..t1, 0.0..top)?;
        // No vertical grid: the vertical rules are the key times.
        chart.configure_mesh().disable_x_mesh().x_desc("time (s)").y_desc(name).label_style((FONT, 14)).light_line_style(WHITE.mix(0.0)).bold_line_style(BLACK.mix(0.08)).draw()?;
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
        chart.configure_series_labels().label_font((FONT, 14)).position(SeriesLabelPosition::UpperRight).background_style(WHITE.mix(0.85)).border_style(BLACK).draw()?;
    }
    root.present()
}
