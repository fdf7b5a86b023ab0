//! The error measures against their reference implementations and their defining properties:
//! FLIP against NVIDIA's `flip-evaluator`, SSIM against scikit-image, on the image pairs and
//! values of tests/fixtures/metrics (made by its make.py), and the `errors` command's output.

use std::path::{Path, PathBuf};
use std::process::Command;
use vmerge::color::Rgb;
use vmerge::film::{exr, Image};
use vmerge::metrics::{self, Errors, Measure, Selection};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/metrics")
}

/// A PFM file (`PF`, little-endian float32 RGB, rows bottom to top) as a top-to-bottom image.
fn read_pfm(path: &Path) -> Image {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut header = bytes.splitn(4, |&b| b == b'\n');
    let mut next = || {
        std::str::from_utf8(header.next().unwrap())
            .unwrap()
            .to_string()
    };
    assert_eq!(next(), "PF", "{}", path.display());
    let size: Vec<u32> = next()
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    assert!(next().parse::<f32>().unwrap() < 0.0, "little-endian");
    let (width, height) = (size[0], size[1]);
    let data = &bytes[bytes.len() - 12 * (width * height) as usize..];
    let floats: Vec<f32> = data
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let rows: Vec<&[f32]> = floats.chunks_exact(3 * width as usize).rev().collect();
    let pixels = rows
        .concat()
        .chunks_exact(3)
        .map(|c| Rgb::new(c[0], c[1], c[2]))
        .collect();
    Image {
        width,
        height,
        pixels,
    }
}

/// The pairs of expected.json: name, test, reference and the reference implementations' values.
fn pairs() -> Vec<(String, Image, Image, serde_json::Value)> {
    let text = std::fs::read_to_string(fixtures().join("expected.json")).unwrap();
    let expected: serde_json::Map<String, serde_json::Value> = serde_json::from_str(&text).unwrap();
    expected
        .into_iter()
        .map(|(name, values)| {
            let test = read_pfm(&fixtures().join(format!("{name}.test.pfm")));
            let reference = read_pfm(&fixtures().join(format!("{name}.reference.pfm")));
            (name, test, reference, values)
        })
        .collect()
}

fn measure(test: &Image, reference: &Image) -> Errors {
    metrics::measure(
        &test.pixels,
        &reference.pixels,
        test.width,
        test.height,
        Selection::All,
    )
}

/// FLIP agrees with flip-evaluator's mean to this much: both work in f32 and filter in the
/// same order, but sum the error map differently (f64 here). A 1% bias of the smallest FLIP
/// in the fixtures (about 0.04) is 4e-4, ten times more.
const FLIP_TOLERANCE: f64 = 2e-6;
/// SSIM is computed in f64 on the same f32 inputs as scikit-image's.
const SSIM_TOLERANCE: f64 = 1e-6;

#[test]
fn flip_and_ssim_match_the_reference_implementations() {
    let pairs = pairs();
    assert!(pairs.len() >= 7, "{} pairs", pairs.len());
    let mut failures = Vec::new();
    for (name, test, reference, expected) in &pairs {
        let got = measure(test, reference);
        for (measure, tolerance) in [
            (Measure::HdrFlip, FLIP_TOLERANCE),
            (Measure::LdrFlip, FLIP_TOLERANCE),
            (Measure::Ssim, SSIM_TOLERANCE),
        ] {
            let want = expected[measure.name()].as_f64().unwrap();
            let value = got.get(measure).unwrap();
            println!(
                "{name} {measure}: {value} (reference {want}, difference {:.2e})",
                value - want
            );
            if (value - want).abs() > tolerance {
                failures.push(format!("{name} {measure}: {value}, reference {want}"));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn flip_falls_and_ssim_rises_as_a_render_converges() {
    let pairs = pairs();
    let renders: Vec<Errors> = [1, 4, 16, 64]
        .iter()
        .map(|n| {
            let (_, test, reference, _) = pairs
                .iter()
                .find(|p| p.0 == format!("cornell-pt-{n}"))
                .unwrap();
            measure(test, reference)
        })
        .collect();
    for pair in renders.windows(2) {
        for m in Measure::ALL {
            let (before, after) = (pair[0].get(m).unwrap(), pair[1].get(m).unwrap());
            assert!(
                m.as_error(after) < m.as_error(before),
                "{m}: {before} then {after}"
            );
        }
    }
}

#[test]
fn identical_images_give_no_error() {
    for (name, _, reference, _) in pairs() {
        let e = measure(&reference, &reference);
        for m in Measure::ALL {
            let want = if m.higher_is_better() { 1.0 } else { 0.0 };
            assert_eq!(e.get(m), Some(want), "{name} {m}");
        }
    }
}

#[test]
fn relative_mse_of_a_scaled_image() {
    // Test (1 + k) c against c everywhere: relmse = k^2 c^2 / (c^2 + 0.01), the same for every
    // pixel and channel.
    let (k, c) = (0.25f64, 0.3f64);
    let reference = vec![Rgb::splat(c as f32); 16 * 16];
    let test = vec![Rgb::splat(((1.0 + k) * c) as f32); 16 * 16];
    let e = metrics::measure(&test, &reference, 16, 16, Selection::Pointwise);
    let (t, r) = (f64::from(((1.0 + k) * c) as f32), f64::from(c as f32));
    let expected = (t - r).powi(2) / (r * r + 0.01);
    let got = e.get(Measure::RelativeMse).unwrap();
    assert!((got - expected).abs() < 1e-12, "{got} {expected}");
    assert!((got - k * k * c * c / (c * c + 0.01)).abs() < 1e-7, "{got}");
    assert_eq!(e.get(Measure::Ssim), None);
}

fn vmerge(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_vmerge"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

#[test]
fn errors_command_prints_every_measure() {
    let dir = tempfile::tempdir().unwrap();
    let (_, test, reference, expected) =
        pairs().into_iter().find(|p| p.0 == "cornell-pt-4").unwrap();
    let (a, b) = (dir.path().join("a.exr"), dir.path().join("b.exr"));
    exr::write_image(&a, &test).unwrap();
    exr::write_image(&b, &reference).unwrap();
    let (a, b) = (a.to_str().unwrap(), b.to_str().unwrap());
    let (ok, out) = vmerge(&["errors", a, b]);
    assert!(ok, "{out}");
    let names: Vec<&str> = out.lines().filter_map(|l| l.split(' ').next()).collect();
    assert_eq!(names, Measure::ALL.map(|m| m.name()), "{out}");
    let value = |name: &str| -> f64 {
        let line = out
            .lines()
            .find(|l| l.starts_with(&format!("{name} ")))
            .unwrap();
        line[name.len() + 1..].parse().unwrap()
    };
    let want = expected["hdr-flip"].as_f64().unwrap();
    assert!((value("hdr-flip") - want).abs() < FLIP_TOLERANCE, "{out}");
    // Script-friendly: the values asked for, in that order, on one line.
    let (ok, one) = vmerge(&["errors", "--measure", "rmse", "--measure", "mae", a, b]);
    assert!(ok);
    assert_eq!(one.trim(), format!("{} {}", value("rmse"), value("mae")));
    let (ok, relative) = vmerge(&["errors", "--relative", a, b]);
    assert!(ok);
    assert_eq!(relative.trim(), value("relmse").to_string());
}
