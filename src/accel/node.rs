//! The flat BVH node: 32 bytes, two to a cache line.

/// A node of the flat BVH, in depth-first order: an interior node's first child is the next
/// node in the array, its second child is at `index`. A leaf (`count > 0`) holds the triangles
/// `index .. index + count` of the SoA triangle store.
#[repr(C, align(32))]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BvhNode {
    /// The node box's lower corner.
    pub min: [f32; 3],
    /// Interior: index of the second child. Leaf: first triangle.
    pub index: u32,
    /// The node box's upper corner.
    pub max: [f32; 3],
    /// 0 for interior nodes, else the number of triangles in the leaf.
    pub count: u32,
}

const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);
const _: () = assert!(std::mem::align_of::<BvhNode>() == 32);

impl BvhNode {
    /// Whether the node is a leaf (`count > 0`).
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }
}
