//! Convergence charts (000 ch. 4): an error measure against render time, both on
//! log scales, one series per input labelled by technique and radius; and [`draw_charts`], the
//! same drawing for any log-log data (the batch report's error-against-radius charts). PNG or
//! SVG by the output's extension.
//! The font ships with the project (assets/fonts) and is compiled in, so no system font stack
//! (fontconfig, freetype) is needed.

use crate::film::{atomic_write, FilmError, Metadata};
use crate::options::OptionName;
use crate::tools::metadata;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

const FONT: &str = "vmerge-sans";
/// Series of at most this many samples are drawn with a mark per sample.
const MARKED: usize = 30;
/// Size of one chart in pixels; a grid of charts is a multiple of it.
const CHART: (u32, u32) = (960, 640);

/// Registers the font compiled into the binary (DejaVu Sans, assets/fonts) with plotters, once.
fn register_font() -> Result<(), String> {
    static RESULT: OnceLock<Result<(), String>> = OnceLock::new();
    RESULT
        .get_or_init(|| {
            plotters::style::register_font(
                FONT,
                FontStyle::Normal,
                include_bytes!("../../assets/fonts/DejaVuSans.ttf"),
            )
            .map_err(|_| "the built-in font does not load".to_string())
        })
        .clone()
}

/// The error a chart shows: any of the measures, SSIM as 1 - SSIM so that every chart falls.
pub use crate::metrics::Measure as Metric;

/// One chart of [`draw_charts`]: log-log axes, one line per series.
#[derive(Clone, Debug)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<ChartSeries>,
}

#[derive(Clone, Debug)]
pub struct ChartSeries {
    pub label: String,
    /// (x, y); points with a coordinate <= 0 cannot be drawn on log axes and are left out.
    pub points: Vec<(f64, f64)>,
}

/// The technique and, when given, the radius; inputs that would share a label get their file
/// name appended.
fn labels(inputs: &[(PathBuf, Metadata)]) -> Vec<String> {
    let short: Vec<String> = inputs
        .iter()
        .map(|(_, m)| match m.options.radius {
            Some(r) => format!("{} r={r}", m.options.technique.name()),
            None => m.options.technique.name().to_string(),
        })
        .collect();
    short
        .iter()
        .zip(inputs)
        .map(|(label, (path, _))| {
            if short.iter().filter(|l| *l == label).count() > 1 {
                let name = path.file_stem().unwrap_or(path.as_os_str());
                format!("{label} ({})", name.to_string_lossy())
            } else {
                label.clone()
            }
        })
        .collect()
}

/// The charts of `inputs`: the whole image and, with `traces`, one per common trace window.
fn load_charts(inputs: &[PathBuf], traces: bool, metric: Metric) -> Result<Vec<Chart>, FilmError> {
    let loaded: Vec<(PathBuf, Metadata)> = inputs
        .iter()
        .map(|path| Ok((path.clone(), metadata(path)?)))
        .collect::<Result<_, FilmError>>()?;
    let Some((first_path, first)) = loaded.first() else {
        return Err(FilmError::Invalid {
            file: PathBuf::new(),
            message: "plot needs at least one input".into(),
        });
    };
    for (path, m) in &loaded {
        let invalid = |message: String| FilmError::Invalid {
            file: path.clone(),
            message,
        };
        if m.errors.is_empty() {
            return Err(invalid(format!(
                "has no error series (render it with {})",
                OptionName("reference")
            )));
        }
        if traces && m.traces.is_empty() {
            return Err(invalid(format!(
                "has no trace windows (render it with {})",
                OptionName("trace")
            )));
        }
        if traces && m.traces != first.traces {
            return Err(invalid(format!(
                "has other trace windows than {}: the charts would mix windows",
                first_path.display()
            )));
        }
    }
    let windows = if traces {
        first.traces.clone()
    } else {
        Vec::new()
    };
    let labels = labels(&loaded);
    let charts = (0..=windows.len())
        .map(|chart| Chart {
            title: match chart {
                0 => "whole image".to_string(),
                w => format!("trace window {} ({})", w - 1, windows[w - 1]),
            },
            x_label: "time [s]".into(),
            y_label: metric.error_label().into(),
            series: loaded
                .iter()
                .zip(&labels)
                .map(|((_, m), label)| ChartSeries {
                    label: label.clone(),
                    // Samples without the measure (the perceptual ones are not taken at
                    // every sample; windows hold MAE and RMSE only) are left out.
                    points: m
                        .errors
                        .iter()
                        .filter_map(|e| {
                            let value = match chart {
                                0 => e.get(metric),
                                w => e.window(w - 1, metric),
                            };
                            Some((e.seconds, metric.as_error(value?)))
                        })
                        .collect(),
                })
                .collect(),
        })
        .collect();
    Ok(charts)
}

