//! A conductor (pbrt-v4's `conductor`): Fresnel reflection with a complex index of refraction
//! per channel, on Trowbridge-Reitz microfacets (Torrance-Sparrow,
//! f = D(wm) F(wo . wm) G(wo, wi) / (4 cos_o cos_i)), or a delta mirror lobe where the surface
//! is effectively smooth. Rough lobes are sampled by visible normals, so the pdf of `wi` is
//! D_wo(wm) / (4 |wo . wm|).

use super::fresnel;
use super::microfacet::{Roughness, Scatter, TrowbridgeReitz};
use super::params::{color, BsdfError, EnergyExcess, ParamReader, ParamSpec, Params};
use super::{
    reflect_local, Albedo, BsdfEval, BsdfSample, Bxdf, BxdfType, LobeKind, Lobes, MicrofacetLobe,
    TransportMode,
};
use crate::color::Rgb;
use crate::frame::Frame;
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conductor {
    /// Real part of the index of refraction, per channel (relative to the outside).
    pub eta: Rgb,
    /// Imaginary part (absorption), per channel.
    pub k: Rgb,
    pub roughness: Roughness,
}

/// Copper's index, pbrt-v4's default conductor (its `metal-Cu-eta` / `metal-Cu-k` in RGB).
const COPPER_ETA: [f32; 3] = [0.200_438, 0.924_033, 1.102_212];
const COPPER_K: [f32; 3] = [3.912_949, 2.452_848, 2.142_188];

/// The largest `reflectance` a conductor takes: at 1 its absorption k would be infinite.
const MAX_REFLECTANCE: f32 = 0.9999;

impl Conductor {
    /// pbrt-v4's conductor of normal-incidence `reflectance`: eta = 1 and
    /// k = 2 sqrt(r) / sqrt(1 - r), which gives exactly r at normal incidence.
    pub fn k_of_reflectance(reflectance: Rgb) -> Rgb {
        let k = |r: f32| {
            let r = r.clamp(0.0, MAX_REFLECTANCE);
            2.0 * r.sqrt() / (1.0 - r).sqrt()
        };
        Rgb::new(k(reflectance.r), k(reflectance.g), k(reflectance.b))
    }

    fn fresnel(&self, cos: f32) -> Rgb {
        fresnel::complex(cos, self.eta, self.k)
    }

    /// Value and pdfs of the rough lobe, both directions above the surface.
    fn eval_rough(&self, m: &TrowbridgeReitz, wo: Vec3, wi: Vec3) -> BsdfEval {
        if wo.z <= 0.0 || wi.z <= 0.0 {
            return BsdfEval::ZERO;
        }
        let wm = (wo + wi).normalize();
        let cos_om = wo.dot(wm);
        if cos_om <= 0.0 {
            return BsdfEval::ZERO;
        }
        let d = m.d(wm);
        let f = self.fresnel(cos_om) * (d * m.g(wo, wi) / (4.0 * wo.z * wi.z));
        // wi . wm = wo . wm for the half vector.
        BsdfEval {
            f,
            pdf_w: m.pdf(wo, wm) / (4.0 * cos_om),
            rev_pdf_w: m.pdf(wi, wm) / (4.0 * cos_om),
        }
    }
}

impl BxdfType for Conductor {
    const NAME: &'static str = "conductor";
    const PARAMS: &'static [ParamSpec] = &[
        ParamSpec {
            default: super::ParamValue::Color(Rgb::new(COPPER_ETA[0], COPPER_ETA[1], COPPER_ETA[2])),
            ..color("eta", 0.0)
        },
        ParamSpec {
            default: super::ParamValue::Color(Rgb::new(COPPER_K[0], COPPER_K[1], COPPER_K[2])),
            ..color("k", 0.0)
        },
        color("reflectance", 0.0),
        Roughness::PARAMS[0],
        Roughness::PARAMS[1],
        Roughness::PARAMS[2],
        Roughness::PARAMS[3],
    ];

    /// `reflectance`, where given, replaces `eta` and `k` as in pbrt-v4.
    fn from_params(p: &ParamReader) -> Result<Self, BsdfError> {
        let (eta, k) = if p.is_given("reflectance") {
            (
                Rgb::WHITE,
                Conductor::k_of_reflectance(p.color("reflectance")?),
            )
        } else {
            (p.color("eta")?, p.color("k")?)
        };
        if eta.min_component() <= 0.0 {
            return Err(BsdfError::BadParameter {
                type_name: Self::NAME,
                param: "eta",
                problem: super::ParamProblem::NotPositive,
            });
        }
        Ok(Conductor {
            eta,
            k,
            roughness: Roughness::read(p)?,
        })
    }
}

