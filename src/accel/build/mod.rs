//! BVH construction: a binned SAH build straight into the flat depth-first node array, and
//! its collapse into the 4-wide tree that single rays traverse (`collapse`).
//!
//! Primitives are known only by their bounding boxes and centroids; the builder returns the
//! node array and the primitive order that the leaves index.

mod binned_sah;
mod collapse;

pub use collapse::{collapse, merged_leaf_map, NO_LEAF};

use crate::math::{Aabb, Vec3};

use super::node::BvhNode;

/// Build settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildParams {
    /// SAH bins per axis.
    pub bins: usize,
    /// Largest leaf; also the size under which a leaf is always allowed.
    pub max_leaf: usize,
    /// Cost of one box test relative to one triangle test.
    pub traversal_cost: f32,
}

impl Default for BuildParams {
    fn default() -> Self {
        BuildParams { bins: 16, max_leaf: 8, traversal_cost: 1.0 }
    }
}

/// Depth at which the builder stops looking for SAH splits and halves ranges instead, so that
/// the tree is never deeper than `MAX_DEPTH` whatever the input (traversal stacks are fixed).
const SAH_DEPTH_LIMIT: usize = 40;
pub const MAX_DEPTH: usize = 64;

/// The flat tree and the primitive order its leaves refer to.
pub struct BuiltBvh {
    pub nodes: Vec<BvhNode>,
    pub order: Vec<u32>,
}

/// Builds a BVH over primitives with the given bounds. An empty input gives one empty leaf.
pub fn build(bounds: &[Aabb], params: BuildParams) -> BuiltBvh {
    let centroids: Vec<Vec3> = bounds.iter().map(Aabb::center).collect();
    let mut b = Builder {
        bounds,
        centroids,
        params,
        order: (0..bounds.len() as u32).collect(),
        nodes: Vec::new(),
    };
    b.nodes.reserve(2 * bounds.len().max(1));
    b.build_node(0, bounds.len(), 0);
    BuiltBvh { nodes: b.nodes, order: b.order }
}

struct Builder<'a> {
    bounds: &'a [Aabb],
    centroids: Vec<Vec3>,
    params: BuildParams,
    order: Vec<u32>,
    nodes: Vec<BvhNode>,
}

impl Builder<'_> {
    /// Builds the subtree over `order[first .. first + count]` and returns its node index.
    fn build_node(&mut self, first: usize, count: usize, depth: usize) -> u32 {
        let index = self.nodes.len();
        let range = &self.order[first..first + count];
        let (bounds, centroid_bounds) =
            range.iter().fold((Aabb::EMPTY, Aabb::EMPTY), |(b, c), &i| {
                (b.union(self.bounds[i as usize]), c.grow(self.centroids[i as usize]))
            });
        let (min, max) = if bounds.is_empty() {
            ([0.0; 3], [0.0; 3])
        } else {
            (bounds.min.into(), bounds.max.into())
        };
        self.nodes.push(BvhNode { min, index: first as u32, max, count: count as u32 });

        let small = count <= self.params.max_leaf;
        if count <= 1 {
            return index as u32;
        }
        let split = if depth < SAH_DEPTH_LIMIT {
            binned_sah::find_split(self, first, count, bounds, centroid_bounds)
        } else {
            None
        };
        let left_count = match split {
            Some(s) if !small || s.cost < count as f32 => {
                binned_sah::partition(self, first, count, s)
            }
            Some(_) => return index as u32, // a leaf is cheaper
            None if small => return index as u32,
            // Too many primitives to leave and no useful split (all centroids equal, or too
            // deep): halve the range. Leaves stay small and the recursion ends.
            None => count / 2,
        };
        let left_count =
            if left_count == 0 || left_count == count { count / 2 } else { left_count };
        self.build_node(first, left_count, depth + 1);
        let right = self.build_node(first + left_count, count - left_count, depth + 1);
        self.nodes[index].index = right;
        self.nodes[index].count = 0;
        index as u32
    }
}
