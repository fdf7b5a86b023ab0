//! Tone-mapped PNG previews: exposure 1, then Reinhard's x / (1 + x) on each channel, so that
//! radiance 1 (the shipped scenes' calibrated mean) maps to 0.5 and nothing clips, then the sRGB
//! transfer curve and 8 bits.

use super::{atomic_write, FilmError};
use crate::color::Rgb;
use std::path::Path;

fn srgb_encode(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let v = if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0 + 0.5) as u8
}

/// 8-bit sRGB bytes of the tone-mapped image, row-major, 3 bytes per pixel.
pub fn tone_map(pixels: &[Rgb]) -> Vec<u8> {
    pixels
        .iter()
        .flat_map(|p| p.to_array())
        .map(|x| {
            // NaN and negative values show black, +infinity white.
            let x = if x.is_nan() { 0.0 } else { x.max(0.0) };
            srgb_encode(if x.is_finite() { x / (1.0 + x) } else { 1.0 })
        })
        .collect()
}

/// Writes the tone-mapped preview of `pixels` atomically.
pub fn write_preview(
    path: &Path,
    pixels: &[Rgb],
    width: u32,
    height: u32,
) -> Result<(), FilmError> {
    let bytes = tone_map(pixels);
    atomic_write(path, |file| {
        let mut encoder = ::png::Encoder::new(file, width, height);
        encoder.set_color(::png::ColorType::Rgb);
        encoder.set_depth(::png::BitDepth::Eight);
        let mut writer = encoder.write_header().map_err(std::io::Error::other)?;
        writer
            .write_image_data(&bytes)
            .map_err(std::io::Error::other)?;
        writer.finish().map_err(std::io::Error::other)
    })
    .map_err(|e| FilmError::Write {
        file: path.into(),
        message: e.to_string(),
    })
}
