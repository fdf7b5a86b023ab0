//! EXR files. A render is one layer holding
//! - the mean radiance `sum / iterations` as 32-bit float `R`, `G`, `B`: what every viewer shows;
//! - the exact f64 sums as pairs of 32-bit unsigned channels `vmerge.sum.R.hi` and
//!   `vmerge.sum.R.lo` (the high and low halves of the f64's bits; likewise G, B), so that
//!   `continue` and `merge` are bit-exact. Viewers show such channels as an extra layer
//!   `vmerge.sum.R` or not at all; they never replace the RGB image;
//! - the [`Metadata`] as text attributes `vmerge.*` of the header.
//!
//! Every write goes through [`atomic_write`](super::atomic_write).

use super::metadata::attribute;
use super::{Film, Metadata};
use crate::color::Rgb;
use exr::prelude::{
    read, AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Layer, LayerAttributes,
    ReadChannels, ReadLayers, Text, WritableImage,
};
use std::path::{Path, PathBuf};
use thiserror::Error;

const SUM_CHANNELS: [[&str; 2]; 3] = [
    ["vmerge.sum.R.hi", "vmerge.sum.R.lo"],
    ["vmerge.sum.G.hi", "vmerge.sum.G.lo"],
    ["vmerge.sum.B.hi", "vmerge.sum.B.lo"],
];

/// What can go wrong with an image file; every message starts with the file's name.
#[derive(Debug, Error)]
pub enum FilmError {
    /// Missing, unreadable, truncated, or not an EXR.
    #[error("{file}: cannot read: {message}")]
    Read { file: PathBuf, message: String },
    /// The file (or its temporary sibling) could not be written; the target is untouched.
    #[error("{file}: cannot write: {message}")]
    Write { file: PathBuf, message: String },
    /// An EXR without vmerge's sums or metadata where a render is needed.
    #[error("{file}: not a vmerge render ({message})")]
    NotARender { file: PathBuf, message: String },
    /// A readable file that does not fit: no colour channels, another resolution, renders that
    /// cannot be merged, ...
    #[error("{file}: {message}")]
    Invalid { file: PathBuf, message: String },
}

/// A plain RGB image.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<Rgb>,
}

impl Image {
    pub fn from_film(film: &Film) -> Self {
        Image {
            width: film.width,
            height: film.height,
            pixels: film.mean(),
        }
    }
}

/// Writes `film` and `metadata` to `path` atomically.
pub fn write_render(path: &Path, film: &Film, metadata: &Metadata) -> Result<(), FilmError> {
    let n = film.pixel_count();
    let mean = film.mean();
    let mut channels: Vec<AnyChannel<FlatSamples>> = Vec::with_capacity(9);
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        let values = mean.iter().map(|p| p.to_array()[c]).collect();
        channels.push(AnyChannel::new(name, FlatSamples::F32(values)));
        let (mut hi, mut lo) = (Vec::with_capacity(n), Vec::with_capacity(n));
        for s in &film.sum {
            let bits = s[c].to_bits();
            hi.push((bits >> 32) as u32);
            lo.push(bits as u32);
        }
        channels.push(AnyChannel::new(SUM_CHANNELS[c][0], FlatSamples::U32(hi)));
        channels.push(AnyChannel::new(SUM_CHANNELS[c][1], FlatSamples::U32(lo)));
    }
    let mut attributes = LayerAttributes::default();
    let fields = metadata.to_attributes().map_err(|e| FilmError::Write {
        file: path.into(),
        message: e.to_string(),
    })?;
    for (name, value) in fields {
        attributes
            .other
            .insert(Text::from(name), AttributeValue::Text(encode_text(&value)));
    }
    write_channels(path, film.width, film.height, channels, attributes)
}

/// Writes a plain RGB EXR (32-bit float R, G, B; no vmerge channels or attributes) atomically.
pub fn write_image(path: &Path, image: &Image) -> Result<(), FilmError> {
    if image.pixels.len() != image.width as usize * image.height as usize {
        return Err(FilmError::Write {
            file: path.into(),
            message: format!(
                "{} pixels do not make a {}x{} image",
                image.pixels.len(),
                image.width,
                image.height
            ),
        });
    }
    let channels = ["R", "G", "B"]
        .into_iter()
        .enumerate()
        .map(|(c, name)| {
            let values = image.pixels.iter().map(|p| p.to_array()[c]).collect();
            AnyChannel::new(name, FlatSamples::F32(values))
        })
        .collect();
    write_channels(
        path,
        image.width,
        image.height,
        channels,
        LayerAttributes::default(),
    )
}

