//! The wide BVH node: `ARITY` child boxes in SoA, so one SIMD slab test covers them all.

/// Child reference flag: the child is a leaf, the low 31 bits its first triangle in the SoA
/// triangle store and `WideNode::count` its triangle count. Without the flag the child is the
/// node at that index of the wide node array.
pub const LEAF_BIT: u32 = 1 << 31;

/// Children per node.
pub const ARITY: usize = 8;

/// One lane per child: the SIMD type of a node's box rows.
pub type ChildLanes = wide::f32x8;

/// An unused child slot: a leaf of zero triangles (so a ray that somehow enters it, which
/// its inverted box prevents for any finite ray, tests nothing) whose box is empty.
pub const EMPTY: u32 = u32::MAX;

/// A node of the wide BVH, collapsed from the binary BVH (`build::collapse`). The boxes of
/// the (up to `ARITY`) children are stored as one row of `ARITY` lanes per bound and axis, so one
/// `ChildLanes` slab test covers every child. Children fill the slots from the first; unused slots
/// hold `EMPTY` with an inverted box (min = +inf, max = -inf), which the slab test misses.
/// Nodes are in depth-first order, the root first.
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WideNode {
    /// Rows `2 * axis` (minimum) and `2 * axis + 1` (maximum), one lane per child. Traversal
    /// picks the near and far row of an axis by the sign of the ray direction.
    pub bounds: [[f32; ARITY]; 6],
    /// Per child: a node index, or `LEAF_BIT | first triangle`, or `EMPTY`.
    pub child: [u32; ARITY],
    /// Per child: the leaf's triangle count (0 for interior children and empty slots).
    pub count: [u32; ARITY],
}

const _: () = assert!(std::mem::size_of::<WideNode>() == 32 * ARITY);
const _: () = assert!(std::mem::align_of::<WideNode>() == 64);

impl WideNode {
    /// A node with every slot empty.
    pub const EMPTY_NODE: WideNode = WideNode {
        bounds: [
            [f32::INFINITY; ARITY],
            [f32::NEG_INFINITY; ARITY],
            [f32::INFINITY; ARITY],
            [f32::NEG_INFINITY; ARITY],
            [f32::INFINITY; ARITY],
            [f32::NEG_INFINITY; ARITY],
        ],
        child: [EMPTY; ARITY],
        count: [0; ARITY],
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
