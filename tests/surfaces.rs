//! Shading normals, textures and the environment light: every technique agrees on the scenes
//! that use them (`smooth`, `textured`, `envmap`), the environment light samples what its pdf
//! says, textures return their texels, a textured furnace still gives 1, and with shading
//! normals off a smooth mesh renders exactly as its flat copy.

mod common;

use common::{assert_agree, load, options, render_stats, PixelStats};
use glam::{Vec2, Vec3};
use std::path::Path;
use vmerge::accel::AccelKind;
use vmerge::color::Rgb;
use vmerge::options::RenderOptions;
use vmerge::options::Technique;
use vmerge::render::render_iterations;
use vmerge::scene::{self, LoadOptions, Scene, SceneError};
use vmerge::texture::{write_pfm, Texture};

fn view(technique: Technique, camera: &str) -> RenderOptions {
    RenderOptions {
        camera: Some(camera.into()),
        ..options(technique, 24)
    }
}

/// Iterations that give each technique comparable noise on these small scenes.
fn iterations(technique: Technique) -> u64 {
    match technique {
        Technique::Lt => 8192,
        Technique::Pt => 4096,
        _ => 2048,
    }
}

fn agree_with_bpt(name: &str, camera: &str, techniques: &[Technique]) {
    let scene = load(name);
    let bpt = render_stats(&scene, &view(Technique::Bpt, camera), 4096);
    for &technique in techniques {
        let stats: PixelStats =
            render_stats(&scene, &view(technique, camera), iterations(technique));
        assert_eq!(stats.dropped, 0, "{name}: {technique:?} dropped samples");
        assert_agree(&format!("{name} ({camera}): {technique:?}"), &stats, &bpt);
    }
}

const ALL_BUT_LT: [Technique; 4] = [
    Technique::Pt,
    Technique::Vcm,
    Technique::Upg,
    Technique::UpgCamera,
];

/// Smooth-shaded objects, glass among them: pt, vcm, upg and upg-camera agree with bpt on the
/// whole view; lt (which cannot see through glass) on the view without the glass sphere.
#[test]
fn techniques_agree_on_smooth_shading() {
    agree_with_bpt("smooth", "objects", &ALL_BUT_LT);
    agree_with_bpt("smooth", "upper", &[Technique::Lt]);
}

#[test]
fn techniques_agree_on_textures() {
    let mut all = ALL_BUT_LT.to_vec();
    all.push(Technique::Lt);
    agree_with_bpt("textured", "floor", &all);
}

#[test]
fn techniques_agree_under_the_environment_image() {
    let mut all = ALL_BUT_LT.to_vec();
    all.push(Technique::Lt);
    agree_with_bpt("envmap", "floor", &all);
}

fn load_options() -> LoadOptions {
    LoadOptions {
        accel: AccelKind::default_kind(),
        lenient: false,
        shading_normals: true,
    }
}

fn env_light(scene: &Scene) -> &vmerge::light::EnvLight {
    let index = scene.lights.sky().expect("the scene has a sky");
    match scene.lights.get(index) {
        vmerge::light::Light::Env { env, .. } => env,
        other => panic!("not an environment light: {other:?}"),
    }
}

/// The documented mapping of an image-frame direction to (u, v).
fn direction_uv(w: Vec3) -> (f32, f32) {
    let u = 0.5 + w.x.atan2(-w.z) / (2.0 * std::f32::consts::PI);
    let v = w.y.clamp(-1.0, 1.0).acos() / std::f32::consts::PI;
    (u, v)
}

