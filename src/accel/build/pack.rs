//! Places the wide tree's leaves in the triangle blocks (`geometry::triangles`): each leaf
//! gets a run of slots inside one block, so a leaf test reads one block.
//!
//! Leaves are taken in depth-first order and each goes into the first of the last `OPEN`
//! blocks it still fits in, else into a fresh one. Nearby leaves in that order are nearby in
//! space, so leaves that share a block tend to be visited by the same rays.

use crate::accel::wide_node::{leaf_range, leaf_ref, WideNode, ARITY, EMPTY, LEAF_BIT, MAX_LEAF};
use crate::geometry::triangles::{LANES, NO_PRIM};

const _: () = assert!(MAX_LEAF <= LANES, "a leaf fits one block");

/// How many recent blocks with free lanes a leaf may go into. Measured on CBbunny, maxplanck
/// and the 1M tori (average leaf 5.7-6.0 triangles): PERF.md, "Triangle blocks" (4 with the
/// 4-wide tree) and "8-wide nodes" (8 keeps the 8-wide tree within 64 bytes per triangle).
const OPEN: usize = 8;

/// Rewrites every leaf reference of `nodes` from a range of `order` to a range of slots and
/// returns what each slot holds (a scene triangle index or `NO_PRIM`), a whole number of
/// blocks long.
pub fn pack_leaves(nodes: &mut [WideNode], order: &[u32]) -> Vec<u32> {
    // The leaves in depth-first order, which is the order of their ranges (the collapse keeps
    // the binary tree's depth-first order, whose leaves tile `order`): a walk instead of a sort.
    let mut leaves: Vec<(usize, usize, u32, u8)> = Vec::with_capacity(order.len() / 4);
    let mut stack: Vec<(u32, u8)> = Vec::with_capacity(64);
    let push_children = |stack: &mut Vec<(u32, u8)>, at: u32| {
        stack.extend((0..ARITY as u8).rev().map(|slot| (at, slot)));
    };
    if !nodes.is_empty() {
        push_children(&mut stack, 0);
    }
    while let Some((at, slot)) = stack.pop() {
        let c = nodes[at as usize].child[slot as usize];
        if c == EMPTY {
            continue;
        }
        if c & LEAF_BIT != 0 {
            let (first, count) = leaf_range(c);
            leaves.push((first, count, at, slot));
        } else {
            push_children(&mut stack, c);
        }
    }
    debug_assert!(leaves.windows(2).all(|w| w[0].0 + w[0].1 == w[1].0));
    let mut slots: Vec<u32> = Vec::with_capacity(order.len() + order.len() / 2);
    // The last `OPEN` blocks that still have free lanes: block index and lanes used.
    let mut open: Vec<(usize, usize)> = Vec::with_capacity(OPEN + 1);
    for (first, count, at, slot) in leaves {
        let start = match open.iter_mut().find(|(_, used)| *used + count <= LANES) {
            Some((block, used)) => {
                *used += count;
                *block * LANES + *used - count
            }
            None => {
                let start = slots.len();
                slots.resize(start + LANES, NO_PRIM);
                if count < LANES {
                    if open.len() == OPEN {
                        open.remove(0);
                    }
                    open.push((start / LANES, count));
                }
                start
            }
        };
        open.retain(|&(_, used)| used < LANES);
        slots[start..start + count].copy_from_slice(&order[first..][..count]);
        nodes[at as usize].child[slot as usize] = leaf_ref(start, count);
    }
    slots
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::build::{build, collapse, BuildParams};
    use crate::math::{Aabb, Vec3};
    use crate::sampler::Pcg32;

    /// Every triangle gets exactly one slot; a leaf lies in one block; leaf slots hold the
    /// leaf's triangles in order.
    #[test]
    fn leaves_lie_in_blocks_and_keep_their_triangles() {
        let mut rng = Pcg32::new(5, 6);
        for n in [1usize, 3, 9, 100, 3000] {
            let boxes: Vec<Aabb> = (0..n)
                .map(|_| {
                    let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                    Aabb::from_points(&[c, c + Vec3::splat(0.1 * rng.next_f32())])
                })
                .collect();
            let bin = build(&boxes, BuildParams::default());
            for max_leaf in [0, 8] {
                let before = collapse(&bin.nodes, max_leaf);
                let mut after = before.clone();
                let slots = pack_leaves(&mut after, &bin.order);
                assert_eq!(slots.len() % LANES, 0);
                let mut seen = vec![false; n];
                for (b, a) in before.iter().zip(&after) {
                    for i in 0..ARITY {
                        if b.child[i] == EMPTY || b.child[i] & LEAF_BIT == 0 {
                            assert_eq!(a.child[i], b.child[i]);
                            continue;
                        }
                        let ((old, count), (new, new_count)) =
                            (leaf_range(b.child[i]), leaf_range(a.child[i]));
                        assert_eq!(count, new_count);
                        assert_eq!(new / LANES, (new + count - 1) / LANES, "n = {n}");
                        assert_eq!(&slots[new..new + count], &bin.order[old..old + count]);
                        for &p in &slots[new..new + count] {
                            assert!(!std::mem::replace(&mut seen[p as usize], true));
                        }
                    }
                }
                assert!(seen.iter().all(|&s| s), "n = {n}");
                let used = slots.iter().filter(|&&p| p != NO_PRIM).count();
                assert_eq!(used, n);
            }
        }
    }
}
