//! Random numbers, below every stage of the pipeline so that each uses the
//! same few generators.
//!
//! The path tracer draws one PCG32 stream per pixel sample, seeded by
//! hashing (seed, pixel, sample index): a sample's numbers therefore do not
//! depend on which thread renders it or in which order, so images are
//! identical for any thread count. SplitMix64 serves where one short
//! fixed-seed stream is enough (visibility sampling, test geometry, bench
//! inputs) and its finalizer is the hash that seeds PCG32.

/// PCG32 (O'Neill 2014, XSH-RR output, 64-bit LCG state).
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const MULT: u64 = 6364136223846793005;

/// SplitMix64's increment, the golden ratio in 64 bits: consecutive
/// states differ in about half their bits.
pub const GOLDEN: u64 = 0x9e37_79b9_7f4a_7c15;

/// SplitMix64's finalizer: a bijective mixer that spreads nearby inputs.
pub fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

impl Pcg32 {
    /// The stream for one sample of one pixel under a global seed.
    pub fn for_sample(seed: u64, pixel: u64, sample: u64) -> Self {
        let a = mix(seed ^ GOLDEN);
        let b = mix(a ^ pixel.wrapping_mul(0xd1b54a32d192ed03));
        let c = mix(b ^ sample.wrapping_mul(0x8cb92ba72f3d8dd7));
        let mut rng = Self {
            state: 0,
            inc: (mix(c ^ 0x5851f42d4c957f2d) << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(c);
        rng.next_u32();
        rng
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in `[0, 1)`: 24 random mantissa bits, so never rounds to 1.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Uniform in `[0, 1)` with 53 bits, for picking from large tables.
    pub fn next_f64(&mut self) -> f64 {
        let hi = (self.next_u32() as u64) << 21;
        let lo = (self.next_u32() >> 11) as u64;
        (hi | lo) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }
}

/// SplitMix64 (Steele, Lea and Flood 2014): a counter stepped by
/// [`GOLDEN`] and passed through [`mix`]. Statistically sound for the
/// short streams it serves and cheap to start anywhere, since any `u64`
/// is a good state.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(GOLDEN);
        mix(self.0)
    }

    /// Uniform in `[0, 1)`: the top 24 bits, so never rounds to 1.
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 * (1.0 / 16_777_216.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn streams_are_reproducible_and_distinct() {
        let draw = |s, p, i| {
            let mut r = Pcg32::for_sample(s, p, i);
            (0..4).map(|_| r.next_u32()).collect::<Vec<_>>()
        };
        assert_eq!(draw(1, 2, 3), draw(1, 2, 3));
        assert_ne!(draw(1, 2, 3), draw(1, 2, 4));
        assert_ne!(draw(1, 2, 3), draw(1, 3, 3));
        assert_ne!(draw(1, 2, 3), draw(2, 2, 3));
    }

    #[test]
    fn uniform_moments() {
        let n = 200_000;
        let (mut sum, mut sq) = (0.0f64, 0.0f64);
        for p in 0..n {
            let x = Pcg32::for_sample(7, p, 0).next_f32() as f64;
            assert!((0.0..1.0).contains(&x));
            sum += x;
            sq += x * x;
        }
        let mean = sum / n as f64;
        let var = sq / n as f64 - mean * mean;
        // Standard error of the mean is 0.29 / sqrt(n) = 6.5e-4.
        assert!((mean - 0.5).abs() < 3e-3, "mean {mean}");
        assert!((var - 1.0 / 12.0).abs() < 2e-3, "variance {var}");
    }

    /// The first outputs of SplitMix64 from seed 0 as published with
    /// the algorithm (and in Java's `SplittableRandom`).
    #[test]
    fn splitmix_matches_the_reference_outputs() {
        let mut r = SplitMix64::new(0);
        assert_eq!(r.next_u64(), 0xe220_a839_7b1d_cdaf);
        assert_eq!(r.next_u64(), 0x6e78_9e6a_a1b9_65f4);
        assert_eq!(r.next_u64(), 0x06c4_5d18_8009_454f);
        let x = SplitMix64::new(3).next_f32();
        assert!((0.0..1.0).contains(&x));
    }
}
