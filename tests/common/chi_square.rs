//! Sampling against the reported pdf, as pbrt-v4's bsdfs_test checks it: directions drawn by
//! `Bsdf::sample` counted in bins of (cos theta, phi) over the whole sphere, against the pdf
//! integrated over each bin (Simpson's rule), by a chi-square test; bins expecting fewer than 5
//! samples are pooled with the samples the BSDF rejects.

use glam::Vec3;
use std::f64::consts::PI;
use vmerge::bsdf::{Bsdf, MaterialKind, TransportMode};
use vmerge::sampling::{Rng, Stream};

const THETA_BINS: usize = 20;
const PHI_BINS: usize = 40;

/// A unit direction from its cosine to +z and its azimuth.
pub fn direction(cos_theta: f64, phi: f64) -> Vec3 {
    let s = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    Vec3::new(
        (s * phi.cos()) as f32,
        (s * phi.sin()) as f32,
        cos_theta as f32,
    )
}

/// Checks that `samples` samples of `kind` seen from `wo` (local to +z) follow its pdf at a
/// significance of about 1e-6; delta samples are left out (they count as pooled). Each sample's
/// pdf and value must also be what `eval` gives for its direction.
pub fn chi_square(kind: &MaterialKind, wo: Vec3, samples: usize, seed: u64) {
    let bsdf = Bsdf::new(kind, Vec3::Z, wo, TransportMode::Radiance).expect("wo off the surface");
    let mut rng = Rng::for_sample(seed, 0, 0, Stream::Eye);
    let cells = 2 * THETA_BINS * PHI_BINS;
    let bin = |w: Vec3| {
        let c = (w.z as f64).clamp(-1.0, 1.0);
        let t = ((1.0 - c) / 2.0 * (2 * THETA_BINS) as f64) as usize;
        let p = ((w.y as f64).atan2(w.x as f64) + PI) / (2.0 * PI) * PHI_BINS as f64;
        t.min(2 * THETA_BINS - 1) * PHI_BINS + (p as usize).min(PHI_BINS - 1)
    };
    let mut observed = vec![0f64; cells];
    for _ in 0..samples {
        let Some(s) = bsdf.sample([rng.next_f32(), rng.next_f32(), rng.next_f32()]) else {
            continue;
        };
        if s.delta {
            continue;
        }
        let e = bsdf.eval(s.wi);
        assert!(
            (e.pdf_w - s.pdf_w).abs() <= 1e-3 * s.pdf_w,
            "{kind:?} wo={wo}: sample pdf {} eval pdf {}",
            s.pdf_w,
            e.pdf_w
        );
        assert!((e.f.g - s.f.g).abs() <= 1e-3 * s.f.g.abs().max(1e-3));
        observed[bin(s.wi)] += 1.0;
    }
    const SUB_T: usize = 64;
    const SUB_P: usize = 24;
    let simpson = |i: usize, n: usize| {
        if i == 0 || i == n {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        }
    };
    let mut expected = vec![0f64; cells];
    let dc = 2.0 / (2 * THETA_BINS) as f64 / SUB_T as f64;
    let d_phi = 2.0 * PI / PHI_BINS as f64 / SUB_P as f64;
    for t in 0..2 * THETA_BINS {
        let c0 = 1.0 - 2.0 * t as f64 / (2 * THETA_BINS) as f64;
        for p in 0..PHI_BINS {
            let mut integral = 0.0;
            for j in 0..=SUB_P {
                let phi = -PI + 2.0 * PI * p as f64 / PHI_BINS as f64 + j as f64 * d_phi;
                for i in 0..=SUB_T {
                    // A hair inside the bin: the horizon's jump is not sampled on its edge.
                    let c = (c0 - i as f64 * dc).clamp(c0 - SUB_T as f64 * dc + 1e-9, c0 - 1e-9);
                    integral += simpson(i, SUB_T)
                        * simpson(j, SUB_P)
                        * bsdf.eval(direction(c, phi)).pdf_w as f64;
                }
            }
            expected[t * PHI_BINS + p] = integral * (dc / 3.0) * (d_phi / 3.0) * samples as f64;
        }
    }
    let (mut chi2, mut dof) = (0.0, 0usize);
    let (mut pooled_o, mut pooled_e) = (0.0, 0.0);
    // The bin that adds most, for the message.
    let mut worst = (0.0, 0usize);
    for (i, (o, e)) in observed.iter().zip(&expected).enumerate() {
        if *e < 5.0 {
            pooled_o += o;
            pooled_e += e;
        } else {
            let term = (o - e) * (o - e) / e;
            if term > worst.0 {
                worst = (term, i);
            }
            chi2 += term;
            dof += 1;
        }
    }
    pooled_o += samples as f64 - observed.iter().sum::<f64>();
    pooled_e += samples as f64 - expected.iter().sum::<f64>();
    if pooled_e > 5.0 {
        chi2 += (pooled_o - pooled_e) * (pooled_o - pooled_e) / pooled_e;
        dof += 1;
    }
    assert!(dof > 20, "{kind:?} wo={wo}: only {dof} bins");
    let k = (dof - 1) as f64;
    let z = 4.753;
    let threshold = k * (1.0 - 2.0 / (9.0 * k) + z * (2.0 / (9.0 * k)).sqrt()).powi(3);
    assert!(
        chi2 < threshold,
        "{kind:?} wo={wo}: chi2 {chi2} over {dof} bins (threshold {threshold}); most from bin \
         (theta {}, phi {}): {} observed, {:.1} expected; pooled {pooled_o} against {pooled_e:.1}",
        worst.1 / PHI_BINS,
        worst.1 % PHI_BINS,
        observed[worst.1],
        expected[worst.1]
    );
}
