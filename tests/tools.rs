//! The file tools: merge, bake, strip, diff, errors, average, measurements, traces, time, plot.

use std::path::{Path, PathBuf};
use vmerge::color::Rgb;
use vmerge::film::{exr as film_exr, ErrorSample, Film, Image, Metadata, TraceWindow};
use vmerge::metrics::{Measure, Selection};
use vmerge::options::RenderOptions;
use vmerge::options::Technique;
use vmerge::sampling::Rng;
use vmerge::tools::{self, Metric};

const W: u32 = 12;
const H: u32 = 8;

/// A render of `iterations` iterations of noisy per-pixel estimates around a gradient.
fn render(seed: u64, iterations: u64) -> (Film, Metadata) {
    let mut film = Film::new(W, H);
    for iteration in 0..iterations {
        let mut rng = Rng::from_seed(seed, iteration);
        let frame: Vec<Rgb> = (0..film.pixel_count())
            .map(|i| Rgb::new(i as f32 / 10.0, rng.next_f32(), 2.0 * rng.next_f32()))
            .collect();
        film.add_iteration(&frame);
    }
    let options = RenderOptions {
        technique: Technique::Vcm,
        seed,
        radius: Some(0.05),
        ..RenderOptions::default()
    };
    let mut m = Metadata::new("scene.toml".into(), "hash-1".into(), options, "bvh");
    m.iterations = iterations;
    m.render_seconds = iterations as f64 * 0.25;
    m.dropped_samples = seed;
    m.statistics = vec![("photons".into(), "96".into())];
    m.traces = vec![
        TraceWindow {
            x: 3,
            y: 3,
            half_width: 2,
        },
        TraceWindow {
            x: 9,
            y: 4,
            half_width: 1,
        },
    ];
    m.errors = (1..=iterations.min(20))
        .map(|i| ErrorSample {
            seconds: i as f64 * 0.25,
            iterations: i,
            mae: 0.5 / (i as f64).sqrt(),
            rmse: (seed as f64 + 1.0) / (i as f64).sqrt(),
            traces: vec![[0.3 / i as f64, 0.4 / i as f64], [0.1, 0.2 / i as f64]],
            others: Default::default(),
        })
        .collect();
    (film, m)
}

fn write(dir: &Path, name: &str, (film, metadata): &(Film, Metadata)) -> PathBuf {
    let path = dir.join(name);
    film_exr::write_render(&path, film, metadata).unwrap();
    path
}

#[test]
fn merge_is_the_iteration_weighted_mean() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (render(1, 3), render(2, 5));
    let inputs = [
        write(dir.path(), "a.exr", &a),
        write(dir.path(), "b.exr", &b),
    ];
    let out = dir.path().join("merged.exr");
    tools::merge(&out, &inputs).unwrap();
    let (merged, m) = film_exr::read_render(&out).unwrap();
    assert_eq!(merged.iterations, 8);
    // The sums add exactly (one f64 addition per value).
    for ((s, x), y) in merged.sum.iter().zip(&a.0.sum).zip(&b.0.sum) {
        for c in 0..3 {
            assert_eq!(s[c].to_bits(), (x[c] + y[c]).to_bits());
        }
    }
    // The mean is (3 mean_a + 5 mean_b) / 8, to f32 rounding of the means.
    let (mean_a, mean_b) = (a.0.mean(), b.0.mean());
    for (i, p) in merged.mean().iter().enumerate() {
        for c in 0..3 {
            let expected =
                (3.0 * mean_a[i].to_array()[c] as f64 + 5.0 * mean_b[i].to_array()[c] as f64) / 8.0;
            let got = p.to_array()[c] as f64;
            assert!(
                (got - expected).abs() <= 1e-6 * expected.abs().max(1.0),
                "pixel {i} channel {c}: {got} vs {expected}"
            );
        }
    }
    assert_eq!(m.iterations, 8);
    assert_eq!(m.render_seconds, 0.75 + 1.25);
    assert_eq!(m.dropped_samples, 1 + 2);
    assert_eq!(m.options.seed, 1);
    assert_eq!(m.statistic(tools::MERGED_SEEDS), Some("1 2"));
    assert_eq!(m.statistic("photons"), Some("96"));
    assert!(m.errors.is_empty());

    // A merge merges again, its seeds listed; merging an input twice is refused.
    let c = write(dir.path(), "c.exr", &render(3, 2));
    let again = dir.path().join("again.exr");
    tools::merge(&again, &[out.clone(), c]).unwrap();
    let (film, m) = film_exr::read_render(&again).unwrap();
    assert_eq!(film.iterations, 10);
    assert_eq!(m.statistic("merged_seeds"), Some("1 2 3"));
    let message = tools::merge(&again, &[out, inputs[1].clone()])
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("b.exr") && message.contains("merged.exr") && message.contains("seed 2"),
        "{message}"
    );
}

