//! Binned surface area heuristic (Wald 2007): centroids are binned along each axis, and the
//! cheapest of the bin boundaries becomes the split. One pass over the primitives fills the
//! bins of all three axes; the bins live on the stack.

use glam::Vec4;

use super::{Box4, BuildParams, PrimRef};

/// Upper bound on `BuildParams::bins` (the size of the stack arrays).
pub const MAX_BINS: usize = 16;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Split {
    pub axis: usize,
    /// Primitives in bins `< bin` go left.
    pub bin: usize,
    /// Expected cost relative to one triangle test, comparable with a leaf's `count`.
    pub cost: f32,
    lo: f32,
    scale: f32,
    bins: usize,
}

impl Split {
    #[inline(always)]
    fn bin_of(&self, c: Vec4) -> usize {
        bin_index(c[self.axis], self.lo, self.scale, self.bins)
    }
}

#[inline(always)]
fn bin_index(c: f32, lo: f32, scale: f32, bins: usize) -> usize {
    // `as usize` saturates, so a rounding excursion below `lo` lands in bin 0.
    (((c - lo) * scale) as usize).min(bins - 1)
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Box4,
    count: u32,
}

const EMPTY_BIN: Bin = Bin { bounds: Box4::EMPTY, count: 0 };

/// The cheapest bin boundary over all axes with nonzero centroid extent, if any. `centroids`
/// bounds the primitives' `centroid2` (twice the centroid).
pub fn find_split(
    prims: &[PrimRef],
    bounds: Box4,
    centroids: Box4,
    params: &BuildParams,
) -> Option<Split> {
    // A small node cannot fill many bins; fewer bins make its sweep cheaper.
    let bins = params.bins.min(prims.len().max(4));
    let lo = centroids.min;
    let extent = centroids.max - centroids.min;
    // Zero extent on an axis: every centroid falls in one bin, so that axis has no split.
    let usable = [extent.x > 0.0, extent.y > 0.0, extent.z > 0.0];
    if !usable.iter().any(|&u| u) {
        return None;
    }
    let scale =
        Vec4::select(extent.cmpgt(Vec4::ZERO), bins as f32 * (1.0 - 1e-6) / extent, Vec4::ZERO);

    let mut grid = [[EMPTY_BIN; MAX_BINS]; 3];
    for p in prims {
        let c = p.centroid2();
        for axis in 0..3 {
            let bin = &mut grid[axis][bin_index(c[axis], lo[axis], scale[axis], bins)];
            bin.bounds = bin.bounds.grow(p);
            bin.count += 1;
        }
    }

    let parent_area = bounds.half_area().max(f32::MIN_POSITIVE);
    let mut best: Option<Split> = None;
    for axis in (0..3).filter(|&a| usable[a]) {
        let grid = &grid[axis][..bins];
        // Sweep from the right to get the area and count of every right side.
        let mut right_area = [0.0f32; MAX_BINS];
        let mut right_count = [0u32; MAX_BINS];
        let (mut acc, mut n) = (Box4::EMPTY, 0u32);
        for k in (1..bins).rev() {
            acc = acc.union(grid[k].bounds);
            n += grid[k].count;
            right_area[k] = acc.half_area();
            right_count[k] = n;
        }
        let (mut acc, mut n) = (Box4::EMPTY, 0u32);
        for k in 1..bins {
            acc = acc.union(grid[k - 1].bounds);
            n += grid[k - 1].count;
            if n == 0 || right_count[k] == 0 {
                continue;
            }
            let cost = params.traversal_cost
                + (acc.half_area() * n as f32 + right_area[k] * right_count[k] as f32)
                    / parent_area;
            if best.is_none_or(|s| cost < s.cost) {
                best = Some(Split { axis, bin: k, cost, lo: lo[axis], scale: scale[axis], bins });
            }
        }
    }
    best
}

/// Reorders `prims` so the split's left side comes first; returns its size.
pub fn partition(prims: &mut [PrimRef], split: Split) -> usize {
    let (mut i, mut j) = (0, prims.len());
    while i < j {
        if split.bin_of(prims[i].centroid2()) < split.bin {
            i += 1;
        } else {
            j -= 1;
            prims.swap(i, j);
        }
    }
    i
}
