//! Alpha cut-outs: a cut-out quad lets through the fraction of rays its alpha leaves open, in
//! both backends, for single rays and packets, closest and any hit; a cut-out emitter emits
//! only where it is there; and the unbiased techniques agree on a scene lit through cut-outs.

mod common;

use common::{assert_agree, assert_means_agree, options, render_stats, PixelStats};
use glam::{Vec2, Vec3};
use std::path::Path;
use std::sync::Arc;
use vmerge::accel::{self, Accel, AccelKind, Alpha, Geometry, Hit, Primitive, Ray, TriangleAlpha};
use vmerge::color::Rgb;
use vmerge::options::{RenderOptions, Technique};
use vmerge::sampling::{Rng, Stream};
use vmerge::scene::{self, LoadOptions, Scene};
use vmerge::texture::Texture;

fn accels() -> Vec<AccelKind> {
    AccelKind::ALL
        .into_iter()
        .filter(|&k| k == AccelKind::Bvh || cfg!(feature = "embree"))
        .collect()
}

/// A unit quad at z = 1 (uv = its x and y) cut out by `alpha`, triangles 0 and 1, in front of
/// an opaque quad at z = 2, triangles 2 and 3; in groups that mix cut-out and opaque triangles,
/// [`WINDOW_GROUPS`].
fn window(alpha: Alpha) -> Geometry {
    let mut g = Geometry::default();
    for (z, lo, hi) in [(1.0, 0.0, 1.0), (2.0, -1.0, 2.0)] {
        for (x, y) in [(lo, lo), (hi, lo), (hi, hi), (lo, hi)] {
            g.positions.push(Vec3::new(x, y, z));
        }
    }
    g.triangles = vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]];
    let uv = |k: u32| g.positions[k as usize].truncate();
    for (t, [a, b, c]) in [(0, [0, 1, 2]), (1, [0, 2, 3])] {
        let uvs = [uv(a), uv(b), uv(c)];
        let alpha = TriangleAlpha {
            alpha: alpha.clone(),
            uvs,
        };
        g.cutouts.set(t, alpha);
    }
    g.group_starts = vec![1, 3];
    g
}

/// The group of each of the window's triangles.
const WINDOW_GROUPS: [u32; 4] = [0, 1, 1, 2];

/// A 4 x 4 alpha texture, open and closed texels and two fractional ones; mean 0.421875.
fn checker() -> Alpha {
    let values = [
        1.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.5, 0.0, 0.0, 0.0, 1.0, 1.0, 0.25, 0.0, 1.0, 0.0,
    ];
    let texels = values.iter().map(|&v| Rgb::splat(v)).collect();
    Alpha::Texture(Arc::new(Texture::new(4, 4, texels).unwrap()))
}

/// Rays whose hit points on the window are uniform over it (so their uvs are uniform over
/// the texture's period), each tilted a little so no two share a direction.
fn rays(n: usize) -> Vec<Ray> {
    let mut rng = Rng::for_sample(41, 0, 0, Stream::Eye);
    (0..n)
        .map(|_| {
            let hit = Vec2::new(rng.next_f32(), rng.next_f32());
            let tilt = Vec2::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5) * 0.02;
            let dir = tilt.extend(1.0);
            Ray::new(hit.extend(1.0) - dir, dir)
        })
        .collect()
}

/// Per ray, whether it passes the window, by each of the four queries: closest hit, any hit
/// short of the back quad, and both in packets of 8.
fn passes(a: &dyn Accel, rays: &[Ray]) -> [Vec<bool>; 4] {
    let through = |hit: Option<vmerge::accel::Hit>| {
        if let Some(Hit {
            primitive: Primitive::Triangle(t),
            group,
            ..
        }) = hit
        {
            assert_eq!(
                group,
                WINDOW_GROUPS[t as usize],
                "{}: triangle {t}",
                a.name()
            );
        }
        matches!(hit.map(|h| h.primitive), Some(Primitive::Triangle(2 | 3)))
    };
    let short = |r: &Ray| Ray { tmax: 1.5, ..*r };
    let mut out: [Vec<bool>; 4] = Default::default();
    for r in rays {
        out[0].push(through(a.intersect(r)));
        out[1].push(!a.occluded(&short(r)));
    }
    for chunk in rays.chunks_exact(8) {
        let packet: [Ray; 8] = std::array::from_fn(|i| chunk[i]);
        let mut hits = [None; 8];
        a.intersect8(&packet, 0xff, &mut hits);
        out[2].extend(hits.iter().map(|&h| through(h)));
        let occluded = a.occluded8(&packet.map(|r| short(&r)), 0xff);
        out[3].extend((0..8).map(|i| occluded & (1 << i) == 0));
    }
    out
}

