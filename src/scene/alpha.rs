//! Alpha cut-outs on meshes, for both formats: the images an alpha is read from, and the
//! marking of a mesh's triangles in the geometry (`accel::alpha` decides each hit).

use super::MeshShading;
use crate::accel::{Alpha, Geometry, TriangleAlpha};
use crate::color::Rgb;
use crate::texture::{self, srgb_to_linear, Texture};
use glam::Vec2;
use std::ops::Range;
use std::path::Path;

/// An alpha image, read as pbrt-v4 reads a float image texture: the alpha channel where the
/// image has one that is not everywhere one (stored linear, as PNG defines it), else the mean
/// of the colour channels (sRGB-decoded for PNG, JPEG and TGA, as the other textures). The
/// value is kept in every channel of the texture. Returns the texture and the file's bytes (for
/// the scene hash); the error is a message naming the file.
pub fn read_image(path: &Path) -> Result<(Texture, Vec<u8>), String> {
    let fail = |e: String| format!("cannot read alpha image {}: {e}", path.display());
    let bytes = std::fs::read(path).map_err(|e| fail(e.to_string()))?;
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    let texture = if matches!(ext.as_str(), "png" | "jpg" | "jpeg" | "tga") {
        let image = image::load_from_memory(&bytes).map_err(|e| fail(e.to_string()))?;
        let rgba = image.to_rgba32f();
        let has_alpha = image.color().has_alpha() && rgba.pixels().any(|p| p[3] != 1.0);
        let texels = rgba
            .pixels()
            .map(|p| {
                let value = if has_alpha {
                    p[3]
                } else {
                    (srgb_to_linear(p[0]) + srgb_to_linear(p[1]) + srgb_to_linear(p[2])) / 3.0
                };
                Rgb::splat(value)
            })
            .collect();
        Texture::new(rgba.width(), rgba.height(), texels)
            .ok_or_else(|| fail("the image is empty".into()))?
    } else {
        let mut image = texture::read(path).map_err(fail)?;
        for t in &mut image.texels {
            *t = Rgb::splat(t.average());
        }
        image
    };
    Ok((texture, bytes))
}

/// Cuts out the geometry's `triangles` with `alpha`, each with its uvs from `shading` (zero
/// where it has none). A constant alpha of 1 or more cuts nothing, as in pbrt-v4.
pub fn cut_out(
    geometry: &mut Geometry,
    shading: &MeshShading,
    triangles: Range<usize>,
    alpha: &Alpha,
) {
    if matches!(alpha, Alpha::Constant(a) if *a >= 1.0) {
        return;
    }
    for t in triangles {
        let uvs = match shading.triangle_uvs.get(t) {
            Some(&indices) if indices != MeshShading::NONE => {
                indices.map(|k| shading.uvs[k as usize])
            }
            _ => [Vec2::ZERO; 3],
        };
        geometry.cutouts.set(
            t as u32,
            TriangleAlpha {
                alpha: alpha.clone(),
                uvs,
            },
        );
    }
}
