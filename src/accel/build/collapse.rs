//! Binary BVH -> 4-wide BVH, by pulling grandchildren up (as in Embree's BVH4 builders and
//! tinybvh's `BVH4_CPU` conversion, described, not copied): each wide node starts with the two
//! children of a binary node and, while it has fewer than four, opens the interior child with
//! the largest surface area (the one a random ray is most likely to enter, so opening it saves
//! the most box-test steps) into its two children. Leaves stay the binary tree's leaves, the
//! same contiguous triangle ranges, so both trees share the triangle store.

use crate::accel::node::BvhNode;
use crate::accel::wide_node::{Bvh4Node, LEAF_BIT};

/// The wide tree of `nodes` (depth-first, root first; the first interior child of a node
/// follows it). An empty binary tree gives an empty one; a binary tree that is one leaf gives
/// one wide node with that leaf as its only child.
pub fn collapse(nodes: &[BvhNode]) -> Vec<Bvh4Node> {
    let mut out = Vec::new();
    let Some(root) = nodes.first() else {
        return out;
    };
    // About one wide node per three binary interior nodes when every node fills up.
    out.reserve(nodes.len() / 6 + 1);
    out.push(Bvh4Node::EMPTY_NODE);
    if root.is_leaf() {
        out[0].set_child(0, root.min, root.max, leaf_ref(root), root.count);
    } else {
        fill(nodes, 0, 0, &mut out);
    }
    out
}

fn leaf_ref(n: &BvhNode) -> u32 {
    assert!(n.index < LEAF_BIT, "triangle index {} does not fit a wide leaf reference", n.index);
    LEAF_BIT | n.index
}

fn half_area(n: &BvhNode) -> f32 {
    let d = [n.max[0] - n.min[0], n.max[1] - n.min[1], n.max[2] - n.min[2]];
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

/// Fills wide node `at` with the (up to four) descendants of the binary interior node `i`,
/// then recurses into the interior ones.
fn fill(nodes: &[BvhNode], i: usize, at: usize, out: &mut Vec<Bvh4Node>) {
    let mut kids = [i + 1, nodes[i].index as usize, 0, 0];
    let mut k = 2;
    while k < 4 {
        let open = (0..k)
            .filter(|&j| !nodes[kids[j]].is_leaf())
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
        if n.is_leaf() {
            out[at].set_child(slot, n.min, n.max, leaf_ref(n), n.count);
        } else {
            let child = out.len();
            out.push(Bvh4Node::EMPTY_NODE);
            out[at].set_child(slot, n.min, n.max, child as u32, 0);
            fill(nodes, c, child, out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::build::{build, BuildParams};
    use crate::accel::wide_node::EMPTY;
    use crate::math::{Aabb, Vec3};
    use crate::sampler::Pcg32;

    /// Leaves of the wide tree: (first, count, box) in visiting order, with every interior
    /// child's box checked to be the union its children's boxes fit in.
    fn leaves(w: &[Bvh4Node], at: usize, out: &mut Vec<(u32, u32)>) {
        let n = &w[at];
        let k = n.children();
        assert!(k >= 2 || (at == 0 && k == 1), "node {at} has {k} children");
        for i in 0..4 {
            if n.child[i] == EMPTY {
                assert!(i >= k, "children are packed from slot 0");
                continue;
            }
            if n.child[i] & LEAF_BIT != 0 {
                out.push((n.child[i] & !LEAF_BIT, n.count[i]));
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
            let wide = collapse(&bin.nodes);
            let mut bin_leaves: Vec<(u32, u32)> =
                bin.nodes.iter().filter(|n| n.is_leaf()).map(|n| (n.index, n.count)).collect();
            let mut wide_leaves = Vec::new();
            leaves(&wide, 0, &mut wide_leaves);
            // Same leaves in the same (depth-first) order.
            assert_eq!(wide_leaves, bin_leaves, "n = {n}");
            bin_leaves.sort();
            let covered: u32 = bin_leaves.iter().map(|l| l.1).sum();
            assert_eq!(covered as usize, n);
            let interior = bin.nodes.len() - wide_leaves.len();
            assert!(wide.len() <= interior.max(1), "n = {n}: {} wide nodes", wide.len());
        }
        assert!(collapse(&[]).is_empty());
    }
}
