//! Binned surface area heuristic (Wald 2007): centroids are binned along each axis, and the
//! cheapest of the bin boundaries becomes the split. One pass over the primitives fills the
//! bins of all three axes; the bins live in a scratch buffer that the recursion reuses.

use glam::{BVec4A, Vec4};
use wide::{f32x4, i32x4};

use super::{Box4, Box8, BuildParams, PrimRef};

/// Upper bound on `BuildParams::bins` (the size of the scratch arrays).
pub const MAX_BINS: usize = 16;
const _: () = assert!(MAX_BINS.is_power_of_two());

#[derive(Debug, Clone, Copy)]
pub struct Split {
    pub axis: usize,
    /// Expected cost relative to one triangle test, comparable with a leaf's `count`.
    pub cost: f32,
    /// Bounds of each side: the union of its bins, i.e. exactly the union of its primitives'
    /// boxes, so the children need no pass of their own to find them.
    pub left: Box8,
    pub right: Box8,
    /// The binning's map (lane `axis` matters), and the first bin of the right side (as a
    /// float, in every lane): primitives in bins below it go left.
    lo: Vec4,
    scale: Vec4,
    bin: Vec4,
}

impl Split {
    /// Whether a primitive goes left. Equivalent to `bin_index(..) < bin`: truncation towards
    /// zero is below the integer `bin` exactly when the value is (and a negative or NaN value
    /// saturates to bin 0, which is left too), so the float comparison alone decides. All
    /// lanes are compared and lane `axis` of the mask taken: picking the lane first would go
    /// through memory.
    #[inline(always)]
    fn goes_left(&self, c: Vec4) -> bool {
        ((c - self.lo) * self.scale).cmpge(self.bin).bitmask() & (1 << self.axis) == 0
    }
}

/// Entries of one set of bins: axis `a`, bin `k` is entry `a * MAX_BINS + k`. Room for a
/// fourth axis makes it a power of two, so masking an index proves it in range to the compiler.
const BIN_SLOTS: usize = 4 * MAX_BINS;

/// Sets of bins that consecutive primitives go to in turn (`Bins`).
const SETS: usize = 4;

/// Nodes of at least this many primitives bin into `SETS` sets, smaller ones into one (the
/// reset and the merge of the extra sets would cost more than they save).
const SETS_MIN: usize = 64;

/// The bins of all three axes, in `SETS` copies. Neighbouring primitives in the array are
/// neighbours in space and so mostly fall in the same bins; with one set, every primitive's
/// update of a bin waits for the previous one's store to that bin (a chain through memory per
/// axis). Dealing the primitives round the sets makes `SETS` independent chains; the sets are
/// merged before the sweep, exactly (unions and sums), so the split does not change. Reused
/// from node to node so that a node only resets the bins it uses.
pub struct Bins {
    boxes: [Box8; SETS * BIN_SLOTS],
    counts: [u32; SETS * BIN_SLOTS],
}

impl Bins {
    pub fn new() -> Box<Bins> {
        Box::new(Bins { boxes: [Box8::EMPTY; SETS * BIN_SLOTS], counts: [0; SETS * BIN_SLOTS] })
    }
}

/// Adds `p` to its bin on each axis in the set starting at `set`.
#[inline(always)]
fn bin_prim(
    boxes: &mut [Box8; SETS * BIN_SLOTS],
    counts: &mut [u32; SETS * BIN_SLOTS],
    set: usize,
    p: &PrimRef,
    (lo, scale, top): (Vec4, Vec4, Vec4),
) {
    // The bin of all three axes at once: clamping to [0, bins - 1] before truncating gives
    // what truncating and then clamping gives (a NaN lane becomes 0, as `as usize` makes it),
    // and the truncation is one vector instruction.
    const AXIS_OFFSET: i32x4 = i32x4::new([0, MAX_BINS as i32, 2 * MAX_BINS as i32, 0]);
    let t = ((p.centroid2() - lo) * scale).max(Vec4::ZERO).min(top);
    let k = (f32x4::from(t.to_array()).fast_trunc_int() + AXIS_OFFSET).to_array();
    for &k in &k[..3] {
        // The mask changes nothing (k < 3 * MAX_BINS); it drops the bounds checks.
        let k = set + (k as usize & (BIN_SLOTS - 1));
        boxes[k] = boxes[k].union(p.0);
        counts[k] += 1;
    }
}

