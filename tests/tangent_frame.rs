//! The tangent frame of anisotropic BSDFs, as pbrt-v4 builds it: the hit carries the surface's
//! dp/du (a sphere's along its parallels about the object z axis, through its transform, or
//! about -y for a TOML sphere, as its texture coordinates run; a triangle's from its uvs,
//! pbrt's default uvs where it has none; a bilinear patch's), the BSDF puts `uroughness`
//! along it (x = dp/du made orthogonal to the shading normal), so the highlight of a surface
//! rougher along u is stretched along dp/du; isotropic materials keep their old frame.

use glam::{DMat4, DVec3, Vec3};
use std::path::Path;
use vmerge::accel::{AccelKind, Ray};
use vmerge::bsdf::microfacet::Roughness;
use vmerge::bsdf::{Albedo, Bsdf, MaterialKind, Normals, TransportMode};
use vmerge::color::Rgb;
use vmerge::frame::{Azimuth, Frame};
use vmerge::scene::{self, LoadOptions, Scene};

/// A conductor that reflects everything (F = 1 to 4e-8) with roughness `u` and `v`.
fn conductor(u: f32, v: f32) -> MaterialKind {
    MaterialKind::Conductor {
        eta: Rgb::WHITE,
        k: Rgb::splat(1e4),
        roughness: Roughness { u, v, remap: false },
    }
}

fn load_pbrt(dir: &Path, body: &str) -> Scene {
    let path = dir.join("scene.pbrt");
    let text = format!(
        "WorldBegin\nLightSource \"point\" \"rgb I\" [1 1 1]\n\
         Material \"conductor\" \"float uroughness\" 0.05 \"float vroughness\" 0.4\n{body}"
    );
    std::fs::write(&path, text).unwrap();
    let options = LoadOptions {
        accel: AccelKind::Bvh,
        lenient: false,
        shading_normals: true,
    };
    scene::load(&path, &options).unwrap_or_else(|e| panic!("{e}"))
}

fn hit_dpdu(scene: &Scene, origin: DVec3, target: DVec3) -> (Vec3, Vec3) {
    let ray = Ray::new(origin.as_vec3(), (target - origin).normalize().as_vec3());
    let hit = scene.intersect(&ray).expect("the ray hits the shape");
    (hit.position, hit.dpdu)
}

fn assert_close(label: &str, got: Vec3, expected: DVec3) {
    let err = (got.as_dvec3() - expected).length() / expected.length();
    assert!(err < 1e-4, "{label}: dp/du {got}, pbrt's {expected}");
}

/// pbrt-v4's sphere: dp/du = phimax (-y, x, 0) at the object-space point (x, y, z), taken to
/// world space by the shape's transform, here a rotation, a uniform scale and a translation,
/// once with a mirror (which swaps handedness).
#[test]
fn sphere_tangent_is_pbrts_dpdu() {
    let dir = tempfile::tempdir().unwrap();
    for mirror in [1.0, -1.0] {
        let body = format!(
            "Translate 0.5 -1 2\nRotate 40 1 2 0.5\nScale {} 0.8 0.8\n\
             Shape \"sphere\" \"float radius\" 1.5\n",
            0.8 * mirror
        );
        let scene = load_pbrt(dir.path(), &body);
        let m = DMat4::from_translation(DVec3::new(0.5, -1.0, 2.0))
            * DMat4::from_axis_angle(DVec3::new(1.0, 2.0, 0.5).normalize(), 40f64.to_radians())
            * DMat4::from_scale(DVec3::new(0.8 * mirror, 0.8, 0.8));
        let center = m.transform_point3(DVec3::ZERO);
        for from in [
            DVec3::new(3.0, 1.0, 4.0),
            DVec3::new(-2.0, 4.0, -1.0),
            DVec3::new(0.3, -5.0, 2.5),
        ] {
            let (p, dpdu) = hit_dpdu(&scene, from, center);
            let po = m.inverse().transform_point3(p.as_dvec3());
            let expected =
                m.transform_vector3(std::f64::consts::TAU * DVec3::new(-po.y, po.x, 0.0));
            assert_close(&format!("mirror {mirror}, from {from}"), dpdu, expected);
        }
    }
}

