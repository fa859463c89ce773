//! The wide BVH node: `ARITY` child boxes in SoA, so one SIMD slab test covers them all.

/// Child reference flag: the child is a leaf (`leaf_ref`). Without the flag the child is the
/// node at that index of the wide node array.
pub const LEAF_BIT: u32 = 1 << 31;

/// Most triangles in a leaf: one triangle block (`geometry::triangles`).
pub const MAX_LEAF: usize = 8;

/// A leaf's first triangle takes the low `FIRST_BITS` bits of its reference, its count the
/// four bits above them.
const FIRST_BITS: u32 = 27;

/// Most triangles a scene may have (16,777,216; `Accel::check_limits` refuses more). Leaf
/// references hold slot indices below `2^FIRST_BITS`, and every 8-slot block holds at least
/// one triangle (`build::pack_leaves` opens a block for a leaf), so `2^FIRST_BITS / 8`
/// triangles always fit. (Packing measures about 1.24 slots per triangle, so the bound is
/// loose; a tighter one would need a proof about the packing, or more bits.)
pub const MAX_TRIANGLES: usize = 1 << (FIRST_BITS - 3);

/// The reference to a leaf of `count` (1 to `MAX_LEAF`) triangles from `first` on. The count
/// rides in the reference, so nodes need no count array (32 bytes of 256): PERF.md,
/// "8-wide nodes".
pub fn leaf_ref(first: usize, count: usize) -> u32 {
    assert!((1..=MAX_LEAF).contains(&count), "a leaf holds 1 to {MAX_LEAF} triangles, not {count}");
    assert!(
        first + count <= 1 << FIRST_BITS,
        "triangle index {first} does not fit a leaf reference"
    );
    LEAF_BIT | ((count as u32) << FIRST_BITS) | first as u32
}

/// (first triangle, count) of a leaf reference.
#[inline(always)]
pub fn leaf_range(child: u32) -> (usize, usize) {
    let first = child & ((1 << FIRST_BITS) - 1);
    (first as usize, ((child >> FIRST_BITS) & 15) as usize)
}

/// Children per node.
pub const ARITY: usize = 8;

/// One lane per child: the SIMD type of a node's box rows.
pub type ChildLanes = wide::f32x8;

/// An unused child slot: a leaf of no triangles, with an inverted box that no finite ray
/// enters (a ray with NaN or infinite terms may, and then tests nothing).
pub const EMPTY: u32 = LEAF_BIT;

/// A node of the wide BVH, collapsed from the binary BVH (`build::collapse`). The boxes of
/// the (up to `ARITY`) children are stored as one row of `ARITY` lanes per bound and axis, so one
/// `ChildLanes` slab test covers every child. Children fill the slots from the first; unused slots
/// hold `EMPTY` with an inverted box (min = +inf, max = -inf), which the slab test misses.
/// Nodes are in depth-first order, the root first.
/// 224 bytes, 32-byte aligned: every node touches four cache lines, as a 256-byte one would.
#[repr(C, align(32))]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WideNode {
    /// Rows `2 * axis` (minimum) and `2 * axis + 1` (maximum), one lane per child. Traversal
    /// picks the near and far row of an axis by the sign of the ray direction.
    pub bounds: [[f32; ARITY]; 6],
    /// Per child: a node index, or a `leaf_ref`, or `EMPTY`.
    pub child: [u32; ARITY],
}

const _: () = assert!(std::mem::size_of::<WideNode>() == 28 * ARITY);
const _: () = assert!(std::mem::align_of::<WideNode>() == 32);
// `children` compares the references as one `u32x8`.
const _: () = assert!(ARITY == 8);

impl WideNode {
    /// A node with every slot empty.
    pub(crate) const EMPTY_NODE: WideNode = WideNode {
        bounds: [
            [f32::INFINITY; ARITY],
            [f32::NEG_INFINITY; ARITY],
            [f32::INFINITY; ARITY],
            [f32::NEG_INFINITY; ARITY],
            [f32::INFINITY; ARITY],
            [f32::NEG_INFINITY; ARITY],
        ],
        child: [EMPTY; ARITY],
    };

    /// Sets slot `i` to a child with the given box.
    pub(crate) fn set_child(&mut self, i: usize, min: [f32; 3], max: [f32; 3], child: u32) {
        for axis in 0..3 {
            self.bounds[2 * axis][i] = min[axis];
            self.bounds[2 * axis + 1][i] = max[axis];
        }
        self.child[i] = child;
    }

    /// Number of used slots (children are packed from slot 0): one compare of the eight
    /// references and a popcount (a filtered count compiled to a bit-by-bit sum of 40
    /// instructions, once per node visit).
    #[inline(always)]
    pub fn children(&self) -> usize {
        let empty = wide::u32x8::new(self.child).simd_eq(wide::u32x8::splat(EMPTY));
        ARITY - empty.to_bitmask().count_ones() as usize
    }
}

/// A row of `WideNode::bounds`: `2 * axis` holds the minima, `2 * axis + 1` the maxima.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(usize)]
pub(super) enum Row {
    MinX = 0,
    MaxX = 1,
    MinY = 2,
    MaxY = 3,
    MinZ = 4,
    MaxZ = 5,
}

impl Row {
    const MIN: [Row; 3] = [Row::MinX, Row::MinY, Row::MinZ];
    const MAX: [Row; 3] = [Row::MaxX, Row::MaxY, Row::MaxZ];

    /// Per axis, the rows a ray with reciprocal direction `inv` enters and leaves a box by:
    /// (minimum, maximum), swapped where the direction is negative.
    #[inline(always)]
    pub(super) fn near_far(inv: [f32; 3]) -> ([Row; 3], [Row; 3]) {
        let neg = inv.map(f32::is_sign_negative);
        let pick = |a: usize, max: bool| if max { Row::MAX[a] } else { Row::MIN[a] };
        ([0, 1, 2].map(|a| pick(a, neg[a])), [0, 1, 2].map(|a| pick(a, !neg[a])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaf_refs_round_trip() {
        for (first, count) in [(0, 1), (5, 8), ((1 << FIRST_BITS) - 3, 3)] {
            let r = leaf_ref(first, count);
            assert!(r & LEAF_BIT != 0 && r != EMPTY);
            assert_eq!(leaf_range(r), (first, count));
        }
        assert_eq!(leaf_range(EMPTY).1, 0);
    }

    /// `simd::prefetch` issues `lines_spanned` prefetches from the line a node starts in: they
    /// must reach its last byte wherever a 32-byte aligned node starts in a line, and a triangle
    /// block's (64-byte aligned) too.
    #[test]
    fn prefetches_cover_nodes_and_blocks() {
        use crate::geometry::triangles::TriangleBlock;
        use crate::simd::lines_spanned;
        fn covered<T>(expect: usize) {
            let (size, align) = (std::mem::size_of::<T>(), std::mem::align_of::<T>());
            assert_eq!(lines_spanned::<T>(), expect);
            for start in (0..64).step_by(align.min(64)) {
                let last_line = (start + size - 1) / 64;
                assert!(last_line < lines_spanned::<T>(), "start {start}");
            }
        }
        covered::<WideNode>(4);
        covered::<TriangleBlock>(5);
        covered::<u8>(1);
    }
}
