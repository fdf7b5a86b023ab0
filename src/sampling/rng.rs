//! PCG32 (O'Neill 2014): small state, good statistics, and independent streams, so every
//! (seed, iteration, pixel, purpose) gets its own sequence and images do not depend on threads.

/// What a random stream is used for; part of its seed so the light pass and the eye pass of
/// one pixel never share numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u64)]
pub enum Stream {
    Eye = 1,
    Light = 2,
    Tentative = 3,
    /// `vcm-upg`'s choice, per merge, of the estimate that makes it.
    Blend = 4,
}

#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

const MULTIPLIER: u64 = 6364136223846793005;

/// SplitMix64 finaliser: spreads consecutive integers over the whole 64-bit range.
pub(super) fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

impl Rng {
    /// A generator from a raw seed and stream selector.
    pub fn from_seed(seed: u64, sequence: u64) -> Self {
        let mut rng = Rng {
            state: 0,
            inc: (sequence << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The stream of one pixel (or light sub-path index) in one iteration.
    pub fn for_sample(seed: u64, iteration: u64, index: u64, stream: Stream) -> Self {
        let key = mix(seed ^ mix(iteration.wrapping_add(mix(stream as u64))));
        Rng::from_seed(mix(key ^ index), mix(key.wrapping_add(index)))
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1): 24 random bits, so the result is never rounded up to 1.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    pub fn next_2d(&mut self) -> [f32; 2] {
        [self.next_f32(), self.next_f32()]
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        let hi = (self.next_u32() as u64) << 21;
        let lo = (self.next_u32() >> 11) as u64;
        (hi | lo) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_mean_and_range() {
        let mut rng = Rng::for_sample(7, 3, 11, Stream::Eye);
        let n = 200_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        let mean = sum / n as f64;
        // Standard error of the mean of U(0,1) is sqrt(1/12/n) ~ 6.5e-4; 5 sigma.
        assert!((mean - 0.5).abs() < 5.0 * (1.0 / 12.0 / n as f64).sqrt());
    }

    #[test]
    fn streams_differ() {
        let a = Rng::for_sample(1, 0, 0, Stream::Eye).next_u32();
        let b = Rng::for_sample(1, 0, 0, Stream::Light).next_u32();
        let c = Rng::for_sample(1, 0, 1, Stream::Eye).next_u32();
        let d = Rng::for_sample(1, 1, 0, Stream::Eye).next_u32();
        assert!(a != b && a != c && a != d && c != d);
        assert_eq!(a, Rng::for_sample(1, 0, 0, Stream::Eye).next_u32());
    }
}