/// The Wilson-Hilferty approximation of the chi-square quantile with `dof` degrees of freedom
/// at the standard normal quantile `z`.
fn chi_square_quantile(dof: f64, z: f64) -> f64 {
    let a = 2.0 / (9.0 * dof);
    dof * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Directions drawn by the environment light fall into bins of 2 x 2 texels as often as its
/// pdf says: the pdf at each texel centre times the texel's solid angle is the texel's
/// probability (the pdf is constant in (u, v) over a texel), and Pearson's statistic over the
/// bins stays below its 1 - 1e-5 quantile. The pdf integrates to 1 over the sphere, also
/// rotated.
#[test]
fn environment_sampling_matches_its_pdf() {
    let dir = tempfile::tempdir().unwrap();
    let path = write_env_scene(dir.path(), [0.0, 0.0, 0.0]);
    let scene = scene::load(&path, &load_options()).unwrap();
    let env = env_light(&scene);
    let (w, h) = (64usize, 32usize);
    let (bw, bh) = (w / 2, h / 2);
    let mut expected = vec![0.0f64; bw * bh];
    let pi = std::f64::consts::PI;
    for y in 0..h {
        for x in 0..w {
            let (u, v) = ((x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
            let (theta, phi) = (pi * v, 2.0 * pi * (u - 0.5));
            let dirw = Vec3::new(
                (theta.sin() * phi.sin()) as f32,
                theta.cos() as f32,
                (-theta.sin() * phi.cos()) as f32,
            );
            let texel_area = (2.0 * pi / w as f64) * (pi / h as f64) * theta.sin();
            expected[(y / 2) * bw + x / 2] += env.pdf_w(dirw) as f64 * texel_area;
        }
    }
    // Memory: an f32 weight and an f64 CDF entry per texel (one more per row), the marginal.
    let distribution = 12 * w * h + 8 * h + 12 * h + 8;
    assert_eq!(scene.lights.env_distribution_bytes(), distribution);
    let total: f64 = expected.iter().sum();
    assert!(
        (total - 1.0).abs() < 1e-4,
        "texel probabilities sum to {total}"
    );
    let n = 400_000u64;
    let mut counts = vec![0u64; bw * bh];
    let mut rng = vmerge::sampling::Rng::for_sample(7, 0, 0, vmerge::sampling::Stream::Light);
    for _ in 0..n {
        let u = rng.next_2d();
        let (d, radiance, pdf) = env
            .sample(u)
            .unwrap_or_else(|| panic!("no sample for {u:?}"));
        assert!((pdf - env.pdf_w(d)).abs() <= 1e-5 * pdf);
        assert_eq!(radiance, env.radiance(d));
        let (u, v) = direction_uv(d);
        let x = ((u * w as f32) as usize).min(w - 1);
        let y = ((v * h as f32) as usize).min(h - 1);
        counts[(y / 2) * bw + x / 2] += 1;
    }
    let (mut chi2, mut bins) = (0.0, 0usize);
    for (c, p) in counts.iter().zip(&expected) {
        let e = p * n as f64;
        if e >= 5.0 {
            chi2 += (*c as f64 - e).powi(2) / e;
            bins += 1;
        } else {
            assert!(
                *c as f64 <= e + 6.0 * e.sqrt().max(1.0),
                "{c} samples where {e} expected"
            );
        }
    }
    let bound = chi_square_quantile((bins - 1) as f64, 4.265);
    assert!(
        chi2 < bound,
        "chi-square {chi2} over {bins} bins (bound {bound})"
    );

    // The pdf of a rotated image integrates to 1: uniform directions, E[pdf * 4 pi] = 1.
    let rotated = write_env_scene(dir.path(), [20.0, 75.0, -10.0]);
    let scene = scene::load(&rotated, &load_options()).unwrap();
    let env = env_light(&scene);
    let m = 400_000;
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for _ in 0..m {
        let d = vmerge::sampling::uniform_sphere(rng.next_2d());
        let x = env.pdf_w(d) as f64 * 4.0 * pi;
        sum += x;
        sum2 += x * x;
    }
    let mean = sum / m as f64;
    let se = ((sum2 / m as f64 - mean * mean) / m as f64).sqrt();
    assert!(
        (mean - 1.0).abs() < 4.0 * se,
        "pdf integral {mean} (se {se})"
    );
}

/// A scene with the test's own environment image: a sky, a ground and a bright spot.
fn write_env_scene(dir: &Path, rotate_deg: [f32; 3]) -> std::path::PathBuf {
    let (w, h) = (64u32, 32u32);
    let texels = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if (20..22).contains(&x) && (7..9).contains(&y) {
                Rgb::new(400.0, 380.0, 330.0)
            } else if y < h / 2 {
                Rgb::new(0.3 + 0.01 * y as f32, 0.5, 0.9 - 0.005 * x as f32)
            } else {
                Rgb::splat(0.1)
            }
        })
        .collect();
    let image = Texture::new(w, h, texels).unwrap();
    std::fs::write(dir.join("sky.pfm"), write_pfm(&image)).unwrap();
    let obj = format!("{}/scenes/envmap/envmap.obj", env!("CARGO_MANIFEST_DIR"));
    let name = format!(
        "scene-{}-{}-{}.toml",
        rotate_deg[0], rotate_deg[1], rotate_deg[2]
    );
    let path = dir.join(name);
    std::fs::write(
        &path,
        format!(
            r#"[render]
sky = {{ image = "sky.pfm", rotate_deg = {rotate_deg:?} }}
[[camera]]
position = [0.0, 1.0, 3.0]
look_at = [0.0, 0.0, 0.0]
fov = 40.0
[[mesh]]
file = "{obj}"
"#
        ),
    )
    .unwrap();
    path
}

/// At each texel centre (u = (x + 0.5) / w, v = 1 - (y + 0.5) / h) a lookup returns the texel
/// exactly, one period further too (repeat wrap); halfway between two texels it returns their
/// mean.
#[test]
fn texture_lookups_are_exact_at_texel_centres() {
    for (w, h) in [(4u32, 8u32), (3, 5), (16, 16)] {
        let texels: Vec<Rgb> = (0..w * h)
            .map(|i| {
                Rgb::new(
                    i as f32 * 0.37 + 0.1,
                    (i * i) as f32 * 0.013,
                    1.0 / (i as f32 + 1.0),
                )
            })
            .collect();
        let t = Texture::new(w, h, texels).unwrap();
        for y in 0..h {
            for x in 0..w {
                let uv = Vec2::new(
                    (x as f32 + 0.5) / w as f32,
                    1.0 - (y as f32 + 0.5) / h as f32,
                );
                assert_eq!(t.lookup(uv), t.texel(x, y), "{w}x{h} texel ({x}, {y})");
                assert_eq!(
                    t.lookup(uv + Vec2::new(1.0, -2.0)),
                    t.texel(x, y),
                    "{w}x{h} texel ({x}, {y}) one period on"
                );
            }
        }
        let mid = t.lookup(Vec2::new(1.0 / w as f32, 1.0 - 0.5 / h as f32));
        let mean = (t.texel(0, 0) + t.texel(1, 0)) * 0.5;
        assert!(
            close(mid, mean, 1e-5),
            "{w}x{h}: midpoint {mid:?}, mean {mean:?}"
        );
    }
}

/// The furnace (walls emitting 0.5 with albedo 0.5) with the albedo from a constant PFM
/// texture of 0.5 in place of the MTL's kd (the table's own kd, 0.9, must not count): radiance
/// 1 everywhere, for pt, bpt and upg.
#[test]
fn a_furnace_with_a_constant_texture_gives_one() {
    let dir = tempfile::tempdir().unwrap();
    let half = Texture::new(2, 2, vec![Rgb::splat(0.5); 4]).unwrap();
    std::fs::write(dir.path().join("half.pfm"), write_pfm(&half)).unwrap();
    let obj = format!("{}/scenes/furnace/furnace.obj", env!("CARGO_MANIFEST_DIR"));
    let path = dir.path().join("scene.toml");
    std::fs::write(
        &path,
        format!(
            r#"[[camera]]
position = [0.1, -0.2, 0.3]
look_at = [0.5, 0.3, -1.0]
fov = 90.0
[[mesh]]
file = "{obj}"
[material.wall]
kd = [0.9, 0.9, 0.9]
emission = [0.5, 0.5, 0.5]
texture = "half.pfm"
"#
        ),
    )
    .unwrap();
    let scene = scene::load(&path, &load_options()).unwrap();
    for technique in [Technique::Pt, Technique::Bpt, Technique::Upg] {
        let stats = render_stats(&scene, &options(technique, 32), 128);
        stats.assert_furnace(&format!("{technique:?}"), 0.005, 0.002);
    }
}

/// `smooth.obj` without its `vn` statements (faces referring to positions alone).
fn flat_copy(dir: &Path) -> std::path::PathBuf {
    let src = format!("{}/scenes/smooth", env!("CARGO_MANIFEST_DIR"));
    let obj = std::fs::read_to_string(format!("{src}/smooth.obj")).unwrap();
    let flat: Vec<String> = obj
        .lines()
        .filter(|l| !l.starts_with("vn "))
        .map(|l| match l.strip_prefix("f ") {
            Some(refs) => {
                let refs: Vec<&str> = refs
                    .split_whitespace()
                    .map(|r| r.split("//").next().unwrap())
                    .collect();
                format!("f {}", refs.join(" "))
            }
            None => l.to_string(),
        })
        .collect();
    std::fs::write(dir.join("smooth.obj"), flat.join("\n") + "\n").unwrap();
    std::fs::copy(format!("{src}/smooth.mtl"), dir.join("smooth.mtl")).unwrap();
    let toml = std::fs::read_to_string(format!("{src}/scene.toml")).unwrap();
    std::fs::write(dir.join("scene.toml"), &toml).unwrap();
    std::fs::write(
        dir.join("per-mesh.toml"),
        toml.replace(
            "file = \"smooth.obj\"",
            &format!("file = \"{src}/smooth.obj\"\nshading_normals = false"),
        ),
    )
    .unwrap();
    dir.join("scene.toml")
}

fn pixels(scene: &Scene, technique: Technique) -> Vec<[u32; 3]> {
    let o = view(technique, "objects");
    let film = render_iterations(scene, &o, 2).unwrap();
    film.mean()
        .iter()
        .map(|c| c.to_array().map(f32::to_bits))
        .collect()
}

/// With `--no-shading-normals` (and with `shading_normals = false` on the mesh) the smooth
/// scene renders bit for bit as a copy of its mesh without normals, in every technique.
#[test]
fn shading_normals_off_renders_the_flat_mesh_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let flat_path = flat_copy(dir.path());
    let smooth_path = format!("{}/scenes/smooth/scene.toml", env!("CARGO_MANIFEST_DIR"));
    let bvh = |shading_normals| LoadOptions {
        accel: AccelKind::Bvh,
        lenient: false,
        shading_normals,
    };
    let flat = scene::load(&flat_path, &bvh(true)).unwrap();
    let off = scene::load(smooth_path.as_ref(), &bvh(false)).unwrap();
    let per_mesh = scene::load(&dir.path().join("per-mesh.toml"), &bvh(true)).unwrap();
    let on = scene::load(smooth_path.as_ref(), &bvh(true)).unwrap();
    for technique in [
        Technique::Pt,
        Technique::Lt,
        Technique::Bpt,
        Technique::Vcm,
        Technique::Upg,
        Technique::UpgCamera,
    ] {
        let reference = pixels(&flat, technique);
        assert!(
            reference == pixels(&off, technique),
            "{technique:?}: --no-shading-normals"
        );
        assert!(
            reference == pixels(&per_mesh, technique),
            "{technique:?}: per mesh"
        );
        assert!(
            reference != pixels(&on, technique),
            "{technique:?}: normals change nothing"
        );
    }
}

