//! Triangles in structure-of-arrays layout, in BVH leaf order.
//!
//! Each triangle is stored as its first vertex and its two edges (v0, e1 = v1 - v0,
//! e2 = v2 - v0), nine f32 columns. Möller-Trumbore needs exactly these, so a leaf test loads
//! nine contiguous 8-wide vectors and does no subtraction per ray. The alternative, three
//! vertex columns, costs six subtractions per triangle per ray; edges also keep the test
//! identical whether one ray meets eight triangles or eight rays meet one.
//! Columns are padded with `LANES` degenerate (all-zero) triangles so an 8-wide load at any
//! leaf start stays in bounds; a zero triangle has det = 0 and never hits.

use glam::Vec3;

/// Lanes of the widest SIMD triangle test.
pub const LANES: usize = 8;

#[derive(Debug, Clone, Default)]
pub struct TriangleSoa {
    pub v0: [Vec<f32>; 3],
    pub e1: [Vec<f32>; 3],
    pub e2: [Vec<f32>; 3],
    /// Original scene triangle index of each stored triangle.
    pub prim: Vec<u32>,
}

impl TriangleSoa {
    /// Stores the triangles `corners(i)` for `i` in `order`, in that order.
    pub fn from_order(corners: impl Fn(usize) -> [Vec3; 3], order: &[u32]) -> TriangleSoa {
        let n = order.len() + LANES;
        let mut s = TriangleSoa {
            v0: std::array::from_fn(|_| Vec::with_capacity(n)),
            e1: std::array::from_fn(|_| Vec::with_capacity(n)),
            e2: std::array::from_fn(|_| Vec::with_capacity(n)),
            prim: order.to_vec(),
        };
        for &i in order {
            let [a, b, c] = corners(i as usize);
            s.push(a, b - a, c - a);
        }
        for _ in 0..LANES {
            s.push(Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
        }
        s
    }

    fn push(&mut self, v0: Vec3, e1: Vec3, e2: Vec3) {
        for k in 0..3 {
            self.v0[k].push(v0[k]);
            self.e1[k].push(e1[k]);
            self.e2[k].push(e2[k]);
        }
    }

    /// Number of real (unpadded) triangles.
    pub fn len(&self) -> usize {
        self.prim.len()
    }

    pub fn is_empty(&self) -> bool {
        self.prim.is_empty()
    }

    #[inline]
    pub fn v0(&self, i: usize) -> Vec3 {
        Vec3::new(self.v0[0][i], self.v0[1][i], self.v0[2][i])
    }

    #[inline]
    pub fn e1(&self, i: usize) -> Vec3 {
        Vec3::new(self.e1[0][i], self.e1[1][i], self.e1[2][i])
    }

    #[inline]
    pub fn e2(&self, i: usize) -> Vec3 {
        Vec3::new(self.e2[0][i], self.e2[1][i], self.e2[2][i])
    }

    /// Heap bytes of the columns.
    pub fn memory_bytes(&self) -> usize {
        9 * self.v0[0].capacity() * 4 + self.prim.capacity() * 4
    }
}
