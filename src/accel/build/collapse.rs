//! Binary BVH -> 8-wide BVH: which binary nodes become wide nodes (as in Embree's BVH8
//! builders and tinybvh's `BVH8_CPU` conversion, which pull grandchildren up), chosen for the
//! least expected traversal cost, by the dynamic programme of Ylitie, Karras and Laine (2017,
//! "Efficient incoherent ray traversal on GPUs through compressed wide BVHs"), described, not
//! copied, with the leaves given: every binary subtree of at most `max_leaf` triangles is one
//! leaf, unless rays start inside its box (`OriginBoxes`: a room's walls). For each binary
//! node and each number of slots k it finds the cheapest way to hand its subtree to its wide
//! parent as exactly k children; a wide node costs its box's area (a random ray's odds of
//! visiting it) times `NODE_COST + SLOT_COST` per used slot.
//!
//! Leaves are contiguous triangle ranges of the shared triangle store. Because a binary
//! subtree's triangles are contiguous (leaves are in depth-first order), a subtree of at most
//! `max_leaf` triangles can become one wide leaf: the binary SAH prices every triangle as one
//! test and makes leaves of one or two triangles, while the single-ray leaf test takes 8 at
//! once.

use super::OriginBoxes;
use crate::accel::node::BvhNode;
use crate::accel::wide_node::{leaf_ref, WideNode, ARITY, MAX_LEAF};

/// Cost of visiting a wide node: one 8-wide box test of a single ray, whatever its slots hold.
const NODE_COST: f32 = 1.0;
/// Cost of each used slot of a visited wide node: packets test every candidate child with
/// all their lanes, and entered children are ordered. Chosen by measurement against 0, 0.05,
/// 0.2 and 0.4 (PERF.md, "Wide nodes by least cost").
const SLOT_COST: f32 = 0.1;

/// The wide tree of `nodes` (depth-first, root first; the first interior child of a node
/// follows it), with binary subtrees of at most `max_leaf` triangles merged into leaves
/// (except where rays start inside them, `OriginBoxes`)
/// (`max_leaf` and the binary leaves at most `MAX_LEAF`)
/// (0: keep the binary leaves). An empty binary tree gives an empty one; a tree that is one
/// leaf gives one wide node with that leaf as its only child.
#[cfg(test)]
pub fn collapse(nodes: &[BvhNode], max_leaf: usize) -> Vec<WideNode> {
    collapse_into(Vec::new(), nodes, max_leaf)
}

/// `collapse` (the tests' form) into `out` (emptied first), whose capacity a caller may have
/// prepared (huge pages before anything touched it): `wide_capacity(nodes)` nodes never
/// reallocate.
pub fn collapse_into(mut out: Vec<WideNode>, nodes: &[BvhNode], max_leaf: usize) -> Vec<WideNode> {
    out.clear();
    let Some(root) = nodes.first() else {
        return out;
    };
    assert!(max_leaf <= MAX_LEAF, "wide leaves hold at most {MAX_LEAF} triangles, not {max_leaf}");
    let c = Collapser::new(nodes, max_leaf);
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
    root: OriginBoxes,
    /// Per binary node (`plans`).
    plans: Vec<Plan>,
}

/// The cheapest ways to hand a binary subtree to a wide parent.
#[derive(Clone, Copy)]
struct Plan {
    /// `cost[k - 1]`: the least cost of the subtree as exactly k slots, for k up to `slots`.
    cost: [f32; ARITY],
    /// `split[k - 1]`, for 2 <= k <= `slots`: how many of the k slots go to the first child's
    /// subtree.
    split: [u8; ARITY],
    /// The most slots the subtree can fill (at most `ARITY`): a leaf is one slot, an interior
    /// node at most as many as its leaves.
    slots: u8,
    /// The node as one wide node: its slot count and how many go to its first child.
    node: (u8, u8),
}

/// Whether cost `c` beats `best`. Costs are areas, and a scene whose coordinates reach
/// 1e19 or so overflows them to infinity or NaN (inf x 0), where `<` never holds; the
/// feasibility of a plan is `Plan::slots`, never a finite cost, so such a scene still gets a
/// well-formed tree (a plan of NaN costs left `node` at zero slots: an index out of bounds).
fn cheaper(c: f32, best: f32) -> bool {
    c < best || (best.is_nan() && !c.is_nan())
}