/// Shading normals change the picture, not the light: on the smooth scene's full view the
/// mean radiance with and without them agrees within 5% (the objects are a small part of the
/// image), while the images differ far beyond the noise.
#[test]
fn shading_normals_change_the_shading_not_the_energy() {
    let on = load("smooth");
    let path = format!("{}/scenes/smooth/scene.toml", env!("CARGO_MANIFEST_DIR"));
    let off = scene::load(
        path.as_ref(),
        &LoadOptions {
            shading_normals: false,
            ..load_options()
        },
    )
    .unwrap();
    let a = render_stats(&on, &view(Technique::Bpt, "objects"), 512);
    let b = render_stats(&off, &view(Technique::Bpt, "objects"), 512);
    let (ma, mb) = (a.image_mean(), b.image_mean());
    assert!((ma - mb).abs() < 0.05 * mb, "means {ma} and {mb}");
    assert!(common::standardised_rms(&a, &b) > 1.5);
}

fn close(a: Rgb, b: Rgb, tolerance: f32) -> bool {
    (a.r - b.r).abs() <= tolerance
        && (a.g - b.g).abs() <= tolerance
        && (a.b - b.b).abs() <= tolerance
}

fn write(dir: &Path, name: &str, text: &str) {
    std::fs::write(dir.join(name), text).unwrap();
}

