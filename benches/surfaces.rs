//! What shading normals, textures and each surface type cost. First one scattering event
//! (building the BSDF, sampling it, evaluating it at the sample) of every type, next to
//! Phong's, over directions spread on the hemisphere. Then the conference room (331k
//! triangles, from ../shared/scenes, skipped when absent) rendered flat, with shading normals,
//! with a texture on every material, and with both. The room's OBJ has neither normals nor
//! uvs, so the bench gives it area-weighted vertex normals and planar uvs (one texture period
//! per 100 units), and each material a texture of its own kd with a faint pattern (+-1%), so
//! the light paths stay those of the flat scene and the cost is the lookups': 64 x 64 texels
//! (all 35 fit in the caches) or 512 x 512 (110 MB, where a lookup waits for memory). Then
//! every surface of one type: Phong (kd 0.3, ks 0.6, n 20) next to pbrt-v4's types (the
//! microfacet ones of the same lobe width, Trowbridge-Reitz alpha 0.3), and every surface a
//! mix of that Phong and that conductor. Each round renders one iteration of each variant in
//! turn; the figures are the medians over rounds of the time of each variant over the flat
//! one's in the same round. Run: `cargo bench --bench surfaces`.

use glam::{Vec2, Vec3};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;
use vmerge::accel::AccelKind;
use vmerge::bsdf::{Albedo, MaterialKind, Params};
use vmerge::color::Rgb;
use vmerge::integrator::RenderContext;
use vmerge::options::{RenderOptions, Technique};
use vmerge::render::create_integrator;
use vmerge::scene::{self, Camera, LoadOptions, MaterialTextures, MeshShading, Mix, Scene};
use vmerge::texture::Texture;

const SIZE: u32 = 256;
const ROUNDS: usize = 7;

fn vertex_normals(parts: &scene::SceneParts) -> MeshShading {
    let g = &parts.geometry;
    let mut normals = vec![Vec3::ZERO; g.positions.len()];
    for t in &g.triangles {
        let [a, b, c] = t.map(|i| g.positions[i as usize]);
        // The cross product's length is twice the area: area-weighted.
        let n = (b - a).cross(c - a);
        for &i in t {
            normals[i as usize] += n;
        }
    }
    MeshShading {
        normals: normals.into_iter().map(Vec3::normalize_or_zero).collect(),
        uvs: g
            .positions
            .iter()
            .map(|p| Vec2::new(p.x + 0.5 * p.y, p.z - 0.5 * p.y) / 100.0)
            .collect(),
        triangle_normals: g.triangles.clone(),
        triangle_uvs: g.triangles.clone(),
        sphere_poles: Vec::new(),
    }
}

fn texture(kd: Rgb, n: u32) -> Texture {
    let texels = (0..n * n)
        .map(|i| {
            let (x, y) = (i % n, i / n);
            kd * (0.99 + 0.02 * ((x ^ y) % 7) as f32 / 6.0)
        })
        .collect();
    Texture::new(n, n, texels).expect("a square texture")
}

/// What the surfaces of a variant are: the room's own, every one of a type, or every one a
/// half-and-half mix of two types.
#[derive(Clone, Copy)]
enum Surfaces<'a> {
    Own,
    All(&'a MaterialKind),
    Mix(&'a MaterialKind, &'a MaterialKind),
}

/// Every material that does not emit becomes a mix of two new materials of types `a` and `b`,
/// each point one of them with probability 1/2.
fn mix_all(parts: &mut scene::SceneParts, a: &MaterialKind, b: &MaterialKind) {
    let Some(base) = parts.materials.iter().find(|m| !m.is_emissive()).cloned() else {
        return;
    };
    let first = parts.materials.len() as u32;
    let mut mixes: Vec<Option<Mix>> = parts
        .materials
        .iter()
        .map(|m| {
            (!m.is_emissive()).then_some(Mix {
                materials: [first, first + 1],
                amount: 0.5,
                amount_texture: None,
            })
        })
        .collect();
    for kind in [a, b] {
        parts.materials.push(vmerge::bsdf::Material {
            kind: kind.clone(),
            ..base.clone()
        });
        parts.material_textures.push(MaterialTextures::default());
        mixes.push(None);
    }
    parts.mixes = mixes;
}

