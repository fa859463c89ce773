//! Triangles in SoA blocks of eight (AoSoA), in BVH leaf order.
//!
//! Each triangle is stored as its three vertices, exactly as the scene gives them: the
//! watertight test (`watertight`) needs every vertex bit-identical in the triangles that share
//! it, which `v0 + (v1 - v0)` would not be. (Möller-Trumbore stored v0 and two edges.)
//!
//! Why blocks: a block holds the nine 8-lane component rows and the eight scene indices of
//! eight slots in 320 contiguous, 64-byte-aligned bytes (five cache lines). A leaf lies inside
//! one block (the build packs leaves so, `accel::build::pack_leaves`), so one leaf test reads
//! five neighbouring lines. With nine separate columns it read nine to eighteen lines from
//! nine places in memory, which is what incoherent rays pay for most (PERF.md, "Triangle
//! blocks"). Slots no leaf uses are degenerate all-zero triangles: every edge function is 0, never a hit.

use glam::Vec3;
use rayon::prelude::*;

/// Lanes of the widest SIMD triangle test, and slots per block.
pub const LANES: usize = 8;

/// `prim` of a slot that holds no triangle.
pub const NO_PRIM: u32 = u32::MAX;

/// Eight triangle slots, one SIMD lane each: rows are [x, y, z] of v0, v1 and v2.
#[repr(C, align(64))]
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TriangleBlock {
    /// The first vertex: rows x, y, z, one lane per slot.
    pub v0: [[f32; LANES]; 3],
    /// The second vertex: rows x, y, z.
    pub v1: [[f32; LANES]; 3],
    /// The third vertex: rows x, y, z.
    pub v2: [[f32; LANES]; 3],
    /// Scene triangle index of each slot (`NO_PRIM` for an unused slot).
    pub prim: [u32; LANES],
}

const _: () = assert!(std::mem::size_of::<TriangleBlock>() == 320);

impl TriangleBlock {
    const EMPTY: TriangleBlock = TriangleBlock {
        v0: [[0.0; LANES]; 3],
        v1: [[0.0; LANES]; 3],
        v2: [[0.0; LANES]; 3],
        prim: [NO_PRIM; LANES],
    };
}

/// The triangle store. Slot `i` is lane `i % LANES` of block `i / LANES`; BVH leaves name
/// ranges of slots.
#[derive(Debug, Clone, Default)]
pub struct TriangleSoa {
    blocks: Vec<TriangleBlock>,
    len: usize,
}

impl TriangleSoa {
    /// Stores triangle `corners(p)` in slot `i` for every `p = slots[i]` other than
    /// `NO_PRIM`; the other slots stay empty.
    #[cfg(test)]
    pub(crate) fn from_slots(
        corners: impl Fn(usize) -> [Vec3; 3] + Sync,
        slots: &[u32],
    ) -> TriangleSoa {
        TriangleSoa::from_slots_in(Vec::new(), corners, slots)
    }

    /// `from_slots` (the tests' form) into `blocks` (emptied first): a caller that
    /// gave its capacity huge pages before anything touched it keeps them. Blocks are filled
    /// in parallel (in the caller's rayon pool), each from its own eight slots.
    pub(crate) fn from_slots_in(
        mut blocks: Vec<TriangleBlock>,
        corners: impl Fn(usize) -> [Vec3; 3] + Sync,
        slots: &[u32],
    ) -> TriangleSoa {
        blocks.clear();
        // Exactly: `memory_bytes` (and `Accel`'s choice of traversal) counts the capacity.
        blocks.reserve_exact(slots.len().div_ceil(LANES));
        blocks.par_extend(slots.par_chunks(LANES).map(|slots| {
            let mut block = TriangleBlock::EMPTY;
            for (lane, &p) in slots.iter().enumerate().filter(|(_, &p)| p != NO_PRIM) {
                let [a, b, c] = corners(p as usize);
                for (row, v) in [(&mut block.v0, a), (&mut block.v1, b), (&mut block.v2, c)] {
                    for k in 0..3 {
                        row[k][lane] = v[k];
                    }
                }
                block.prim[lane] = p;
            }
            block
        }));
        let len = slots.iter().filter(|&&p| p != NO_PRIM).count();
        TriangleSoa { blocks, len }
    }

    /// Number of stored triangles (used slots).
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether no slot holds a triangle.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The blocks, for leaf tests and for `madvise`.
    #[inline(always)]
    pub(crate) fn blocks(&self) -> &[TriangleBlock] {
        &self.blocks
    }

    /// The block holding slot `i`, and the slot's lane in it.
    #[inline(always)]
    pub(crate) fn slot(&self, i: usize) -> (&TriangleBlock, usize) {
        (&self.blocks[i / LANES], i % LANES)
    }

    /// The vertices (v0, v1, v2) of slot `i` (the layout's tests; traversal broadcasts each
    /// coordinate straight from its block, `traverse_packet::splat_tri`).
    #[cfg(test)]
    pub(crate) fn vertices(&self, i: usize) -> [Vec3; 3] {
        let (b, l) = self.slot(i);
        let get = |row: &[[f32; LANES]; 3]| Vec3::new(row[0][l], row[1][l], row[2][l]);
        [get(&b.v0), get(&b.v1), get(&b.v2)]
    }

    /// Scene triangle index of slot `i`.
    #[inline(always)]
    pub fn prim(&self, i: usize) -> u32 {
        let (b, l) = self.slot(i);
        b.prim[l]
    }

    /// Heap bytes of the blocks.
    pub fn memory_bytes(&self) -> usize {
        self.blocks.capacity() * std::mem::size_of::<TriangleBlock>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Slots map to (block, lane) in order, gaps stay empty, and vertices are stored as given.
    #[test]
    fn slots_fill_blocks_in_order() {
        let corners = |p: usize| {
            let a = Vec3::splat(p as f32);
            [a, a + Vec3::X, a + Vec3::Y]
        };
        let mut slots = vec![NO_PRIM; 16];
        slots[3] = 7;
        slots[9] = 2;
        let t = TriangleSoa::from_slots(corners, &slots);
        assert_eq!(t.len(), 2);
        assert_eq!(t.blocks().len(), 2);
        assert_eq!(t.prim(3), 7);
        assert_eq!(t.prim(9), 2);
        assert_eq!(t.prim(4), NO_PRIM);
        let seven = Vec3::splat(7.0);
        assert_eq!(t.vertices(3), [seven, seven + Vec3::X, seven + Vec3::Y]);
        assert_eq!(t.vertices(9)[0], Vec3::splat(2.0));
        assert_eq!(t.vertices(8), [Vec3::ZERO; 3]);
        assert_eq!(t.memory_bytes(), 640);
    }
}
