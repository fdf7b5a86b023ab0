//! Error measures of an image against a reference: the one list of measures ([`Measure`]) that
//! the CLI, the reference traces, batch reports and the Python module iterate over, and their
//! values for a pair of images ([`Errors`], [`measure`]).
//!
//! - [`pointwise`]: mean absolute error, RMS error (000 sec. 3.4) and relative MSE;
//! - [`flip`]: NVIDIA's perceptual FLIP, LDR (Andersson et al. 2020) and HDR (2021);
//! - [`ssim`]: structural similarity (Wang et al. 2004).
//!
//! Renders hold linear radiance. The HDR measures take it as it is; the LDR ones (LDR-FLIP and
//! SSIM) compare the images as the PNG preview shows them ([`display`]): Reinhard's x / (1 + x)
//! on each channel, so that nothing clips.

pub mod flip;
pub mod pointwise;
pub mod ssim;

use crate::color::Rgb;
use rayon::prelude::*;
use std::fmt;

/// One error measure. [`Measure::ALL`] lists them in the order every output uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Measure {
    /// Mean absolute error over pixels and channels (000 sec. 3.4).
    Mae,
    /// Root-mean-square error over pixels and channels (000 sec. 3.4).
    Rmse,
    /// Mean of (a - b)^2 / (b^2 + 0.01) over pixels and channels.
    RelativeMse,
    /// LDR-FLIP of the preview images, in [0, 1].
    LdrFlip,
    /// HDR-FLIP of the radiance images, in [0, 1].
    HdrFlip,
    /// Mean SSIM of the preview images' channels, 1 for identical images.
    Ssim,
}

impl Measure {
    pub const ALL: [Measure; 6] = [
        Measure::Mae,
        Measure::Rmse,
        Measure::RelativeMse,
        Measure::LdrFlip,
        Measure::HdrFlip,
        Measure::Ssim,
    ];

    /// The short name used on the command line, in plans, metadata and table headers.
    pub fn name(self) -> &'static str {
        match self {
            Measure::Mae => "mae",
            Measure::Rmse => "rmse",
            Measure::RelativeMse => "relmse",
            Measure::LdrFlip => "ldr-flip",
            Measure::HdrFlip => "hdr-flip",
            Measure::Ssim => "ssim",
        }
    }

    pub fn from_name(name: &str) -> Option<Measure> {
        Measure::ALL.into_iter().find(|m| m.name() == name)
    }

    /// What it is, in words (axis labels, help texts).
    pub fn label(self) -> &'static str {
        match self {
            Measure::Mae => "mean absolute error",
            Measure::Rmse => "RMS error",
            Measure::RelativeMse => "relative MSE",
            Measure::LdrFlip => "LDR-FLIP",
            Measure::HdrFlip => "HDR-FLIP",
            Measure::Ssim => "SSIM",
        }
    }

    /// What [`Measure::as_error`] gives, in words (chart axes).
    pub fn error_label(self) -> &'static str {
        match self {
            Measure::Ssim => "1 - SSIM",
            other => other.label(),
        }
    }

    /// SSIM grows as images get closer; every other measure falls.
    pub fn higher_is_better(self) -> bool {
        self == Measure::Ssim
    }

    /// The value as an error that falls to 0 as the image converges (1 - SSIM for SSIM), for
    /// rankings and log-scale charts.
    pub fn as_error(self, value: f64) -> f64 {
        if self.higher_is_better() {
            1.0 - value
        } else {
            value
        }
    }

    /// Measured pixel by pixel, so cheap enough for every sample of a reference trace and
    /// meaningful on a few pixels (trace windows). FLIP and SSIM filter over neighbourhoods
    /// of several pixels and cost tens of operations per pixel and tap.
    pub fn is_pointwise(self) -> bool {
        matches!(self, Measure::Mae | Measure::Rmse | Measure::RelativeMse)
    }

    fn index(self) -> usize {
        self as usize
    }
}

impl fmt::Display for Measure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A value per measure, `None` where it was not measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Errors([Option<f64>; Measure::ALL.len()]);

impl Errors {
    pub fn get(&self, measure: Measure) -> Option<f64> {
        self.0[measure.index()]
    }

    pub fn set(&mut self, measure: Measure, value: f64) {
        self.0[measure.index()] = Some(value);
    }

    /// The measured values, in the order of [`Measure::ALL`].
    pub fn iter(&self) -> impl Iterator<Item = (Measure, f64)> + '_ {
        Measure::ALL
            .into_iter()
            .filter_map(|m| self.get(m).map(|v| (m, v)))
    }
}

/// Which measures [`measure`] computes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Selection {
    /// The pixel-wise measures only ([`Measure::is_pointwise`]).
    Pointwise,
    /// Every measure of [`Measure::ALL`]; FLIP and SSIM need images of at least
    /// [`ssim::MIN_SIZE`] pixels each way and are left out of smaller ones.
    All,
}

/// The measures of `test` against `reference`, two row-major images `width` pixels wide of the
/// same size.
pub fn measure(
    test: &[Rgb],
    reference: &[Rgb],
    width: u32,
    height: u32,
    selection: Selection,
) -> Errors {
    debug_assert_eq!(test.len(), reference.len());
    debug_assert_eq!(test.len(), width as usize * height as usize);
    let mut errors = pointwise::errors_in(test, reference, width, (0, 0, width, height));
    if selection == Selection::All && width.min(height) >= ssim::MIN_SIZE {
        let (w, h) = (width as usize, height as usize);
        let (test_display, reference_display) = (display(test), display(reference));
        errors.set(
            Measure::LdrFlip,
            flip::ldr(&reference_display, &test_display, w, h, flip::DEFAULT_PPD),
        );
        errors.set(
            Measure::HdrFlip,
            flip::hdr(reference, test, w, h, flip::DEFAULT_PPD),
        );
        let encode = |p: &[Rgb]| -> Vec<Rgb> {
            p.par_iter()
                .map(|c| Rgb::from_array(c.to_array().map(srgb_encode)))
                .collect()
        };
        errors.set(
            Measure::Ssim,
            ssim::ssim(
                &encode(&test_display),
                &encode(&reference_display),
                w,
                h,
                1.0,
            ),
        );
    }
    errors
}

/// The image as the PNG preview shows it, in linear RGB within [0, 1]: x / (1 + x) on each
/// channel (Reinhard), non-finite and negative values as 0.
pub fn display(pixels: &[Rgb]) -> Vec<Rgb> {
    let tone = |x: f32| {
        if x.is_finite() && x > 0.0 {
            x / (1.0 + x)
        } else if x == f32::INFINITY {
            1.0
        } else {
            0.0
        }
    };
    pixels
        .par_iter()
        .map(|p| Rgb::from_array(p.to_array().map(tone)))
        .collect()
}

/// The sRGB transfer curve (IEC 61966-2-1) of a linear value in [0, 1].
pub fn srgb_encode(linear: f32) -> f32 {
    let c = linear.clamp(0.0, 1.0);
    if c <= 0.0031308 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// The inverse of [`srgb_encode`].
pub fn srgb_decode(encoded: f32) -> f32 {
    if encoded <= 0.04045 {
        encoded / 12.92
    } else {
        ((encoded + 0.055) / 1.055).powf(2.4)
    }
}
