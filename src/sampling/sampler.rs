//! The numbers a path is built from: randomised quasi-Monte Carlo by default, or independent
//! PCG32 numbers (`--sampler independent`).
//!
//! The Sobol sampler gives every 2D draw of a path (pixel jitter, light point, BSDF direction,
//! ...) its own copy of the 2D Sobol' (0,2)-sequence, shuffled and Owen-scrambled with hashes
//! of that dimension's seed (Burley 2020, "Practical Hash-based Owen Scrambling", sec. 4-6;
//! pbrt-v4's `PaddedSobolSampler` is the same design). Every power-of-two prefix of a pixel's
//! samples is then stratified in each 2D projection (a (0, m, 2)-net), while the dimensions
//! stay independent of each other, and each sample on its own is uniform in the unit cube: the
//! estimators stay unbiased whatever order their numbers are drawn in.
//!
//! Eye sub-paths form one sequence per pixel over the iterations. Light sub-paths form one
//! sequence over all iterations (sample `iteration * paths + path`), so with one light path
//! per pixel of a power-of-two image the paths of every iteration are stratified together.

use super::rng::{mix, Rng, Stream};
use crate::options::SamplerKind;

/// The source of one sub-path's numbers.
#[derive(Clone, Debug)]
pub enum Sampler {
    Sobol(SobolSample),
    Independent(Rng),
}

impl Sampler {
    /// The eye sub-path of `pixel` in `iteration`.
    pub fn eye(kind: SamplerKind, seed: u64, iteration: u64, pixel: u64) -> Self {
        match kind {
            SamplerKind::Sobol => {
                Sampler::Sobol(SobolSample::new(seed, Stream::Eye, pixel, iteration))
            }
            SamplerKind::Independent => {
                Sampler::Independent(Rng::for_sample(seed, iteration, pixel, Stream::Eye))
            }
        }
    }

    /// Light sub-path `path` of the `paths` traced in `iteration`.
    pub fn light(kind: SamplerKind, seed: u64, iteration: u64, path: u64, paths: u64) -> Self {
        match kind {
            SamplerKind::Sobol => {
                let index = iteration.wrapping_mul(paths).wrapping_add(path);
                Sampler::Sobol(SobolSample::new(seed, Stream::Light, 0, index))
            }
            SamplerKind::Independent => {
                Sampler::Independent(Rng::for_sample(seed, iteration, path, Stream::Light))
            }
        }
    }

    /// Starts the numbers of the sub-path's vertex `vertex` (0: the camera's or the light's
    /// point). Each vertex draws from its own block of Sobol dimensions, so a draw keeps its
    /// dimension in every sample whatever was drawn before it on the path (a mirror bounce
    /// skips light sampling, a short path skips Russian roulette). Independent numbers need no
    /// such alignment and are left as they are.
    #[inline]
    pub fn start_vertex(&mut self, vertex: u32) {
        if let Sampler::Sobol(s) = self {
            s.dimension = u64::from(vertex) * DIMENSIONS_PER_VERTEX;
        }
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        match self {
            Sampler::Sobol(s) => s.next_1d(),
            Sampler::Independent(rng) => rng.next_f32(),
        }
    }

    /// Uniform in [0, 1)^2, the two numbers stratified together.
    #[inline]
    pub fn next_2d(&mut self) -> [f32; 2] {
        match self {
            Sampler::Sobol(s) => s.next_2d(),
            Sampler::Independent(rng) => rng.next_2d(),
        }
    }

    /// Two 2D points stratified jointly, such as a light sub-path's start: a point on the
    /// light and a direction from it.
    #[inline]
    pub fn next_4d(&mut self) -> [[f32; 2]; 2] {
        match self {
            Sampler::Sobol(s) => {
                let [a, b, c, d] = s.next_4d();
                [[a, b], [c, d]]
            }
            Sampler::Independent(rng) => [rng.next_2d(), rng.next_2d()],
        }
    }

    /// The numbers of one scattering: a BSDF sample's choice and 2D point (as
    /// [`Sampler::next_choice_2d`] has them) and, where `roulette`, the number Russian
    /// roulette compares with its continuation probability (else 0). The Sobol sampler takes
    /// all four from one slot: a hash and a shuffle fewer a vertex than a separate 1D draw,
    /// and the roulette number stratified jointly with the direction.
    #[inline(always)]
    pub fn next_scatter(&mut self, roulette: bool) -> ([f32; 3], f32) {
        match self {
            Sampler::Sobol(s) => s.next_scatter(roulette),
            Sampler::Independent(rng) => {
                let choice = rng.next_f32();
                let [u, v] = rng.next_2d();
                let r = if roulette { rng.next_f32() } else { 0.0 };
                ([choice, u, v], r)
            }
        }
    }

