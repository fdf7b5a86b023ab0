//! Lafortune's energy-conserving Phong (000 eq. 3.1):
//! f = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha), alpha the angle between `wi` and the mirror
//! direction of `wo`. Each lobe is importance sampled; the lobe is picked in proportion to its
//! albedo and the pdfs are those of the whole mixture, so MIS sees the real density.

use super::params::{
    color, number, BsdfError, EnergyExcess, EnergyFix, ParamRange, ParamReader, ParamSpec,
    Params,
};
use super::{
    reflect_local, Albedo, BsdfEval, BsdfSample, Bxdf, BxdfType, Lobe, LobeKind, LobeShape, Lobes,
    TransportMode,
};
use crate::color::Rgb;
use crate::frame::Frame;
use crate::sampling::{cosine_hemisphere, cosine_hemisphere_pdf, power_cosine, power_cosine_pdf};
use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Phong {
    pub kd: Rgb,
    pub ks: Rgb,
    pub exponent: f32,
}

/// [`Phong`] with what its evaluation and sampling derive from the parameters.
struct Prepared {
    kd: Rgb,
    ks: Rgb,
    exponent: f32,
    /// The exponent when it is a whole number (as most scenes' are): `powi`'s few multiplies
    /// then replace `powf`, which the merge loop and every BSDF evaluation would pay.
    whole_exponent: Option<i32>,
    /// Probability of sampling the diffuse lobe.
    diffuse_probability: f32,
}

impl Phong {
    #[inline]
    fn prepare(&self) -> Prepared {
        let Phong { kd, ks, exponent } = *self;
        let (d, s) = (kd.average(), ks.average());
        let diffuse_probability = if d + s > 0.0 { d / (d + s) } else { 1.0 };
        // Exporters write whole exponents as single-precision decimals (40 as 39.999996):
        // within 1e-5 of a whole number the exponent is that number, a change of the lobe far
        // below any render's noise, so `powi` serves it too. Rounded through i32 (exponents are
        // >= 0; `round` would be a libm call).
        let whole = (exponent + 0.5) as i32;
        let whole_exponent =
            ((whole as f32 - exponent).abs() <= 1e-5 * exponent.max(1.0)).then_some(whole);
        let exponent = whole_exponent.map_or(exponent, |n| n as f32);
        Prepared {
            kd,
            ks,
            exponent,
            whole_exponent,
            diffuse_probability,
        }
    }
}

impl Prepared {
    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3) -> BsdfEval {
        if wi.z <= 0.0 {
            return BsdfEval::ZERO;
        }
        // cos(alpha) is symmetric in wo and wi, so one value serves both pdfs.
        let cos_alpha = reflect_local(wo).dot(wi).max(0.0);
        let lobe = match self.whole_exponent {
            Some(n) => cos_alpha.powi(n),
            None => cos_alpha.powf(self.exponent),
        };
        let f = self.kd * FRAC_1_PI + self.ks * ((self.exponent + 2.0) * 0.5 * FRAC_1_PI * lobe);
        let specular_pdf = power_cosine_pdf(cos_alpha, lobe, self.exponent);
        let pd = self.diffuse_probability;
        BsdfEval {
            f,
            pdf_w: pd * cosine_hemisphere_pdf(wi.z) + (1.0 - pd) * specular_pdf,
            rev_pdf_w: pd * cosine_hemisphere_pdf(wo.z) + (1.0 - pd) * specular_pdf,
        }
    }
}

impl BxdfType for Phong {
    const NAME: &'static str = "phong";
    const PARAMS: &'static [ParamSpec] = &[
        color("kd", 0.8),
        color("ks", 0.0),
        number("exponent", 1.0, ParamRange::NonNegative),
    ];

    fn from_params(p: &ParamReader) -> Result<Self, BsdfError> {
        Ok(Phong {
            kd: p.color("kd")?,
            ks: p.color("ks")?,
            exponent: p.number("exponent")?,
        })
    }
}

impl Bxdf for Phong {
    fn params(&self) -> Params {
        Params::new()
            .with_color("kd", self.kd)
            .with_color("ks", self.ks)
            .with_number("exponent", self.exponent)
    }

    /// 000 eq. 3.1 conserves energy only for kd + ks <= 1: larger sums are scaled down per
    /// channel.
    fn energy_excess(&self) -> Option<EnergyExcess> {
        let total = self.kd + self.ks;
        if total.max_component() <= 1.0 + 1e-6 {
            return None;
        }
        let f = |c: f32| if c > 1.0 { 1.0 / c } else { 1.0 };
        let scale = Rgb::new(f(total.r), f(total.g), f(total.b));
        Some(EnergyExcess {
            what: "kd + ks",
            total,
            fix: EnergyFix::Scaled,
            conserving: Phong {
                kd: self.kd * scale,
                ks: self.ks * scale,
                exponent: self.exponent,
            }
            .into(),
        })
    }

    fn albedo(&self) -> Albedo {
        Albedo {
            kd: self.kd,
            ks: self.ks,
            roughness: None,
            vroughness: None,
        }
    }

    fn with_albedo(&self, albedo: Albedo) -> Self {
        Phong {
            kd: albedo.kd,
            ks: albedo.ks,
            exponent: self.exponent,
        }
    }

    fn kd_limit(&self, ks: Rgb) -> Rgb {
        Rgb::WHITE - ks
    }

    fn is_delta(&self) -> bool {
        false
    }

    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3, _: TransportMode) -> BsdfEval {
        self.prepare().eval(wo, wi)
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3], _: TransportMode) -> Option<BsdfSample> {
        let phong = self.prepare();
        let wi = if u[0] < phong.diffuse_probability {
            cosine_hemisphere([u[1], u[2]])
        } else {
            Frame::from_z(reflect_local(wo)).to_world(power_cosine([u[1], u[2]], phong.exponent))
        };
        phong.eval(wo, wi).sample_at(wi)
    }

    fn continuation_albedo(&self) -> Rgb {
        self.kd + self.ks
    }

    #[inline]
    fn lobes(&self, wo: Vec3, frame: &Frame) -> Lobes {
        let phong = self.prepare();
        let pd = phong.diffuse_probability;
        let mut lobes = Lobes::NONE;
        if pd > 0.0 {
            lobes.push(LobeKind::Polar(Lobe {
                weight: pd,
                axis: frame.z,
                shape: LobeShape::Cosine,
            }));
        }
        if pd < 1.0 {
            lobes.push(LobeKind::Polar(Lobe {
                weight: 1.0 - pd,
                axis: frame.to_world(reflect_local(wo)),
                shape: LobeShape::PowerCosine {
                    exponent: phong.exponent,
                },
            }));
        }
        lobes
    }
}
