//! The random numbers of a whole queue's path vertices, drawn in one pass.
//!
//! Every path vertex at one depth may take the same list of decisions (light samples, a BSDF
//! sample, lobe and roulette), so shading first plans that list, then draws every number of
//! every queued path here, and the shading code only reads them. For the Sobol sampler the
//! draws are one flat loop of integer hashing over arrays, which the compiler vectorises; drawn
//! one at a time inside the shading code they cost more than the area-light sampling itself
//! (PERF.md "Whole renders").

use super::{sobol, Decision, PathSampler, SamplerKind};

/// One 2D number per (queued path, planned slot). Stored by blocks of `LANES` queue entries,
/// slot-major within a block and each slot's first coordinates before its second ones
/// (`[block][slot][coordinate][lane]`), so that the lanes of a shading chunk load a slot's
/// coordinate with one vector load and the draw loop writes its lane arrays as they are.
#[derive(Default)]
pub struct DrawBatch {
    depth: u32,
    /// Per slot: the decision, its draw number and how many draws of it a vertex takes.
    slots: Vec<(Decision, u32, u32)>,
    /// Per slot: the Sobol dimension key of `(decision, depth)`.
    dimensions: Vec<u32>,
    numbers: Vec<f32>,
}

impl DrawBatch {
    /// Starts a new plan for vertices reached by rays of depth `depth`.
    pub fn plan(&mut self, depth: u32) {
        self.depth = depth;
        self.slots.clear();
        self.dimensions.clear();
    }

    /// Plans `count` draws of `decision` per vertex; returns the first one's slot.
    pub fn add(&mut self, decision: Decision, count: u32) -> usize {
        let first = self.slots.len();
        for sub in 0..count {
            self.slots.push((decision, sub, count));
            self.dimensions.push(decision.dimension(self.depth));
        }
        first
    }

    /// Numbers per vertex.
    pub fn stride(&self) -> usize {
        self.slots.len()
    }

    /// Draws every planned number for the paths `order` names (queue order) among `samplers`.
    pub fn draw(&mut self, kind: SamplerKind, samplers: &mut [PathSampler], order: &[u32]) {
        if self.slots.is_empty() {
            return; // Nothing planned (normal shading, or vertices past the last depth).
        }
        let stride = self.slots.len();
        // Grown, never cleared or shrunk: every number a vertex reads is written below, so
        // old values need no zeroing, and a batch that shrank at a deep bounce (or emptied at
        // the last depth) does not zero its growth again at the next tile's camera rays
        // (clearing and refilling had zeroed the whole batch per depth: a memset of 1% of a
        // `-m 5` render's instructions; resizing to each depth's length still zeroed 0.26%).
        let needed = order.len().div_ceil(LANES) * 2 * LANES * stride;
        if self.numbers.len() < needed {
            self.numbers.resize(needed, 0.0);
        }
        let blocks = order.chunks(LANES).zip(self.numbers.chunks_mut(2 * LANES * stride));
        match kind {
            SamplerKind::Independent => {
                for (paths, out) in blocks {
                    for (l, &p) in paths.iter().enumerate() {
                        let sampler = &mut samplers[p as usize];
                        for k in 0..stride {
                            out[2 * k * LANES + l] = sampler.rng.next_f32();
                            out[(2 * k + 1) * LANES + l] = sampler.rng.next_f32();
                        }
                    }
                }
            }
            SamplerKind::Sobol => {
                for (paths, out) in blocks {
                    draw_sobol_block(&self.slots, &self.dimensions, samplers, paths, out);
                }
            }
        }
    }

    /// The numbers of queue entry `q`.
    #[inline]
    pub fn of(&self, q: usize) -> Numbers<'_> {
        let (block, lane) = self.block_of(q);
        Numbers { block, lane }
    }

    /// The block holding queue entry `q` (`[slot][coordinate][lane]`, `LANES` lanes per
    /// coordinate) and its lane.
    #[inline]
    pub fn block_of(&self, q: usize) -> (&[f32], usize) {
        let n = self.slots.len() * 2 * LANES;
        (&self.numbers[q / LANES * n..(q / LANES + 1) * n], q % LANES)
    }
}

