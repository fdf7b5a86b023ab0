//! Camera splats of a light pass: each parallel task lists the (pixel, value) pairs its light
//! vertices send to the camera, and the lists are added to the frame on every thread, a band
//! of pixels per task. Each pixel receives its splats in the order of the lists, and within a
//! list in the order made, as one thread adding list after list would: the image does not
//! depend on the threads.

use super::add_sample;
use crate::color::Rgb;
use rayon::prelude::*;

/// Bands of pixels the lists are regrouped into: enough for every thread of a large machine to
/// take several, few enough that a list's band offsets stay small beside its splats.
const BANDS: usize = 64;

/// One task's camera splats.
#[derive(Default)]
pub struct Splats {
    made: Vec<(usize, Rgb)>,
    /// `made` regrouped by band, stable; band `b` is `by_band[starts[b]..starts[b + 1]]`.
    by_band: Vec<(usize, Rgb)>,
    starts: Vec<usize>,
}

impl Splats {
    /// Empties the list for the next iteration, keeping its storage.
    pub fn clear(&mut self) {
        self.made.clear();
    }

    pub fn push(&mut self, pixel: usize, value: Rgb) {
        self.made.push((pixel, value));
    }

    /// Regroups the splats by band of `band_len` pixels (a stable counting sort).
    fn arrange(&mut self, band_len: usize) {
        self.starts.clear();
        self.starts.resize(BANDS + 1, 0);
        for &(pixel, _) in &self.made {
            self.starts[pixel / band_len + 1] += 1;
        }
        for b in 0..BANDS {
            self.starts[b + 1] += self.starts[b];
        }
        self.by_band.clear();
        self.by_band.resize(self.made.len(), (0, Rgb::BLACK));
        // Each band's start serves as its cursor, which ends where the next band starts.
        for &splat in &self.made {
            let cursor = &mut self.starts[splat.0 / band_len];
            self.by_band[*cursor] = splat;
            *cursor += 1;
        }
        self.starts.copy_within(0..BANDS, 1);
        self.starts[0] = 0;
    }

    fn band(&self, band: usize) -> &[(usize, Rgb)] {
        &self.by_band[self.starts[band]..self.starts[band + 1]]
    }
}

/// Adds the splats of every task in `tasks` (reached through `splats`) to `frame`, in task
/// order, on all threads; returns the samples dropped for being NaN or infinite.
pub fn add_splats<T: Send>(
    frame: &mut [Rgb],
    tasks: &mut [T],
    splats: impl Fn(&mut T) -> &mut Splats + Sync,
) -> u64 {
    let band_len = frame.len().div_ceil(BANDS).max(1);
    tasks
        .par_iter_mut()
        .for_each(|task| splats(task).arrange(band_len));
    let lists: Vec<&Splats> = tasks.iter_mut().map(|task| &*splats(task)).collect();
    frame
        .par_chunks_mut(band_len)
        .enumerate()
        .map(|(band, pixels)| {
            let first = band * band_len;
            let mut dropped = 0;
            for list in &lists {
                for &(pixel, value) in list.band(band) {
                    add_sample(&mut pixels[pixel - first], value, &mut dropped);
                }
            }
            dropped
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::{Rng, Stream};

    /// Lists of splats over a frame of `pixels`, values of very different sizes (so the order
    /// of addition shows in the bits) and a few NaNs and infinities.
    fn random_lists(rng: &mut Rng, pixels: usize, lists: usize) -> Vec<Splats> {
        (0..lists)
            .map(|_| {
                let mut splats = Splats::default();
                for _ in 0..rng.next_u32() % 300 {
                    let pixel = rng.next_u32() as usize % pixels;
                    let scale = [1e-6, 1.0, 1e6][rng.next_u32() as usize % 3];
                    let value = match rng.next_u32() % 50 {
                        0 => Rgb::new(f32::NAN, 0.0, 0.0),
                        1 => Rgb::new(0.0, f32::INFINITY, 0.0),
                        _ => Rgb::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * scale,
                    };
                    splats.push(pixel, value);
                }
                splats
            })
            .collect()
    }

    /// `add_splats` against one thread adding list after list, bit for bit.
    fn check(lists: &mut [Splats], pixels: usize) {
        let mut serial = vec![Rgb::BLACK; pixels];
        let mut serial_dropped = 0;
        for list in &*lists {
            for &(pixel, value) in &list.made {
                add_sample(&mut serial[pixel], value, &mut serial_dropped);
            }
        }
        let mut frame = vec![Rgb::BLACK; pixels];
        let dropped = add_splats(&mut frame, lists, |list| list);
        assert_eq!(dropped, serial_dropped, "{pixels} pixels");
        for (p, (a, b)) in frame.iter().zip(&serial).enumerate() {
            assert_eq!(
                a.to_array().map(f32::to_bits),
                b.to_array().map(f32::to_bits),
                "pixel {p} of {pixels}"
            );
        }
    }

    #[test]
    fn bands_add_each_pixel_in_list_order() {
        let mut rng = Rng::for_sample(5, 0, 0, Stream::Light);
        // Fewer pixels than bands, a length no band count divides, and a larger frame.
        for pixels in [1, 10, 1000, 4099] {
            let mut lists = random_lists(&mut rng, pixels, 40);
            check(&mut lists, pixels);
            // The storage kept for the next iteration: cleared lists refilled.
            for (list, fresh) in lists.iter_mut().zip(random_lists(&mut rng, pixels, 40)) {
                list.clear();
                for &(pixel, value) in &fresh.made {
                    list.push(pixel, value);
                }
            }
            check(&mut lists, pixels);
        }
    }
}
