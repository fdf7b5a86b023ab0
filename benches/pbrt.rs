//! Loading Bitterli's pbrt-v4 scenes (../shared/scenes/bitterli/): the whole load of each scene
//! (parse, PLY meshes read in parallel, import, ray-query build), and the PLY decoder against
//! `ply-rs-bw`'s element reader (typed `PropertyAccess` structs, its fastest path) on every
//! PLY file of the scenes, single-threaded, in interleaved rounds.
//!
//! Run: `cargo bench --bench pbrt`.

use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{BeginList, PropertyAccess, PropertyAccessResult};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;
use vmerge::accel::AccelKind;
use vmerge::scene::{self, LoadOptions};

const SCENES: [&str; 5] = [
    "veach-bidir",
    "veach-ajar",
    "dining-room",
    "living-room",
    "salle-de-bain",
];
const ROUNDS: usize = 5;

#[derive(Default)]
struct Vertex([f32; 8]);

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Self::default()
    }
    fn set_float(&mut self, name: &str, value: f32) -> PropertyAccessResult {
        let k = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            "nx" => 3,
            "ny" => 4,
            "nz" => 5,
            "u" => 6,
            "v" => 7,
            _ => return PropertyAccessResult::Ignored,
        };
        self.0[k] = value;
        PropertyAccessResult::Set
    }
}

#[derive(Default)]
struct Face(Vec<i32>);

impl PropertyAccess for Face {
    fn new() -> Self {
        Self::default()
    }
    fn begin_list_int(&mut self, name: &str, _len: usize) -> BeginList<'_, i32> {
        match name {
            "vertex_indices" => BeginList::Fill(&mut self.0),
            _ => BeginList::UnsupportedType,
        }
    }
}

/// Triangles of a PLY file by ply-rs-bw (quads split, as vmerge does).
fn crate_triangles(bytes: &[u8]) -> usize {
    let mut reader = ply_rs_bw::parser::Reader::new(bytes);
    let vertex_parser = Parser::<Vertex>::new();
    let face_parser = Parser::<Face>::new();
    let header = vertex_parser.read_header(&mut reader).expect("header");
    let mut triangles = 0;
    for (name, element) in &header.elements {
        match name.as_str() {
            "vertex" => {
                let v = vertex_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .expect("vertices");
                black_box(&v);
            }
            "face" => {
                let f = face_parser
                    .read_payload_for_element(&mut reader, element, &header)
                    .expect("faces");
                triangles += f.iter().map(|f| f.0.len().saturating_sub(2)).sum::<usize>();
            }
            _ => panic!("unexpected element {name}"),
        }
    }
    triangles
}

fn main() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/bitterli");
    if !root.exists() {
        eprintln!("skipping: {} is absent", root.display());
        return;
    }
    println!(
        "whole load, best of {ROUNDS} (s): scene, parts (parse + meshes + import), + embree build"
    );
    for name in SCENES {
        let path = root.join(name).join("scene-v4.pbrt");
        let options = LoadOptions {
            accel: AccelKind::default_kind(),
            lenient: true,
            shading_normals: true,
        };
        let (mut parts_s, mut total_s) = (f64::MAX, f64::MAX);
        for _ in 0..ROUNDS {
            let t = Instant::now();
            let parts = scene::load_parts(&path, &options).expect("loads");
            parts_s = parts_s.min(t.elapsed().as_secs_f64());
            let t = Instant::now();
            black_box(scene::Scene::build(parts, options.accel).expect("builds"));
            total_s = total_s.min(parts_s + t.elapsed().as_secs_f64());
        }
        println!("{name}: {parts_s:.3} {total_s:.3}");
    }
    let mut files: Vec<PathBuf> = Vec::new();
    for name in SCENES {
        let dir = root.join(name).join("models");
        let mut these: Vec<_> = std::fs::read_dir(&dir)
            .expect("models folder")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.extension().is_some_and(|e| e == "ply"))
            .collect();
        these.sort();
        files.extend(these);
    }
    let data: Vec<Vec<u8>> = files
        .iter()
        .map(|f| std::fs::read(f).expect("readable"))
        .collect();
    let mb = data.iter().map(Vec::len).sum::<usize>() as f64 / 1e6;
    let (mut ours, mut theirs) = (Vec::new(), Vec::new());
    let mut triangles = (0, 0);
    for _ in 0..ROUNDS {
        let t = Instant::now();
        triangles.0 = data
            .iter()
            .map(|d| scene::pbrt::ply::parse(d).expect("parses").triangles.len())
            .sum::<usize>();
        ours.push(t.elapsed().as_secs_f64());
        let t = Instant::now();
        triangles.1 = data.iter().map(|d| crate_triangles(d)).sum::<usize>();
        theirs.push(t.elapsed().as_secs_f64());
    }
    assert_eq!(
        triangles.0, triangles.1,
        "both readers see the same triangles"
    );
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (a, b) = (median(&mut ours), median(&mut theirs));
    println!(
        "PLY, {} files, {mb:.1} MB, {} triangles, one thread, median of {ROUNDS}: vmerge {a:.3} s, \
         ply-rs-bw elements {b:.3} s, ratio {:.2}",
        files.len(),
        triangles.0,
        b / a
    );
}