/// A sphere of a TOML scene: dp/du of its own texture coordinates, u = 1/2 + atan2(n.x, -n.z)
/// / (2 pi) about the y axis, which is 2 pi r (-n.z, 0, n.x) at the outward normal n.
#[test]
fn toml_sphere_tangent_follows_its_texture_coordinates() {
    let path = format!(
        "{}/scenes/microfacets/scene.toml",
        env!("CARGO_MANIFEST_DIR")
    );
    let options = LoadOptions {
        accel: AccelKind::Bvh,
        lenient: false,
        shading_normals: true,
    };
    let scene = scene::load(path.as_ref(), &options).unwrap_or_else(|e| panic!("{e}"));
    // The anisotropic aluminium sphere.
    let (center, radius) = (DVec3::new(-0.45, 0.38, -0.35), 0.38);
    for from in [DVec3::new(0.0, 1.0, 3.4), DVec3::new(-0.95, 0.9, 0.4)] {
        let (p, dpdu) = hit_dpdu(&scene, from, center);
        let n = (p.as_dvec3() - center) / radius;
        let expected = std::f64::consts::TAU * radius * DVec3::new(-n.z, 0.0, n.x);
        assert_close(&format!("from {from}"), dpdu, expected);
    }
}

/// pbrt-v4's triangle: dp/du from the uvs (u runs here from p0 to p2), the default uvs (0,0), (1,0), (1,1) where the mesh has none (dp/du = p1 - p0),
/// and the first axis of the frame around the normal where the uvs are degenerate.
#[test]
fn triangle_tangent_is_pbrts_dpdu() {
    let dir = tempfile::tempdir().unwrap();
    let p = "\"point3 P\" [0 0 0  2 0 0  0 0 3]";
    let cases = [
        ("\"point2 uv\" [0 0  0 2  1 0]", DVec3::new(0.0, 0.0, 3.0)),
        ("", DVec3::new(2.0, 0.0, 0.0)),
        // pbrt's CoordinateSystem around its normal (p2 - p0) x (p1 - p0) = +y.
        ("\"point2 uv\" [0 0  1 1  2 2]", DVec3::X),
    ];
    for (uv, expected) in cases {
        let body = format!("Shape \"trianglemesh\" {p} {uv} \"integer indices\" [0 1 2]\n");
        let scene = load_pbrt(dir.path(), &body);
        let (_, dpdu) = hit_dpdu(&scene, DVec3::new(0.4, 2.0, 0.5), DVec3::new(0.5, 0.0, 0.7));
        assert_close(&format!("uv [{uv}]"), dpdu, expected);
    }
    // Turned to face the other way, the triangle keeps dp/du on its line (the sign no BSDF
    // sees, as below).
    let body =
        format!("ReverseOrientation\nShape \"trianglemesh\" {p} \"integer indices\" [0 1 2]\n");
    let scene = load_pbrt(dir.path(), &body);
    let (_, dpdu) = hit_dpdu(&scene, DVec3::new(0.4, 2.0, 0.5), DVec3::new(0.5, 0.0, 0.7));
    assert_close("turned", -dpdu, DVec3::new(2.0, 0.0, 0.0));
}

/// pbrt-v4's bilinear patch p00, p10, p01, p11 without uvs: dp/du = (1 - v) (p10 - p00) +
/// v (p11 - p01), here a parallelogram's constant p10 - p00, in both triangles it is cut into
/// (up to the sign, which no BSDF sees: a lobe is symmetric about its axes).
#[test]
fn bilinear_patch_tangent_is_pbrts_dpdu() {
    let dir = tempfile::tempdir().unwrap();
    let body = "Shape \"bilinearmesh\" \"point3 P\" [0 0 0  2 0 0  0.5 0 1.5  2.5 0 1.5]\n";
    let scene = load_pbrt(dir.path(), body);
    let expected = DVec3::new(2.0, 0.0, 0.0);
    // Points near p10 and near p01, one in each triangle.
    for target in [DVec3::new(1.9, 0.0, 0.1), DVec3::new(0.6, 0.0, 1.4)] {
        let (_, dpdu) = hit_dpdu(&scene, target + DVec3::new(0.1, 1.0, 0.2), target);
        let sign = dpdu.as_dvec3().dot(expected).signum();
        assert_close(&format!("at {target}"), sign as f32 * dpdu, expected);
    }
}

/// A shading normal and a tangent that lies half-way between the axes of the frame vmerge
/// builds without one, where an arbitrary frame would make the highlight round.
fn oblique_setup() -> (Normals, Vec3) {
    let ns = Vec3::new(0.2, -0.3, 0.9).normalize();
    let old = Frame::from_z(ns);
    let tangent = 3.0 * (old.x + old.y) + 0.7 * ns;
    (Normals::flat(ns), tangent)
}

