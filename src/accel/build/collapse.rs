//! Binary BVH -> 8-wide BVH, by pulling grandchildren up (as in Embree's BVH8 builders and
//! tinybvh's `BVH8_CPU` conversion, described, not copied): each wide node starts with the two
//! children of a binary node and, while it has fewer than `ARITY`, opens the interior child with
//! the largest surface area (the one a random ray is most likely to enter, so opening it saves
//! the most box-test steps) into its two children.
//!
//! Leaves are contiguous triangle ranges of the shared triangle store. Because a binary
//! subtree's triangles are contiguous (leaves are in depth-first order), a subtree of at most
//! `max_leaf` triangles can become one wide leaf: the binary SAH prices every triangle as one
//! test and makes leaves of one or two triangles, while the single-ray leaf test takes 8 at
//! once.

use crate::accel::node::BvhNode;
use crate::accel::wide_node::{leaf_ref, WideNode, ARITY, MAX_LEAF};

/// The wide tree of `nodes` (depth-first, root first; the first interior child of a node
/// follows it), with binary subtrees of at most `max_leaf` triangles merged into leaves
/// (`max_leaf` and the binary leaves at most `MAX_LEAF`)
/// (0: keep the binary leaves). An empty binary tree gives an empty one; a tree that is one
/// leaf gives one wide node with that leaf as its only child.
#[cfg(test)]
pub fn collapse(nodes: &[BvhNode], max_leaf: usize) -> Vec<WideNode> {
    collapse_into(Vec::new(), nodes, max_leaf)
}

/// [`collapse`] into `out` (emptied first), whose capacity a caller may have prepared (huge
/// pages before anything touched it): `wide_capacity(nodes)` nodes never reallocate.
pub fn collapse_into(mut out: Vec<WideNode>, nodes: &[BvhNode], max_leaf: usize) -> Vec<WideNode> {
    out.clear();
    let Some(root) = nodes.first() else {
        return out;
    };
    assert!(max_leaf <= MAX_LEAF, "wide leaves hold at most {MAX_LEAF} triangles, not {max_leaf}");
    let c = Collapser { nodes, ranges: subtree_ranges(nodes), max_leaf };
    out.reserve(wide_capacity(nodes));
    out.push(WideNode::EMPTY_NODE);
    if c.is_leaf(0) {
        out[0].set_child(0, root.min, root.max, c.leaf_ref(0));
    } else {
        c.fill(0, 0, &mut out);
    }
    out
}

/// Most wide nodes `collapse` makes from `nodes`: each but the root replaces at least one
/// binary interior node (at least two children each), so at most the interior count, at most
/// half the binary nodes (plus the root of a one-leaf tree).
pub fn wide_capacity(nodes: &[BvhNode]) -> usize {
    nodes.len() / 2 + 1
}

/// (first triangle, triangle count) of every binary subtree. Children follow their parent in
/// the array, so one backward pass sees both children before the parent.
fn subtree_ranges(nodes: &[BvhNode]) -> Vec<(u32, u32)> {
    let mut r = vec![(0, 0); nodes.len()];
    for i in (0..nodes.len()).rev() {
        let n = &nodes[i];
        r[i] = if n.is_leaf() {
            (n.index, n.count)
        } else {
            let (a, b) = (r[i + 1], r[n.index as usize]);
            (a.0, a.1 + b.1)
        };
    }
    r
}

fn half_area(n: &BvhNode) -> f32 {
    let d = [n.max[0] - n.min[0], n.max[1] - n.min[1], n.max[2] - n.min[2]];
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

struct Collapser<'a> {
    nodes: &'a [BvhNode],
    ranges: Vec<(u32, u32)>,
    max_leaf: usize,
}