/// A texture file that does not exist: an error naming the MTL, the material's entry and the
/// file; with `lenient` the scene loads and the material keeps its constant colour.
#[test]
fn a_missing_texture_is_named_or_with_lenient_replaced_by_the_colour() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write(
        d,
        "m.mtl",
        "newmtl wall\nKd 0.3 0.4 0.5\nmap_Kd nowhere.png\nKe 1 1 1\n",
    );
    write(
        d,
        "m.obj",
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl wall\nf 1/1 2/2 3/3\n",
    );
    write(
        d,
        "scene.toml",
        "[[camera]]\nposition = [0.2, 0.2, 2.0]\nlook_at = [0.2, 0.2, 0.0]\nfov = 40.0\n[[mesh]]\nfile = \"m.obj\"\n",
    );
    let err = scene::load(&d.join("scene.toml"), &load_options())
        .err()
        .expect("a missing texture is an error");
    let message = err.to_string();
    assert!(matches!(err, SceneError::Invalid { .. }));
    for needle in ["m.mtl", "material 'wall': map_Kd", "nowhere.png"] {
        assert!(message.contains(needle), "'{needle}' not in: {message}");
    }
    let lenient = scene::load(
        &d.join("scene.toml"),
        &LoadOptions {
            lenient: true,
            ..load_options()
        },
    )
    .unwrap();
    let albedo = lenient.albedo(0, Vec2::new(0.3, 0.3));
    assert_eq!(albedo.kd, Rgb::new(0.3, 0.4, 0.5));

    write(
        d,
        "table.toml",
        "[[camera]]\nposition = [0.2, 0.2, 2.0]\nlook_at = [0.2, 0.2, 0.0]\nfov = 40.0\n[[mesh]]\nfile = \"m.obj\"\n[material.wall]\nemission = [1.0, 1.0, 1.0]\ntexture = \"gone.tga\"\n",
    );
    let message = scene::load(&d.join("table.toml"), &load_options())
        .err()
        .expect("a missing texture is an error")
        .to_string();
    for needle in ["table.toml", "material.wall.texture", "gone.tga"] {
        assert!(message.contains(needle), "'{needle}' not in: {message}");
    }
}

