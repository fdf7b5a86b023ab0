//! EXR files. A render is the mean radiance as 32-bit float R, G, B (what every viewer shows),
//! plus the exact f64 sums as pairs of u32 channels (so `continue` and `merge` are bit-exact),
//! plus the [`Metadata`] as a text attribute. Every write goes through a temporary file in the
//! same directory, flushed and renamed over the target.

use super::{Film, Metadata};
use crate::color::Rgb;
use exr::prelude::{
    read, AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Layer, LayerAttributes,
    ReadChannels, ReadLayers, Text, WritableImage,
};
use std::path::{Path, PathBuf};
use thiserror::Error;

const METADATA_ATTRIBUTE: &str = "vmerge";
const SUM_CHANNELS: [[&str; 2]; 3] = [
    ["vmerge.sum.R.hi", "vmerge.sum.R.lo"],
    ["vmerge.sum.G.hi", "vmerge.sum.G.lo"],
    ["vmerge.sum.B.hi", "vmerge.sum.B.lo"],
];

#[derive(Debug, Error)]
pub enum FilmError {
    #[error("{file}: cannot read: {message}")]
    Read { file: PathBuf, message: String },
    #[error("{file}: cannot write: {message}")]
    Write { file: PathBuf, message: String },
    #[error("{file}: not a vmerge render ({message})")]
    NotARender { file: PathBuf, message: String },
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
    let toml = metadata.to_toml().map_err(|message| FilmError::Write {
        file: path.into(),
        message,
    })?;
    let mut attributes = LayerAttributes::default();
    attributes.other.insert(
        Text::from(METADATA_ATTRIBUTE),
        AttributeValue::Text(encode_text(&toml)),
    );
    write_channels(path, film.width, film.height, channels, attributes)
}

/// Writes a plain RGB EXR (no vmerge channels or attributes) atomically.
pub fn write_image(path: &Path, image: &Image) -> Result<(), FilmError> {
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

fn read_any(path: &Path) -> Result<AnyImage, FilmError> {
    if !path.exists() {
        return Err(FilmError::Read {
            file: path.into(),
            message: "no such file (missing)".into(),
        });
    }
    read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| FilmError::Read {
            file: path.into(),
            message: format!("not a readable EXR: {e}"),
        })
}

fn channel<'a>(image: &'a AnyImage, name: &str) -> Option<&'a FlatSamples> {
    image
        .layer_data
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == name)
        .map(|c| &c.sample_data)
}

fn to_f32(samples: &FlatSamples) -> Vec<f32> {
    samples.values_as_f32().collect()
}

/// Reads any RGB (or luminance-only) EXR as a plain image.
pub fn read_image(path: &Path) -> Result<Image, FilmError> {
    let image = read_any(path)?;
    let size = image.layer_data.size;
    let rgb: Vec<Vec<f32>> = match (
        channel(&image, "R"),
        channel(&image, "G"),
        channel(&image, "B"),
    ) {
        (Some(r), Some(g), Some(b)) => vec![to_f32(r), to_f32(g), to_f32(b)],
        _ => match channel(&image, "Y") {
            Some(y) => vec![to_f32(y); 3],
            None => {
                return Err(FilmError::Invalid {
                    file: path.into(),
                    message: "has no R, G, B or Y channels".into(),
                })
            }
        },
    };
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
    let text = match image
        .layer_data
        .attributes
        .other
        .get(&Text::from(METADATA_ATTRIBUTE))
    {
        Some(AttributeValue::Text(t)) => decode_text(t),
        _ => {
            return Err(not_render(
                "no vmerge metadata; it was not written by vmerge render",
            ))
        }
    };
    let metadata =
        Metadata::from_toml(&text).map_err(|e| not_render(&format!("unreadable metadata: {e}")))?;
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
    let sum = (0..size.area())
        .map(|i| [sums[0][i], sums[1][i], sums[2][i]])
        .collect();
    let film = Film {
        width: size.width() as u32,
        height: size.height() as u32,
        sum,
        iterations: metadata.iterations,
    };
    Ok((film, metadata))
}

/// EXR text is Latin-1; anything else (a non-ASCII path) is escaped as `\u{...}`.
fn encode_text(s: &str) -> Text {
    let escaped: String = s
        .chars()
        .map(|c| {
            if c.is_ascii() && c != '\\' {
                c.to_string()
            } else {
                format!("\\u{{{:x}}}", c as u32)
            }
        })
        .collect();
    Text::from_bytes_unchecked(escaped.bytes().collect())
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