/// One queue entry's numbers in a `DrawBatch`.
#[derive(Clone, Copy)]
pub struct Numbers<'a> {
    block: &'a [f32],
    lane: usize,
}

impl Numbers<'_> {
    /// The number of planned slot `slot`.
    #[inline]
    pub fn get(&self, slot: usize) -> [f32; 2] {
        let at = 2 * slot * LANES + self.lane;
        [self.block[at], self.block[at + LANES]]
    }
}

/// Paths whose numbers one SIMD pass draws, and the block size of the numbers' layout.
pub const LANES: usize = 16;

/// Every planned number of up to `LANES` paths (`out`: their block,
/// `[slot][coordinate][lane]`).
/// Each slot's numbers come from one fixed-size lane loop, branch-free and all in 32-bit
/// integers, which the compiler turns into SIMD; lanes past `paths.len()` compute
/// numbers nobody reads.
fn draw_sobol_block(
    slots: &[(Decision, u32, u32)],
    dimensions: &[u32],
    samplers: &[PathSampler],
    paths: &[u32],
    out: &mut [f32],
) {
    let (mut pixel_key, mut sample) = ([0u32; LANES], [0u32; LANES]);
    for (l, &p) in paths.iter().enumerate() {
        let s = &samplers[p as usize];
        (pixel_key[l], sample[l]) = (s.pixel_key, s.sample);
    }
    for (k, (&(_, sub, count), &dimension)) in slots.iter().zip(dimensions).enumerate() {
        let (mut x, mut y) = ([0.0f32; LANES], [0.0f32; LANES]);
        for l in 0..LANES {
            let key = sobol::mix32(pixel_key[l] ^ dimension);
            [x[l], y[l]] = sobol::sobol_2d(key, sample[l].wrapping_mul(count).wrapping_add(sub));
        }
        out[2 * k * LANES..(2 * k + 1) * LANES].copy_from_slice(&x);
        out[(2 * k + 1) * LANES..(2 * k + 2) * LANES].copy_from_slice(&y);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The batch hands every path exactly the numbers `PathSampler::get_2d` would draw.
    #[test]
    fn batch_draws_equal_single_sobol_draws() {
        let (depth, spp) = (3, 64);
        let mut samplers: Vec<PathSampler> =
            (0..37).map(|i| PathSampler::new(7, 1000 + i / 5, (i % 5) as u32, spp)).collect();
        let mut batch = DrawBatch::default();
        batch.plan(depth);
        let lights = batch.add(Decision::SceneLight(1), 4);
        let bsdf = batch.add(Decision::Bsdf, 1);
        let lobe = batch.add(Decision::LobeAndRoulette, 1);
        let order: Vec<u32> = (0..samplers.len() as u32).rev().collect();
        batch.draw(SamplerKind::Sobol, &mut samplers, &order);
        for (q, &p) in order.iter().enumerate() {
            let (got, s) = (batch.of(q), &mut samplers[p as usize]);
            for j in 0..4 {
                let want = s.get_2d(SamplerKind::Sobol, depth, Decision::SceneLight(1), j, 4);
                assert_eq!(got.get(lights + j as usize), want);
            }
            assert_eq!(got.get(bsdf), s.get_2d(SamplerKind::Sobol, depth, Decision::Bsdf, 0, 1));
            let want = s.get_2d(SamplerKind::Sobol, depth, Decision::LobeAndRoulette, 0, 1);
            assert_eq!(got.get(lobe), want);
        }
        // The independent sampler: each path's numbers in slot order from its own stream.
        let mut fresh = samplers.clone();
        batch.draw(SamplerKind::Independent, &mut samplers, &order);
        for (q, &p) in order.iter().enumerate() {
            let rng = &mut fresh[p as usize].rng;
            for k in 0..batch.stride() {
                assert_eq!(batch.of(q).get(k), [rng.next_f32(), rng.next_f32()]);
            }
        }
        // A plan with no slots draws nothing, for any number of paths.
        batch.plan(depth);
        batch.draw(SamplerKind::Sobol, &mut samplers, &order);
        assert_eq!(batch.stride(), 0);
    }
}