/// The room with or without shading normals, with textures of `texture_size` texels a side
/// (0: none), and with the given surfaces.
fn variant(path: &Path, normals: bool, texture_size: u32, surfaces: Surfaces) -> Scene {
    let textured = texture_size > 0;
    let options = LoadOptions {
        accel: AccelKind::default_kind(),
        lenient: true,
        shading_normals: true,
    };
    let mut parts = scene::load_parts(path, &options).expect("the conference room loads");
    match surfaces {
        Surfaces::Own => {}
        Surfaces::All(kind) => {
            for m in parts.materials.iter_mut().filter(|m| !m.is_emissive()) {
                m.kind = kind.clone();
            }
        }
        Surfaces::Mix(a, b) => mix_all(&mut parts, a, b),
    }
    let shading = vertex_normals(&parts);
    parts.shading = MeshShading {
        triangle_normals: if normals {
            shading.triangle_normals
        } else {
            Vec::new()
        },
        triangle_uvs: if textured {
            shading.triangle_uvs
        } else {
            Vec::new()
        },
        ..shading
    };
    if textured {
        parts.textures = parts
            .materials
            .iter()
            .map(|m| Arc::new(texture(Albedo::of(&m.kind).kd, texture_size)))
            .collect();
        parts.material_textures = (0..parts.materials.len() as u32)
            .map(|i| MaterialTextures {
                kd: Some(i),
                ks: None,
                roughness: None,
                vroughness: None,
            })
            .collect();
    }
    Scene::build(parts, options.accel).expect("the conference room builds")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    event_costs();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("benches/scenes/conference.toml");
    if !path.exists()
        || !Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../shared/scenes/conference/conference.obj")
            .exists()
    {
        eprintln!("skipping: the conference room is absent");
        return;
    }
    // Every surface Phong, then each of pbrt-v4's types, the microfacet ones of about the
    // same lobe width (alpha 0.3, Phong n = 2 / alpha^2 - 2 = 20).
    let kind = |name: &str, params: Params| MaterialKind::from_params(name, &params).unwrap();
    let roughness =
        |name: &str, p: Params| p.with_number(name, 0.3).with_number("remaproughness", 0.0);
    let phong = kind(
        "phong",
        Params::new()
            .with_color("kd", Rgb::splat(0.3))
            .with_color("ks", Rgb::splat(0.6))
            .with_number("exponent", 20.0),
    );
    let conductor = kind("conductor", roughness("roughness", Params::new()));
    let dielectric = kind("dielectric", roughness("roughness", Params::new()));
    let thin = kind("thindielectric", Params::new());
    let transmission = kind("diffusetransmission", Params::new());
    let coated_diffuse = kind("coateddiffuse", roughness("roughness", Params::new()));
    let coated_conductor = kind(
        "coatedconductor",
        roughness(
            "interface.roughness",
            roughness("conductor.roughness", Params::new()),
        ),
    );
    let own = Surfaces::Own;
    let variants = [
        ("flat", false, 0, own),
        ("shading normals", true, 0, own),
        ("textures 64^2", false, 64, own),
        ("textures 512^2", false, 512, own),
        ("normals + 512^2", true, 512, own),
        ("all phong n 20", false, 0, Surfaces::All(&phong)),
        ("all conductor", false, 0, Surfaces::All(&conductor)),
        ("all dielectric", false, 0, Surfaces::All(&dielectric)),
        ("all thindielectric", false, 0, Surfaces::All(&thin)),
        ("all diffusetransm.", false, 0, Surfaces::All(&transmission)),
        (
            "all coateddiffuse",
            false,
            0,
            Surfaces::All(&coated_diffuse),
        ),
        (
            "all coatedconductor",
            false,
            0,
            Surfaces::All(&coated_conductor),
        ),
        (
            "mix phong+conductor",
            false,
            0,
            Surfaces::Mix(&phong, &conductor),
        ),
    ];
    let names: Vec<&str> = variants.iter().map(|v| v.0).collect();
    let scenes: Vec<Scene> = variants
        .iter()
        .map(|&(_, n, t, k)| variant(&path, n, t, k))
        .collect();
    let texture_bytes: usize = scenes[3].textures.iter().map(|t| t.bytes()).sum();
    println!(
        "shading data {:.1} MB (normals, uvs and their indices), textures {:.1} MB",
        scenes[4].shading.bytes() as f64 / 1e6,
        texture_bytes as f64 / 1e6
    );
    for technique in [Technique::Pt, Technique::Bpt] {
        let options = RenderOptions {
            technique,
            resolution: Some([SIZE, SIZE]),
            ..Default::default()
        };
        let mut integrators: Vec<_> = scenes
            .iter()
            .map(|scene| {
                let camera = Camera::new(scene.camera(None).expect("camera"), SIZE, SIZE);
                create_integrator(RenderContext {
                    scene,
                    camera,
                    options: &options,
                })
            })
            .collect();
        let mut frame = vec![Rgb::BLACK; (SIZE * SIZE) as usize];
        let mut ratios = vec![Vec::new(); names.len()];
        let mut seconds = vec![Vec::new(); names.len()];
        for round in 0..=ROUNDS {
            let mut times = Vec::new();
            for integrator in integrators.iter_mut() {
                frame.fill(Rgb::BLACK);
                let start = Instant::now();
                integrator.render_iteration(round as u64, &mut frame);
                times.push(start.elapsed().as_secs_f64());
            }
            // Round 0 warms the caches and is left out.
            if round > 0 {
                for (i, t) in times.iter().enumerate() {
                    ratios[i].push(t / times[0]);
                    seconds[i].push(*t);
                }
            }
        }
        for (i, name) in names.iter().enumerate() {
            println!(
                "{technique:?} {SIZE}x{SIZE}: {name:19} {:.3} s per iteration, {:.3} x flat",
                median(seconds[i].clone()),
                median(ratios[i].clone())
            );
        }
    }
}

