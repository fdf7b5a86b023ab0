//! FLIP, NVIDIA's perceptual difference of a test image from a reference as seen by a viewer
//! flipping between the two: LDR-FLIP (Andersson, Nilsson, Akenine-Möller, Oskarsson, Åström
//! and Fairchild, "FLIP: A Difference Evaluator for Alternating Images", HPG 2020) and HDR-FLIP
//! (Andersson, Nilsson, Shirley and Akenine-Möller, "Visualizing Errors in Rendered High
//! Dynamic Range Images", Eurographics 2021 short papers). The result is the mean of a
//! per-pixel error in [0, 1]: 0 for identical images.
//!
//! LDR-FLIP of two linear RGB images in [0, 1], per pixel:
//! - colour pipeline: both images in the opponent space YCxCz are filtered with the contrast
//!   sensitivity functions of the achromatic, red-green and blue-yellow channels (sums of
//!   Gaussians, 2020 eqs. 2-3) for `ppd` pixels per degree of visual angle, mapped back to
//!   linear RGB clamped to [0, 1], then to CIELAB with the Hunt adjustment (a, b scaled by
//!   0.01 L); the HyAB distance |dL| + ||(da, db)|| raised to q_c = 0.7 is mapped to [0, 1] by
//!   the piecewise linear map that sends p_c c_max to p_t (p_c = 0.4, p_t = 0.95, c_max the
//!   distance between pure green and pure blue): the colour error e_c;
//! - feature pipeline: on the luminance, edges (first derivatives of a Gaussian of standard
//!   deviation 0.5 w ppd, w = 0.082 degrees) and points (second derivatives); the feature error
//!   e_f = (max(|edge_a - edge_b|, |point_a - point_b|) / sqrt 2)^q_f, q_f = 0.5;
//! - the error e_c^(1 - e_f).
//!
//! HDR-FLIP tone-maps both radiance images with ACES (Narkowicz's fit) at exposures 2^c for c
//! evenly spaced from c_start = log2(x_max / Y_max) to c_stop = log2(x_max / Y_median), Y the
//! reference's luminances and x_max where the tone curve reaches 0.85, over
//! max(2, ceil(c_stop - c_start)) exposures, and takes at each pixel the largest LDR-FLIP error.
//! Where the reference's median luminance is 0 (mostly black images) the median of its non-zero
//! luminances stands in, since the published rule would need infinitely many exposures.
//!
//! The filters are separable, applied in x then y with borders clamped to the edge, in f32: NVIDIA's
//! C++ implementation behind the `flip-evaluator` package, which tests/metrics.rs compares
//! against (means within 2e-6).

use crate::color::Rgb;
use rayon::prelude::*;

const PI: f32 = std::f32::consts::PI;
/// Pixels per degree of NVIDIA's default viewer: 0.7 m from a 0.7 m wide 3840-pixel monitor.
pub const DEFAULT_PPD: f32 = 0.7 * (3840.0 / 0.7) * (PI / 180.0);

const QC: f32 = 0.7;
const PC: f32 = 0.4;
const PT: f32 = 0.95;
const W: f32 = 0.082;
const QF: f32 = 0.5;

/// D65 white's XYZ, and its reciprocal.
const ILLUMINANT: [f32; 3] = [0.95042855, 1.0, 1.0889003];
const INV_ILLUMINANT: [f32; 3] = [1.0521569, 1.0, 0.9183577];

/// ACES (Narkowicz 2015) as (k0 x^2 + k1 x + k2) / (k3 x^2 + k4 x + k5), the 0.6 pre-exposure
/// folded in.
const ACES: [f32; 6] = [
    0.6 * 0.6 * 2.51,
    0.6 * 0.03,
    0.0,
    0.6 * 0.6 * 2.43,
    0.6 * 0.59,
    0.14,
];

/// Mean LDR-FLIP of `test` against `reference`, linear RGB images (values clamped to [0, 1]),
/// row-major, `width` x `height`, seen at `ppd` pixels per degree.
pub fn ldr(reference: &[Rgb], test: &[Rgb], width: usize, height: usize, ppd: f32) -> f64 {
    let clamp = |p: &[Rgb]| -> Vec<[f32; 3]> {
        p.iter()
            .map(|c| c.to_array().map(|v| v.clamp(0.0, 1.0)))
            .collect()
    };
    let filters = Filters::new(ppd);
    let map = error_map(&clamp(reference), &clamp(test), width, height, &filters);
    mean(&map)
}