/// Textures named twice are decoded once, and the textured scene's texels arrive linear: the
/// checker's light squares (sRGB 230, 230, 220) decode to 0.79, 0.79, 0.72.
#[test]
fn textures_are_shared_and_decoded_from_srgb() {
    let scene = load("textured");
    assert_eq!(scene.textures.len(), 2, "checker.png (twice) and photo.tga");
    let checker = scene
        .textures
        .iter()
        .find(|t| t.width == 8)
        .expect("the 8 x 8 checker");
    let light = checker.texel(0, 0);
    assert!(
        close(light, Rgb::new(0.7913, 0.7913, 0.7159), 1e-3),
        "{light:?}"
    );
}

/// Every supported format decodes to the same linear texels: 8-bit PNG, TGA (and JPEG, lossy)
/// from sRGB, PFM and EXR as stored; an unknown extension is an error that names it.
#[test]
fn textures_decode_png_tga_jpeg_pfm_and_exr() {
    use vmerge::texture::{read, srgb_to_linear};
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (4u32, 3u32);
    let codes: Vec<[u8; 3]> = (0..w * h)
        .map(|i| [(i * 20) as u8, (255 - i * 15) as u8, (i * 7 + 100) as u8])
        .collect();
    let linear: Vec<Rgb> = codes
        .iter()
        .map(|c| {
            Rgb::new(
                srgb_to_linear(c[0] as f32 / 255.0),
                srgb_to_linear(c[1] as f32 / 255.0),
                srgb_to_linear(c[2] as f32 / 255.0),
            )
        })
        .collect();
    let buffer = image::RgbImage::from_fn(w, h, |x, y| image::Rgb(codes[(y * w + x) as usize]));
    for (ext, tolerance) in [("png", 1e-6), ("tga", 1e-6), ("jpg", 0.15)] {
        let path = dir.path().join(format!("t.{ext}"));
        buffer.save(&path).unwrap();
        let t = read(&path).unwrap();
        assert_eq!((t.width, t.height), (w, h), "{ext}");
        for (a, b) in t.texels.iter().zip(&linear) {
            assert!(close(*a, *b, tolerance), "{ext}: {a:?} vs {b:?}");
        }
    }
    let float = Texture::new(w, h, linear.iter().map(|c| *c * 7.5).collect()).unwrap();
    std::fs::write(dir.path().join("t.pfm"), write_pfm(&float)).unwrap();
    assert_eq!(read(&dir.path().join("t.pfm")).unwrap(), float);
    let exr_path = dir.path().join("t.exr");
    vmerge::film::exr::write_image(
        &exr_path,
        &vmerge::film::exr::Image {
            width: w,
            height: h,
            pixels: float.texels.clone(),
        },
    )
    .unwrap();
    assert_eq!(read(&exr_path).unwrap(), float);
    let err = read(&dir.path().join("t.bmp")).unwrap_err();
    assert!(err.contains("bmp"), "{err}");
}
