//! The arithmetic of mapping pbrt-v4 materials onto vmerge's four BSDFs (the README's table):
//! Fresnel reflectance at normal incidence, roughness to a Phong exponent, and the RGB values
//! of pbrt's named metal spectra.

use crate::color::Rgb;

/// The largest Phong exponent a mapped material gets: past it, f32 cannot resolve the lobe
/// (its width, sqrt(2/n) rad, nears the spacing of cosines close to 1).
pub const MAX_EXPONENT: f32 = 10_000.0;

/// pbrt-v4's `TrowbridgeReitzDistribution::RoughnessToAlpha` (used when `remaproughness`).
pub fn roughness_to_alpha(roughness: f32) -> f32 {
    roughness.max(0.0).sqrt()
}

/// The Phong exponent with the same lobe width as a microfacet distribution of roughness
/// `alpha`: n = 2 / alpha^2 - 2 (Walter et al. 2007, the Beckmann-Phong correspondence),
/// clamped to [1, MAX_EXPONENT].
pub fn phong_exponent(alpha: f32) -> f32 {
    if alpha <= 0.0 {
        return MAX_EXPONENT;
    }
    (2.0 / (alpha * alpha) - 2.0).clamp(1.0, MAX_EXPONENT)
}

/// Reflectance at normal incidence of a dielectric interface of relative index `eta`.
pub fn dielectric_f0(eta: f32) -> f32 {
    let r = (eta - 1.0) / (eta + 1.0);
    r * r
}

/// Reflectance at normal incidence of a conductor, per channel:
/// ((eta - 1)^2 + k^2) / ((eta + 1)^2 + k^2).
pub fn conductor_f0(eta: Rgb, k: Rgb) -> Rgb {
    let f = |n: f32, k: f32| ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k);
    Rgb::new(f(eta.r, k.r), f(eta.g, k.g), f(eta.b, k.b))
}

/// RGB values of pbrt's named metal spectra (`"metal-Au-eta"`, ...): the spectra averaged
/// over the sRGB primaries' bands, the values renderers that work in RGB use for them.
pub fn named_spectrum(name: &str) -> Option<Rgb> {
    Some(match name {
        "metal-Ag-eta" => Rgb::new(0.155_265, 0.116_723, 0.138_381),
        "metal-Ag-k" => Rgb::new(4.828_343, 3.122_246, 2.146_95),
        "metal-Al-eta" => Rgb::new(1.657_46, 0.880_369, 0.521_229),
        "metal-Al-k" => Rgb::new(9.223_869, 6.269_523, 4.837_001),
        "metal-Au-eta" => Rgb::new(0.143_119, 0.374_957, 1.442_479),
        "metal-Au-k" => Rgb::new(3.983_16, 2.385_721, 1.603_215),
        "metal-Cu-eta" => Rgb::new(0.200_438, 0.924_033, 1.102_212),
        "metal-Cu-k" => Rgb::new(3.912_949, 2.452_848, 2.142_188),
        "metal-CuZn-eta" => Rgb::new(0.444, 0.527, 1.094),
        "metal-CuZn-k" => Rgb::new(3.695, 2.765, 1.829),
        "glass-BK7" => Rgb::splat(1.5168),
        "glass-BAF10" => Rgb::splat(1.67),
        "glass-F11" => Rgb::splat(1.62),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fresnel_and_exponents() {
        assert!((dielectric_f0(1.5) - 0.04).abs() < 1e-6);
        // A conductor with k = 0 is a dielectric.
        let f = conductor_f0(Rgb::splat(1.5), Rgb::BLACK);
        assert!((f.r - 0.04).abs() < 1e-6);
        // Silver reflects over 90 % at normal incidence.
        let ag = conductor_f0(
            named_spectrum("metal-Ag-eta").unwrap(),
            named_spectrum("metal-Ag-k").unwrap(),
        );
        assert!(
            ag.min_component() > 0.9 && ag.max_component() < 1.0,
            "{ag:?}"
        );
        assert!((phong_exponent(0.1) - 198.0).abs() < 1e-3);
        assert_eq!(phong_exponent(0.0), MAX_EXPONENT);
        assert_eq!(phong_exponent(0.001), MAX_EXPONENT);
        assert_eq!(phong_exponent(2.0), 1.0);
        assert_eq!(roughness_to_alpha(0.25), 0.5);
    }
}