/// A constant alpha and a texture of known mean: every backend and query lets through
/// 1 - (mean alpha) of the rays, within 4 binomial standard errors (0.8% of the fraction at
/// 2^17 rays, so a 1% bias fails), and the backends and queries decide ray by ray alike (the
/// decision hashes the ray, not the traversal; a texture read at barycentrics that differ in
/// the last bits between backends may flip a few).
#[test]
fn a_cut_out_window_passes_the_open_fraction() {
    let rays = rays(1 << 17);
    for (name, alpha, open) in [
        ("constant 0.4", Alpha::Constant(0.4), 0.6),
        ("checker", checker(), 1.0 - 0.421875),
    ] {
        let geometry = window(alpha);
        let mut reference: Option<Vec<bool>> = None;
        for kind in accels() {
            let a = accel::build(kind, &geometry).unwrap();
            for (query, pass) in ["intersect", "occluded", "intersect8", "occluded8"]
                .iter()
                .zip(passes(a.as_ref(), &rays))
            {
                let label = format!("{name}, {}, {query}", kind.name());
                let n = pass.len() as f64;
                let fraction = pass.iter().filter(|&&p| p).count() as f64 / n;
                let se = (open * (1.0 - open) / n).sqrt();
                assert!(
                    (fraction - open).abs() <= 4.0 * se,
                    "{label}: {fraction} of the rays pass, expected {open} (se {se})"
                );
                let reference = reference.get_or_insert_with(|| pass.clone());
                let differ = pass.iter().zip(reference.iter()).filter(|(a, b)| a != b);
                assert!(differ.count() <= 4, "{label}: decides other rays");
            }
        }
    }
}

/// Alpha 0 cuts everything out, alpha 1 nothing.
#[test]
fn alpha_zero_and_one_are_exact() {
    let rays = rays(4096);
    for (alpha, open) in [(0.0, true), (1.0, false)] {
        for kind in accels() {
            let a = accel::build(kind, &window(Alpha::Constant(alpha))).unwrap();
            for pass in passes(a.as_ref(), &rays) {
                assert!(pass.iter().all(|&p| p == open), "alpha {alpha}");
            }
        }
    }
}

/// A quad in the plane y = `y` over x and z in [lo, hi], facing up or down, uv 0..1 over it.
fn horizontal(y: f32, lo: f32, hi: f32, up: bool) -> String {
    let faces = if up {
        "f 1/1 3/3 2/2\nf 1/1 4/4 3/3\n"
    } else {
        "f 1/1 2/2 3/3\nf 1/1 3/3 4/4\n"
    };
    format!(
        "v {lo} {y} {lo}\nv {hi} {y} {lo}\nv {hi} {y} {hi}\nv {lo} {y} {hi}\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n{faces}"
    )
}

/// A 4 x 4 PNG whose alpha channel holds `alpha` (8-bit), the colour white.
fn write_alpha_png(path: &Path, alpha: [u8; 16]) {
    let mut image = image::RgbaImage::new(4, 4);
    for (i, p) in image.pixels_mut().enumerate() {
        *p = image::Rgba([255, 255, 255, alpha[i]]);
    }
    image.save(path).unwrap();
}

fn load_scene(dir: &Path, toml: &str, accel: AccelKind) -> Scene {
    let path = dir.join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    let options = LoadOptions {
        accel,
        lenient: false,
        shading_normals: true,
    };
    scene::load(&path, &options).unwrap_or_else(|e| panic!("{e}"))
}

fn stats(scene: &Scene, technique: Technique, iterations: u64) -> PixelStats {
    let o: RenderOptions = options(technique, 32);
    render_stats(scene, &o, iterations)
}

/// A floor lit by an emitter of radiance 10 with alpha 0.75 through a black window with alpha
/// 0.4 receives what a plain emitter of radiance 10 x 0.75 x 0.6 = 4.5 gives without the
/// window: pt (by next-event estimation and by hits), lt (light sub-paths leave the cut-out
/// emitter) and bpt agree with that image, in both backends. The window lies across every
/// path from the light to the floor; the camera sees neither.
#[test]
fn a_cut_out_emitter_through_a_window_equals_a_dimmer_light() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(p.join("floor.obj"), horizontal(0.0, -2.0, 3.0, true)).unwrap();
    std::fs::write(p.join("window.obj"), horizontal(0.5, -1.5, 2.5, false)).unwrap();
    std::fs::write(p.join("light.obj"), horizontal(1.0, 0.0, 1.0, false)).unwrap();
    let scene = |emission: f32, cut_out: bool| {
        let mut toml = format!(
            r#"
[[camera]]
position = [0.5, 0.3, 2.5]
look_at = [0.5, 0.0, 0.5]
fov = 30.0

[material.light]
kd = [0.0, 0.0, 0.0]
emission = [{emission}, {emission}, {emission}]

[material.black]
kd = [0.0, 0.0, 0.0]

[material.grey]
kd = [0.6, 0.6, 0.6]

[[mesh]]
file = "floor.obj"
material = "grey"

[[mesh]]
file = "light.obj"
material = "light"
"#
        );
        if cut_out {
            toml += "alpha = 0.75\n\n[[mesh]]\nfile = \"window.obj\"\nmaterial = \"black\"\nalpha = 0.4\n";
        }
        toml
    };
    let plain = load_scene(p, &scene(4.5, false), AccelKind::Bvh);
    // Its own seed: renders sharing random numbers would agree too well.
    let mut o = options(Technique::Pt, 32);
    o.seed += 500;
    let reference = render_stats(&plain, &o, 256);
    for accel in accels() {
        let cut = load_scene(p, &scene(10.0, true), accel);
        assert_eq!(cut.geometry.cutouts.len(), 4);
        // Light tracing is the noisiest here: it gets more iterations.
        for (technique, iterations) in [
            (Technique::Pt, 256),
            (Technique::Lt, 1024),
            (Technique::Bpt, 256),
        ] {
            let label = format!("{} {technique:?}", accel.name());
            assert_agree(&label, &stats(&cut, technique, iterations), &reference);
        }
    }
}

