//! Binned surface area heuristic (Wald 2007): centroids are binned along each axis, and the
//! cheapest of the bin boundaries becomes the split.

use crate::math::{Aabb, Vec3};

use super::Builder;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Split {
    pub axis: usize,
    /// Primitives in bins `< bin` go left.
    pub bin: usize,
    /// Expected cost relative to one triangle test, comparable with a leaf's `count`.
    pub cost: f32,
    lo: f32,
    scale: f32,
}

impl Split {
    #[inline]
    fn bin_of(&self, c: Vec3, bins: usize) -> usize {
        (((c[self.axis] - self.lo) * self.scale) as usize).min(bins - 1)
    }
}

/// The cheapest bin boundary over all axes with nonzero centroid extent, if any.
pub fn find_split(
    b: &Builder,
    first: usize,
    count: usize,
    bounds: Aabb,
    centroids: Aabb,
) -> Option<Split> {
    let bins = b.params.bins;
    let parent_area = bounds.half_area().max(f32::MIN_POSITIVE);
    let mut best: Option<Split> = None;
    for axis in 0..3 {
        let (lo, hi) = (centroids.min[axis], centroids.max[axis]);
        if !(hi > lo) {
            continue; // zero extent: every centroid falls in one bin
        }
        let scale = bins as f32 * (1.0 - 1e-6) / (hi - lo);
        let probe = Split { axis, bin: 0, cost: 0.0, lo, scale };
        let mut bin_bounds = vec![Aabb::EMPTY; bins];
        let mut bin_count = vec![0u32; bins];
        for &i in &b.order[first..first + count] {
            let k = probe.bin_of(b.centroids[i as usize], bins);
            bin_bounds[k] = bin_bounds[k].union(b.bounds[i as usize]);
            bin_count[k] += 1;
        }
        // Sweep from the right to get the area and count of every right side.
        let mut right_area = vec![0.0f32; bins];
        let (mut acc, mut n) = (Aabb::EMPTY, 0u32);
        let mut right_count = vec![0u32; bins];
        for k in (1..bins).rev() {
            acc = acc.union(bin_bounds[k]);
            n += bin_count[k];
            right_area[k] = acc.half_area();
            right_count[k] = n;
        }
        let (mut acc, mut n) = (Aabb::EMPTY, 0u32);
        for k in 1..bins {
            acc = acc.union(bin_bounds[k - 1]);
            n += bin_count[k - 1];
            if n == 0 || right_count[k] == 0 {
                continue;
            }
            let cost = b.params.traversal_cost
                + (acc.half_area() * n as f32 + right_area[k] * right_count[k] as f32)
                    / parent_area;
            if best.is_none_or(|s| cost < s.cost) {
                best = Some(Split { axis, bin: k, cost, lo, scale });
            }
        }
    }
    best
}

/// Reorders `order[first .. first + count]` so the split's left side comes first; returns its
/// size.
pub fn partition(b: &mut Builder, first: usize, count: usize, split: Split) -> usize {
    let bins = b.params.bins;
    let range = &mut b.order[first..first + count];
    let (mut i, mut j) = (0, count);
    while i < j {
        if split.bin_of(b.centroids[range[i] as usize], bins) < split.bin {
            i += 1;
        } else {
            j -= 1;
            range.swap(i, j);
        }
    }
    i
}
