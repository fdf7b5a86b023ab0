//! The pixel-wise measures, over all pixels of a rectangle and the three channels R, G, B
//! (n = 3 x pixels, a the image, b the reference):
//!
//! - mean absolute error, mae = sum |a - b| / n (000 sec. 3.4);
//! - root-mean-square error, rmse = sqrt(sum (a - b)^2 / n) (000 sec. 3.4);
//! - relative MSE, relmse = sum (a - b)^2 / (b^2 + 0.01) / n: pbrt's `imgtool diff` and most
//!   rendering papers (e.g. Rousselle et al. 2011); the 0.01 keeps black reference pixels from
//!   dividing by zero, so dark regions weigh about as much as bright ones.

use super::{Errors, Measure};
use crate::color::Rgb;
use rayon::prelude::*;

/// Added to the squared reference in relative MSE's denominator.
pub const RELATIVE_MSE_EPSILON: f64 = 0.01;

/// The pixel-wise measures ([`Measure::is_pointwise`]) of `a` against the reference `b` over
/// the pixel rectangle `(x0, y0, x1, y1)`, meaning `[x0, x1) x [y0, y1)`, of images `width`
/// pixels wide. An empty rectangle gives 0 for each.
///
/// Rows are summed in parallel, then added in row order, so the result does not depend on the
/// thread count.
pub fn errors_in(a: &[Rgb], b: &[Rgb], width: u32, rect: (u32, u32, u32, u32)) -> Errors {
    let (x0, y0, x1, y1) = rect;
    let rows: Vec<[f64; 3]> = (y0..y1)
        .into_par_iter()
        .map(|y| {
            let start = y as usize * width as usize;
            let range = start + x0 as usize..start + x1 as usize;
            let mut sums = [0.0f64; 3];
            for (p, q) in a[range.clone()].iter().zip(&b[range]) {
                for (p, q) in p.to_array().into_iter().zip(q.to_array()) {
                    let (p, q) = (f64::from(p), f64::from(q));
                    let d = p - q;
                    sums[0] += d.abs();
                    sums[1] += d * d;
                    sums[2] += d * d / (q * q + RELATIVE_MSE_EPSILON);
                }
            }
            sums
        })
        .collect();
    let sums = rows.into_iter().fold([0.0; 3], |acc, row| {
        [acc[0] + row[0], acc[1] + row[1], acc[2] + row[2]]
    });
    let n = 3 * x1.saturating_sub(x0) as usize * y1.saturating_sub(y0) as usize;
    let mean = |sum: f64| if n == 0 { 0.0 } else { sum / n as f64 };
    let mut errors = Errors::default();
    errors.set(Measure::Mae, mean(sums[0]));
    errors.set(Measure::Rmse, mean(sums[1]).sqrt());
    errors.set(Measure::RelativeMse, mean(sums[2]));
    errors
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_match_their_definition() {
        // a - b = (1, -2, 0) on one pixel of four, b = 1 everywhere: sum |d| = 3,
        // sum d^2 = 5, n = 12, relative terms d^2 / 1.01.
        let b = vec![Rgb::splat(1.0); 4];
        let mut a = b.clone();
        a[3] = Rgb::new(2.0, -1.0, 1.0);
        let e = errors_in(&a, &b, 2, (0, 0, 2, 2));
        assert_eq!(e.get(Measure::Mae), Some(3.0 / 12.0));
        assert_eq!(e.get(Measure::Rmse), Some((5.0f64 / 12.0).sqrt()));
        let relative = e.get(Measure::RelativeMse).unwrap();
        assert!((relative - 5.0 / 1.01 / 12.0).abs() < 1e-15, "{relative}");
        // The window holding only that pixel: n = 3.
        let e = errors_in(&a, &b, 2, (1, 1, 2, 2));
        assert_eq!(e.get(Measure::Mae), Some(1.0));
        assert_eq!(e.get(Measure::Rmse), Some((5.0f64 / 3.0).sqrt()));
        assert!(e.get(Measure::LdrFlip).is_none());
    }

    #[test]
    fn errors_do_not_depend_on_the_thread_count() {
        let mut rng = crate::sampling::Rng::from_seed(3, 0);
        let mut noise = || -> Vec<Rgb> {
            (0..64 * 64)
                .map(|_| Rgb::new(rng.next_f32(), rng.next_f32() * 1e3, rng.next_f32()))
                .collect()
        };
        let (a, b) = (noise(), noise());
        let run = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let e = pool.install(|| errors_in(&a, &b, 64, (0, 0, 64, 64)));
            e.iter().map(|(_, v)| v.to_bits()).collect::<Vec<_>>()
        };
        assert_eq!(run(1), run(3));
    }
}