fn write_channels(
    path: &Path,
    width: u32,
    height: u32,
    channels: Vec<AnyChannel<FlatSamples>>,
    attributes: LayerAttributes,
) -> Result<(), FilmError> {
    let layer = Layer::new(
        (width as usize, height as usize),
        attributes,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels.into()),
    );
    let image = exr::image::Image::from_layer(layer);
    super::atomic_write(path, |file| {
        image
            .write()
            .to_buffered(file)
            .map_err(|e| std::io::Error::other(e.to_string()))
    })
    .map_err(|e| FilmError::Write {
        file: path.into(),
        message: e.to_string(),
    })
}

type AnyImage = exr::image::Image<Layer<AnyChannels<FlatSamples>>>;

/// The most pixels an EXR read may have (a 32768 x 32768 image): a forged header must not
/// make the reader allocate without bound.
const MAX_READ_PIXELS: usize = 1 << 30;

fn read_any(path: &Path) -> Result<AnyImage, FilmError> {
    let unreadable = |message: String| FilmError::Read {
        file: path.into(),
        message,
    };
    if !path.exists() {
        return Err(unreadable("no such file (missing)".into()));
    }
    let bytes =
        crate::files::read(path, crate::files::Kind::Exr).map_err(|e| unreadable(e.message))?;
    let meta = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(&bytes), false)
        .map_err(|e| unreadable(format!("not a readable EXR: {e}")))?;
    for header in &meta.headers {
        let size = header.layer_size;
        let samples = size
            .width()
            .checked_mul(size.height())
            .and_then(|area| area.checked_mul(header.channels.list.len()));
        if samples.is_none_or(|n| n > MAX_READ_PIXELS * 9) || size.area() > MAX_READ_PIXELS {
            return Err(unreadable(format!(
                "its header claims {}x{} pixels of {} channels, more than vmerge reads",
                size.width(),
                size.height(),
                header.channels.list.len()
            )));
        }
    }
    read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| unreadable(format!("not a readable EXR: {e}")))
}

/// The channel `name` if it has one sample per pixel; subsampled channels (chroma in
/// luminance-chroma files) are not colour vmerge can use.
fn channel<'a>(image: &'a AnyImage, name: &str) -> Option<&'a FlatSamples> {
    image
        .layer_data
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == name)
        .map(|c| &c.sample_data)
        .filter(|samples| samples.len() == image.layer_data.size.area())
}

fn to_f32(samples: &FlatSamples) -> Vec<f32> {
    samples.values_as_f32().collect()
}