/// The oriented BSDF is the canonical one (tangent x, normal z) turned onto the surface: the
/// axes are pbrt's `Frame::FromXZ(dp/du orthogonalised, ns)`, to the azimuth's 1e-4 radians.
#[test]
fn anisotropic_bsdf_is_evaluated_in_the_tangent_frame() {
    let kind = conductor(0.3, 0.08);
    let (normals, tangent) = oblique_setup();
    let ns = normals.ns;
    let x = (tangent - ns * ns.dot(tangent)).normalize();
    let wo = (0.3 * x + 0.5 * ns.cross(x) + 0.8 * ns).normalize();
    let albedo = Albedo::of(&kind);
    let azimuth = Azimuth::of(tangent, ns);
    let b = Bsdf::oriented(&kind, albedo, normals, azimuth, wo, TransportMode::Radiance)
        .expect("wo off the surface");
    let frame = *b.frame();
    assert!((frame.x - x).length() < 1e-4, "x {} vs {x}", frame.x);
    assert_eq!(frame.z, ns);
    let local_wo = frame.to_local(wo);
    let canonical = Bsdf::new(&kind, Vec3::Z, local_wo, TransportMode::Radiance).unwrap();
    for i in 0..64 {
        let (c, phi) = ((i as f32 + 0.5) / 64.0, i as f32 * 2.399_963);
        let s = (1.0 - c * c).sqrt();
        let local_wi = Vec3::new(s * phi.cos(), s * phi.sin(), c);
        let got = b.eval(frame.to_world(local_wi));
        let want = canonical.eval(local_wi);
        let rel = |a: f32, b: f32| (a - b).abs() <= 1e-3 * b.abs() + 1e-6;
        assert!(
            rel(got.f.r, want.f.r) && rel(got.pdf_w, want.pdf_w),
            "wi {local_wi}: {got:?} vs {want:?}"
        );
    }
}

/// Sampled at normal incidence, a surface with uroughness 0.3 and vroughness 0.05 scatters
/// along dp/du: the mean square of wi's component along the tangent exceeds that along the
/// bitangent by about (0.3 / 0.05)^2; in a frame blind to the tangent, turned 45 degrees
/// from it, the two would be equal.
#[test]
fn anisotropic_highlight_is_stretched_along_the_tangent() {
    let kind = conductor(0.3, 0.05);
    let (normals, tangent) = oblique_setup();
    let ns = normals.ns;
    let t = (tangent - ns * ns.dot(tangent)).normalize();
    let b = ns.cross(t);
    let bsdf = Bsdf::oriented(
        &kind,
        Albedo::of(&kind),
        normals,
        Azimuth::of(tangent, ns),
        ns,
        TransportMode::Radiance,
    )
    .unwrap();
    let n = 128;
    let (mut along_t, mut along_b, mut count) = (0.0f64, 0.0f64, 0usize);
    for i in 0..n {
        for j in 0..n {
            let u = [
                0.5,
                (i as f32 + 0.5) / n as f32,
                (j as f32 + 0.5) / n as f32,
            ];
            if let Some(s) = bsdf.sample(u) {
                along_t += (s.wi.dot(t) as f64).powi(2);
                along_b += (s.wi.dot(b) as f64).powi(2);
                count += 1;
            }
        }
    }
    assert!(count > n * n / 2, "{count} samples");
    let ratio = along_t / along_b;
    assert!(ratio > 15.0, "mean squares along t and b in ratio {ratio}");
}

/// Isotropic materials ignore the tangent: their frame, and with it the mapping of random
/// numbers to directions, is the one they had without it.
#[test]
fn isotropic_bsdfs_keep_their_frame() {
    let (normals, tangent) = oblique_setup();
    let wo = Vec3::new(0.1, 0.2, 0.97).normalize();
    for kind in [
        conductor(0.2, 0.2),
        MaterialKind::Lambert {
            kd: Rgb::splat(0.5),
        },
    ] {
        let albedo = Albedo::of(&kind);
        let azimuth = Azimuth::of(tangent, normals.ns);
        let b = Bsdf::oriented(&kind, albedo, normals, azimuth, wo, TransportMode::Radiance);
        assert_eq!(*b.unwrap().frame(), Frame::from_z(normals.ns));
    }
}
