//! Vertex connection and merging: the furnace for ppm, bpm and vcm, vcm without merging is
//! bpt, and vcm converges to bpt as its radius shrinks; with a merge radius per pixel, the
//! same and the furnace and bpt's image for upg and the density map's weights.

mod common;

use common::{assert_agree, floor_view, load, options, render_stats, PixelStats};
use vmerge::options::{DensityMis, RenderOptions, Technique};

/// Radiance 1 everywhere: within 1% (merging at a radius of 1.5% of the box's side is biased
/// only in the thin bands along its edges), with a standard error below 0.2% so the test can
/// see a 1% error.
#[test]
fn ppm_bpm_and_vcm_pass_the_furnace() {
    assert_merging_furnace(|o| o.radius = Some(0.03));
}

/// ppm, bpm and vcm in the furnace, each with its radius set by `radius`: within 1% of 1, with
/// a standard error below 0.2%.
fn assert_merging_furnace(radius: impl Fn(&mut RenderOptions)) {
    let scene = load("furnace");
    for technique in [Technique::Ppm, Technique::Bpm, Technique::Vcm] {
        let mut o = options(technique, 64);
        radius(&mut o);
        let stats = render_stats(&scene, &o, 256);
        stats.assert_furnace(&format!("{technique:?}"), 0.01, 0.002);
    }
}

/// With merging off, vcm's weights are bpt's (001 sec. 5.5): the same image within noise.
#[test]
fn vcm_without_merging_is_bpt() {
    let scene = load("cornell-box");
    let bpt = render_stats(&scene, &floor_view(Technique::Bpt, 32), 2048);
    let mut o = floor_view(Technique::Vcm, 32);
    o.no_vm = true;
    let vcm = render_stats(&scene, &o, 2048);
    assert_agree("vcm --no-vm vs bpt", &vcm, &bpt);
}

/// vcm with a shrinking radius (alpha = 0.75) approaches bpt's image: the image mean within 1%
/// of it, and the RMS difference falls as iterations grow (bias and noise both shrink).
#[test]
fn vcm_converges_to_bpt() {
    for name in ["cornell-spheres", "cornell-glossy"] {
        let scene = load(name);
        let bpt = render_stats(&scene, &floor_view(Technique::Bpt, 32), 2048);
        let short = render_stats(&scene, &floor_view(Technique::Vcm, 32), 64);
        let long = render_stats(&scene, &floor_view(Technique::Vcm, 32), 1024);
        let (m, r) = (long.image_mean(), bpt.image_mean());
        assert!((m - r).abs() < 0.01 * r, "{name}: vcm mean {m}, bpt {r}");
        let (early, late) = (short.rms_difference(&bpt), long.rms_difference(&bpt));
        assert!(
            late < 0.5 * early,
            "{name}: RMS difference {early} -> {late}"
        );
    }
}