/// Mean HDR-FLIP of `test` against `reference`, linear radiance images (negative values count
/// as 0), row-major, `width` x `height`, seen at `ppd` pixels per degree.
pub fn hdr(reference: &[Rgb], test: &[Rgb], width: usize, height: usize, ppd: f32) -> f64 {
    let filters = Filters::new(ppd);
    let (start, stop) = exposures(reference);
    let count = (stop - start).ceil().max(2.0) as usize;
    let step = (stop - start) / (count - 1) as f32;
    let mut worst = vec![0.0f32; width * height];
    for i in 0..count {
        let scale = 2.0f32.powf(start + i as f32 * step);
        let tone_map = |p: &[Rgb]| -> Vec<[f32; 3]> {
            p.par_iter()
                .map(|c| c.to_array().map(|v| aces(v.max(0.0) * scale)))
                .collect()
        };
        let map = error_map(
            &tone_map(reference),
            &tone_map(test),
            width,
            height,
            &filters,
        );
        worst
            .par_iter_mut()
            .zip(&map)
            .for_each(|(w, e)| *w = w.max(*e));
    }
    mean(&worst)
}

fn mean(map: &[f32]) -> f64 {
    map.iter().map(|&e| f64::from(e)).sum::<f64>() / map.len().max(1) as f64
}

/// ACES, clamped to [0, 1]; values so large that x^2 overflows map to 1, the curve's limit.
fn aces(x: f32) -> f32 {
    let [k0, k1, k2, k3, k4, k5] = ACES;
    let y = (x * x * k0 + x * k1 + k2) / (x * x * k3 + x * k4 + k5);
    if y.is_nan() {
        1.0
    } else {
        y.clamp(0.0, 1.0)
    }
}

/// `(c_start, c_stop)` of HDR-FLIP for `reference`.
fn exposures(reference: &[Rgb]) -> (f32, f32) {
    let [k0, k1, k2, k3, k4, k5] = ACES;
    // Where the tone curve reaches t: a x^2 + b x + c = 0.
    let t = 0.85;
    let (a, b, c) = (k0 - t * k3, k1 - t * k4, k2 - t * k5);
    let d1 = -0.5 * (b / a);
    let x_max = d1 + (d1 * d1 - c / a).sqrt();
    let mut luminances: Vec<f32> = reference
        .iter()
        .map(|p| luminance(p.to_array().map(|v| v.max(0.0))))
        .collect();
    let y_max = luminances.iter().copied().fold(0.0f32, f32::max);
    if y_max <= 0.0 {
        return (0.0, 0.0);
    }
    let median = |values: &mut [f32]| {
        let middle = values.len() / 2;
        *values.select_nth_unstable_by(middle, f32::total_cmp).1
    };
    let mut y_median = median(&mut luminances);
    if y_median <= 0.0 {
        luminances.retain(|&y| y > 0.0);
        y_median = median(&mut luminances);
    }
    ((x_max / y_max).log2(), (x_max / y_median).log2())
}

fn luminance([r, g, b]: [f32; 3]) -> f32 {
    0.2126 * r + 0.7152 * g + 0.0722 * b
}

fn linear_rgb_to_xyz([r, g, b]: [f32; 3]) -> [f32; 3] {
    // sRGB primaries, D65 white, as exact fractions.
    [
        10135552.0 / 24577794.0 * r + 8788810.0 / 24577794.0 * g + 4435075.0 / 24577794.0 * b,
        2613072.0 / 12288897.0 * r + 8788810.0 / 12288897.0 * g + 887015.0 / 12288897.0 * b,
        1425312.0 / 73733382.0 * r + 8788810.0 / 73733382.0 * g + 70074185.0 / 73733382.0 * b,
    ]
}

fn xyz_to_linear_rgb([x, y, z]: [f32; 3]) -> [f32; 3] {
    [
        3.2410033 * x - 1.5373989 * y - 0.49861586 * z,
        -0.96922433 * x + 1.8759301 * y + 0.041554224 * z,
        0.055639423 * x - 0.2040112 * y + 1.0571489 * z,
    ]
}

