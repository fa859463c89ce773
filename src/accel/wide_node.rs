//! The 4-wide BVH node for single-ray traversal: four child boxes in SoA, 128 bytes, two
//! cache lines.

/// Child reference flag: the child is a leaf, the low 31 bits its first triangle in the SoA
/// triangle store and `Bvh4Node::count` its triangle count. Without the flag the child is the
/// node at that index of the wide node array.
pub const LEAF_BIT: u32 = 1 << 31;

/// An unused child slot: a leaf of zero triangles (so a ray that somehow enters it, which
/// its inverted box prevents for any finite ray, tests nothing) whose box is empty.
pub const EMPTY: u32 = u32::MAX;

/// A node of the 4-wide BVH, collapsed from the binary BVH (`build::collapse`). The boxes of
/// the (up to four) children are stored as one row of four lanes per bound and axis, so one
/// `f32x4` slab test covers every child. Children fill the slots from the first; unused slots
/// hold `EMPTY` with an inverted box (min = +inf, max = -inf), which the slab test misses.
/// Nodes are in depth-first order, the root first.
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bvh4Node {
    /// Rows `2 * axis` (minimum) and `2 * axis + 1` (maximum), one lane per child. Traversal
    /// picks the near and far row of an axis by the sign of the ray direction.
    pub bounds: [[f32; 4]; 6],
    /// Per child: a node index, or `LEAF_BIT | first triangle`, or `EMPTY`.
    pub child: [u32; 4],
    /// Per child: the leaf's triangle count (0 for interior children and empty slots).
    pub count: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<Bvh4Node>() == 128);
const _: () = assert!(std::mem::align_of::<Bvh4Node>() == 64);

impl Bvh4Node {
    /// A node with every slot empty.
    pub const EMPTY_NODE: Bvh4Node = Bvh4Node {
        bounds: [
            [f32::INFINITY; 4],
            [f32::NEG_INFINITY; 4],
            [f32::INFINITY; 4],
            [f32::NEG_INFINITY; 4],
            [f32::INFINITY; 4],
            [f32::NEG_INFINITY; 4],
        ],
        child: [EMPTY; 4],
        count: [0; 4],
    };

    /// Sets slot `i` to a child with the given box.
    pub fn set_child(&mut self, i: usize, min: [f32; 3], max: [f32; 3], child: u32, count: u32) {
        for axis in 0..3 {
            self.bounds[2 * axis][i] = min[axis];
            self.bounds[2 * axis + 1][i] = max[axis];
        }
        self.child[i] = child;
        self.count[i] = count;
    }

    /// Number of used slots (children are packed from slot 0).
    #[inline(always)]
    pub fn children(&self) -> usize {
        self.child.iter().filter(|&&c| c != EMPTY).count()
    }
}