/// The caustic under the glass sphere of `caustic`, seen through the sphere, is lit along
/// light-specular-specular-diffuse-specular-specular-eye paths from a point light: no
/// connection can sample them (every connection needs two non-specular ends), merging can.
/// Over the pixels that look through the sphere at the floor in its shadow, where the caustic
/// lies, vcm must be brighter than bpt by far more than the noise; over the pixels that see no
/// glass at all, the two agree in the mean.
#[test]
fn vcm_renders_the_caustic_seen_through_the_glass() {
    use vmerge::accel::Ray;
    use vmerge::bsdf::{Bsdf, MaterialKind, TransportMode};
    let scene = load("caustic");
    let size = 32;
    let bpt = render_stats(&scene, &floor_view(Technique::Bpt, size), 1024);
    let vcm = render_stats(&scene, &floor_view(Technique::Vcm, size), 1024);
    let camera = vmerge::scene::Camera::new(scene.camera(Some("floor")).unwrap(), size, size);
    let is_glass =
        |material: u32| matches!(scene.material(material).kind, MaterialKind::Glass { .. });
    // Follows a pixel's centre ray through the glass by refraction (the ray most of the
    // pixel's light takes) to the first diffuse surface: (saw glass, where it ended).
    let follow = |pixel: usize| {
        let (x, y) = (
            (pixel % size as usize) as f32,
            (pixel / size as usize) as f32,
        );
        let mut ray = camera.generate_ray(x + 0.5, y + 0.5);
        let mut through_glass = false;
        for _ in 0..8 {
            let hit = scene.intersect(&ray)?;
            if !is_glass(hit.material) {
                return Some((through_glass, hit.position));
            }
            through_glass = true;
            let kind = &scene.material(hit.material).kind;
            let bsdf = Bsdf::new(kind, hit.ng, -ray.dir.normalize(), TransportMode::Radiance)?;
            let refracted = bsdf.sample([0.9999, 0.5, 0.5])?;
            ray = Ray::spawn(hit.position, hit.ng, refracted.wi);
        }
        None
    };
    // The light at (0, 1.2, 1) shines through the sphere's centre (0, 0.45, 0) onto the floor
    // around (0, 0, -0.6), where the glass focuses it; seen through the sphere, which magnifies
    // what lies behind it, that floor fills most of the sphere's pixels.
    let ends: Vec<_> = (0..(size * size) as usize).map(follow).collect();
    let caustic: Vec<usize> = (0..ends.len())
        .filter(|&i| {
            ends[i].is_some_and(|(glass, p)| {
                glass && p.y.abs() < 1e-3 && p.x * p.x + (p.z + 0.6) * (p.z + 0.6) < 0.5 * 0.5
            })
        })
        .collect();
    let clear: Vec<usize> = (0..ends.len())
        .filter(|&i| ends[i].is_some_and(|(glass, _)| !glass))
        .collect();
    assert!(caustic.len() >= 10, "{} caustic pixels", caustic.len());
    let window = |stats: &PixelStats, pixels: &[usize]| {
        let n = pixels.len() as f64;
        let mean = pixels.iter().map(|&i| stats.mean[i]).sum::<f64>() / n;
        let var = pixels.iter().map(|&i| stats.var_of_mean[i]).sum::<f64>() / (n * n);
        (mean, var)
    };
    let ((v, v_var), (b, b_var)) = (window(&vcm, &caustic), window(&bpt, &caustic));
    let se = (v_var + b_var).sqrt();
    assert!(
        v - b > 6.0 * se && v > 1.5 * b,
        "through the glass ({} pixels): vcm {v}, bpt {b} (se {se})",
        caustic.len()
    );
    let ((v, v_var), (b, b_var)) = (window(&vcm, &clear), window(&bpt, &clear));
    let se = (v_var + b_var).sqrt();
    assert!(
        (v - b).abs() < (0.02 * b).max(4.0 * se),
        "elsewhere: vcm {v}, bpt {b} (se {se})"
    );
}

/// Every shipped scene, through every camera, keeps the bounding-sphere default radius
/// (0.003 x its diameter): the view rule only takes over where the bounds dwarf the view.
#[test]
fn shipped_scenes_keep_the_bounding_sphere_default_radius() {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| {
            let path = e.ok()?.path();
            path.join("scene.toml")
                .exists()
                .then(|| path.file_name()?.to_str().map(String::from))?
        })
        .collect();
    names.sort();
    assert!(names.len() > 10, "{names:?}");
    for name in names {
        let scene = load(&name);
        if scene.defaults.radius.is_some() {
            continue;
        }
        let [w, h] = scene.defaults.resolution;
        for desc in &scene.cameras {
            let camera = vmerge::scene::Camera::new(desc, w, h);
            assert_eq!(
                scene.default_radius(&camera),
                0.003 * 2.0 * scene.bounding_sphere.1,
                "{name}, camera {}",
                desc.name
            );
        }
    }
}

/// The furnace with a merge radius per pixel (001 sec. 6.1): one pixel footprint at the first
/// non-specular eye vertex, about the global radius of the test above. Within 1%, with a
/// standard error below 0.2%.
#[test]
fn per_pixel_radius_passes_the_furnace() {
    assert_merging_furnace(|o| o.radius_pixels = Some(1.0));
}