#[test]
fn merge_refuses_renders_that_differ() {
    let dir = tempfile::tempdir().unwrap();
    let first = write(dir.path(), "first.exr", &render(1, 2));
    type Change = Box<dyn Fn(&mut Film, &mut Metadata)>;
    let cases: Vec<(&str, Change, &str)> = vec![
        (
            "scene.exr",
            Box::new(|_, m| m.scene_hash = "hash-2".into()),
            "different scene",
        ),
        (
            "resolution.exr",
            Box::new(|f, _| *f = Film::new(W, H + 1)),
            "different resolution",
        ),
        (
            "technique.exr",
            Box::new(|_, m| m.options.technique = Technique::Bpm),
            "different technique (bpm, not vcm)",
        ),
        (
            "radius.exr",
            Box::new(|_, m| m.options.radius = Some(0.1)),
            "radius: 0.1",
        ),
        (
            "alpha.exr",
            Box::new(|_, m| m.options.alpha = Some(0.5)),
            "alpha: 0.5 vs default",
        ),
        ("seed.exr", Box::new(|_, _| ()), "has seed 1"),
    ];
    for (name, change, expected) in cases {
        let (mut film, mut metadata) = render(1, 2);
        if name != "seed.exr" {
            metadata.options.seed = 9;
        }
        change(&mut film, &mut metadata);
        let path = write(dir.path(), name, &(film, metadata));
        let out = dir.path().join("out.exr");
        let message = tools::merge(&out, &[first.clone(), path])
            .unwrap_err()
            .to_string();
        assert!(
            message.contains(name) && message.contains("first.exr") && message.contains(expected),
            "{name}: {message}"
        );
        assert!(!out.exists(), "{name}: wrote the output");
    }
    let plain = dir.path().join("plain.exr");
    tools::bake(&plain, &first).unwrap();
    let message = tools::merge(&dir.path().join("out.exr"), &[first, plain])
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("plain.exr: not a vmerge render"),
        "{message}"
    );
}

#[test]
fn bake_writes_plain_rgb_without_vmerge_data() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(4, 3);
    let input = write(dir.path(), "render.exr", &r);
    let out = dir.path().join("baked.exr");
    tools::bake(&out, &input).unwrap();
    let raw = exr::prelude::read_all_flat_layers_from_file(&out).unwrap();
    assert_eq!(raw.layer_data.len(), 1);
    let layer = &raw.layer_data[0];
    assert!(
        layer.attributes.other.is_empty(),
        "{:?}",
        layer.attributes.other
    );
    let names: Vec<String> = layer
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    assert_eq!(names, ["B", "G", "R"]);
    assert_eq!(film_exr::read_image(&out).unwrap().pixels, r.0.mean());
}

#[test]
fn strip_drops_the_error_series_and_keeps_the_sums() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(5, 4);
    let input = write(dir.path(), "render.exr", &r);
    let out = dir.path().join("stripped.exr");
    tools::strip(&out, &input).unwrap();
    let (film, m) = film_exr::read_render(&out).unwrap();
    assert_eq!(film, r.0);
    assert!(m.errors.is_empty() && m.traces.is_empty() && m.reference.is_none());
    assert_eq!(m.options, r.1.options);
    assert_eq!(m.iterations, r.1.iterations);
}

#[test]
fn measurements_time_and_traces_read_the_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let r = render(6, 3);
    let path = write(dir.path(), "render.exr", &r);
    let csv = tools::measurements(&path).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("seconds,iterations,mae,rmse,trace0_mae,trace0_rmse,trace1_mae,trace1_rmse")
    );
    let rows: Vec<Vec<f64>> = lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 3);
    for (row, e) in rows.iter().zip(&r.1.errors) {
        let expected = [
            e.seconds,
            e.iterations as f64,
            e.mae,
            e.rmse,
            e.traces[0][0],
            e.traces[0][1],
            e.traces[1][0],
            e.traces[1][1],
        ];
        assert_eq!(row[..], expected[..]);
    }
    assert_eq!(tools::time(&path).unwrap(), 0.75);
    assert_eq!(tools::traces(&path).unwrap(), r.1.traces);
}

fn write_image(dir: &Path, name: &str, width: u32, pixels: Vec<Rgb>) -> PathBuf {
    let path = dir.join(name);
    let height = pixels.len() as u32 / width;
    film_exr::write_image(
        &path,
        &Image {
            width,
            height,
            pixels,
        },
    )
    .unwrap();
    path
}