impl Bxdf for Conductor {
    fn params(&self) -> Params {
        self.roughness.write(
            Params::new()
                .with_color("eta", self.eta)
                .with_color("k", self.k),
        )
    }

    /// Fresnel reflectance never exceeds 1.
    fn energy_excess(&self) -> Option<EnergyExcess> {
        None
    }

    fn albedo(&self) -> Albedo {
        Albedo::NONE
    }

    fn with_albedo(&self, albedo: Albedo) -> Self {
        Conductor {
            roughness: albedo.roughness_of(self.roughness),
            ..*self
        }
    }

    fn is_delta(&self) -> bool {
        self.roughness.distribution().effectively_smooth()
    }

    fn anisotropic(&self) -> bool {
        self.roughness.u != self.roughness.v
    }

    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3, _: TransportMode) -> BsdfEval {
        let m = self.roughness.distribution();
        if m.effectively_smooth() {
            return BsdfEval::ZERO;
        }
        self.eval_rough(&m, wo, wi)
    }

    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3], _: TransportMode) -> Option<BsdfSample> {
        let m = self.roughness.distribution();
        if m.effectively_smooth() {
            let wi = reflect_local(wo);
            return Some(BsdfSample {
                wi,
                f: self.fresnel(wi.z) / wi.z.abs(),
                pdf_w: 1.0,
                rev_pdf_w: 1.0,
                delta: true,
            });
        }
        if wo.z <= 0.0 {
            return None;
        }
        let wm = m.sample_wm(wo, [u[1], u[2]]);
        let wi = Scatter::Reflect.apply(wo, wm, u[0])?;
        self.eval_rough(&m, wo, wi).sample_at(wi)
    }

    fn continuation_albedo(&self) -> Rgb {
        self.fresnel(1.0)
    }

    #[inline]
    fn lobes(&self, _: Vec3, _: &Frame) -> Lobes {
        if self.is_delta() {
            Lobes::NONE
        } else {
            Lobes::NONE.with(LobeKind::Microfacet {
                weight: 1.0,
                lobe: MicrofacetLobe {
                    distribution: self.roughness.distribution(),
                    scatter: Scatter::Reflect,
                },
            })
        }
    }
}

impl Conductor {
    /// The defaults' parameters (pbrt-v4's copper), for callers building one in code.
    pub fn copper(roughness: Roughness) -> Self {
        Conductor {
            eta: Rgb::from_array(COPPER_ETA),
            k: Rgb::from_array(COPPER_K),
            roughness,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflectance_gives_its_value_at_normal_incidence() {
        let r = Rgb::new(0.2, 0.5, 0.9);
        let c = Conductor {
            eta: Rgb::WHITE,
            k: Conductor::k_of_reflectance(r),
            roughness: Roughness {
                u: 0.0,
                v: 0.0,
                remap: true,
            },
        };
        let f = c.fresnel(1.0);
        for (a, b) in f.to_array().into_iter().zip(r.to_array()) {
            assert!((a - b).abs() < 1e-5, "{f:?}");
        }
        assert!(c.is_delta());
        let s = c.sample(Vec3::new(0.0, 0.6, 0.8), [0.5; 3], TransportMode::Radiance);
        let s = s.unwrap();
        assert!(s.delta && (s.wi - Vec3::new(0.0, -0.6, 0.8)).length() < 1e-6);
    }

    #[test]
    fn parameters_round_trip() {
        let c = Conductor::copper(Roughness {
            u: 0.1,
            v: 0.3,
            remap: false,
        });
        let specs = <Conductor as BxdfType>::PARAMS;
        let p = c.params();
        let back = Conductor::from_params(&ParamReader::new("conductor", specs, &p)).unwrap();
        assert_eq!(back, c);
    }
}
