//! Image textures: decoded once per file into linear RGB, looked up bilinearly with repeat
//! wrap, v flipped as OBJ's texture coordinates expect (v = 0 is the image's bottom row).

use crate::color::Rgb;
use glam::Vec2;
use std::path::Path;

/// A decoded image in linear RGB, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub width: u32,
    pub height: u32,
    pub texels: Vec<Rgb>,
}

impl Texture {
    /// `None` when the sizes and the texel count disagree or a side is zero.
    pub fn new(width: u32, height: u32, texels: Vec<Rgb>) -> Option<Self> {
        (width > 0 && height > 0 && texels.len() == width as usize * height as usize).then_some(
            Texture {
                width,
                height,
                texels,
            },
        )
    }

    pub fn texel(&self, x: u32, y: u32) -> Rgb {
        self.texels[(y * self.width + x) as usize]
    }

    /// Bytes held by the texels.
    pub fn bytes(&self) -> usize {
        self.texels.len() * std::mem::size_of::<Rgb>()
    }

    /// Bilinear lookup at `uv` with repeat wrap. Texel (x, y) has its centre at
    /// u = (x + 0.5) / width, v = 1 - (y + 0.5) / height, where it returns that texel exactly.
    pub fn lookup(&self, uv: Vec2) -> Rgb {
        let (w, h) = (self.width as f32, self.height as f32);
        let s = uv.x * w - 0.5;
        let t = (1.0 - uv.y) * h - 0.5;
        let (s0, t0) = (s.floor(), t.floor());
        let (fs, ft) = (snap(s - s0), snap(t - t0));
        // Repeat wrap without integer division (a lookup is mostly waiting for memory already).
        let wrap = |i: f32, n: f32| ((i - (i / n).floor() * n) as u32).min(n as u32 - 1);
        let next = |i: u32, n: u32| if i + 1 == n { 0 } else { i + 1 };
        let (x0, y0) = (wrap(s0, w), wrap(t0, h));
        let (x1, y1) = (next(x0, self.width), next(y0, self.height));
        let top = self.texel(x0, y0) * (1.0 - fs) + self.texel(x1, y0) * fs;
        let bottom = self.texel(x0, y1) * (1.0 - fs) + self.texel(x1, y1) * fs;
        top * (1.0 - ft) + bottom * ft
    }
}

/// Interpolation weights this close to a texel centre are that centre: an f32 uv of a centre
/// lands up to a few 1e-7 texels off it (its own rounding), which would otherwise mix in a
/// neighbour; 1e-4 of a texel is far below what a filter of one texel's width resolves.
const SNAP: f32 = 1e-4;

fn snap(f: f32) -> f32 {
    if f < SNAP {
        0.0
    } else if f > 1.0 - SNAP {
        1.0
    } else {
        f
    }
}

/// The sRGB transfer function's inverse (IEC 61966-2-1).
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Reads a texture by its extension: PNG, JPEG and TGA are sRGB-encoded, Radiance `.hdr`, PFM
/// and EXR linear. The error is a message for the caller to put after the file's name.
pub fn read(path: &Path) -> Result<Texture, String> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    match ext.as_str() {
        "png" | "jpg" | "jpeg" | "tga" => read_srgb(path),
        "hdr" => read_hdr(path),
        "pfm" => {
            let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
            parse_pfm(&bytes)
        }
        "exr" => read_exr(path),
        _ => Err(format!(
            "unsupported image type '{ext}' (png, jpg, tga, hdr, pfm, exr)"
        )),
    }
}

fn decode(path: &Path) -> Result<image::DynamicImage, String> {
    image::io::Reader::open(path)
        .map_err(|e| e.to_string())?
        .with_guessed_format()
        .map_err(|e| e.to_string())?
        .decode()
        .map_err(|e| e.to_string())
}

fn read_srgb(path: &Path) -> Result<Texture, String> {
    let rgb = decode(path)?.to_rgb16();
    // One table for every 16-bit code (8-bit images arrive scaled by 257).
    let table: Vec<f32> = (0..=u16::MAX)
        .map(|c| srgb_to_linear(c as f32 / u16::MAX as f32))
        .collect();
    let texels = rgb
        .pixels()
        .map(|p| {
            Rgb::new(
                table[p[0] as usize],
                table[p[1] as usize],
                table[p[2] as usize],
            )
        })
        .collect();
    Texture::new(rgb.width(), rgb.height(), texels).ok_or_else(|| "the image is empty".into())
}

fn read_hdr(path: &Path) -> Result<Texture, String> {
    let rgb = decode(path)?.to_rgb32f();
    let texels = rgb.pixels().map(|p| Rgb::new(p[0], p[1], p[2])).collect();
    Texture::new(rgb.width(), rgb.height(), texels).ok_or_else(|| "the image is empty".into())
}