    /// A choice (`[0]`, such as a BSDF's lobe or a light) and a 2D point (`[1]`, `[2]`), as
    /// a BSDF sample or a light sample takes them. Always inlined: a call returns the three
    /// numbers through memory in pieces that the caller's wider loads straddle, a
    /// store-forwarding stall at every vertex.
    #[inline(always)]
    pub fn next_choice_2d(&mut self) -> [f32; 3] {
        match self {
            Sampler::Sobol(s) => s.next_choice_2d(),
            Sampler::Independent(rng) => {
                let choice = rng.next_f32();
                let [u, v] = rng.next_2d();
                [choice, u, v]
            }
        }
    }
}

/// Slots of draws one vertex may make: a light pick with its point, and a BSDF lobe with its
/// direction and the roulette number (2), with room to spare.
const DIMENSIONS_PER_VERTEX: u64 = 8;

/// One sample of a Sobol sequence: its index and the key that seeds its dimensions.
#[derive(Clone, Debug)]
pub struct SobolSample {
    /// The sample's index, bit-reversed: the shuffle and the scrambles work on reversed bits.
    reversed_index: u32,
    key: u64,
    dimension: u64,
}

impl SobolSample {
    /// Sample `index` of the sequence (`seed`, `stream`, `sequence`). Indices past 2^32 start
    /// a fresh randomisation rather than repeating points.
    fn new(seed: u64, stream: Stream, sequence: u64, index: u64) -> Self {
        let key = mix(seed ^ mix(stream as u64 ^ mix(sequence ^ mix(index >> 32))));
        SobolSample {
            reversed_index: (index as u32).reverse_bits(),
            key,
            dimension: 0,
        }
    }

    /// The hash of the next dimension slot: its low half shuffles the index, the high half
    /// seeds the coordinates' scrambles.
    #[inline]
    fn next_slot(&mut self) -> u64 {
        let h = mix(self.key ^ self.dimension.wrapping_mul(0x9e37_79b9_7f4a_7c15));
        self.dimension += 1;
        h
    }

    /// The index shuffled by slot hash `h` (the nested uniform scramble of the index, Burley
    /// sec. 6), left bit-reversed.
    #[inline]
    fn shuffled(&self, h: u64) -> u32 {
        laine_karras(self.reversed_index, h as u32)
    }

    #[inline]
    fn next_1d(&mut self) -> f32 {
        let h = self.next_slot();
        to_unit(scrambled(
            SobolDimension::Zero,
            self.shuffled(h),
            scramble_seeds(h)[0],
        ))
    }

    #[inline]
    fn next_2d(&mut self) -> [f32; 2] {
        let h = self.next_slot();
        point_2d(self.shuffled(h), h)
    }

    /// Dimensions 0-2 of one shuffled Sobol' point, the 2D point on dimensions 0 and 1 (as
    /// [`Self::next_2d`] has it: a (0, 2)-net for every power-of-two run) and the choice on
    /// dimension 2, stratified on its own and jointly with the point (a (1, m, 3)-net). One
    /// slot: a hash and a shuffle fewer than a 1D and a 2D draw.
    #[inline]
    fn next_choice_2d(&mut self) -> [f32; 3] {
        self.next_scatter(false).0
    }

    /// [`Self::next_choice_2d`]'s three numbers and, where `roulette`, dimension 3 of the same
    /// point (else 0): a (3, m, 4)-net for every power-of-two run.
    #[inline]
    fn next_scatter(&mut self, roulette: bool) -> ([f32; 3], f32) {
        let h = self.next_slot();
        let r = self.shuffled(h);
        let [u, v] = point_2d(r, h);
        let choice = to_unit(scrambled(SobolDimension::Two, r, third_seed(h)));
        let roulette = if roulette {
            to_unit(scrambled(SobolDimension::Three, r, fourth_seed(h)))
        } else {
            0.0
        };
        ([choice, u, v], roulette)
    }

