//! pbrt-v4's `disk` and `cylinder`, tessellated into triangle meshes in object space, with
//! the uvs and normals pbrt defines for them.
//!
//! Tessellated rather than intersected analytically: as meshes they are lights, textured
//! surfaces and occluders in both ray-query backends and in every technique without new code.
//! The image cannot tell, because (1) the angular step is at most [`MAX_STEP`]: an inscribed
//! polygon with that step has an area error 1 - sin(d)/d < 1e-4, and the outline lies within
//! d^2/12 (about 5e-5) of the radius once rescaled; and (2) the radii are rescaled so that the
//! tessellated area equals the analytic one exactly, so an emitter's power is right.

use super::ply::PlyMesh;

/// The largest angular step (radians): 1 - sin(d)/d = 1e-4 at d = 0.0245.
const MAX_STEP: f64 = 0.0245;

/// pbrt-v4's `disk`: at z = `height`, between radii `inner` and `radius`, from phi = 0 to
/// `phimax` radians; normal +z, u = phi / phimax, v = (radius - r) / (radius - inner).
pub(super) fn disk(radius: f64, inner: f64, height: f64, phimax: f64) -> PlyMesh {
    let (n, step) = steps(phimax);
    // A polygon sector of step d has area r^2 sin(d) / 2 against the circle's r^2 d / 2.
    let s = (step / step.sin()).sqrt();
    let mut mesh = PlyMesh {
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        triangles: Vec::new(),
    };
    let mut vertex = |r: f64, phi: f64, v: f64| {
        let i = mesh.positions.len() as u32;
        let (sin, cos) = phi.sin_cos();
        mesh.positions
            .push([(s * r * cos) as f32, (s * r * sin) as f32, height as f32]);
        mesh.normals.push([0.0, 0.0, 1.0]);
        mesh.uvs.push([(phi / phimax) as f32, v as f32]);
        i
    };
    let rim: Vec<u32> = (0..=n)
        .map(|k| vertex(radius, k as f64 * step, 0.0))
        .collect();
    if inner > 0.0 {
        let hole: Vec<u32> = (0..=n)
            .map(|k| vertex(inner, k as f64 * step, 1.0))
            .collect();
        for k in 0..n {
            mesh.triangles.push([hole[k], rim[k], rim[k + 1]]);
            mesh.triangles.push([hole[k], rim[k + 1], hole[k + 1]]);
        }
    } else {
        // One centre vertex per sector, with the sector's mid u, so u does not sweep
        // across a whole sector at the centre.
        let centres: Vec<u32> = (0..n)
            .map(|k| vertex(0.0, (k as f64 + 0.5) * step, 1.0))
            .collect();
        for k in 0..n {
            mesh.triangles.push([centres[k], rim[k], rim[k + 1]]);
        }
    }
    mesh
}

/// pbrt-v4's `cylinder`: around the z axis from `zmin` to `zmax`, from phi = 0 to `phimax`
/// radians; normal outwards, u = phi / phimax, v = (z - zmin) / (zmax - zmin).
pub(super) fn cylinder(radius: f64, zmin: f64, zmax: f64, phimax: f64) -> PlyMesh {
    let (n, step) = steps(phimax);
    // A chord of step d is 2 r sin(d/2) long against the arc's r d.
    let r = radius * (0.5 * step) / (0.5 * step).sin();
    let mut mesh = PlyMesh {
        positions: Vec::new(),
        normals: Vec::new(),
        uvs: Vec::new(),
        triangles: Vec::new(),
    };
    for k in 0..=n {
        let phi = k as f64 * step;
        let (sin, cos) = phi.sin_cos();
        for (z, v) in [(zmin, 0.0), (zmax, 1.0)] {
            mesh.positions
                .push([(r * cos) as f32, (r * sin) as f32, z as f32]);
            mesh.normals.push([cos as f32, sin as f32, 0.0]);
            mesh.uvs.push([(phi / phimax) as f32, v]);
        }
    }
    for k in 0..n as u32 {
        let [b0, t0, b1, t1] = [2 * k, 2 * k + 1, 2 * k + 2, 2 * k + 3];
        mesh.triangles.push([b0, b1, t1]);
        mesh.triangles.push([b0, t1, t0]);
    }
    mesh
}

/// The number of equal angular steps over `phimax` radians, and the step.
fn steps(phimax: f64) -> (usize, f64) {
    let n = (phimax / MAX_STEP).ceil().max(1.0) as usize;
    (n, phimax / n as f64)
}

/// The same mesh facing the other way: pbrt flips a quadric's normal under
/// ReverseOrientation and under a transform that swaps handedness.
pub(super) fn flipped(mesh: &PlyMesh) -> PlyMesh {
    PlyMesh {
        positions: mesh.positions.clone(),
        normals: mesh.normals.iter().map(|n| n.map(|c| -c)).collect(),
        uvs: mesh.uvs.clone(),
        triangles: mesh.triangles.clone(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use std::f64::consts::TAU;

    fn area(mesh: &PlyMesh) -> f64 {
        mesh.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| Vec3::from_array(mesh.positions[i as usize]).as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    #[test]
    fn areas_are_exact_and_outlines_close() {
        let half = std::f64::consts::PI;
        for (phimax, inner) in [(TAU, 0.0), (TAU, 0.4), (0.75 * TAU, 0.25), (0.01, 0.0)] {
            let m = disk(2.0, inner, 0.5, phimax);
            let exact = 0.5 * phimax * (4.0 - inner * inner);
            assert!(
                (area(&m) / exact - 1.0).abs() < 1e-6,
                "disk {phimax} {inner}"
            );
            for (p, uv) in m.positions.iter().zip(&m.uvs) {
                let r = Vec3::new(p[0], p[1], 0.0).length() as f64;
                // v = (radius - r) / (radius - inner) as pbrt defines it.
                let v = (2.0 - r) / (2.0 - inner);
                assert!((v - uv[1] as f64).abs() < 1e-4, "{r} {uv:?}");
                assert!(p[2] == 0.5 && (0.0..=1.0).contains(&uv[0]));
            }
            let c = cylinder(2.0, -1.0, 0.5, phimax);
            let exact = phimax * 2.0 * 1.5;
            assert!((area(&c) / exact - 1.0).abs() < 1e-6, "cylinder {phimax}");
        }
        assert_eq!(steps(TAU).0, 257);
        // Winding: counter-clockwise seen from the normals' side.
        for m in [disk(1.0, 0.0, 0.0, half), cylinder(1.0, 0.0, 1.0, half)] {
            for t in &m.triangles {
                let [a, b, c] = t.map(|i| Vec3::from_array(m.positions[i as usize]));
                let n = Vec3::from_array(m.normals[t[0] as usize]);
                assert!((b - a).cross(c - a).dot(n) > 0.0);
            }
        }
        let f = flipped(&disk(1.0, 0.0, 0.0, half));
        assert!(f.normals.iter().all(|n| n[2] == -1.0));
    }
}
