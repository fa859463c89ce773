//! Random numbers. Every number a path draws is derived from (seed, pixel, sample index, the
//! decision it feeds) so that an image does not depend on the thread count or the order in
//! which work is scheduled.
//!
//! Two samplers: `Sobol` (the default) gives every decision of a path its own Owen-scrambled 2D
//! Sobol sequence over the pixel's samples (`sobol.rs`), so a pixel's samples stratify each
//! decision; `Independent` draws everything from one PCG32 stream per pixel sample.

mod batch;
mod pcg32;
pub mod sobol;

pub use batch::{DrawBatch, Numbers, LANES as DRAW_BLOCK};
pub use pcg32::{splitmix64, Pcg32};

/// How a render draws its random numbers (`--sampler`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SamplerKind {
    /// Owen-scrambled Sobol points, one 2D sequence per decision (padded).
    #[default]
    Sobol,
    /// Independent uniform numbers from one PCG32 stream per pixel sample.
    Independent,
}

impl SamplerKind {
    /// The sampler's name, as `--sampler` takes it.
    pub fn name(&self) -> &'static str {
        match self {
            SamplerKind::Sobol => "sobol",
            SamplerKind::Independent => "independent",
        }
    }

    /// The sampler named `name` (as `name` returns it), or `None` for an unknown name.
    pub fn parse(name: &str) -> Option<SamplerKind> {
        match name {
            "sobol" => Some(SamplerKind::Sobol),
            "independent" => Some(SamplerKind::Independent),
            _ => None,
        }
    }
}

/// The random decisions of a path vertex; with the vertex depth they name a Sobol dimension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Decision {
    /// Where in the pixel the camera ray goes.
    CameraJitter,
    /// A point on scene light number `.0` (course light sampling).
    SceneLight(u32),
    /// Which emitter and where on it (emissive-geometry sampling under MIS).
    Emitter,
    /// A uniform hemisphere direction (`-H`).
    Hemisphere,
    /// The BSDF sample's direction.
    Bsdf,
    /// The BSDF lobe choice (x) and Russian roulette (y).
    LobeAndRoulette,
    /// Where in the pixel an extra camera ray on an emitter's outline goes
    /// (`--edge-samples`, `wavefront::stages::generate`).
    EdgeJitter,
}

impl Decision {
    /// The decision's Sobol dimension at `depth`, hashed: a pixel's sequence key is this
    /// XOR the pixel's key, mixed once more (`sobol::mix32`).
    fn dimension(self, depth: u32) -> u32 {
        let (slot, extra) = match self {
            Decision::CameraJitter => (0u32, 0u32),
            Decision::SceneLight(i) => (1, i),
            Decision::Emitter => (2, 0),
            Decision::Hemisphere => (3, 0),
            Decision::Bsdf => (4, 0),
            Decision::LobeAndRoulette => (5, 0),
            Decision::EdgeJitter => (6, 0),
        };
        // Depth below 2^16 and light index below 2^13 (both far beyond any render) keep the
        // dimensions distinct before the (bijective) mix.
        sobol::mix32((depth << 16) ^ (slot << 13) ^ extra)
    }
}

/// Hash of (seed, pixel): the root of a pixel's Sobol keys, shared by all its samples.
#[inline]
pub fn pixel_key(seed: u64, pixel: u64) -> u32 {
    splitmix64(seed ^ splitmix64(pixel).rotate_left(17)) as u32
}

/// The camera-jitter numbers of `N` paths of the Sobol sampler (pixel keys and sample
/// indices), each equal to its `PathSampler::get_2d(Sobol, 0, CameraJitter, 0, 1)`: one
/// fixed-size lane loop, which the compiler vectorises as it does `DrawBatch`'s.
#[inline]
pub fn sobol_camera_jitter<const N: usize>(
    pixel_keys: &[u32; N],
    samples: &[u32; N],
) -> ([f32; N], [f32; N]) {
    let dimension = Decision::CameraJitter.dimension(0);
    let (mut x, mut y) = ([0.0f32; N], [0.0f32; N]);
    for l in 0..N {
        [x[l], y[l]] = sobol::sobol_2d(sobol::mix32(pixel_keys[l] ^ dimension), samples[l]);
    }
    (x, y)
}

/// The random numbers of one path (one pixel sample).
#[derive(Debug, Clone)]
pub struct PathSampler {
    /// The independent stream (all numbers of `SamplerKind::Independent`).
    pub rng: Pcg32,
    /// Hash of (seed, pixel): the root of this pixel's Sobol keys.
    pixel_key: u32,
    /// The sample's index within its pixel.
    sample: u32,
}

impl PathSampler {
    /// The sampler of sample `sample` of pixel `pixel` (row-major index in the image) in a
    /// render seeded `seed` with `spp` samples per pixel.
    pub fn new(seed: u64, pixel: u64, sample: u32, spp: u32) -> PathSampler {
        let key = pixel_key(seed, pixel);
        PathSampler::for_pixel(SamplerKind::Independent, seed, pixel, key, sample, spp)
    }

    /// The sampler of sample `sample` of a pixel whose key is `pixel_key` (`pixel_key(seed,
    /// pixel)`, hashed once per pixel), for a render of `kind`. Equal to `new` wherever `kind`
    /// reads it: the Sobol sampler never touches the independent stream, so it is not seeded
    /// (two `splitmix64` and two PCG steps per path that camera-ray generation used to pay).
    #[inline]
    pub fn for_pixel(
        kind: SamplerKind,
        seed: u64,
        pixel: u64,
        pixel_key: u32,
        sample: u32,
        spp: u32,
    ) -> PathSampler {
        let rng = match kind {
            SamplerKind::Independent => Pcg32::for_index(seed, pixel * spp as u64 + sample as u64),
            SamplerKind::Sobol => Pcg32::UNUSED,
        };
        PathSampler { rng, pixel_key, sample }
    }

    /// The root of this pixel's Sobol keys (see `pixel_key`).
    #[inline]
    pub fn pixel_key(&self) -> u32 {
        self.pixel_key
    }

    /// The sample's index within its pixel.
    #[inline]
    pub fn sample(&self) -> u32 {
        self.sample
    }

    /// Two numbers in [0, 1) for `decision` at path depth `depth`. A decision taken `count`
    /// times per vertex (e.g. `-l` light samples) passes its draw number `sub` < `count`; the
    /// Sobol sampler then spreads the pixel's `spp x count` draws over one sequence.
    #[inline]
    pub fn get_2d(
        &mut self,
        kind: SamplerKind,
        depth: u32,
        decision: Decision,
        sub: u32,
        count: u32,
    ) -> [f32; 2] {
        match kind {
            SamplerKind::Independent => [self.rng.next_f32(), self.rng.next_f32()],
            SamplerKind::Sobol => {
                let key = sobol::mix32(self.pixel_key ^ decision.dimension(depth));
                let index = (self.sample as u64 * count as u64 + sub as u64) as u32;
                sobol::sobol_2d(key, index)
            }
        }
    }
}