/// Per-pixel radii where light sub-paths cannot carry radius-free sums and re-run their MIS
/// steps at every eye sub-path's radius instead: upg (clamped acceptance, 000 eq. 2.80), vcm
/// with 002's VCM* (density factors) and upg-camera with both in the furnace, within 1% with a
/// standard error below 0.2%. Two pixel footprints, so that the density map's k exceeds 1 in
/// places.
#[test]
fn per_pixel_radius_with_upg_and_the_density_map_passes_the_furnace() {
    let scene = load("furnace");
    for (technique, density) in [
        (Technique::Upg, None),
        (Technique::Vcm, Some(DensityMis::Star)),
        (Technique::UpgCamera, Some(DensityMis::Star)),
    ] {
        let mut o = options(technique, 32);
        o.radius_pixels = Some(2.0);
        o.density_mis = density;
        let stats = render_stats(&scene, &o, 128);
        stats.assert_furnace(&format!("{technique:?} {density:?}"), 0.01, 0.002);
    }
}

/// upg is unbiased at any radius, so with a radius per pixel too: per pixel, its image agrees
/// with bpt's (the statistic of the BPT tests: means and the standardised difference). On
/// `closeup` the footprints differ twentyfold across the view, so an eye sub-path's radius is
/// far from the first iteration's median one the light sub-paths are traced with; weighing
/// them at that radius instead of re-running them at the eye's moves the standardised
/// difference to about 3.
#[test]
fn upg_with_per_pixel_radii_agrees_with_bpt() {
    let scene = load("closeup");
    let bpt = render_stats(&scene, &options(Technique::Bpt, 16), 8192);
    let mut o = options(Technique::Upg, 16);
    o.radius_pixels = Some(1.0);
    let upg = render_stats(&scene, &o, 4096);
    assert_agree("upg --radius-pixels 1 vs bpt", &upg, &bpt);
}

/// vcm with per-pixel radii shrinking (alpha = 0.75) approaches bpt's image as the global
/// radius does (`vcm_converges_to_bpt`): the mean within 1%, the RMS difference falling. The
/// spheres' mirror and glass put specular vertices before the first non-specular one.
#[test]
fn vcm_with_per_pixel_radii_converges_to_bpt() {
    let scene = load("cornell-spheres");
    let bpt = render_stats(&scene, &floor_view(Technique::Bpt, 32), 2048);
    let mut o = floor_view(Technique::Vcm, 32);
    o.radius_pixels = Some(0.25);
    let short = render_stats(&scene, &o, 64);
    let long = render_stats(&scene, &o, 1024);
    let (m, r) = (long.image_mean(), bpt.image_mean());
    assert!((m - r).abs() < 0.01 * r, "vcm mean {m}, bpt {r}");
    let (early, late) = (short.rms_difference(&bpt), long.rms_difference(&bpt));
    assert!(late < 0.5 * early, "RMS difference {early} -> {late}");
}

