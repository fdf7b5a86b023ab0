//! Path-tracing throughput (samples per second) on the default Cornell box and on a large real
//! mesh (the 331k-triangle conference room from ../shared/scenes, skipped when absent), with
//! each ray-query backend. Run: `cargo bench --bench render`.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::path::Path;
use std::time::Duration;
use vmerge::accel::AccelKind;
use vmerge::color::Rgb;
use vmerge::integrator::RenderContext;
use vmerge::options::RenderOptions;
use vmerge::options::Technique;
use vmerge::render::create_integrator;
use vmerge::scene::Camera;

mod common;
use common::load_scene;

const SIZE: u32 = 128;

fn bench_scene(c: &mut Criterion, name: &str, path: &Path) {
    let mut kinds = vec![AccelKind::Bvh];
    if cfg!(feature = "embree") {
        kinds.insert(0, AccelKind::Embree);
    }
    let Some(scenes) = kinds
        .into_iter()
        .map(|accel| load_scene(name, path, accel).map(|scene| (accel, scene)))
        .collect::<Option<Vec<_>>>()
    else {
        return;
    };
    let mut group = c.benchmark_group(format!("pt/{name}"));
    group.throughput(Throughput::Elements((SIZE * SIZE) as u64));
    group
        .sample_size(10)
        .measurement_time(Duration::from_secs(10));
    for (accel, scene) in &scenes {
        let options = RenderOptions {
            technique: Technique::Pt,
            resolution: Some([SIZE, SIZE]),
            ..Default::default()
        };
        let camera = Camera::new(scene.camera(None).expect("camera"), SIZE, SIZE);
        let mut pt = create_integrator(RenderContext {
            scene,
            camera,
            options: &options,
        });
        let mut frame = vec![Rgb::BLACK; (SIZE * SIZE) as usize];
        let mut iteration = 0;
        group.bench_function(accel.name(), |b| {
            b.iter(|| {
                frame.fill(Rgb::BLACK);
                pt.render_iteration(iteration, &mut frame);
                iteration += 1;
            })
        });
    }
    group.finish();
}

fn benches(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    bench_scene(
        c,
        "cornell-box",
        &root.join("scenes/cornell-box/scene.toml"),
    );
    bench_scene(
        c,
        "conference",
        &root.join("benches/scenes/conference.toml"),
    );
}

criterion_group! {
    name = render;
    // Criterion's charts need a system font stack the project does not depend on.
    config = Criterion::default().without_plots();
    targets = benches
}
criterion_main!(render);
