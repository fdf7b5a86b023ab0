//! Structural similarity, SSIM (Wang, Bovik, Sheikh and Simoncelli, "Image quality
//! assessment: from error visibility to structural similarity", IEEE TIP 13(4), 2004).
//!
//! For each channel, with Gaussian-weighted local means mu, variances sigma^2 and covariance
//! sigma_xy (window of standard deviation 1.5 pixels, truncated at radius 5: 11 x 11 taps,
//! population rather than sample statistics, as in the paper), at each pixel
//!
//! SSIM = (2 mu_x mu_y + C1) (2 sigma_xy + C2) / ((mu_x^2 + mu_y^2 + C1) (sigma_x^2 + sigma_y^2 + C2))
//!
//! with C1 = (0.01 L)^2, C2 = (0.03 L)^2 and L the data range. The image's SSIM is the mean over
//! the pixels at least 5 pixels from the border (nearer ones would see the padding), averaged over
//! the three channels. The window reflects at the borders (`d c b a | a b c d`). This is
//! scikit-image's `structural_similarity(a, b, channel_axis=2, gaussian_weights=True,
//! sigma=1.5, use_sample_covariance=False, data_range=L)`, which the tests compare against.

use crate::color::Rgb;
use rayon::prelude::*;

/// Standard deviation of the Gaussian window, in pixels.
pub const SIGMA: f64 = 1.5;
/// The window's radius: scikit-image's (and SciPy's) truncation at 3.5 standard deviations.
pub const RADIUS: usize = 5;
/// The smallest width and height SSIM is defined for: one whole window.
pub const MIN_SIZE: u32 = 2 * RADIUS as u32 + 1;
const K1: f64 = 0.01;
const K2: f64 = 0.03;

/// The mean SSIM of `a` and `b` (row-major, `width` x `height`, at least [`MIN_SIZE`] each
/// way) over the three channels, for values spanning `data_range`. Symmetric in `a` and `b`;
/// 1 for identical images.
pub fn ssim(a: &[Rgb], b: &[Rgb], width: usize, height: usize, data_range: f64) -> f64 {
    debug_assert!(width.min(height) >= MIN_SIZE as usize);
    let total: f64 = (0..3)
        .map(|c| {
            let x: Vec<f64> = a.iter().map(|p| f64::from(p.to_array()[c])).collect();
            let y: Vec<f64> = b.iter().map(|p| f64::from(p.to_array()[c])).collect();
            channel(&x, &y, width, height, data_range)
        })
        .sum();
    total / 3.0
}

/// SSIM of one channel.
fn channel(x: &[f64], y: &[f64], width: usize, height: usize, data_range: f64) -> f64 {
    let kernel = kernel();
    let blur = |f: &dyn Fn(usize) -> f64| blur(f, width, height, &kernel);
    let mu_x = blur(&|i| x[i]);
    let mu_y = blur(&|i| y[i]);
    let xx = blur(&|i| x[i] * x[i]);
    let yy = blur(&|i| y[i] * y[i]);
    let xy = blur(&|i| x[i] * y[i]);
    let c1 = (K1 * data_range).powi(2);
    let c2 = (K2 * data_range).powi(2);
    let rows: Vec<f64> = (RADIUS..height - RADIUS)
        .into_par_iter()
        .map(|row| {
            (RADIUS..width - RADIUS)
                .map(|col| {
                    let i = row * width + col;
                    let (mx, my) = (mu_x[i], mu_y[i]);
                    let var_x = xx[i] - mx * mx;
                    let var_y = yy[i] - my * my;
                    let cov = xy[i] - mx * my;
                    (2.0 * mx * my + c1) * (2.0 * cov + c2)
                        / ((mx * mx + my * my + c1) * (var_x + var_y + c2))
                })
                .sum::<f64>()
        })
        .collect();
    let count = (width - 2 * RADIUS) * (height - 2 * RADIUS);
    rows.iter().sum::<f64>() / count as f64
}

/// The normalised Gaussian weights at offsets -RADIUS..=RADIUS.
fn kernel() -> [f64; 2 * RADIUS + 1] {
    let mut k = [0.0; 2 * RADIUS + 1];
    for (i, w) in k.iter_mut().enumerate() {
        let d = i as f64 - RADIUS as f64;
        *w = (-0.5 * d * d / (SIGMA * SIGMA)).exp();
    }
    let sum: f64 = k.iter().sum();
    k.map(|w| w / sum)
}

/// Index `i` reflected into `0..n` about the edges' half-pixel (`d c b a | a b c d`); `i` lies
/// at most `n` outside.
fn reflect(i: isize, n: usize) -> usize {
    let n = n as isize;
    let r = if i < 0 {
        -i - 1
    } else if i >= n {
        2 * n - i - 1
    } else {
        i
    };
    r as usize
}

/// The values `f(i)` of a `width` x `height` image filtered with the separable `kernel`.
fn blur(f: &dyn Fn(usize) -> f64, width: usize, height: usize, kernel: &[f64]) -> Vec<f64> {
    let r = kernel.len() as isize / 2;
    let values: Vec<f64> = (0..width * height).map(f).collect();
    let mut vertical = vec![0.0; width * height];
    vertical
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(row, out)| {
            for (k, w) in kernel.iter().enumerate() {
                let src = reflect(row as isize + k as isize - r, height) * width;
                for (o, v) in out.iter_mut().zip(&values[src..src + width]) {
                    *o += w * v;
                }
            }
        });
    let mut out = vec![0.0; width * height];
    out.par_chunks_mut(width)
        .zip(vertical.par_chunks(width))
        .for_each(|(out, line)| {
            for (col, o) in out.iter_mut().enumerate() {
                *o = kernel
                    .iter()
                    .enumerate()
                    .map(|(k, w)| w * line[reflect(col as isize + k as isize - r, width)])
                    .sum();
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(seed: u64, n: usize) -> Vec<Rgb> {
        let mut rng = crate::sampling::Rng::from_seed(seed, 0);
        (0..n)
            .map(|_| Rgb::new(rng.next_f32(), rng.next_f32(), rng.next_f32()))
            .collect()
    }

    #[test]
    fn identical_images_give_one_and_order_does_not_matter() {
        let (a, b) = (noise(1, 24 * 16), noise(2, 24 * 16));
        assert_eq!(ssim(&a, &a, 24, 16, 1.0), 1.0);
        let (ab, ba) = (ssim(&a, &b, 24, 16, 1.0), ssim(&b, &a, 24, 16, 1.0));
        assert!((ab - ba).abs() < 1e-12 && ab < 0.2, "{ab} {ba}");
    }

    #[test]
    fn a_uniform_offset_costs_only_the_luminance_term() {
        // Constant images mu and mu + d: no variance, so SSIM = (2 mu (mu + d) + C1) /
        // (mu^2 + (mu + d)^2 + C1).
        let (mu, d) = (0.25f32, 0.125f32);
        let a = vec![Rgb::splat(mu); 12 * 12];
        let b = vec![Rgb::splat(mu + d); 12 * 12];
        let (mu, d, c1) = (f64::from(mu), f64::from(d), (K1 * 1.0f64).powi(2));
        let expected = (2.0 * mu * (mu + d) + c1) / (mu * mu + (mu + d) * (mu + d) + c1);
        let got = ssim(&a, &b, 12, 12, 1.0);
        assert!((got - expected).abs() < 1e-12, "{got} {expected}");
    }
}