impl Collapser<'_> {
    /// Whether binary node `i` becomes a wide leaf.
    fn is_leaf(&self, i: usize) -> bool {
        self.nodes[i].is_leaf() || self.ranges[i].1 as usize <= self.max_leaf
    }

    fn leaf_ref(&self, i: usize) -> u32 {
        let (first, count) = self.ranges[i];
        leaf_ref(first as usize, count as usize)
    }

    /// Fills wide node `at` with the (up to `ARITY`) descendants of the binary interior node
    /// `i`, then recurses into the interior ones.
    fn fill(&self, i: usize, at: usize, out: &mut Vec<WideNode>) {
        let nodes = self.nodes;
        let mut kids = [0; ARITY];
        (kids[0], kids[1]) = (i + 1, nodes[i].index as usize);
        let mut k = 2;
        while k < ARITY {
            let open = (0..k)
                .filter(|&j| !self.is_leaf(kids[j]))
                .max_by(|&a, &b| half_area(&nodes[kids[a]]).total_cmp(&half_area(&nodes[kids[b]])));
            let Some(j) = open else {
                break; // every child is a leaf
            };
            // Replace the child by its two children in place, keeping depth-first order.
            let n = kids[j];
            kids.copy_within(j + 1..k, j + 2);
            kids[j] = n + 1;
            kids[j + 1] = nodes[n].index as usize;
            k += 1;
        }
        for (slot, &c) in kids[..k].iter().enumerate() {
            let n = &nodes[c];
            if self.is_leaf(c) {
                out[at].set_child(slot, n.min, n.max, self.leaf_ref(c));
            } else {
                let child = out.len();
                out.push(WideNode::EMPTY_NODE);
                out[at].set_child(slot, n.min, n.max, child as u32);
                self.fill(c, child, out);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::build::{build, BuildParams};
    use crate::accel::wide_node::{leaf_range, EMPTY, LEAF_BIT};
    use crate::math::{Aabb, Vec3};
    use crate::sampler::Pcg32;

    /// Leaves of the wide tree: (first, count, box) in visiting order, with every interior
    /// child's box checked to be the union its children's boxes fit in.
    fn leaves(w: &[WideNode], at: usize, out: &mut Vec<(u32, u32)>) {
        let n = &w[at];
        let k = n.children();
        assert!(k >= 2 || (at == 0 && k == 1), "node {at} has {k} children");
        for i in 0..ARITY {
            if n.child[i] == EMPTY {
                assert!(i >= k, "children are packed from slot 0");
                continue;
            }
            if n.child[i] & LEAF_BIT != 0 {
                let (first, count) = leaf_range(n.child[i]);
                out.push((first as u32, count as u32));
            } else {
                let c = n.child[i] as usize;
                assert!(c > at, "depth-first order");
                for j in 0..w[c].children() {
                    for axis in 0..3 {
                        assert!(w[c].bounds[2 * axis][j] >= n.bounds[2 * axis][i]);
                        assert!(w[c].bounds[2 * axis + 1][j] <= n.bounds[2 * axis + 1][i]);
                    }
                }
                leaves(w, c, out);
            }
        }
    }

    #[test]
    fn collapse_keeps_every_leaf_once_and_nests_boxes() {
        let mut rng = Pcg32::new(3, 4);
        for n in [1usize, 2, 7, 9, 100, 3000] {
            let boxes: Vec<Aabb> = (0..n)
                .map(|_| {
                    let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                    Aabb::from_points(&[c, c + Vec3::splat(0.1 * rng.next_f32())])
                })
                .collect();
            let bin = build(&boxes, BuildParams::default());
            let bin_leaves: Vec<(u32, u32)> =
                bin.nodes.iter().filter(|n| n.is_leaf()).map(|n| (n.index, n.count)).collect();
            for max_leaf in [0, 4, 8] {
                let wide = collapse(&bin.nodes, max_leaf);
                let mut wide_leaves = Vec::new();
                leaves(&wide, 0, &mut wide_leaves);
                if max_leaf == 0 {
                    // Same leaves in the same (depth-first) order.
                    assert_eq!(wide_leaves, bin_leaves, "n = {n}");
                }
                // In depth-first order the leaves tile the triangle store exactly.
                let mut next = 0;
                for &(first, count) in &wide_leaves {
                    assert_eq!(first, next, "n = {n}, max_leaf {max_leaf}");
                    assert!(count as usize <= MAX_LEAF, "n = {n}: leaf of {count}");
                    next += count;
                }
                assert_eq!(next as usize, n);
                let interior = bin.nodes.len() - bin_leaves.len();
                assert!(wide.len() <= interior.max(1), "n = {n}: {} wide nodes", wide.len());
            }
        }
        assert!(collapse(&[], 8).is_empty());
    }
}