    /// Dimensions 0-3 of one shuffled Sobol' point: a (3, m, 4)-net for every power-of-two
    /// run, so the two 2D points are stratified jointly, not only each on its own. Two slots.
    #[inline]
    fn next_4d(&mut self) -> [f32; 4] {
        let h = self.next_slot();
        let r = self.shuffled(h);
        let [a, b] = point_2d(r, h);
        let [s2, s3] = scramble_seeds(self.next_slot());
        [
            a,
            b,
            to_unit(scrambled(SobolDimension::Two, r, s2)),
            to_unit(scrambled(SobolDimension::Three, r, s3)),
        ]
    }
}

/// Two scramble seeds from a slot's hash.
#[inline]
fn scramble_seeds(h: u64) -> [u32; 2] {
    [
        (h >> 32) as u32,
        (h.wrapping_mul(0xd1b5_4a32_d192_ed03) >> 32) as u32,
    ]
}

/// Dimensions 0 and 1 of the shuffled point `r` of the slot hashed `h`, scrambled by the
/// slot's seeds.
#[inline]
fn point_2d(r: u32, h: u64) -> [f32; 2] {
    let [s0, s1] = scramble_seeds(h);
    [
        to_unit(scrambled(SobolDimension::Zero, r, s0)),
        to_unit(scrambled(SobolDimension::One, r, s1)),
    ]
}

/// A third scramble seed from a slot's hash, for a slot's dimension 2.
#[inline]
fn third_seed(h: u64) -> u32 {
    (h.wrapping_mul(0x94d0_49bb_1331_11eb) >> 32) as u32
}

/// A fourth scramble seed from a slot's hash, for a slot's dimension 3.
#[inline]
fn fourth_seed(h: u64) -> u32 {
    (h.wrapping_mul(0xbf58_476d_1ce4_e5b9) >> 32) as u32
}

/// The first four dimensions of Sobol'.
#[derive(Clone, Copy)]
enum SobolDimension {
    Zero,
    One,
    Two,
    Three,
}

/// Owen-scrambled Sobol' coordinate of the index whose reversed bits are `r`: an Owen scramble
/// of x is reverse(permute(reverse(x))), and reverse(x) is [`sobol_reversed`] of `r`.
#[inline]
fn scrambled(dimension: SobolDimension, r: u32, seed: u32) -> u32 {
    laine_karras(sobol_reversed(dimension, r), seed).reverse_bits()
}

/// A hash permutation of 32-bit words in which every bit is flipped by a function of the bits
/// below it, so on bit-reversed numbers it is an Owen scramble (Burley 2020, sec. 4, with his
/// improved constants).
#[inline]
fn laine_karras(mut x: u32, seed: u32) -> u32 {
    x = x.wrapping_add(seed);
    x ^= x.wrapping_mul(0x6c50_b47c);
    x ^= x.wrapping_mul(0xb82f_1e52);
    x ^= x.wrapping_mul(0xc7af_e638);
    x ^= x.wrapping_mul(0x8d22_f6e6);
    x
}

/// Sobol' dimension `dimension` with its input and output bit-reversed,
/// reverse(C reverse(r)) for the dimension's generator matrix C, from four byte-indexed
/// tables: a linear map over GF(2), so each set bit of `r` adds (XOR) one reversed direction
/// number. Dimension 0 (van der Corput, C = the bit reversal) is reverse(r) itself.
#[inline]
fn sobol_reversed(dimension: SobolDimension, r: u32) -> u32 {
    let tables = match dimension {
        SobolDimension::Zero => return r.reverse_bits(),
        SobolDimension::One => &SOBOL_REVERSED_BYTES[0],
        SobolDimension::Two => &SOBOL_REVERSED_BYTES[1],
        SobolDimension::Three => &SOBOL_REVERSED_BYTES[2],
    };
    let [b0, b1, b2, b3] = r.to_le_bytes();
    tables[0][b0 as usize]
        ^ tables[1][b1 as usize]
        ^ tables[2][b2 as usize]
        ^ tables[3][b3 as usize]
}

/// The primitive polynomials and initial direction numbers m_1..m_s of Sobol' dimensions 1-3
/// (Joe and Kuo's `new-joe-kuo-6.21201`, its d = 2, 3, 4): degree s, the inner coefficients
/// a_1..a_(s-1) as the bits of a (a_1 highest), and m.
const POLYNOMIALS: [(u32, u32, [u32; 3]); 3] =
    [(1, 0, [1, 0, 0]), (2, 1, [1, 3, 0]), (3, 1, [1, 3, 1])];

