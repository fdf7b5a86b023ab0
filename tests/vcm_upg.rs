mod common;

use common::{floor_view, load, render_stats, PixelStats};
use vmerge::options::Technique;

fn map(label: &str, a: &PixelStats, b: &PixelStats, size: usize) {
    println!("{label}");
    for y in 0..size {
        let row: String = (0..size)
            .map(|x| {
                let i = y * size + x;
                let z = (a.mean[i] - b.mean[i]) / (a.var_of_mean[i] + b.var_of_mean[i]).sqrt().max(1e-12);
                match z {
                    z if z > 6.0 => '#',
                    z if z > 3.0 => '+',
                    z if z < -6.0 => '@',
                    z if z < -3.0 => '-',
                    _ => '.',
                }
            })
            .collect();
        println!("{row}");
    }
}

fn sq_bias(a: &PixelStats, b: &PixelStats) -> (f64, f64) {
    let mut s = 0.0;
    let mut v = 0.0;
    for i in 0..a.mean.len() {
        let d = a.mean[i] - b.mean[i];
        let var = a.var_of_mean[i] + b.var_of_mean[i];
        s += d * d - var;
        v += 2.0 * var * var + 4.0 * d * d * var;
    }
    (s, v.sqrt())
}

#[test]
#[ignore]
fn explore() {
    let scene = load("corners");
    let size = 24;
    let t = std::time::Instant::now();
    let bpt = render_stats(&scene, &floor_view(Technique::Bpt, size), 2048);
    println!("bpt {:?}", t.elapsed());
    for radius in [0.08f32, 0.15] {
    for (technique, near, far) in [(Technique::Vcm, 2.0, 6.0), (Technique::VcmUpg, 2.0, 6.0), (Technique::VcmUpg, 1000.0, 2000.0)] {
        let mut o = floor_view(technique, size);
        o.radius = Some(radius);
        o.alpha = Some(1.0);
        if technique == Technique::VcmUpg {
            o.blend_near = near;
            o.blend_far = far;
        }
        let t = std::time::Instant::now();
        let s = render_stats(&scene, &o, 1024);
        println!("r {radius} {technique:?} {near} {far} {:?} mean {} bpt {} sqbias {:?}", t.elapsed(), s.image_mean(), bpt.image_mean(), sq_bias(&s, &bpt));
        { map(&format!("{technique:?}"), &s, &bpt, size as usize); }
    }
    }
}