#[test]
fn diff_errors_and_average_on_a_tiny_pair() {
    let dir = tempfile::tempdir().unwrap();
    let a = write_image(
        dir.path(),
        "a.exr",
        2,
        vec![Rgb::new(3.0, 1.0, 0.0), Rgb::new(0.5, 2.0, 4.0)],
    );
    let b = write_image(
        dir.path(),
        "b.exr",
        2,
        vec![Rgb::new(2.0, 0.0, 0.0), Rgb::new(1.0, -4.0, 4.0)],
    );
    let out = dir.path().join("diff.exr");
    tools::diff(&out, &a, &b).unwrap();
    // |a - b| / |b|; where b = 0, |a - b|.
    assert_eq!(
        film_exr::read_image(&out).unwrap().pixels,
        vec![Rgb::new(0.5, 1.0, 0.0), Rgb::new(0.5, 1.5, 0.0)]
    );
    // Differences 1, 1, 0, -0.5, 6, 0: sum |d| = 8.5, sum d^2 = 38.25, n = 6.
    let errors = tools::errors(&a, &b, Selection::All).unwrap();
    assert_eq!(errors.get(Measure::Mae), Some(8.5 / 6.0));
    assert_eq!(errors.get(Measure::Rmse), Some((38.25f64 / 6.0).sqrt()));
    assert_eq!(tools::average(&a).unwrap(), [1.75, 1.5, 2.0]);
    // d^2 / (b^2 + 0.01) per channel, over 6 channels.
    let terms = [1.0 / 4.01, 1.0 / 0.01, 0.0, 0.25 / 1.01, 36.0 / 16.01, 0.0];
    let expected = terms.iter().sum::<f64>() / 6.0;
    let relative = errors.get(Measure::RelativeMse).unwrap();
    assert!((relative - expected).abs() < 1e-12 * expected, "{relative}");
    let same = tools::errors(&a, &a, Selection::All).unwrap();
    assert_eq!(same.get(Measure::RelativeMse), Some(0.0));
    // 2x1 pixels: too small for the windows of FLIP and SSIM.
    assert_eq!(same.get(Measure::Ssim), None);

    let wide = write_image(dir.path(), "wide.exr", 4, vec![Rgb::BLACK; 4]);
    for message in [
        tools::errors(&a, &wide, Selection::All)
            .unwrap_err()
            .to_string(),
        tools::diff(&out, &a, &wide).unwrap_err().to_string(),
    ] {
        assert!(
            message.contains("wide.exr") && message.contains("a.exr") && message.contains("4x1"),
            "{message}"
        );
    }
}

/// Distinct RGB colours of a PNG.
fn colours(path: &Path) -> (u32, u32, usize) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let mut distinct: Vec<&[u8]> = buffer[..info.buffer_size()].chunks(3).collect();
    distinct.sort_unstable();
    distinct.dedup();
    (info.width, info.height, distinct.len())
}

#[test]
fn plot_draws_charts() {
    let dir = tempfile::tempdir().unwrap();
    let a = write(dir.path(), "a.exr", &render(1, 20));
    let b = write(dir.path(), "b.exr", &render(2, 10));
    let out = dir.path().join("chart.png");
    tools::plot(&out, &[a.clone(), b.clone()], false, Metric::Rmse).unwrap();
    let (width, height, distinct) = colours(&out);
    // Two series in two colours, black axes and text on white, antialiased text.
    assert!(distinct > 2, "{distinct} colours");
    // With traces: the whole image and two windows, a 2 x 2 grid.
    let grid = dir.path().join("traces.png");
    tools::plot(&grid, &[a.clone(), b.clone()], true, Metric::Rmse).unwrap();
    let (grid_width, grid_height, _) = colours(&grid);
    assert_eq!((grid_width, grid_height), (2 * width, 2 * height));

    let svg = dir.path().join("chart.svg");
    tools::plot(&svg, &[a.clone(), b.clone()], false, Metric::Rmse).unwrap();
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.starts_with("<svg") && text.contains("vcm r=0.05 (a)"));
    assert!(text.contains("RMS error") && text.contains("<polyline"));
    // The thesis's metric: the same chart of the mean absolute error, another polyline.
    let mae = dir.path().join("mae.svg");
    tools::plot(&mae, &[a.clone(), b], false, Metric::Mae).unwrap();
    let mae_text = std::fs::read_to_string(&mae).unwrap();
    assert!(mae_text.contains("mean absolute error") && !mae_text.contains("RMS error"));
    let polyline = |t: &str| t.split("<polyline").nth(1).map(str::to_owned);
    assert_ne!(polyline(&text), polyline(&mae_text));

    let plain = dir.path().join("plain.exr");
    let (film, mut m) = render(3, 2);
    m.errors.clear();
    film_exr::write_render(&plain, &film, &m).unwrap();
    let message = tools::plot(&out, &[a, plain], false, Metric::Rmse)
        .unwrap_err()
        .to_string();
    assert!(message.contains("plain.exr") && message.contains("no error series"));
}