/// The 32 direction numbers v_1..v_32 of a dimension, as 32-bit fixed point (v_k = m_k / 2^k),
/// by Bratley and Fox's recurrence m_k = 2 a_1 m_(k-1) ^ 4 a_2 m_(k-2) ^ ... ^ 2^s m_(k-s) ^
/// m_(k-s).
const fn directions(degree: u32, a: u32, initial: [u32; 3]) -> [u32; 32] {
    let s = degree as usize;
    let mut m = [0u64; 32];
    let mut k = 0;
    while k < 32 {
        m[k] = if k < s {
            initial[k] as u64
        } else {
            let mut x = m[k - s] ^ (m[k - s] << s);
            let mut i = 1;
            while i < s {
                if (a >> (s - 1 - i)) & 1 == 1 {
                    x ^= m[k - i] << i;
                }
                i += 1;
            }
            x
        };
        k += 1;
    }
    let mut v = [0u32; 32];
    let mut k = 0;
    while k < 32 {
        // m_k < 2^k, so m_k / 2^k in 32 bits is m_k << (32 - k) with k counted from 1.
        v[k] = (m[k] << (31 - k)) as u32;
        k += 1;
    }
    v
}

/// `SOBOL_REVERSED_BYTES[d - 1][k][b]`: [`sobol_reversed`] of dimension d at `b << 8k`.
static SOBOL_REVERSED_BYTES: [[[u32; 256]; 4]; 3] = [
    reversed_byte_tables(POLYNOMIALS[0]),
    reversed_byte_tables(POLYNOMIALS[1]),
    reversed_byte_tables(POLYNOMIALS[2]),
];

const fn reversed_byte_tables((degree, a, initial): (u32, u32, [u32; 3])) -> [[u32; 256]; 4] {
    // Bit p of r is bit 31 - p of the index, whose direction number is v_(32 - p).
    let v = directions(degree, a, initial);
    let mut tables = [[0u32; 256]; 4];
    let mut k = 0;
    while k < 4 {
        let mut b = 0;
        while b < 256 {
            let mut x = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if b & (1 << bit) != 0 {
                    x ^= v[31 - (8 * k + bit)].reverse_bits();
                }
                bit += 1;
            }
            tables[k][b] = x;
            b += 1;
        }
        k += 1;
    }
    tables
}

