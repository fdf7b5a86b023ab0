//! EXR and PNG files: renders round-trip bit-exactly, bad files give errors naming the file,
//! plain EXRs from other programs read as images.

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Layer, LayerAttributes, WritableImage,
};
use std::path::{Path, PathBuf};
use vmerge::color::Rgb;
use vmerge::film::{exr as film_exr, png, ErrorSample, Film, FilmError, Metadata, TraceWindow};
use vmerge::options::RenderOptions;
use vmerge::options::Technique;
use vmerge::sampling::Rng;

/// A film whose sums use every bit of the f64 mantissa, plus awkward values.
fn film(width: u32, height: u32, seed: u64) -> Film {
    let mut rng = Rng::from_seed(seed, 0);
    let mut film = Film::new(width, height);
    film.iterations = 37;
    for s in &mut film.sum {
        *s = [
            rng.next_f64() * 37.0,
            rng.next_f64() * 1e-3,
            rng.next_f64() * 1e6,
        ];
    }
    film.sum[0] = [0.0, -0.0, f64::MIN_POSITIVE / 3.0];
    film.sum[1] = [1e300, 0.1 + 0.2, 1.0 / 3.0];
    film
}

fn metadata() -> Metadata {
    let options = RenderOptions {
        technique: Technique::Vcm,
        seed: 12345678901234567890,
        resolution: Some([24, 16]),
        radius: Some(0.02),
        ..RenderOptions::default()
    };
    let mut m = Metadata::new(
        "/scenes/box/scene.toml".into(),
        "f00d".into(),
        options,
        "bvh",
    );
    m.iterations = 37;
    m.render_seconds = 12.345678901234567;
    m.dropped_samples = 2;
    m.statistics = vec![
        ("light subpaths".into(), "384".into()),
        ("note".into(), "C:\\scènes\\u{41}\tbox\n∑".into()),
    ];
    m.reference = Some("référence.exr".into());
    m.traces = vec![TraceWindow {
        x: 4,
        y: 5,
        half_width: 3,
    }];
    m.errors = (1..=3)
        .map(|i| ErrorSample {
            seconds: i as f64 / 3.0,
            iterations: i * 10,
            mae: 1.0 / (i as f64 + 0.7),
            rmse: 2.0 / (i as f64 + 0.1),
            traces: vec![[i as f64 * 0.1, i as f64 * 0.2]],
            others: Default::default(),
        })
        .collect();
    m
}

fn bits(film: &Film) -> Vec<[u64; 3]> {
    film.sum.iter().map(|s| s.map(f64::to_bits)).collect()
}

#[test]
fn a_render_round_trips_bit_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("render.exr");
    let (film, metadata) = (film(24, 16, 1), metadata());
    film_exr::write_render(&path, &film, &metadata).unwrap();
    let (back, back_metadata) = film_exr::read_render(&path).unwrap();
    assert_eq!((back.width, back.height), (24, 16));
    assert_eq!(back.iterations, 37);
    assert_eq!(bits(&back), bits(&film));
    assert_eq!(back_metadata, metadata);
    // What a viewer shows: the mean as f32.
    let image = film_exr::read_image(&path).unwrap();
    assert_eq!(image.pixels, film.mean());
    // Nothing but the file itself is left in the directory.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn writing_over_a_render_replaces_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("render.exr");
    film_exr::write_render(&path, &film(8, 8, 1), &metadata()).unwrap();
    let newer = film(8, 8, 2);
    film_exr::write_render(&path, &newer, &metadata()).unwrap();
    assert_eq!(bits(&film_exr::read_render(&path).unwrap().0), bits(&newer));
}

fn assert_names(result: Result<impl std::fmt::Debug, FilmError>, path: &Path) -> String {
    let message = result.expect_err("an error").to_string();
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    assert!(message.contains(&name), "{message} does not name {name}");
    message
}

#[test]
fn a_missing_file_is_an_error_naming_it() {
    let path = PathBuf::from("no-such-dir/no-such-render.exr");
    let message = assert_names(film_exr::read_render(&path), &path);
    assert!(message.contains("missing"), "{message}");
    assert_names(film_exr::read_image(&path), &path);
}

#[test]
fn garbage_is_an_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut rng = Rng::from_seed(7, 0);
    let noise: Vec<u8> = (0..4096).map(|_| rng.next_u32() as u8).collect();
    for (name, bytes) in [
        ("empty.exr", Vec::new()),
        ("text.exr", b"this is not an image\n".to_vec()),
        ("noise.exr", noise),
        // The EXR magic number followed by nonsense.
        (
            "magic.exr",
            [0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0, 1, 2, 3].to_vec(),
        ),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        assert_names(film_exr::read_render(&path), &path);
        assert_names(film_exr::read_image(&path), &path);
    }
}