/// Draws the convergence chart of `inputs` (vmerge renders made with `--reference`) into
/// `out`: SVG when its extension is `.svg`, PNG otherwise. Each input is one series, `metric`
/// against render time on log-log axes, labelled with its technique and radius.
///
/// With `traces`, the same file holds a grid of charts: the whole image first, then one chart
/// per trace window (the inputs must share their windows).
pub fn plot(out: &Path, inputs: &[PathBuf], traces: bool, metric: Metric) -> Result<(), FilmError> {
    draw_charts(out, &load_charts(inputs, traces, metric)?)
}

/// Draws `charts` in a grid into `out` (SVG when its extension is `.svg`, PNG otherwise), each
/// on log-log axes.
pub fn draw_charts(out: &Path, charts: &[Chart]) -> Result<(), FilmError> {
    let count = charts.len().max(1);
    let columns = (count as f64).sqrt().ceil() as u32;
    let rows = (count as u32).div_ceil(columns);
    let size = (CHART.0 * columns, CHART.1 * rows);
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
            let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
            draw(&root, charts, (rows, columns)).map_err(err)?;
        }
        atomic_write(out, |f| f.write_all(text.as_bytes())).map_err(|e| err(e.to_string()))
    } else {
        let mut buffer = vec![0u8; size.0 as usize * size.1 as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut buffer, size).into_drawing_area();
            draw(&root, charts, (rows, columns)).map_err(err)?;
        }
        atomic_write(out, |f| {
            let mut encoder = ::png::Encoder::new(f, size.0, size.1);
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
    charts: &[Chart],
    (rows, columns): (u32, u32),
) -> Result<(), String> {
    register_font()?;
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let areas = root.split_evenly((rows as usize, columns as usize));
    for (chart, area) in charts.iter().zip(&areas) {
        let all: Vec<(f64, f64)> = chart
            .series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .filter(|&(t, e)| t > 0.0 && e > 0.0)
            .collect();
        let (t0, t1) = bounds(all.iter().map(|p| p.0));
        let (e0, e1) = bounds(all.iter().map(|p| p.1));
        let mut ctx = ChartBuilder::on(area)
            .caption(&chart.title, (FONT, 20))
            .margin(10)
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(
                (t0..t1).log_scale().with_key_points(log_ticks(t0, t1)),
                (e0..e1).log_scale().with_key_points(log_ticks(e0, e1)),
            )
            .map_err(|e| e.to_string())?;
        ctx.configure_mesh()
            .x_desc(&chart.x_label)
            .y_desc(&chart.y_label)
            .x_label_formatter(&|v| tick(*v))
            .y_label_formatter(&|v| tick(*v))
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 16))
            .draw()
            .map_err(|e| e.to_string())?;
        for (i, s) in chart.series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            let points: Vec<(f64, f64)> = s
                .points
                .iter()
                .copied()
                .filter(|&(t, e)| t > 0.0 && e > 0.0)
                .collect();
            // Short series get a mark per sample, so that even one sample shows.
            if points.len() <= MARKED {
                ctx.draw_series(points.iter().map(|&p| Circle::new(p, 3, color.filled())))
                    .map_err(|e| e.to_string())?;
            }
            ctx.draw_series(LineSeries::new(points, color.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(s.label.clone())
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        // Errors fall with time, so the upper right corner is the free one.
        ctx.configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font((FONT, 14))
            .draw()
            .map_err(|e| e.to_string())?;
    }
    root.present().map_err(|e| e.to_string())
}

/// Round values between `lo` and `hi` (> 0) for a log axis: 1, 2, ..., 9 times the powers of
/// ten when the range spans less than a decade, 1, 2, 3, 5 times them up to 2.5 decades, 1, 2, 5
/// times them up to five, the powers alone beyond (every few powers over many decades).
fn log_ticks(lo: f64, hi: f64) -> Vec<f64> {
    let decades = (hi / lo).log10();
    let mantissas: &[f64] = if decades < 1.0 {
        &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0]
    } else if decades < 2.5 {
        &[1.0, 2.0, 3.0, 5.0]
    } else if decades < 5.0 {
        &[1.0, 2.0, 5.0]
    } else {
        &[1.0]
    };
    let step = (decades / 8.0).ceil().max(1.0) as i32;
    let first = lo.log10().floor() as i32;
    let last = hi.log10().ceil() as i32;
    (first..=last)
        .step_by(step as usize)
        .flat_map(|e| mantissas.iter().map(move |m| m * 10f64.powi(e)))
        .filter(|v| (lo..=hi).contains(v))
        .collect()
}

/// A tick label with three significant digits at most: `0.25`, `120`, `3e-5`.
fn tick(v: f64) -> String {
    if v == 0.0 || (1e-3..1e5).contains(&v.abs()) {
        let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
        let text = format!("{v:.digits$}");
        if text.contains('.') {
            text.trim_end_matches('0').trim_end_matches('.').to_string()
        } else {
            text
        }
    } else {
        format!("{v:.1e}")
    }
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