/// The top 24 bits as a float in [0, 1), never rounded up to 1.
#[inline]
fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Dimension 1 of Sobol' bit by bit, the definition the tables are built from.
    fn sobol_1_reference(mut i: u32) -> u32 {
        let (mut x, mut v) = (0u32, 1u32 << 31);
        while i != 0 {
            if i & 1 != 0 {
                x ^= v;
            }
            i >>= 1;
            v ^= v >> 1;
        }
        x
    }

    #[test]
    fn dimension_1_tables_match_the_generator() {
        let mut rng = Rng::from_seed(1, 2);
        for i in (0..4096).chain((0..4096).map(|_| rng.next_u32())) {
            let r = i.reverse_bits();
            assert_eq!(
                sobol_reversed(SobolDimension::One, r).reverse_bits(),
                sobol_1_reference(i),
                "index {i}"
            );
        }
        // The first points of Sobol' dimension 1: 0, 1/2, 3/4, 1/4.
        let first: Vec<u32> = (0u32..4)
            .map(|i| sobol_reversed(SobolDimension::One, i.reverse_bits()).reverse_bits() >> 30)
            .collect();
        assert_eq!(first, [0, 2, 3, 1]);
    }

    /// The direction numbers m_k of dimensions 1-3, as SciPy's `qmc.Sobol` (Joe and Kuo's
    /// numbers) gives them: its first 1024 unscrambled points match these to the bit.
    #[test]
    fn direction_numbers_follow_the_recurrence() {
        let m = |d: usize, k: usize| {
            directions(POLYNOMIALS[d].0, POLYNOMIALS[d].1, POLYNOMIALS[d].2)[k] >> (31 - k)
        };
        assert_eq!(
            (0..6).map(|k| m(0, k)).collect::<Vec<_>>(),
            [1, 3, 5, 15, 17, 51]
        );
        assert_eq!(
            (0..6).map(|k| m(1, k)).collect::<Vec<_>>(),
            [1, 3, 3, 9, 29, 23]
        );
        assert_eq!(
            (0..6).map(|k| m(2, k)).collect::<Vec<_>>(),
            [1, 3, 1, 5, 31, 29]
        );
    }

    /// How many of `points` lie in each elementary box of the dimensions `dims`, split in
    /// 2^`shape[k]` along `dims[k]`.
    fn box_counts<const N: usize>(points: &[[f32; N]], dims: &[usize], shape: &[u32]) -> Vec<u32> {
        let mut counts = vec![0u32; 1 << shape.iter().sum::<u32>()];
        for p in points {
            let mut cell = 0usize;
            for (&d, &bits) in dims.iter().zip(shape) {
                cell = (cell << bits) | (p[d] * (1u32 << bits) as f32) as usize;
            }
            counts[cell] += 1;
        }
        counts
    }

    /// The four dimensions of the first 2^m shuffled points form a (3, m, 4)-net: every
    /// elementary box of volume 2^(3 - m) holds exactly 2^3 of them.
    #[test]
    fn four_dimensional_prefixes_are_nets() {
        let m = 8u32;
        let points: Vec<[f32; 4]> = (0..1u64 << m)
            .map(|i| SobolSample::new(6, Stream::Light, 0, i).next_4d())
            .collect();
        assert_four_dimensional_net(&points, m);
    }

    /// Every elementary box of volume 2^(3 - m) holds exactly 2^3 of the 2^m `points`: a
    /// (3, m, 4)-net.
    fn assert_four_dimensional_net(points: &[[f32; 4]], m: u32) {
        let volume_bits = m - 3;
        for a0 in 0..=volume_bits {
            for a1 in 0..=volume_bits - a0 {
                for a2 in 0..=volume_bits - a0 - a1 {
                    let a = [a0, a1, a2, volume_bits - a0 - a1 - a2];
                    let counts = box_counts(points, &[0, 1, 2, 3], &a);
                    assert!(counts.iter().all(|&c| c == 8), "shape {a:?}: {counts:?}");
                }
            }
        }
    }

    /// A scattering's four numbers from one slot: its first three are the slot's choice and
    /// point, with or without the roulette number, and the first 2^m form a (3, m, 4)-net.
    #[test]
    fn scatter_draws_extend_the_choice_and_point_to_a_net() {
        let m = 8u32;
        let mut samples = Vec::new();
        for i in 0..1u64 << m {
            let (u, roulette) = SobolSample::new(3, Stream::Eye, 9, i).next_scatter(true);
            assert_eq!(
                SobolSample::new(3, Stream::Eye, 9, i).next_scatter(false),
                (u, 0.0)
            );
            assert_eq!(u, SobolSample::new(3, Stream::Eye, 9, i).next_choice_2d());
            samples.push([u[0], u[1], u[2], roulette]);
        }
        assert_four_dimensional_net(&samples, m);
    }

    /// A choice and a point from one slot: the first 2^m of them form a (1, m, 3)-net (every
    /// elementary box of volume 2^(1 - m) holds exactly 2), and the points alone a (0, m, 2)-net.
    #[test]
    fn choice_and_point_prefixes_are_nets() {
        let m = 8u32;
        let samples: Vec<[f32; 3]> = (0..1u64 << m)
            .map(|i| SobolSample::new(11, Stream::Eye, 5, i).next_choice_2d())
            .collect();
        for a0 in 0..m {
            for a1 in 0..m - a0 {
                let shape = [a0, a1, m - 1 - a0 - a1];
                let counts = box_counts(&samples, &[0, 1, 2], &shape);
                assert!(
                    counts.iter().all(|&c| c == 2),
                    "shape {shape:?}: {counts:?}"
                );
            }
        }
        for a in 0..=m {
            let counts = box_counts(&samples, &[1, 2], &[a, m - a]);
            assert!(
                counts.iter().all(|&c| c == 1),
                "point shape {a}: {counts:?}"
            );
        }
    }

    #[test]
    fn scrambles_are_bijections_that_keep_prefixes() {
        // An Owen scramble maps every aligned interval of length 2^-k onto another: the top k
        // bits of the result depend on the top k bits of the input only. Here it scrambles the
        // number x (the van der Corput point of the index whose reversed bits are x).
        let mut rng = Rng::from_seed(3, 4);
        for _ in 0..1000 {
            let (x, y, seed) = (rng.next_u32(), rng.next_u32(), rng.next_u32());
            let k = rng.next_u32() % 32;
            let top = |v: u32| v.checked_shr(32 - k).unwrap_or(0);
            let same_top = top(x) == top(y);
            let (sx, sy) = (
                scrambled(SobolDimension::Zero, x, seed),
                scrambled(SobolDimension::Zero, y, seed),
            );
            assert_eq!(same_top, top(sx) == top(sy));
            assert_eq!(x == y, sx == sy);
        }
    }

    /// The samples `0..n` of a pixel's first dimensions.
    fn pixel_points(seed: u64, pixel: u64, n: u64, skip: usize) -> Vec<[f32; 2]> {
        (0..n)
            .map(|i| {
                let mut s = SobolSample::new(seed, Stream::Eye, pixel, i);
                for _ in 0..skip {
                    s.next_1d();
                }
                s.next_2d()
            })
            .collect()
    }

    #[test]
    fn every_power_of_two_prefix_is_a_net() {
        // (0, m, 2)-net: each of the 2^m elementary boxes of every shape 2^-a x 2^-(m-a)
        // holds exactly one of the first 2^m points.
        for (pixel, skip) in [(0, 0), (17, 1), (123_456, 5)] {
            let points = pixel_points(9, pixel, 256, skip);
            for m in 0..=8u32 {
                let prefix = &points[..1 << m];
                for a in 0..=m {
                    let mut seen = vec![false; 1 << m];
                    for p in prefix {
                        let cx = (p[0] * (1u32 << a) as f32) as usize;
                        let cy = (p[1] * (1u32 << (m - a)) as f32) as usize;
                        let cell = cx << (m - a) | cy;
                        assert!(!seen[cell], "pixel {pixel}, 2^{m} points, shape {a}");
                        seen[cell] = true;
                    }
                }
            }
        }
    }

    #[test]
    fn one_dimensional_prefixes_are_stratified() {
        for pixel in [0, 5, 99] {
            let n = 64;
            let mut strata = vec![false; n];
            for i in 0..n as u64 {
                let mut s = SobolSample::new(2, Stream::Eye, pixel, i);
                s.next_2d();
                let x = s.next_1d();
                let cell = (x * n as f32) as usize;
                assert!(!strata[cell], "pixel {pixel}, sample {i}");
                strata[cell] = true;
            }
        }
    }

    #[test]
    fn each_sample_is_uniform_and_its_dimensions_independent() {
        // Over many pixels (independent randomisations) sample 0's coordinates are uniform and
        // the products of different dimensions average 1/4. 5 standard errors.
        let n = 200_000u64;
        let (mut sums, mut cross) = ([0.0f64; 4], [0.0f64; 2]);
        for pixel in 0..n {
            let mut s = SobolSample::new(11, Stream::Light, pixel, 3);
            let [a, b] = s.next_2d();
            let c = s.next_1d();
            let [d, _] = s.next_2d();
            for (sum, x) in sums.iter_mut().zip([a, b, c, d]) {
                assert!((0.0..1.0).contains(&x));
                *sum += x as f64;
            }
            cross[0] += (a * c) as f64;
            cross[1] += (b * d) as f64;
        }
        let n = n as f64;
        for sum in sums {
            assert!((sum / n - 0.5).abs() < 5.0 * (1.0 / 12.0 / n).sqrt());
        }
        // Var(XY) for independent uniforms = 1/9 - 1/16.
        for c in cross {
            assert!((c / n - 0.25).abs() < 5.0 * ((1.0 / 9.0 - 1.0 / 16.0) / n).sqrt());
        }
    }

    #[test]
    fn light_paths_of_one_iteration_are_stratified_together() {
        let (paths, iteration) = (1024u64, 3u64);
        let mut seen = vec![false; paths as usize];
        for path in 0..paths {
            let Sampler::Sobol(mut s) =
                Sampler::light(SamplerKind::Sobol, 4, iteration, path, paths)
            else {
                unreachable!()
            };
            let [x, y] = s.next_2d();
            let cell = ((x * 32.0) as usize) * 32 + (y * 32.0) as usize;
            assert!(!seen[cell], "path {path}");
            seen[cell] = true;
        }
    }
}