/// A 10 m room on a 221 m ground plane (Bitterli's classroom has these proportions): the
/// bounding-sphere rule would merge at a radius set by the plane, and the default takes the
/// camera's view instead, within a factor 2 of 0.003 x the room's diagonal.
#[test]
fn a_room_on_a_huge_ground_plane_gets_a_default_radius_of_the_room() {
    let dir = tempfile::tempdir().unwrap();
    let (lo, hi) = ([-5.0f32, 0.0, -4.0], [5.0f32, 3.0, 4.0]);
    let mut obj = String::from("mtllib room.mtl\nusemtl white\n");
    // The room's eight corners, then its six faces, then the ground's four corners.
    for i in 0..8 {
        let c = |axis: usize| {
            if i >> axis & 1 == 0 {
                lo[axis]
            } else {
                hi[axis]
            }
        };
        obj += &format!("v {} {} {}\n", c(0), c(1), c(2));
    }
    for [a, b, c, d] in [
        [1, 3, 7, 5],
        [2, 6, 8, 4],
        [1, 5, 6, 2],
        [3, 4, 8, 7],
        [1, 2, 4, 3],
        [5, 7, 8, 6],
    ] {
        obj += &format!("f {a} {b} {c}\nf {a} {c} {d}\n");
    }
    let g = 110.5;
    for (x, z) in [(-g, -g), (g, -g), (g, g), (-g, g)] {
        obj += &format!("v {x} -0.01 {z}\n");
    }
    obj += "f 9 12 11\nf 9 11 10\n";
    std::fs::write(dir.path().join("room.obj"), obj).unwrap();
    std::fs::write(
        dir.path().join("room.mtl"),
        "newmtl white\nKd 0.5 0.5 0.5\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("scene.toml"),
        r#"
[render]
resolution = [64, 64]

[[camera]]
name = "inside"
position = [0.0, 1.5, 3.5]
look_at = [0.0, 1.2, -4.0]
up = [0.0, 1.0, 0.0]
fov = 60.0

[[mesh]]
file = "room.obj"

[[light]]
type = "point"
position = [0.0, 2.5, 0.0]
intensity = [10.0, 10.0, 10.0]
"#,
    )
    .unwrap();
    let options = vmerge::scene::LoadOptions {
        accel: vmerge::accel::AccelKind::default_kind(),
        lenient: false,
        shading_normals: true,
    };
    let scene = vmerge::scene::load(&dir.path().join("scene.toml"), &options).unwrap();
    let camera = vmerge::scene::Camera::new(&scene.cameras[0], 64, 64);
    let room = 0.003 * glam::Vec3::from(hi).distance(glam::Vec3::from(lo));
    let bounding = 0.003 * 2.0 * scene.bounding_sphere.1;
    assert!(
        bounding > 10.0 * room,
        "bounding rule {bounding}, room {room}"
    );
    let radius = scene.default_radius(&camera);
    assert!(
        radius < 2.0 * room && radius > 0.5 * room,
        "default radius {radius}, room {room}, bounding rule {bounding}"
    );
}

/// The statistics an EXR records name the radius mode: global, or per pixel with its factor,
/// and the first radius, K times the median pixel footprint.
#[test]
fn statistics_report_the_radius_mode() {
    use vmerge::integrator::RenderContext;
    let scene = load("furnace");
    for (radius_pixels, mode) in [
        (None, "global"),
        (Some(2.0), "per-pixel, 2 pixel footprints"),
    ] {
        let mut o = options(Technique::Vcm, 16);
        o.radius_pixels = radius_pixels;
        let camera = vmerge::scene::Camera::new(scene.camera(None).unwrap(), 16, 16);
        let integrator = vmerge::render::create_integrator(RenderContext {
            scene: &scene,
            camera: camera.clone(),
            options: &o,
        });
        let stats = integrator.statistics(std::time::Duration::from_secs(1));
        let get = |key: &str| {
            stats
                .iter()
                .find(|(k, _)| k == key)
                .map(|(_, v)| v.clone())
                .unwrap_or_else(|| panic!("no {key} in {stats:?}"))
        };
        assert_eq!(get("radius_mode"), mode);
        let base: f32 = get("base_radius").parse().unwrap();
        match radius_pixels {
            // The furnace is seen from inside: the median footprint lies between those of the
            // pixels nearest and farthest from the walls, the corners and the centre.
            Some(k) => {
                let footprint = |x: f32, y: f32| {
                    let ray = camera.generate_ray(x, y);
                    let t = scene.intersect(&ray).unwrap().hit.t * ray.dir.length();
                    k * t / camera.pdf_w(ray.dir).sqrt()
                };
                let samples = [
                    footprint(0.5, 0.5),
                    footprint(15.5, 15.5),
                    footprint(8.0, 8.0),
                ];
                let lo = samples.iter().copied().fold(f32::MAX, f32::min);
                let hi = samples.iter().copied().fold(0.0, f32::max);
                assert!(base > 0.5 * lo && base < 2.0 * hi, "{base} vs {lo}..{hi}");
            }
            None => assert_eq!(base, scene.default_radius(&camera)),
        }
    }
}