/// The first RGB layer of an EXR (a missing alpha channel is fine; it is not used).
fn read_exr(path: &Path) -> Result<Texture, String> {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |resolution, _| {
            (
                resolution.width(),
                vec![Rgb::BLACK; resolution.width() * resolution.height()],
            )
        },
        |(width, texels): &mut (usize, Vec<Rgb>), position, (r, g, b, _): (f32, f32, f32, f32)| {
            texels[position.y() * *width + position.x()] = Rgb::new(r, g, b);
        },
    )
    .map_err(|e| e.to_string())?;
    let (width, texels) = image.layer_data.channel_data.pixels;
    let height = texels.len() / width.max(1);
    if texels.iter().any(|t| !t.is_finite()) {
        return Err("the image holds a NaN or infinite value".into());
    }
    Texture::new(width as u32, height as u32, texels).ok_or_else(|| "the image is empty".into())
}

/// Portable float map: "PF" (RGB) or "Pf" (grey), width and height, a scale whose sign is the
/// byte order (negative: little-endian), then rows of f32 from the bottom up.
pub fn parse_pfm(bytes: &[u8]) -> Result<Texture, String> {
    let mut fields = Vec::new();
    let mut pos = 0;
    while fields.len() < 4 {
        while pos < bytes.len() && bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        let start = pos;
        while pos < bytes.len() && !bytes[pos].is_ascii_whitespace() {
            pos += 1;
        }
        if start == pos {
            return Err("truncated PFM header".into());
        }
        fields.push(String::from_utf8_lossy(&bytes[start..pos]).into_owned());
    }
    // Exactly one whitespace byte separates the header from the data.
    pos += 1;
    let channels = match fields[0].as_str() {
        "PF" => 3,
        "Pf" => 1,
        other => return Err(format!("not a PFM file (magic '{other}')")),
    };
    let number = |s: &str, what: &str| -> Result<u32, String> {
        s.parse::<u32>()
            .ok()
            .filter(|&n| n > 0)
            .ok_or_else(|| format!("bad PFM {what} '{s}'"))
    };
    let width = number(&fields[1], "width")?;
    let height = number(&fields[2], "height")?;
    let scale: f32 = fields[3]
        .parse()
        .ok()
        .filter(|s: &f32| s.is_finite() && *s != 0.0)
        .ok_or_else(|| format!("bad PFM scale '{}'", fields[3]))?;
    let count = width as usize * height as usize * channels;
    let data = bytes
        .get(pos..)
        .filter(|d| d.len() >= count * 4)
        .ok_or_else(|| {
            format!("PFM data truncated: {width} x {height} x {channels} floats expected")
        })?;
    let value = |i: usize| {
        let b = [
            data[4 * i],
            data[4 * i + 1],
            data[4 * i + 2],
            data[4 * i + 3],
        ];
        if scale < 0.0 {
            f32::from_le_bytes(b)
        } else {
            f32::from_be_bytes(b)
        }
    };
    let mut texels = Vec::with_capacity(width as usize * height as usize);
    for y in 0..height as usize {
        let row = height as usize - 1 - y;
        for x in 0..width as usize {
            let i = (row * width as usize + x) * channels;
            texels.push(if channels == 3 {
                Rgb::new(value(i), value(i + 1), value(i + 2))
            } else {
                Rgb::splat(value(i))
            });
        }
    }
    if texels.iter().any(|t| !t.is_finite()) {
        return Err("PFM holds a NaN or infinite value".into());
    }
    Texture::new(width, height, texels).ok_or_else(|| "the image is empty".into())
}

/// Writes a little-endian RGB PFM (for scenes and tests that make their own images).
pub fn write_pfm(texture: &Texture) -> Vec<u8> {
    let mut out = format!("PF\n{} {}\n-1\n", texture.width, texture.height).into_bytes();
    for y in (0..texture.height).rev() {
        for x in 0..texture.width {
            for c in texture.texel(x, y).to_array() {
                out.extend_from_slice(&c.to_le_bytes());
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pfm_round_trips() {
        let t = Texture::new(
            2,
            2,
            vec![
                Rgb::new(1.0, 2.0, 3.0),
                Rgb::new(4.0, 5.0, 6.0),
                Rgb::new(7.0, 8.0, 9.0),
                Rgb::new(0.5, 0.25, 0.125),
            ],
        )
        .unwrap();
        assert_eq!(parse_pfm(&write_pfm(&t)).unwrap(), t);
        assert!(parse_pfm(b"PF\n2 2\n-1\n1234").is_err());
        assert!(parse_pfm(b"P6\n2 2\n255\n").is_err());
    }

    #[test]
    fn srgb_decoding_matches_its_end_points() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        assert!((srgb_to_linear(0.5) - 0.214).abs() < 1e-3);
    }
}