fn xyz_to_ycxcz(xyz: [f32; 3]) -> [f32; 3] {
    let [x, y, z] = [0, 1, 2].map(|i| xyz[i] * INV_ILLUMINANT[i]);
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

fn ycxcz_to_xyz([yy, cx, cz]: [f32; 3]) -> [f32; 3] {
    let y = (yy + 16.0) / 116.0;
    let xyz = [y + cx / 500.0, y, y - cz / 200.0];
    [0, 1, 2].map(|i| xyz[i] * ILLUMINANT[i])
}

fn xyz_to_lab(xyz: [f32; 3]) -> [f32; 3] {
    let delta = 6.0f32 / 29.0;
    let delta_cube = delta * delta * delta;
    let factor = 1.0 / (3.0 * delta * delta);
    let f = |v: f32| {
        if v > delta_cube {
            v.powf(1.0 / 3.0)
        } else {
            factor * v + 4.0 / 29.0
        }
    };
    let [x, y, z] = [0, 1, 2].map(|i| f(xyz[i] * INV_ILLUMINANT[i]));
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

/// CIELAB with the Hunt adjustment: chroma scaled by 0.01 L.
fn hunt([l, a, b]: [f32; 3]) -> [f32; 3] {
    [l, 0.01 * l * a, 0.01 * l * b]
}

fn hyab(p: [f32; 3], q: [f32; 3]) -> f32 {
    (p[0] - q[0]).abs() + ((p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
}

/// The separated filters for one `ppd`.
struct Filters {
    /// Achromatic and red-green contrast sensitivity, one Gaussian each: `[y, cx]` per tap.
    ycx: Vec<[f32; 2]>,
    /// Blue-yellow, a sum of two Gaussians, each separated (the square root of its 1D form)
    /// so that filtering in x then y gives the sum: `[first, second]` per tap.
    cz: Vec<[f32; 2]>,
    /// Feature detection: `[gaussian, first derivative, second derivative]` per tap.
    feature: Vec<[f32; 3]>,
}

impl Filters {
    fn new(ppd: f32) -> Filters {
        // Contrast sensitivity functions: a sqrt(pi / b) exp(-pi^2 x^2 / b) in degrees
        // (2020 eq. 2), with (a, b) = (1, 0.0047) achromatic, (1, 0.0053) red-green,
        // (34.1, 0.04) + (13.5, 0.025) blue-yellow.
        let pi_sq = PI * PI;
        let gaussian = |x2: f32, a: f32, b: f32| a * (PI / b).sqrt() * (-pi_sq * x2 / b).exp();
        let gaussian_sqrt =
            |x2: f32, a: f32, b: f32| (a * (PI / b).sqrt()).sqrt() * (-pi_sq * x2 / b).exp();
        // Radius: three standard deviations of the widest Gaussian (b = 0.04).
        let radius = (3.0 * (0.04f32 / (2.0 * pi_sq)).sqrt() * ppd).ceil() as i32;
        let taps = |r: i32| (-r..=r).map(move |i| i as f32);
        let mut ycx: Vec<[f32; 2]> = taps(radius)
            .map(|i| {
                let x2 = (i / ppd).powi(2);
                [gaussian(x2, 1.0, 0.0047), gaussian(x2, 1.0, 0.0053)]
            })
            .collect();
        let mut cz: Vec<[f32; 2]> = taps(radius)
            .map(|i| {
                let x2 = (i / ppd).powi(2);
                [
                    gaussian_sqrt(x2, 34.1, 0.04),
                    gaussian_sqrt(x2, 13.5, 0.025),
                ]
            })
            .collect();
        let sum = |v: &[[f32; 2]], c: usize| v.iter().map(|t| t[c]).sum::<f32>();
        let (sum_y, sum_cx) = (sum(&ycx, 0), sum(&ycx, 1));
        let cz_norm = 1.0 / (sum(&cz, 0).powi(2) + sum(&cz, 1).powi(2)).sqrt();
        for t in &mut ycx {
            *t = [t[0] / sum_y, t[1] / sum_cx];
        }
        for t in &mut cz {
            *t = t.map(|v| v * cz_norm);
        }
        // Edges and points: a Gaussian of standard deviation 0.5 w ppd pixels and its
        // derivatives, the derivatives' positive and negative weights each summing to +-1.
        let sd = 0.5 * W * ppd;
        let r = (3.0 * sd).ceil() as i32;
        let mut feature: Vec<[f32; 3]> = taps(r)
            .map(|x| {
                let g = (-(x * x) / (2.0 * sd * sd)).exp();
                [g, -x * g, (x * x / (sd * sd) - 1.0) * g]
            })
            .collect();
        let g_sum: f32 = feature.iter().map(|t| t[0]).sum();
        let signed_sums = |c: usize| {
            feature.iter().fold((0.0f32, 0.0f32), |(pos, neg), t| {
                if t[c] > 0.0 {
                    (pos + t[c], neg)
                } else {
                    (pos, neg - t[c])
                }
            })
        };
        let (d_pos, d_neg) = signed_sums(1);
        let (dd_pos, dd_neg) = signed_sums(2);
        for t in &mut feature {
            *t = [
                t[0] / g_sum,
                t[1] / if t[1] > 0.0 { d_pos } else { d_neg },
                t[2] / if t[2] > 0.0 { dd_pos } else { dd_neg },
            ];
        }
        Filters { ycx, cz, feature }
    }
}

/// The per-pixel LDR-FLIP error of `test` against `reference`, linear RGB in [0, 1].
fn error_map(
    reference: &[[f32; 3]],
    test: &[[f32; 3]],
    width: usize,
    height: usize,
    filters: &Filters,
) -> Vec<f32> {
    let opponent = |p: &[[f32; 3]]| -> Vec<[f32; 3]> {
        p.par_iter()
            .map(|&c| xyz_to_ycxcz(linear_rgb_to_xyz(c)))
            .collect()
    };
    let (reference, test) = (opponent(reference), opponent(test));
    let colour = colour_error(&reference, &test, width, height, filters);
    let features = feature_error(&reference, &test, width, height, filters);
    colour
        .par_iter()
        .zip(&features)
        .map(|(&c, &f)| c.powf(1.0 - f))
        .collect()
}

/// Filters `image` (row-major, `width` wide) along x with clamped borders: `f(tap, value)` is
/// the contribution of one tap, summed per pixel.
fn filter_x<T: Copy + Send + Sync, U: Copy + Send + Default + std::ops::AddAssign>(
    image: &[T],
    width: usize,
    radius: usize,
    f: impl Fn(usize, T) -> U + Sync,
) -> Vec<U> {
    let mut out = vec![U::default(); image.len()];
    out.par_chunks_mut(width)
        .zip(image.par_chunks(width))
        .for_each(|(out, row)| {
            for (x, o) in out.iter_mut().enumerate() {
                for tap in 0..2 * radius + 1 {
                    let xx = (x + tap).saturating_sub(radius).min(width - 1);
                    *o += f(tap, row[xx]);
                }
            }
        });
    out
}

/// Filters along y with clamped borders, then maps each pixel's sum with `finish`.
fn filter_y<T: Copy + Send + Sync, U: Copy + Default + std::ops::AddAssign, V: Send>(
    image: &[T],
    width: usize,
    height: usize,
    radius: usize,
    f: impl Fn(usize, T) -> U + Sync,
    finish: impl Fn(usize, U) -> V + Sync,
) -> Vec<V> {
    (0..width * height)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let mut sum = U::default();
            for tap in 0..2 * radius + 1 {
                let yy = (y + tap).saturating_sub(radius).min(height - 1);
                sum += f(tap, image[yy * width + x]);
            }
            finish(i, sum)
        })
        .collect()
}

#[derive(Clone, Copy, Default)]
struct V4([f32; 4]);

impl std::ops::AddAssign for V4 {
    fn add_assign(&mut self, o: V4) {
        for (a, b) in self.0.iter_mut().zip(o.0) {
            *a += b;
        }
    }
}

#[derive(Clone, Copy, Default)]
struct V3([f32; 3]);

impl std::ops::AddAssign for V3 {
    fn add_assign(&mut self, o: V3) {
        for (a, b) in self.0.iter_mut().zip(o.0) {
            *a += b;
        }
    }
}

/// The colour error e_c of each pixel (YCxCz inputs).
fn colour_error(
    reference: &[[f32; 3]],
    test: &[[f32; 3]],
    width: usize,
    height: usize,
    filters: &Filters,
) -> Vec<f32> {
    let radius = filters.ycx.len() / 2;
    // (Y, Cx, Cz, Cz) times the tap's weights: Y and Cx by their Gaussians, Cz by its two.
    let weigh = |tap: usize, v: V4| {
        let (ycx, cz) = (filters.ycx[tap], filters.cz[tap]);
        V4([
            ycx[0] * v.0[0],
            ycx[1] * v.0[1],
            cz[0] * v.0[2],
            cz[1] * v.0[3],
        ])
    };
    // Per image: filtered (Y, Cx, Cz first Gaussian, Cz second Gaussian).
    let first = |image: &[[f32; 3]]| {
        filter_x(image, width, radius, |tap, c: [f32; 3]| {
            weigh(tap, V4([c[0], c[1], c[2], c[2]]))
        })
    };
    let (reference, test) = (first(reference), first(test));
    let pairs: Vec<(V4, V4)> = reference.into_iter().zip(test).collect();
    let c_max = hyab(
        hunt(xyz_to_lab(linear_rgb_to_xyz([0.0, 1.0, 0.0]))),
        hunt(xyz_to_lab(linear_rgb_to_xyz([0.0, 0.0, 1.0]))),
    )
    .powf(QC);
    let pc_max = PC * c_max;
    let to_lab = |v: V4| {
        let rgb = xyz_to_linear_rgb(ycxcz_to_xyz([v.0[0], v.0[1], v.0[2] + v.0[3]]));
        hunt(xyz_to_lab(linear_rgb_to_xyz(
            rgb.map(|c| c.clamp(0.0, 1.0)),
        )))
    };
    filter_y(
        &pairs,
        width,
        height,
        radius,
        |tap, (r, t): (V4, V4)| {
            let (r, t) = (weigh(tap, r), weigh(tap, t));
            V8(r, t)
        },
        |_, V8(r, t)| {
            let d = hyab(to_lab(r), to_lab(t)).powf(QC);
            // Below p_c c_max to [0, p_t], above to (p_t, 1].
            if d < pc_max {
                d * PT / pc_max
            } else {
                PT + (d - pc_max) / (c_max - pc_max) * (1.0 - PT)
            }
        },
    )
}

#[derive(Clone, Copy, Default)]
struct V8(V4, V4);

impl std::ops::AddAssign for V8 {
    fn add_assign(&mut self, o: V8) {
        self.0 += o.0;
        self.1 += o.1;
    }
}

/// The feature exponent e_f of each pixel (YCxCz inputs).
fn feature_error(
    reference: &[[f32; 3]],
    test: &[[f32; 3]],
    width: usize,
    height: usize,
    filters: &Filters,
) -> Vec<f32> {
    let radius = filters.feature.len() / 2;
    // Per image along x: (first derivative, second derivative, Gaussian) of the luminance
    // normalised to [0, 1].
    let first = |image: &[[f32; 3]]| {
        filter_x(image, width, radius, |tap, c: [f32; 3]| {
            let w = filters.feature[tap];
            let y = c[0] * (1.0 / 116.0) + 16.0 / 116.0;
            V3([w[1] * y, w[2] * y, w[0] * y])
        })
    };
    let (reference, test) = (first(reference), first(test));
    let pairs: Vec<(V3, V3)> = reference.into_iter().zip(test).collect();
    // Along y: (dx, ddx, dy, ddy).
    let weigh = |tap: usize, v: V3| {
        let w = filters.feature[tap];
        V4([w[0] * v.0[0], w[0] * v.0[1], w[1] * v.0[2], w[2] * v.0[2]])
    };
    let features = |v: V4| {
        let [dx, ddx, dy, ddy] = v.0;
        ((dx * dx + dy * dy).sqrt(), (ddx * ddx + ddy * ddy).sqrt())
    };
    filter_y(
        &pairs,
        width,
        height,
        radius,
        |tap, (r, t): (V3, V3)| V8(weigh(tap, r), weigh(tap, t)),
        |_, V8(r, t)| {
            let ((edge_r, point_r), (edge_t, point_t)) = (features(r), features(t));
            let d = (edge_r - edge_t).abs().max((point_r - point_t).abs());
            (std::f32::consts::FRAC_1_SQRT_2 * d).powf(QF)
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(seed: u64, n: usize, scale: f32) -> Vec<Rgb> {
        let mut rng = crate::sampling::Rng::from_seed(seed, 0);
        (0..n)
            .map(|_| Rgb::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale)
            .collect()
    }

    #[test]
    fn identical_images_give_zero() {
        let a = noise(1, 40 * 30, 1.0);
        assert_eq!(ldr(&a, &a, 40, 30, DEFAULT_PPD), 0.0);
        let a = noise(1, 40 * 30, 20.0);
        assert_eq!(hdr(&a, &a, 40, 30, DEFAULT_PPD), 0.0);
    }

    #[test]
    fn black_against_white_is_the_largest_colour_error() {
        // Uniform images: no features, so the error is e_c; black to white is a HyAB
        // distance of 100 in L, beyond p_c c_max.
        let black = vec![Rgb::BLACK; 20 * 20];
        let white = vec![Rgb::WHITE; 20 * 20];
        let e = ldr(&black, &white, 20, 20, DEFAULT_PPD);
        let c_max = hyab(
            hunt(xyz_to_lab(linear_rgb_to_xyz([0.0, 1.0, 0.0]))),
            hunt(xyz_to_lab(linear_rgb_to_xyz([0.0, 0.0, 1.0]))),
        )
        .powf(QC);
        let expected = PT + (100.0f32.powf(QC) - PC * c_max) / (c_max - PC * c_max) * (1.0 - PT);
        assert!((e - f64::from(expected)).abs() < 1e-4, "{e} {expected}");
    }
}