/// The cheapest bin boundary over all axes with nonzero centroid extent, if any. `centroids`
/// bounds the primitives' `centroid2` (twice the centroid).
pub fn find_split(
    prims: &[PrimRef],
    bounds: Box8,
    centroids: Box4,
    params: &BuildParams,
    bins_buf: &mut Bins,
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
    let map = (lo, scale, Vec4::splat((bins - 1) as f32));

    let Bins { boxes, counts } = bins_buf;
    let sets = if prims.len() >= SETS_MIN { SETS } else { 1 };
    for set in 0..sets {
        for axis in 0..3 {
            let at = set * BIN_SLOTS + axis * MAX_BINS;
            boxes[at..at + bins].fill(Box8::EMPTY);
            counts[at..at + bins].fill(0);
        }
    }
    if sets == 1 {
        for p in prims {
            bin_prim(boxes, counts, 0, p, map);
        }
    } else {
        let quads = prims.chunks_exact(SETS);
        for p in quads.remainder() {
            bin_prim(boxes, counts, 0, p, map);
        }
        for q in quads {
            for (set, p) in q.iter().enumerate() {
                bin_prim(boxes, counts, set * BIN_SLOTS, p, map);
            }
        }
        for set in 1..SETS {
            for axis in 0..3 {
                for k in axis * MAX_BINS..axis * MAX_BINS + bins {
                    boxes[k] = boxes[k].union(boxes[set * BIN_SLOTS + k]);
                    counts[k] += counts[set * BIN_SLOTS + k];
                }
            }
        }
    }

    let parent_area = bounds.half_area().max(f32::MIN_POSITIVE);
    let mut best: Option<(usize, usize, f32)> = None;
    for axis in (0..3).filter(|&a| usable[a]) {
        let boxes = &boxes[axis * MAX_BINS..axis * MAX_BINS + bins];
        let counts = &counts[axis * MAX_BINS..axis * MAX_BINS + bins];
        // Sweep from the right to get the area and count of every right side.
        let mut right_area = [0.0f32; MAX_BINS];
        let mut right_count = [0u32; MAX_BINS];
        let (mut acc, mut n) = (Box8::EMPTY, 0u32);
        for k in (1..bins).rev() {
            acc = acc.union(boxes[k]);
            n += counts[k];
            right_area[k] = acc.half_area();
            right_count[k] = n;
        }
        let (mut acc, mut n) = (Box8::EMPTY, 0u32);
        for k in 1..bins {
            acc = acc.union(boxes[k - 1]);
            n += counts[k - 1];
            if n == 0 || right_count[k] == 0 {
                continue;
            }
            let cost = params.traversal_cost
                + (acc.half_area() * n as f32 + right_area[k] * right_count[k] as f32)
                    / parent_area;
            if best.is_none_or(|(_, _, c)| cost < c) {
                best = Some((axis, k, cost));
            }
        }
    }
    let (axis, bin, cost) = best?;
    let boxes = &boxes[axis * MAX_BINS..axis * MAX_BINS + bins];
    let left = boxes[..bin].iter().fold(Box8::EMPTY, |a, &b| a.union(b));
    let right = boxes[bin..].iter().fold(Box8::EMPTY, |a, &b| a.union(b));
    Some(Split { axis, cost, left, right, lo, scale, bin: Vec4::splat(bin as f32) })
}

