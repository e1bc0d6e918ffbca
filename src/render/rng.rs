//! Random numbers for the path tracer: one PCG32 stream per pixel sample,
//! seeded by hashing (seed, pixel, sample index). A sample's numbers therefore
//! do not depend on which thread renders it or in which order, so images are
//! identical for any thread count.

/// PCG32 (O'Neill 2014, XSH-RR output, 64-bit LCG state).
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const MULT: u64 = 6364136223846793005;

/// SplitMix64's finalizer: a bijective mixer that spreads nearby inputs.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58476d1ce4e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d049bb133111eb);
    z ^ (z >> 31)
}

impl Pcg32 {
    /// The stream for one sample of one pixel under a global seed.
    pub fn for_sample(seed: u64, pixel: u64, sample: u64) -> Self {
        let a = mix(seed ^ 0x9e3779b97f4a7c15);
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
}
