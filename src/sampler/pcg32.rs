/// PCG32 (O'Neill 2014, "PCG-XSH-RR" with 64-bit state): small, fast, and statistically good
/// enough for Monte Carlo. Also drives the benchmark ray sets (BENCHMARK.md).
#[derive(Debug, Clone)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const MULT: u64 = 6364136223846793005;

impl Pcg32 {
    /// A generator for slots that are never drawn from (a path of the Sobol sampler), made
    /// without the cost of seeding one.
    pub const UNUSED: Pcg32 = Pcg32 { state: 0, inc: 1 };

    /// A generator on stream `stream` (any value; the increment is made odd), seeded with `seed`.
    pub fn new(seed: u64, stream: u64) -> Pcg32 {
        let mut rng = Pcg32 { state: 0, inc: (stream << 1) | 1 };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULT).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// An independent stream for item `index` (e.g. a pixel sample) of a render seeded `seed`.
    ///
    /// PCG streams that differ only in their increment are strongly correlated, so every item
    /// shares one increment and starts at its own hashed point of the 2^64-long sequence instead.
    pub fn for_index(seed: u64, index: u64) -> Pcg32 {
        Pcg32::new(splitmix64(seed ^ splitmix64(index)), 0)
    }

    /// A uniform float in [0, 1): the top 24 bits, so every value is exactly representable.
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

/// The splitmix64 finaliser (Steele et al. 2014): a bijective 64-bit mixer.
pub fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_reference_sequence() {
        // pcg32-global demo: seed 42, stream 54 starts with 0xa15c02b7 0x7b47f409 0xba1d3330.
        let mut r = Pcg32::new(42, 54);
        assert_eq!(
            [r.next_u32(), r.next_u32(), r.next_u32()],
            [0xa15c02b7, 0x7b47f409, 0xba1d3330]
        );
    }

    #[test]
    fn neighbouring_index_streams_are_uncorrelated() {
        // The sample correlation of the first draws of adjacent items must look like noise.
        let n = 20_000;
        let xs: Vec<(f64, f64)> = (0..n)
            .map(|i| {
                let a = Pcg32::for_index(1, i).next_f32() as f64 - 0.5;
                let b = Pcg32::for_index(1, i + 1).next_f32() as f64 - 0.5;
                (a, b)
            })
            .collect();
        let cov: f64 = xs.iter().map(|(a, b)| a * b).sum::<f64>() / n as f64;
        let corr = cov / (1.0 / 12.0);
        assert!(corr.abs() < 4.0 / (n as f64).sqrt(), "correlation {corr}");
        // And different seeds give different streams for the same item.
        assert_ne!(Pcg32::for_index(1, 5).next_u32(), Pcg32::for_index(2, 5).next_u32());
    }

    #[test]
    fn floats_are_in_the_unit_interval_and_roughly_uniform() {
        let mut r = Pcg32::new(1, 2);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let x = r.next_f32();
            assert!((0.0..1.0).contains(&x));
            sum += x as f64;
        }
        assert!((sum / n as f64 - 0.5).abs() < 0.01);
    }
}
