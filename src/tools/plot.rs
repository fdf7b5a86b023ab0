//! Convergence charts (000 Fig. 4.x): RMS error against render time, both on log scales, one
//! series per input labelled by technique and radius. PNG or SVG by the output's extension.
//! The font ships with the project (assets/fonts), so no system font stack is needed.

use crate::film::{atomic_write, FilmError, Metadata};
use crate::tools::metadata;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Once;

const FONT: &str = "vmerge-sans";
const SIZE: (u32, u32) = (960, 640);

fn register_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TrueType font compiled into the binary; failure is impossible
        // short of a corrupt build, and then text is simply not drawn.
        let _ = plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            include_bytes!("../../assets/fonts/DejaVuSans.ttf"),
        );
    });
}

struct Series {
    label: String,
    /// (seconds, rmse) of the whole image, then one list per trace window.
    points: Vec<Vec<(f64, f64)>>,
}

fn label(m: &Metadata) -> String {
    let mut label = m.options.technique.name().to_string();
    if let Some(r) = m.options.radius {
        label.push_str(&format!(" r={r}"));
    }
    label
}

fn load_series(inputs: &[PathBuf]) -> Result<Vec<Series>, FilmError> {
    inputs
        .iter()
        .map(|path| {
            let m = metadata(path)?;
            if m.errors.is_empty() {
                return Err(FilmError::Invalid {
                    file: path.clone(),
                    message: "has no error series (render it with --reference)".into(),
                });
            }
            let windows = m.traces.len();
            let mut points = vec![Vec::new(); windows + 1];
            for e in &m.errors {
                points[0].push((e.seconds, e.rmse));
                for (w, [_, rmse]) in e.traces.iter().enumerate().take(windows) {
                    points[w + 1].push((e.seconds, *rmse));
                }
            }
            Ok(Series {
                label: label(&m),
                points,
            })
        })
        .collect()
}

/// Draws the charts of `inputs` into `out` (.png or .svg). With `traces`, one chart per trace
/// window is drawn beside the whole-image chart, in a grid in the same file.
pub fn plot(out: &Path, inputs: &[PathBuf], traces: bool) -> Result<(), FilmError> {
    register_font();
    let series = load_series(inputs)?;
    let charts = if traces {
        series.iter().map(|s| s.points.len()).min().unwrap_or(1)
    } else {
        1
    };
    let svg = out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("svg"));
    let err = |message: String| FilmError::Write {
        file: out.into(),
        message,
    };
    if svg {
        let mut text = String::new();
        {
            let root = SVGBackend::with_string(&mut text, SIZE).into_drawing_area();
            draw(&root, &series, charts).map_err(err)?;
        }
        atomic_write(out, |f| f.write_all(text.as_bytes())).map_err(|e| err(e.to_string()))
    } else {
        let mut buffer = vec![0u8; (SIZE.0 * SIZE.1 * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buffer, SIZE).into_drawing_area();
            draw(&root, &series, charts).map_err(err)?;
        }
        atomic_write(out, |f| {
            let mut encoder = ::png::Encoder::new(f, SIZE.0, SIZE.1);
            encoder.set_color(::png::ColorType::Rgb);
            encoder.set_depth(::png::BitDepth::Eight);
            let mut w = encoder.write_header().map_err(std::io::Error::other)?;
            w.write_image_data(&buffer).map_err(std::io::Error::other)?;
            w.finish().map_err(std::io::Error::other)
        })
        .map_err(|e| err(e.to_string()))
    }
}

fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    series: &[Series],
    charts: usize,
) -> Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let columns = (charts as f64).sqrt().ceil() as usize;
    let rows = charts.div_ceil(columns);
    let areas = root.split_evenly((rows, columns));
    for (chart, area) in areas.iter().enumerate().take(charts) {
        let title = if chart == 0 {
            "whole image".to_string()
        } else {
            format!("trace window {}", chart - 1)
        };
        let all: Vec<(f64, f64)> = series
            .iter()
            .flat_map(|s| s.points[chart].iter().copied())
            .filter(|&(t, e)| t > 0.0 && e > 0.0)
            .collect();
        let (t0, t1) = bounds(all.iter().map(|p| p.0));
        let (e0, e1) = bounds(all.iter().map(|p| p.1));
        let mut ctx = ChartBuilder::on(area)
            .caption(&title, (FONT, 20))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d((t0..t1).log_scale(), (e0..e1).log_scale())
            .map_err(|e| e.to_string())?;
        ctx.configure_mesh()
            .x_desc("time [s]")
            .y_desc("RMS error")
            .label_style((FONT, 14))
            .draw()
            .map_err(|e| e.to_string())?;
        for (i, s) in series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let points = s.points[chart]
                .iter()
                .copied()
                .filter(|&(t, e)| t > 0.0 && e > 0.0);
            ctx.draw_series(LineSeries::new(points, color.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(s.label.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        ctx.configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font((FONT, 14))
            .draw()
            .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())
}

/// A positive range covering `values`, padded so a single value still makes an axis.
fn bounds(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| {
        (lo.min(v), hi.max(v))
    });
    if !lo.is_finite() || hi <= 0.0 {
        return (1e-3, 1.0);
    }
    (lo / 1.2, hi * 1.2)
}