/// The channels to show as RGB: `R`, `G`, `B`; else `Y` (luminance) as grey; else the `R`, `G`,
/// `B` (or `Y`) of the one layer that has them (`Combined.R`, ...), as other programs write.
fn colour_channels<'a>(
    image: &'a AnyImage,
    path: &Path,
) -> Result<[&'a FlatSamples; 3], FilmError> {
    let names: Vec<String> = image
        .layer_data
        .channel_data
        .list
        .iter()
        .map(|c| c.name.to_string())
        .collect();
    let find = |prefix: &str| {
        let get = |c: &str| channel(image, &format!("{prefix}{c}"));
        match (get("R"), get("G"), get("B"), get("Y")) {
            (Some(r), Some(g), Some(b), _) => Some([r, g, b]),
            (_, _, _, Some(y)) => Some([y, y, y]),
            _ => None,
        }
    };
    if let Some(found) = find("") {
        return Ok(found);
    }
    let mut layers: Vec<(&str, [&FlatSamples; 3])> = names
        .iter()
        .filter_map(|n| n.rfind('.').map(|i| &n[..=i]))
        .filter_map(|p| find(p).map(|c| (p, c)))
        .collect();
    layers.sort_unstable_by_key(|(p, _)| *p);
    layers.dedup_by_key(|(p, _)| *p);
    match layers[..] {
        [(_, found)] => Ok(found),
        [] => Err(FilmError::Invalid {
            file: path.into(),
            message: format!(
                "has no R, G, B or Y channels (it has: {})",
                names.join(", ")
            ),
        }),
        _ => Err(FilmError::Invalid {
            file: path.into(),
            message: format!(
                "has several colour layers ({}) and no plain R, G, B to choose",
                layers
                    .iter()
                    .map(|(p, _)| p.trim_end_matches('.'))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }),
    }
}

/// Reads any RGB (or luminance-only) EXR as a plain image.
pub fn read_image(path: &Path) -> Result<Image, FilmError> {
    let image = read_any(path)?;
    let size = image.layer_data.size;
    let rgb = colour_channels(&image, path)?.map(to_f32);
    let pixels = (0..size.area())
        .map(|i| Rgb::new(rgb[0][i], rgb[1][i], rgb[2][i]))
        .collect();
    Ok(Image {
        width: size.width() as u32,
        height: size.height() as u32,
        pixels,
    })
}

/// Reads a vmerge render: its exact film and its metadata.
pub fn read_render(path: &Path) -> Result<(Film, Metadata), FilmError> {
    let image = read_any(path)?;
    let not_render = |message: &str| FilmError::NotARender {
        file: path.into(),
        message: message.into(),
    };
    let attributes = &image.layer_data.attributes.other;
    if !attributes
        .keys()
        .any(|name| name.to_string().starts_with(attribute::PREFIX))
    {
        return Err(not_render(
            "no vmerge metadata; it was not written by vmerge render, or was baked",
        ));
    }
    let metadata = Metadata::from_attributes(|name| match attributes.get(&Text::from(name)) {
        Some(AttributeValue::Text(t)) => Some(decode_text(t)),
        _ => None,
    })
    .map_err(|e| not_render(&format!("unreadable metadata: {e}")))?;
    let size = image.layer_data.size;
    let mut sums = Vec::with_capacity(3);
    for [hi, lo] in SUM_CHANNELS {
        match (channel(&image, hi), channel(&image, lo)) {
            (Some(FlatSamples::U32(h)), Some(FlatSamples::U32(l))) => sums.push(
                h.iter()
                    .zip(l)
                    .map(|(&h, &l)| f64::from_bits(((h as u64) << 32) | l as u64))
                    .collect::<Vec<_>>(),
            ),
            _ => {
                return Err(not_render(
                    "the exact sums are missing (baked or stripped by another program?)",
                ))
            }
        }
    }
    let sum: Vec<[f64; 3]> = (0..size.area())
        .map(|i| [sums[0][i], sums[1][i], sums[2][i]])
        .collect();
    check_sums(path, &sum, size.width(), &metadata)?;
    let film = Film {
        width: size.width() as u32,
        height: size.height() as u32,
        sum,
        iterations: metadata.iterations,
    };
    Ok((film, metadata))
}

/// A render's sums must be finite (samples that are not never reach the film, so a file with
/// such sums was altered), all zero when it records no iteration, and its recorded options must
/// pass the checks `render` applies to the command line.
fn check_sums(
    path: &Path,
    sum: &[[f64; 3]],
    width: usize,
    metadata: &Metadata,
) -> Result<(), FilmError> {
    let invalid = |message: String| FilmError::Invalid {
        file: path.into(),
        message,
    };
    metadata.validate().map_err(|e| invalid(e.to_string()))?;
    for (i, s) in sum.iter().enumerate() {
        for (c, value) in s.iter().enumerate() {
            let (x, y) = (i % width.max(1), i / width.max(1));
            if !value.is_finite() {
                return Err(invalid(format!(
                    "the channel {} has {value} at pixel ({x}, {y}): an altered or damaged file",
                    SUM_CHANNELS[c][0].trim_end_matches(".hi")
                )));
            }
            if metadata.iterations == 0 && *value != 0.0 {
                return Err(invalid(format!(
                    "{} records 0 iterations but {} has {value} at pixel ({x}, {y})",
                    super::metadata::attribute::ITERATIONS,
                    SUM_CHANNELS[c][0].trim_end_matches(".hi")
                )));
            }
        }
    }
    Ok(())
}

/// EXR text is Latin-1; anything else (a non-ASCII path) is escaped as `\u{...}`, and so is
/// the backslash itself, so that [`decode_text`] can tell the two apart.
fn encode_text(s: &str) -> Text {
    use std::fmt::Write;
    let mut escaped = String::with_capacity(s.len());
    for c in s.chars() {
        if c.is_ascii() && c != '\\' {
            escaped.push(c);
        } else {
            // Writing to a String cannot fail.
            let _ = write!(escaped, "\\u{{{:x}}}", c as u32);
        }
    }
    Text::from_bytes_unchecked(escaped.into_bytes().into())
}

fn decode_text(t: &Text) -> String {
    let s = t.to_string();
    let mut out = String::with_capacity(s.len());
    let mut rest = s.as_str();
    while let Some(i) = rest.find("\\u{") {
        out.push_str(&rest[..i]);
        let tail = &rest[i + 3..];
        match tail
            .find('}')
            .and_then(|j| u32::from_str_radix(&tail[..j], 16).ok().zip(Some(j)))
        {
            Some((code, j)) => {
                out.extend(char::from_u32(code));
                rest = &tail[j + 1..];
            }
            None => {
                out.push_str("\\u{");
                rest = tail;
            }
        }
    }
    out.push_str(rest);
    out
}