/// A floor lit by a cut-out emitter (an alpha image) through a cut-out grey quad (another);
/// the camera sees the floor, the quad and its shadow: bpt, vcm and upg agree with pt (vcm at
/// a small radius), the Embree and BVH images agree, and UPG's tentative rays give the same
/// image traced one by one and in packets.
#[test]
fn techniques_and_backends_agree_through_cut_outs() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    std::fs::write(p.join("floor.obj"), horizontal(0.0, -2.0, 3.0, true)).unwrap();
    std::fs::write(p.join("leaf.obj"), horizontal(0.5, 0.0, 1.0, false)).unwrap();
    std::fs::write(p.join("light.obj"), horizontal(1.0, -0.2, 1.2, false)).unwrap();
    write_alpha_png(
        &p.join("leaf.png"),
        [
            255, 0, 0, 255, 0, 255, 128, 0, 0, 0, 255, 255, 64, 0, 255, 0,
        ],
    );
    write_alpha_png(
        &p.join("light.png"),
        [
            255, 255, 0, 0, 255, 255, 0, 0, 0, 0, 255, 255, 0, 0, 255, 255,
        ],
    );
    let toml = r#"
[render]
max_path_length = 6

[[camera]]
position = [0.5, 1.6, 2.8]
look_at = [0.5, 0.0, 0.5]
fov = 45.0

[material.light]
kd = [0.0, 0.0, 0.0]
emission = [6.0, 6.0, 6.0]

[material.grey]
kd = [0.6, 0.6, 0.6]

[[mesh]]
file = "floor.obj"
material = "grey"

[[mesh]]
file = "leaf.obj"
material = "grey"
alpha = "leaf.png"

[[mesh]]
file = "light.obj"
material = "light"
alpha = "light.png"
"#;
    let mut by_backend = Vec::new();
    for accel in accels() {
        let scene = load_scene(p, toml, accel);
        assert_eq!(scene.geometry.cutouts.len(), 4);
        let pt = stats(&scene, Technique::Pt, 1024);
        for technique in [Technique::Bpt, Technique::Vcm, Technique::Upg] {
            let mut o = options(technique, 32);
            o.radius = Some(0.005);
            let s = render_stats(&scene, &o, 256);
            assert_agree(&format!("{} {technique:?} vs pt", accel.name()), &s, &pt);
        }
        let mut o = options(Technique::Upg, 32);
        o.radius = Some(0.2);
        o.upg_packet = 1;
        let single = vmerge::render::render_iterations(&scene, &o, 2).unwrap();
        o.upg_packet = 8;
        let packets = vmerge::render::render_iterations(&scene, &o, 2).unwrap();
        assert_eq!(single.sum, packets.sum, "{}: upg packets", accel.name());
        by_backend.push(pt);
    }
    if let [embree, bvh] = &by_backend[..] {
        assert_means_agree("pt: embree vs bvh", embree, bvh);
    }
}

/// The pbrt-v4 comparison scene's cut-outs load: an alpha image texture on the light and on
/// the leaf, a constant on the panel.
#[test]
fn the_pbrt_scene_loads_its_cut_outs() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/pbrt-compare/alpha-cutout.pbrt");
    let options = LoadOptions {
        accel: AccelKind::Bvh,
        lenient: false,
        shading_normals: true,
    };
    let scene = scene::load(&path, &options).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.geometry.cutouts.len(), 6);
    let about_alpha = |w: &&scene::Warning| w.message.contains("alpha");
    assert!(
        !scene.warnings.iter().any(|w| about_alpha(&w)),
        "{:?}",
        scene.warnings
    );
    let constant = (0..scene.geometry.triangles.len() as u32)
        .filter_map(|t| scene.geometry.cutouts.get(t))
        .filter(|a| a.alpha == Alpha::Constant(0.5))
        .count();
    assert_eq!(constant, 2);
}