impl<'a> Collapser<'a> {
    /// The collapse of `nodes` (not empty), its plans made.
    fn new(nodes: &'a [BvhNode], max_leaf: usize) -> Collapser<'a> {
        let root = OriginBoxes::of_root(nodes[0].min, nodes[0].max);
        let ranges = subtree_ranges(nodes);
        let mut c = Collapser { nodes, ranges, max_leaf, root, plans: Vec::new() };
        c.plans = c.plans();
        c
    }

    /// Whether binary node `i` becomes a wide leaf: a binary leaf, or a small subtree that rays
    /// do not start inside (`OriginBoxes`).
    fn is_leaf(&self, i: usize) -> bool {
        let n = &self.nodes[i];
        n.is_leaf()
            || (self.ranges[i].1 as usize <= self.max_leaf
                && !self.root.holds_origins(n.min, n.max))
    }

    fn leaf_ref(&self, i: usize) -> u32 {
        let (first, count) = self.ranges[i];
        leaf_ref(first as usize, count as usize)
    }

    /// Every binary node's `Plan`, children before parents (one backward pass).
    fn plans(&self) -> Vec<Plan> {
        let nodes = self.nodes;
        let unused =
            Plan { cost: [f32::INFINITY; ARITY], split: [0; ARITY], slots: 1, node: (0, 0) };
        let mut plans = vec![unused; nodes.len()];
        for x in (0..nodes.len()).rev() {
            let mut plan = unused;
            if self.is_leaf(x) {
                // A leaf's own cost is the same whichever wide node holds it.
                plan.cost[0] = 0.0;
            } else {
                let (first, second) = (&plans[x + 1], &plans[nodes[x].index as usize]);
                let (a, b) = (first.slots as usize, second.slots as usize);
                plan.slots = (a + b).min(ARITY) as u8;
                for k in 2..=plan.slots as usize {
                    // j slots to the first child, k - j to the second, each within its reach.
                    let js = k.saturating_sub(b).max(1)..=a.min(k - 1);
                    for (n, j) in js.enumerate() {
                        let c = first.cost[j - 1] + second.cost[k - j - 1];
                        if n == 0 || cheaper(c, plan.cost[k - 1]) {
                            (plan.cost[k - 1], plan.split[k - 1]) = (c, j as u8);
                        }
                    }
                }
                let area = half_area(&nodes[x]);
                for k in 2..=plan.slots as usize {
                    let c = area * (NODE_COST + SLOT_COST * k as f32) + plan.cost[k - 1];
                    if k == 2 || cheaper(c, plan.cost[0]) {
                        (plan.cost[0], plan.node) = (c, (k as u8, plan.split[k - 1]));
                    }
                }
            }
            plans[x] = plan;
        }
        plans
    }

    /// Appends to `kids` the binary nodes that are the `k` slots of `x`'s subtree, in
    /// depth-first order.
    fn slots(&self, x: usize, k: usize, kids: &mut [usize; ARITY], n: &mut usize) {
        if k == 1 {
            kids[*n] = x;
            *n += 1;
        } else {
            let j = self.plans[x].split[k - 1] as usize;
            self.slots(x + 1, j, kids, n);
            self.slots(self.nodes[x].index as usize, k - j, kids, n);
        }
    }

    /// Fills wide node `at` with the planned descendants of the binary interior node `i`, then
    /// recurses into the interior ones.
    fn fill(&self, i: usize, at: usize, out: &mut Vec<WideNode>) {
        let nodes = self.nodes;
        let (k, j) = self.plans[i].node;
        let mut kids = [0; ARITY];
        let mut n = 0;
        self.slots(i + 1, j as usize, &mut kids, &mut n);
        self.slots(nodes[i].index as usize, (k - j) as usize, &mut kids, &mut n);
        for (slot, &c) in kids[..n].iter().enumerate() {
            let b = &nodes[c];
            if self.is_leaf(c) {
                out[at].set_child(slot, b.min, b.max, self.leaf_ref(c));
            } else {
                let child = out.len();
                out.push(WideNode::EMPTY_NODE);
                out[at].set_child(slot, b.min, b.max, child as u32);
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

    /// Expected cost of the wide tree `w` under the collapse's model: every wide node's box
    /// area (the root's: `root`) times `NODE_COST + SLOT_COST` per used slot.
    fn wide_cost(w: &[WideNode], at: usize, area: f32) -> f32 {
        let n = &w[at];
        let k = n.children();
        let mut cost = area * (NODE_COST + SLOT_COST * k as f32);
        for i in 0..k {
            if n.child[i] & LEAF_BIT == 0 {
                let b = BvhNode {
                    min: [n.bounds[0][i], n.bounds[2][i], n.bounds[4][i]],
                    max: [n.bounds[1][i], n.bounds[3][i], n.bounds[5][i]],
                    index: 0,
                    count: 0,
                };
                cost += wide_cost(w, n.child[i] as usize, half_area(&b));
            }
        }
        cost
    }

    /// The same cost for the greedy collapse this one replaced: each wide node takes the two
    /// children of its binary node and opens the interior child of largest area until it has
    /// `ARITY` children.
    fn greedy_cost(c: &Collapser, i: usize) -> f32 {
        let nodes = c.nodes;
        let mut kids = vec![i + 1, nodes[i].index as usize];
        while kids.len() < ARITY {
            let open = (0..kids.len())
                .filter(|&j| !c.is_leaf(kids[j]))
                .max_by(|&a, &b| half_area(&nodes[kids[a]]).total_cmp(&half_area(&nodes[kids[b]])));
            let Some(j) = open else { break };
            let n = kids[j];
            kids.splice(j..=j, [n + 1, nodes[n].index as usize]);
        }
        let own = half_area(&nodes[i]) * (NODE_COST + SLOT_COST * kids.len() as f32);
        own + kids.iter().filter(|&&k| !c.is_leaf(k)).map(|&k| greedy_cost(c, k)).sum::<f32>()
    }

    /// The wide tree costs what the plan says it costs, and never more than the greedy
    /// collapse's, on random scenes (and less on the larger ones).
    #[test]
    fn planned_tree_is_no_costlier_than_the_greedy_one() {
        let mut rng = Pcg32::new(9, 2);
        let mut cheaper = 0;
        for n in [9usize, 40, 300, 2000, 2000, 5000] {
            let boxes: Vec<Aabb> = (0..n)
                .map(|_| {
                    let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32() * 0.2) * 10.0;
                    Aabb::from_points(&[c, c + Vec3::splat(0.3 * rng.next_f32())])
                })
                .collect();
            let bin = build(&boxes, BuildParams::default());
            let c = Collapser::new(&bin.nodes, 8);
            let wide = collapse(&bin.nodes, 8);
            let planned = c.plans[0].cost[0];
            let built = wide_cost(&wide, 0, half_area(&bin.nodes[0]));
            assert!((built - planned).abs() <= 1e-4 * planned, "n = {n}: {built} vs {planned}");
            let greedy = greedy_cost(&c, 0);
            assert!(planned <= greedy * (1.0 + 1e-5), "n = {n}: {planned} vs greedy {greedy}");
            cheaper += (planned < 0.999 * greedy) as usize;
        }
        // Measured: equal on the three smaller scenes, 0.1-11% cheaper on the larger ones.
        assert!(cheaper >= 2, "the plan beat the greedy collapse on {cheaper} scenes");
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

    /// Rays start inside a room, so no leaf may span it (`OriginBoxes`): the room's twelve
    /// wall triangles end up in leaves of one wall each, while a compact mesh in the room keeps
    /// its leaves of up to `MAX_LEAF` triangles (over 5 on average, as without the room).
    /// Built as `Accel` builds (nodes of 8 merged), and with every split.
    #[test]
    fn rooms_split_into_walls_meshes_keep_full_leaves() {
        let p = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        let mut tris: Vec<[Vec3; 3]> = Vec::new();
        for axis in 0..3 {
            for side in [0.0, 10.0] {
                let corner = |a: f32, b: f32| {
                    let mut c = [0.0; 3];
                    c[axis] = side;
                    c[(axis + 1) % 3] = a;
                    c[(axis + 2) % 3] = b;
                    p(c[0], c[1], c[2])
                };
                tris.push([corner(0.0, 0.0), corner(10.0, 0.0), corner(10.0, 10.0)]);
                tris.push([corner(0.0, 0.0), corner(10.0, 10.0), corner(0.0, 10.0)]);
            }
        }
        let walls = tris.len();
        let mut rng = Pcg32::new(3, 4);
        for _ in 0..256 {
            let c = p(rng.next_f32(), rng.next_f32(), rng.next_f32()) + Vec3::splat(4.5);
            let mut d = || Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.05;
            let (a, b) = (d(), d());
            tris.push([c, c + a, c + b]);
        }
        let boxes: Vec<Aabb> = tris.iter().map(|t| Aabb::from_points(t)).collect();
        let mesh_leaves = |boxes: &[Aabb], merge: usize, offset: u32| {
            let bin = crate::accel::build::build_merged(
                boxes.len(),
                |i| boxes[i],
                BuildParams::default(),
                merge,
            );
            let wide = collapse(&bin.nodes, MAX_LEAF);
            let mut found = Vec::new();
            leaves(&wide, 0, &mut found);
            let mut mesh: Vec<Vec<u32>> = Vec::new();
            for (first, count) in found {
                let mut ids: Vec<u32> = bin.order[first as usize..][..count as usize].to_vec();
                ids.sort_unstable();
                if ids[0] < offset {
                    assert!(
                        ids.iter().all(|&i| i / 2 == ids[0] / 2),
                        "merge {merge}: a leaf spans walls {ids:?}"
                    );
                } else {
                    mesh.push(ids.iter().map(|i| i - offset).collect());
                }
            }
            mesh.sort();
            mesh
        };
        for merge in [0, MAX_LEAF] {
            let in_room = mesh_leaves(&boxes, merge, walls as u32);
            let alone = mesh_leaves(&boxes[walls..], merge, 0);
            for leaves in [&in_room, &alone] {
                let triangles: usize = leaves.iter().map(Vec::len).sum();
                assert_eq!(triangles, 256);
                // Binning differs under the room's root, so the leaves are not the same ones.
                assert!(leaves.len() * 5 <= 256, "merge {merge}: {} mesh leaves", leaves.len());
            }
        }
    }
}