#[test]
fn every_truncation_of_a_render_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("whole.exr");
    film_exr::write_render(&path, &film(16, 16, 3), &metadata()).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    let cut = dir.path().join("cut.exr");
    // Every length in the header, then steps through the pixel data, and one byte short.
    let lengths = (0..2048.min(bytes.len()))
        .chain((2048..bytes.len()).step_by(97))
        .chain([bytes.len() - 1]);
    for length in lengths {
        std::fs::write(&cut, &bytes[..length]).unwrap();
        let read = film_exr::read_render(&cut);
        assert!(read.is_err(), "a render cut to {length} bytes was read");
        assert_names(read, &cut);
    }
}

#[test]
fn a_plain_exr_is_an_image_but_not_a_render() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plain.exr");
    let image = film_exr::Image::from_film(&film(5, 3, 4));
    film_exr::write_image(&path, &image).unwrap();
    assert_eq!(film_exr::read_image(&path).unwrap(), image);
    let message = assert_names(film_exr::read_render(&path), &path);
    assert!(message.contains("not a vmerge render"), "{message}");
}

/// Writes an EXR the way other programs do: float channels with the given names.
fn write_channels(path: &Path, width: usize, height: usize, channels: &[(&str, Vec<f32>)]) {
    let list: Vec<AnyChannel<FlatSamples>> = channels
        .iter()
        .map(|(name, values)| AnyChannel::new(*name, FlatSamples::F32(values.clone())))
        .collect();
    let layer = Layer::new(
        (width, height),
        LayerAttributes::default(),
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(list.into()),
    );
    exr::image::Image::from_layer(layer)
        .write()
        .to_file(path)
        .unwrap();
}

#[test]
fn images_from_other_programs_are_read() {
    let dir = tempfile::tempdir().unwrap();
    let ramp: Vec<f32> = (0..6).map(|i| i as f32 * 0.5).collect();
    let grey: Vec<Rgb> = ramp.iter().map(|&v| Rgb::splat(v)).collect();

    let luminance = dir.path().join("luminance.exr");
    write_channels(&luminance, 3, 2, &[("Y", ramp.clone())]);
    let image = film_exr::read_image(&luminance).unwrap();
    assert_eq!((image.width, image.height), (3, 2));
    assert_eq!(image.pixels, grey);

    // One named layer with an alpha channel, as a compositor writes it.
    let layered = dir.path().join("layered.exr");
    let doubled: Vec<f32> = ramp.iter().map(|v| v * 2.0).collect();
    write_channels(
        &layered,
        3,
        2,
        &[
            ("Combined.R", ramp.clone()),
            ("Combined.G", doubled.clone()),
            ("Combined.B", ramp.clone()),
            ("Combined.A", vec![1.0; 6]),
        ],
    );
    let image = film_exr::read_image(&layered).unwrap();
    assert_eq!(image.pixels[3], Rgb::new(1.5, 3.0, 1.5));

    let ambiguous = dir.path().join("two-layers.exr");
    write_channels(
        &ambiguous,
        3,
        2,
        &[
            ("diffuse.R", ramp.clone()),
            ("diffuse.G", ramp.clone()),
            ("diffuse.B", ramp.clone()),
            ("specular.R", ramp.clone()),
            ("specular.G", ramp.clone()),
            ("specular.B", ramp.clone()),
        ],
    );
    let message = assert_names(film_exr::read_image(&ambiguous), &ambiguous);
    assert!(message.contains("diffuse, specular"), "{message}");

    let depth = dir.path().join("depth.exr");
    write_channels(&depth, 3, 2, &[("Z", ramp)]);
    let message = assert_names(film_exr::read_image(&depth), &depth);
    assert!(message.contains("no R, G, B or Y"), "{message}");
}

#[test]
fn writing_into_a_missing_directory_is_an_error_naming_the_file() {
    let path = PathBuf::from("no-such-directory/render.exr");
    let result = film_exr::write_render(&path, &film(4, 4, 5), &metadata());
    let message = assert_names(result, &path);
    assert!(message.contains("cannot write"), "{message}");
}

#[test]
fn the_preview_is_reinhard_then_srgb() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("preview.png");
    // 0 -> 0; 1 -> 1/2 -> sRGB 188; 3 -> 3/4 -> sRGB 225; NaN and negative -> 0, +inf -> 255.
    let pixels = vec![
        Rgb::new(0.0, 1.0, 3.0),
        Rgb::new(f32::NAN, -1.0, f32::INFINITY),
    ];
    png::write_preview(&path, &pixels, 2, 1).unwrap();
    let decoder = ::png::Decoder::new(std::fs::File::open(&path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buffer = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buffer).unwrap();
    assert_eq!((info.width, info.height), (2, 1));
    assert_eq!(info.color_type, ::png::ColorType::Rgb);
    assert_eq!(&buffer[..6], &[0, 188, 225, 0, 0, 255]);
}
