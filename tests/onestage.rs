//! One-stage vertex merging (`memory = one-stage`, 001 sec. 6.2): the same image as two-stage
//! in expectation, and the same image for any thread count.

mod common;

use common::{assert_agree, floor_view, load, render_stats_by_seed};
use vmerge::color::Rgb;
use vmerge::integrator::RenderContext;
use vmerge::options::{MemoryLayout, RenderOptions, Technique};
use vmerge::render::create_integrator;
use vmerge::scene::{Camera, Scene};

/// Few iterations per render (8), each render from its own seed, so the first iteration (merging
/// with light sub-paths traced for it alone) and, for vcm, the radius shrinking fast from one
/// iteration to the next (the stored vertices' merge terms re-weighed) weigh in every batch; a large
/// radius gives the merges a large share of the image.
fn options(technique: Technique, memory: MemoryLayout) -> RenderOptions {
    RenderOptions {
        radius: Some(0.06),
        alpha: (technique == Technique::Vcm).then_some(0.25),
        memory,
        seed: if memory == MemoryLayout::OneStage {
            10_000
        } else {
            0
        },
        ..floor_view(technique, 32)
    }
}

#[test]
fn one_stage_agrees_with_two_stage() {
    let scene = load("cornell-box");
    for technique in [Technique::Vcm, Technique::Bpm] {
        let two = render_stats_by_seed(&scene, &options(technique, MemoryLayout::TwoStage), 8);
        let one = render_stats_by_seed(&scene, &options(technique, MemoryLayout::OneStage), 8);
        assert_agree(&format!("{technique:?} one-stage vs two-stage"), &one, &two);
    }
}

/// The sum of `iterations` iterations on `threads` worker threads.
fn render_on(scene: &Scene, o: &RenderOptions, iterations: u64, threads: usize) -> Vec<Rgb> {
    let [w, h] = o.resolution.expect("a resolution");
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool");
    pool.install(|| {
        let camera = Camera::new(scene.camera(o.camera.as_deref()).unwrap(), w, h);
        let mut integrator = create_integrator(RenderContext {
            scene,
            camera,
            options: o,
        });
        let mut sum = vec![Rgb::BLACK; (w * h) as usize];
        let mut frame = sum.clone();
        for iteration in 0..iterations {
            frame.fill(Rgb::BLACK);
            integrator.render_iteration(iteration, &mut frame);
            for (s, f) in sum.iter_mut().zip(&frame) {
                *s += *f;
            }
        }
        sum
    })
}

/// More pixels than one wave of tasks, so the camera splats of several waves meet.
#[test]
fn one_stage_image_does_not_depend_on_threads() {
    let scene = load("cornell-box");
    let o = RenderOptions {
        resolution: Some([320, 240]),
        memory: MemoryLayout::OneStage,
        ..common::options(Technique::Vcm, 1)
    };
    let one = render_on(&scene, &o, 2, 1);
    let two = render_on(&scene, &o, 2, 2);
    let differ = one.iter().zip(&two).filter(|(a, b)| a != b).count();
    assert_eq!(differ, 0, "{differ} pixels differ between 1 and 2 threads");
    assert!(one.iter().any(|c| c.average() > 0.0));
}

/// A continued render retraces the light sub-paths its next iteration merges with: its
/// iteration is the uninterrupted render's, bit for bit.
#[test]
fn a_continued_one_stage_render_is_the_uninterrupted_one() {
    let scene = load("cornell-box");
    let o = options(Technique::Vcm, MemoryLayout::OneStage);
    let [w, h] = o.resolution.expect("a resolution");
    let integrator = || {
        let camera = Camera::new(scene.camera(o.camera.as_deref()).unwrap(), w, h);
        create_integrator(RenderContext {
            scene: &scene,
            camera,
            options: &o,
        })
    };
    let mut frame = vec![Rgb::BLACK; (w * h) as usize];
    let mut whole = integrator();
    for iteration in 0..3 {
        frame.fill(Rgb::BLACK);
        whole.render_iteration(iteration, &mut frame);
    }
    let mut continued = vec![Rgb::BLACK; frame.len()];
    integrator().render_iteration(2, &mut continued);
    assert_eq!(continued, frame);
    assert!(frame.iter().any(|c| c.average() > 0.0));
}