/// Reorders `prims` so the split's left side comes first; returns its size and the centroid
/// bounds of both sides (which the children's splits need), gathered on the way.
///
/// Ranges of 33 to `BLOCKWISE_MAX` go block by block (as in BlockQuicksort, Edelkamp and
/// Weiss 2016): one block from each end is classified without branches, noting the primitives
/// on the wrong side, and those are then swapped in pairs. In such nodes which side a
/// primitive goes is a coin toss for the branch predictor, and a branch per primitive costs a
/// misprediction every other primitive. Larger nodes go one at a time: there the input
/// order (a mesh's, coherent in space) leaves long runs on one side that predict well, and the
/// branchy loop measured twice as fast on the 1M tori. The order within each side differs
/// from a one-at-a-time partition, which changes nothing but the order of triangles inside a
/// leaf (binning does not depend on order).
pub fn partition(prims: &mut [PrimRef], split: &Split) -> (usize, Box4, Box4) {
    const BLOCK: usize = 16;
    const BLOCKWISE_MAX: usize = 8192;
    let (mut lb, mut rb) = (Box4::EMPTY, Box4::EMPTY);
    let (mut l, mut r) = (0, prims.len());
    // Offsets of the primitives still to swap: right-goers in the block at `l`, left-goers in
    // the block ending at `r` (counted back from `r - 1`).
    let (mut off_l, mut off_r) = ([0u8; BLOCK], [0u8; BLOCK]);
    let (mut start_l, mut num_l, mut start_r, mut num_r) = (0, 0, 0, 0);
    while r - l > 2 * BLOCK && prims.len() <= BLOCKWISE_MAX {
        if num_l == 0 {
            start_l = 0;
            for i in 0..BLOCK {
                let c = prims[l + i].centroid2();
                let left = split.goes_left(c);
                (lb, rb) = grow_side(lb, rb, c, left);
                off_l[num_l] = i as u8;
                num_l += usize::from(!left);
            }
        }
        if num_r == 0 {
            start_r = 0;
            for i in 0..BLOCK {
                let c = prims[r - 1 - i].centroid2();
                let left = split.goes_left(c);
                (lb, rb) = grow_side(lb, rb, c, left);
                off_r[num_r] = i as u8;
                num_r += usize::from(left);
            }
        }
        let m = num_l.min(num_r);
        for k in 0..m {
            let (a, b) = (l + off_l[start_l + k] as usize, r - 1 - off_r[start_r + k] as usize);
            prims.swap(a, b);
        }
        (num_l, num_r, start_l, start_r) = (num_l - m, num_r - m, start_l + m, start_r + m);
        if num_l == 0 {
            l += BLOCK;
        }
        if num_r == 0 {
            r -= BLOCK;
        }
    }
    // What is left (at most three blocks, possibly classified already: growing a box by a
    // point it holds changes nothing), one at a time.
    let (mut i, mut j) = (l, r);
    while i < j {
        let c = prims[i].centroid2();
        if split.goes_left(c) {
            lb = lb.grow_point(c);
            i += 1;
        } else {
            rb = rb.grow_point(c);
            j -= 1;
            prims.swap(i, j);
        }
    }
    (i, lb, rb)
}

/// Grows the centroid box of `c`'s side, without a branch.
#[inline(always)]
fn grow_side(lb: Box4, rb: Box4, c: Vec4, left: bool) -> (Box4, Box4) {
    // Selects rather than an index into an array of the two: that would keep the boxes in
    // memory, one store-to-load chain through every primitive.
    let m = BVec4A::splat(left);
    let (gl, gr) = (lb.grow_point(c), rb.grow_point(c));
    (
        Box4 { min: Vec4::select(m, gl.min, lb.min), max: Vec4::select(m, gl.max, lb.max) },
        Box4 { min: Vec4::select(m, rb.min, gr.min), max: Vec4::select(m, rb.max, gr.max) },
    )
}
