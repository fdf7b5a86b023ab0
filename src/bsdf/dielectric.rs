//! A dielectric interface (pbrt-v4's `dielectric`): on Trowbridge-Reitz microfacets, Fresnel
//! reflection and refraction by Walter et al. (2007) with the generalized half vector
//! wm ~ eta wi + wo; where it is effectively smooth (or eta is 1), exactly the delta lobes of
//! [`Glass`].
//!
//! It follows glass's conventions (see glass.rs): the geometric normal's orientation tells
//! entering from leaving, `eta` is the index inside over outside, refracted radiance is
//! scaled by 1/eta'^2 (eta' = n_t / n_i across the crossing) and importance is not. A
//! microfacet normal is sampled from those visible from `wo`; reflection is then chosen with
//! probability F(wo . wm), refraction with 1 - F, so the pdfs are
//! D_wo(wm) F / (4 |wo . wm|) and D_wo(wm) (1 - F) |wi . wm| / (wi . wm + wo . wm / eta')^2.

use super::fresnel;
use super::microfacet::{Roughness, Scatter, TrowbridgeReitz};
use super::params::{number, BsdfError, EnergyExcess, ParamRange, ParamReader, ParamSpec, Params};
use super::{
    Albedo, BsdfEval, BsdfSample, Bxdf, BxdfType, Glass, LobeKind, Lobes, MicrofacetLobe, TransportMode,
};
use crate::color::Rgb;
use crate::frame::Frame;
use glam::Vec3;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dielectric {
    /// Index of refraction inside (the side the normal points away from) over outside.
    pub eta: f32,
    pub roughness: Roughness,
}

/// What a pair of directions means at a rough interface: the microfacet normal that
/// connects them (facing +z), the relative index across (1 for reflection) and whether they
/// reflect.
struct HalfVector {
    wm: Vec3,
    etap: f32,
    reflect: bool,
}

impl Dielectric {
    fn is_smooth(&self, m: &TrowbridgeReitz) -> bool {
        self.eta == 1.0 || m.effectively_smooth()
    }

    /// The generalized half vector of `wo` and `wi`; `None` where they are grazing or the
    /// microfacet would face away from either.
    fn half_vector(&self, wo: Vec3, wi: Vec3) -> Option<HalfVector> {
        let (cos_o, cos_i) = (wo.z, wi.z);
        if cos_o == 0.0 || cos_i == 0.0 {
            return None;
        }
        let reflect = cos_o * cos_i > 0.0;
        let etap = match (reflect, cos_o > 0.0) {
            (true, _) => 1.0,
            (false, true) => self.eta,
            (false, false) => 1.0 / self.eta,
        };
        let wm = wi * etap + wo;
        let len2 = wm.length_squared();
        if len2 <= 0.0 {
            return None;
        }
        let wm = wm / len2.sqrt();
        let wm = if wm.z < 0.0 { -wm } else { wm };
        // Microfacets seen from behind by either direction carry nothing.
        if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
            return None;
        }
        Some(HalfVector { wm, etap, reflect })
    }

    /// The pdf of sampling `wi` from `wo` through the microfacet normal `wm` of the pair;
    /// swapping the two gives the reverse pdf (the pair has the same `wm` either way).
    fn pdf(&self, m: &TrowbridgeReitz, wo: Vec3, wi: Vec3, wm: Vec3, reflect: bool) -> f32 {
        let r = fresnel::dielectric(wo.dot(wm), self.eta);
        if reflect {
            m.pdf(wo, wm) / (4.0 * wo.dot(wm).abs()) * r
        } else {
            let etap = if wo.z > 0.0 { self.eta } else { 1.0 / self.eta };
            let denom = (wi.dot(wm) + wo.dot(wm) / etap).powi(2);
            m.pdf(wo, wm) * wi.dot(wm).abs() / denom * (1.0 - r)
        }
    }

    fn eval_rough(
        &self,
        m: &TrowbridgeReitz,
        wo: Vec3,
        wi: Vec3,
        mode: TransportMode,
    ) -> BsdfEval {
        let Some(HalfVector { wm, etap, reflect }) = self.half_vector(wo, wi) else {
            return BsdfEval::ZERO;
        };
        let r = fresnel::dielectric(wo.dot(wm), self.eta);
        let (cos_o, cos_i) = (wo.z, wi.z);
        let f = if reflect {
            m.d(wm) * m.g(wo, wi) * r / (4.0 * cos_i * cos_o).abs()
        } else {
            let (dot_i, dot_o) = (wi.dot(wm), wo.dot(wm));
            let denom = (dot_i + dot_o / etap).powi(2) * cos_i * cos_o;
            let ft = m.d(wm) * (1.0 - r) * m.g(wo, wi) * (dot_i * dot_o / denom).abs();
            // Radiance is compressed into the narrower solid angle of the denser medium
            // (glass.rs); importance is not.
            match mode {
                TransportMode::Radiance => ft / (etap * etap),
                TransportMode::Importance => ft,
            }
        };
        BsdfEval {
            f: Rgb::splat(f),
            pdf_w: self.pdf(m, wo, wi, wm, reflect),
            rev_pdf_w: self.pdf(m, wi, wo, wm, reflect),
        }
    }
}

impl BxdfType for Dielectric {
    const NAME: &'static str = "dielectric";
    const PARAMS: &'static [ParamSpec] = &[
        number("eta", 1.5, ParamRange::Positive),
        Roughness::PARAMS[0],
        Roughness::PARAMS[1],
        Roughness::PARAMS[2],
        Roughness::PARAMS[3],
    ];

    fn from_params(p: &ParamReader) -> Result<Self, BsdfError> {
        Ok(Dielectric {
            eta: p.number("eta")?,
            roughness: Roughness::read(p)?,
        })
    }
}

impl Bxdf for Dielectric {
    fn params(&self) -> Params {
        self.roughness
            .write(Params::new().with_number("eta", self.eta))
    }

    fn energy_excess(&self) -> Option<EnergyExcess> {
        None
    }

    fn albedo(&self) -> Albedo {
        Albedo::NONE
    }

    fn with_albedo(&self, albedo: Albedo) -> Self {
        Dielectric {
            roughness: albedo.roughness_of(self.roughness),
            ..*self
        }
    }

    fn is_delta(&self) -> bool {
        self.is_smooth(&self.roughness.distribution())
    }

    fn two_sided(&self) -> bool {
        false
    }

    fn anisotropic(&self) -> bool {
        self.roughness.u != self.roughness.v
    }

    #[inline]
    fn eval(&self, wo: Vec3, wi: Vec3, mode: TransportMode) -> BsdfEval {
        let m = self.roughness.distribution();
        if self.is_smooth(&m) {
            return BsdfEval::ZERO;
        }
        self.eval_rough(&m, wo, wi, mode)
    }

    /// `wo` local to the outward normal (negative z when leaving).
    #[inline]
    fn sample(&self, wo: Vec3, u: [f32; 3], mode: TransportMode) -> Option<BsdfSample> {
        let m = self.roughness.distribution();
        if self.is_smooth(&m) {
            return Glass { ior: self.eta }.sample(wo, u, mode);
        }
        if wo.z == 0.0 {
            return None;
        }
        let wm = m.sample_wm(wo, [u[1], u[2]]);
        let wi = Scatter::Dielectric { eta: self.eta }.apply(wo, wm, u[0])?;
        self.eval_rough(&m, wo, wi, mode).sample_at(wi)
    }

    fn continuation_albedo(&self) -> Rgb {
        Rgb::WHITE
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
                    scatter: Scatter::Dielectric { eta: self.eta },
                },
            })
        }
    }
}