/// The cost of one scattering event (building the BSDF, sampling it, evaluating it at the
/// sample) of every type next to Phong's, per call over directions spread on the hemisphere;
/// the figures are medians over rounds. The rough types have alpha 0.3 (Phong's n 20) where not
/// said otherwise; a mix costs the hash of the point on top of the type it picks, measured in
/// the room below.
fn event_costs() {
    use std::hint::black_box;
    use vmerge::bsdf::{Bsdf, MaterialKind, Params, TransportMode};
    let kind = |name: &str, params: Params| {
        MaterialKind::from_params(name, &params).expect("valid parameters")
    };
    let alpha =
        |name: &str, a: f32, p: Params| p.with_number(name, a).with_number("remaproughness", 0.0);
    let kinds = [
        (
            "phong n 20",
            kind(
                "phong",
                Params::new()
                    .with_color("kd", Rgb::splat(0.3))
                    .with_color("ks", Rgb::splat(0.6))
                    .with_number("exponent", 20.0),
            ),
        ),
        ("lambert", kind("lambert", Params::new())),
        ("mirror", kind("mirror", Params::new())),
        ("glass", kind("glass", Params::new())),
        ("conductor smooth", kind("conductor", Params::new())),
        (
            "conductor 0.3",
            kind("conductor", alpha("roughness", 0.3, Params::new())),
        ),
        (
            "conductor 0.1 x 0.4",
            kind(
                "conductor",
                alpha("uroughness", 0.1, alpha("vroughness", 0.4, Params::new())),
            ),
        ),
        (
            "dielectric 0.3",
            kind("dielectric", alpha("roughness", 0.3, Params::new())),
        ),
        ("thindielectric", kind("thindielectric", Params::new())),
        (
            "diffusetransmission",
            kind("diffusetransmission", Params::new()),
        ),
        ("coateddiffuse smooth", kind("coateddiffuse", Params::new())),
        (
            "coateddiffuse 0.3",
            kind("coateddiffuse", alpha("roughness", 0.3, Params::new())),
        ),
        (
            "coatedconductor 0.3/0.3",
            kind(
                "coatedconductor",
                alpha(
                    "interface.roughness",
                    0.3,
                    alpha("conductor.roughness", 0.3, Params::new()),
                ),
            ),
        ),
    ];
    const CALLS: u32 = 1 << 20;
    let directions: Vec<Vec3> = (0..1024)
        .map(|i| {
            let z = (i as f32 + 0.5) / 1024.0;
            let phi = i as f32 * 2.399_963;
            let r = (1.0 - z * z).sqrt();
            Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect();
    let mut per_call = vec![Vec::new(); kinds.len()];
    for _ in 0..ROUNDS {
        for (slot, (_, k)) in per_call.iter_mut().zip(&kinds) {
            let start = Instant::now();
            let mut sum = 0.0f32;
            for i in 0..CALLS {
                let wo = directions[(i & 1023) as usize];
                let u = [
                    (i.wrapping_mul(2_654_435_761) >> 8) as f32 / (1u32 << 24) as f32,
                    (i.wrapping_mul(2_246_822_519) >> 8) as f32 / (1u32 << 24) as f32,
                    (i.wrapping_mul(3_266_489_917) >> 8) as f32 / (1u32 << 24) as f32,
                ];
                let bsdf = Bsdf::new(black_box(k), Vec3::Z, wo, TransportMode::Radiance);
                if let Some(s) = bsdf.as_ref().and_then(|b| b.sample(u)) {
                    let e = bsdf.as_ref().map_or(0.0, |b| b.eval(s.wi).pdf_w);
                    sum += s.f.g + e;
                }
            }
            black_box(sum);
            slot.push(start.elapsed().as_secs_f64() * 1e9 / CALLS as f64);
        }
    }
    let phong = median(per_call[0].clone());
    for ((name, _), times) in kinds.iter().zip(per_call) {
        let t = median(times);
        println!(
            "{name:24} {t:6.1} ns per scattering event, {:.2} x phong",
            t / phong
        );
    }
}
