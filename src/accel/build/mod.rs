//! BVH construction: a binned SAH build straight into the flat depth-first node array, and
//! its collapse into the 8-wide tree that rays traverse (`collapse`), whose leaves are then
//! placed in triangle blocks (`pack`).
//!
//! Primitives are known only by their bounding boxes; the builder returns the node array and
//! the primitive order that the leaves index. It works on an array of 32-byte primitive
//! references (box + index) that it partitions in place, so every pass over a node's
//! primitives streams through contiguous memory instead of chasing an index array. Subtrees of
//! more than `PARALLEL_MIN` primitives are built on both sides of a `rayon::join`; the result
//! does not depend on the thread count.

mod binned_sah;
mod collapse;
mod pack;

#[cfg(test)]
pub(crate) use collapse::collapse;
pub(crate) use collapse::{collapse_into, wide_capacity};
pub(crate) use pack::pack_leaves;

use glam::Vec4;
use rayon::prelude::*;
use wide::f32x8;

use crate::accel::hugepage;
use crate::math::Aabb;

use super::node::BvhNode;

/// Build settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BuildParams {
    /// SAH bins per axis (at most `binned_sah::MAX_BINS`).
    pub bins: usize,
    /// Largest leaf; also the size under which a leaf is always allowed. At most
    /// `wide_node::MAX_LEAF`, the most a wide leaf holds.
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
/// Deepest the binary tree can be; the fixed traversal stacks are sized from it.
pub const MAX_DEPTH: usize = 64;

/// Subtrees at least this large are built in parallel with their sibling. Below it the cost
/// of a separate node vector outweighs the gain.
const PARALLEL_MIN: usize = 16 * 1024;

/// The flat tree and the primitive order its leaves refer to.
pub struct BuiltBvh {
    /// The nodes in depth-first order, the root first.
    pub nodes: Vec<BvhNode>,
    /// Input primitive indices in leaf order: a leaf's `index .. index + count` range of this.
    pub order: Vec<u32>,
    /// The union of the primitives' boxes (empty for no primitives).
    pub bounds: Aabb,
}

/// A box as one 8-lane vector: the lower corner in lanes 0..3 and the upper corner negated
/// in lanes 4..7 (lanes 3 and 7 spare). With the upper corner negated, the union of two boxes
/// is one 8-lane `min`, so binning a primitive is one load, one `min` and one store per axis.
/// Negation is exact, so the boxes are the same floats as with a separate `max`.
#[derive(Debug, Clone, Copy)]
struct Box8(f32x8);

impl Box8 {
    const EMPTY: Box8 = Box8(f32x8::new([f32::INFINITY; 8]));

    fn new(b: &Aabb, spare: f32) -> Box8 {
        let (l, u) = (b.min, b.max);
        Box8(f32x8::new([l.x, l.y, l.z, spare, -u.x, -u.y, -u.z, 0.0]))
    }

    #[inline(always)]
    fn union(self, o: Box8) -> Box8 {
        Box8(self.0.fast_min(o.0))
    }

    #[inline(always)]
    fn lower(&self) -> Vec4 {
        Vec4::from_slice(&self.0.as_array()[..4])
    }

    #[inline(always)]
    fn neg_upper(&self) -> Vec4 {
        Vec4::from_slice(&self.0.as_array()[4..])
    }

    fn aabb(self) -> Aabb {
        Aabb { min: self.lower().truncate(), max: (-self.neg_upper()).truncate() }
    }

    /// Half the surface area, 0 for an empty box.
    #[inline(always)]
    fn half_area(self) -> f32 {
        let e = (-self.neg_upper() - self.lower()).max(Vec4::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    }
}

/// A primitive as the builder sees it: its box, with its index in the input in the spare lane
/// of the lower corner. The index rides in the mantissa of a float with a fixed exponent
/// (`INDEX_TAG`), in [2, 8): the spare lane goes through the binning arithmetic with the
/// others, and an index stored as raw bits would be a subnormal float there, which costs a
/// microcode assist per operation.
#[derive(Debug, Clone, Copy)]
struct PrimRef(Box8);

/// Exponent bits of the index lane; indices take the 24 bits below (`MAX_PRIMS`).
const INDEX_TAG: u32 = 0x4000_0000;
/// Most primitives one build takes (`wide_node::MAX_TRIANGLES` is no more).
const MAX_PRIMS: usize = 1 << 24;

impl PrimRef {
    fn new(b: &Aabb, index: u32) -> PrimRef {
        PrimRef(Box8::new(b, f32::from_bits(INDEX_TAG | index)))
    }

    #[inline(always)]
    fn index(&self) -> u32 {
        self.0 .0.as_array()[3].to_bits() & (MAX_PRIMS as u32 - 1)
    }

    /// Twice the centroid (w lane meaningless): binning only needs it up to a common scale.
    #[inline(always)]
    fn centroid2(&self) -> Vec4 {
        self.0.lower() - self.0.neg_upper()
    }
}

/// A box of points (the centroids) with SIMD corners; only x, y, z mean anything.
#[derive(Debug, Clone, Copy)]
struct Box4 {
    min: Vec4,
    max: Vec4,
}

impl Box4 {
    const EMPTY: Box4 =
        Box4 { min: Vec4::splat(f32::INFINITY), max: Vec4::splat(f32::NEG_INFINITY) };

    #[inline(always)]
    fn grow_point(self, p: Vec4) -> Box4 {
        Box4 { min: self.min.min(p), max: self.max.max(p) }
    }

    #[inline(always)]
    fn union(self, o: Box4) -> Box4 {
        Box4 { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
}

/// Builds a BVH over primitives with the given bounds. An empty input gives one empty leaf.
pub fn build(bounds: &[Aabb], params: BuildParams) -> BuiltBvh {
    build_merged(bounds.len(), |i| bounds[i], params, 0)
}

/// [`build`] over the `count` primitives whose boxes `box_of` gives (computed in parallel, in
/// the caller's rayon pool), except that every node of at most `merge` primitives becomes a
/// leaf without looking for a split, unless rays start inside it (`OriginBoxes`). For the wide
/// tree (`collapse` with the same `merge`), which turns every such binary subtree into one
/// leaf anyway (a box inside one that holds no origins holds none either): its
/// nodes, leaf ranges and boxes come out the same, only the order of the triangles inside a
/// leaf differs, and the many small nodes near the leaves (most of the binary tree's nodes)
/// cost nothing.
pub(crate) fn build_merged(
    count: usize,
    box_of: impl Fn(usize) -> Aabb + Sync,
    params: BuildParams,
    merge: usize,
) -> BuiltBvh {
    assert!(params.bins >= 2 && params.bins <= binned_sah::MAX_BINS, "bins out of range");
    assert!(merge <= params.max_leaf.max(1), "merged leaves hold at most max_leaf primitives");
    assert!(count <= MAX_PRIMS, "at most {MAX_PRIMS} primitives");
    // The two big arrays ask for huge pages before they are first touched (`hugepage`:
    // arrays under 1 MiB are left alone): far fewer page faults in a fresh process.
    let mut prims: Vec<PrimRef> = Vec::with_capacity(count);
    hugepage::prefer(prims.spare_capacity_mut());
    prims.par_extend((0..count).into_par_iter().map(|i| PrimRef::new(&box_of(i), i as u32)));
    // The root's boxes over fixed chunks, combined in order: the same floats whatever the
    // thread count (the sign of a zero can depend on the order of a min).
    let (root_bounds, root_centroids) = prims
        .par_chunks(BOUNDS_CHUNK)
        .map(bounds_of)
        .collect::<Vec<_>>()
        .into_iter()
        .fold((Box8::EMPTY, Box4::EMPTY), |(b, c), (cb, cc)| (b.union(cb), c.union(cc)));
    // A binary tree over n primitives has at most 2n - 1 nodes, so the array never grows (and
    // is never copied) during the build.
    let mut nodes = Vec::with_capacity((2 * count).max(1));
    hugepage::prefer(nodes.spare_capacity_mut());
    let mut bins = binned_sah::Bins::new();
    let node = Node { bounds: root_bounds, centroids: root_centroids, first: 0, depth: 0 };
    let root = root_bounds.aabb();
    let root = if root.is_empty() {
        OriginBoxes::of_root([0.0; 3], [0.0; 3])
    } else {
        OriginBoxes::of_root(root.min.into(), root.max.into())
    };
    let ctx = Ctx { params, merge, root };
    build_node(&mut nodes, &mut prims, node, &ctx, &mut bins);
    // Give back the rest of the reservation so the memory the benchmark reports is what
    // traversal uses (shrinking a large block in place does not copy it).
    nodes.shrink_to_fit();
    BuiltBvh {
        nodes,
        order: prims.par_iter().map(PrimRef::index).collect(),
        bounds: root_bounds.aabb(),
    }
}

/// Primitives per chunk of the root's bounds pass.
const BOUNDS_CHUNK: usize = 16 * 1024;

/// What every node of one build shares.
struct Ctx {
    params: BuildParams,
    /// Nodes of at most this many primitives are leaves (`build_merged`), unless rays start
    /// inside them.
    merge: usize,
    root: OriginBoxes,
}

/// Which boxes rays start inside. The SAH prices a box by its area, the odds that a ray from
/// outside crosses it; a ray that starts inside a box cannot skip it, whatever the split. In
/// an enclosed scene (a room: every Cornell box) a small subtree can span the whole room, e.g.
/// the walls, and every ray then tests every triangle of that leaf. So a box whose share of
/// the scene's volume is at least `ORIGIN_SHARE` times its share of the scene's surface area is
/// split even where the SAH would keep a leaf: flat or small boxes (a wall, a mesh's leaves)
/// have a tiny volume share, the room's box a share of 1.
#[derive(Clone, Copy, Debug)]
pub(crate) struct OriginBoxes {
    volume: f64,
    half_area: f64,
}

/// See `OriginBoxes` (PERF.md, "Rooms split into walls").
const ORIGIN_SHARE: f64 = 0.25;

impl OriginBoxes {
    pub(crate) fn of_root(min: [f32; 3], max: [f32; 3]) -> OriginBoxes {
        let (volume, half_area) = volume_and_half_area(min, max);
        OriginBoxes { volume, half_area }
    }

    /// Whether rays are likely to start inside the box `min`..`max` (`OriginBoxes`).
    pub(crate) fn holds_origins(&self, min: [f32; 3], max: [f32; 3]) -> bool {
        let (volume, half_area) = volume_and_half_area(min, max);
        self.volume > 0.0 && volume * self.half_area >= ORIGIN_SHARE * half_area * self.volume
    }
}

/// In f64: a volume of f32 extents can overflow f32 (a scene 1e13 across), and an infinite
/// volume would make every box hold origins.
fn volume_and_half_area(min: [f32; 3], max: [f32; 3]) -> (f64, f64) {
    let d = [0, 1, 2].map(|a| (max[a] as f64 - min[a] as f64).max(0.0));
    (d[0] * d[1] * d[2], d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
}

/// The box and the centroid (`centroid2`) box of `prims`.
fn bounds_of(prims: &[PrimRef]) -> (Box8, Box4) {
    prims
        .iter()
        .fold((Box8::EMPTY, Box4::EMPTY), |(b, c), p| (b.union(p.0), c.grow_point(p.centroid2())))
}

/// What a node knows before it is built: its bounds, which its parent's split found, and
/// where it sits.
#[derive(Clone, Copy)]
struct Node {
    bounds: Box8,
    centroids: Box4,
    /// Its first primitive's position in the final order.
    first: usize,
    depth: usize,
}

/// Appends the subtree over `prims` to `nodes` in depth-first order and returns its root's
/// index in `nodes`.
fn build_node(
    nodes: &mut Vec<BvhNode>,
    prims: &mut [PrimRef],
    node: Node,
    ctx: &Ctx,
    bins: &mut binned_sah::Bins,
) -> u32 {
    let params = &ctx.params;
    let Node { bounds, centroids, first, depth } = node;
    let index = nodes.len();
    let count = prims.len();
    let aabb = bounds.aabb();
    let (min, max) =
        if aabb.is_empty() { ([0.0; 3], [0.0; 3]) } else { (aabb.min.into(), aabb.max.into()) };
    nodes.push(BvhNode { min, index: first as u32, max, count: count as u32 });
    let origins = count > 1 && ctx.root.holds_origins(min, max);
    if count <= 1 || (count <= ctx.merge && !origins) {
        return index as u32;
    }

    let small = count <= params.max_leaf && !origins;
    let split = if depth < SAH_DEPTH_LIMIT {
        binned_sah::find_split(prims, bounds, centroids, params, bins)
    } else {
        None
    };
    let (left_count, left_node, right_node) = match split {
        Some(s) if !small || s.cost < count as f32 => {
            let (left_count, left_centroids, right_centroids) = binned_sah::partition(prims, &s);
            // Both sides of a split hold primitives: the bins that the split was chosen from
            // count the same primitives as the partition.
            debug_assert!(left_count > 0 && left_count < count);
            let left = Node { bounds: s.left, centroids: left_centroids, first, depth: depth + 1 };
            let right = Node {
                bounds: s.right,
                centroids: right_centroids,
                first: first + left_count,
                depth: depth + 1,
            };
            (left_count, left, right)
        }
        Some(_) => return index as u32, // a leaf is cheaper
        None if small => return index as u32,
        // Too many primitives to leave and no useful split (all centroids equal, or too
        // deep): halve the range. Leaves stay small and the recursion ends.
        None => {
            let half = count / 2;
            let side = |prims: &[PrimRef], first: usize| {
                let (bounds, centroids) = bounds_of(prims);
                Node { bounds, centroids, first, depth: depth + 1 }
            };
            (half, side(&prims[..half], first), side(&prims[half..], first + half))
        }
    };
    let (left, right) = prims.split_at_mut(left_count);

    let right_index = if count >= PARALLEL_MIN {
        // Both halves into their own vectors at once, then appended: the left subtree right
        // after this node, the right one after it, interior links shifted by where each lands.
        let build_alone = |prims: &mut [PrimRef], node: Node, bins: &mut binned_sah::Bins| {
            let mut sub = Vec::with_capacity(2 * prims.len());
            build_node(&mut sub, prims, node, ctx, bins);
            sub
        };
        let (l, r) = rayon::join(
            || build_alone(left, left_node, bins),
            || build_alone(right, right_node, &mut binned_sah::Bins::new()),
        );
        append_shifted(nodes, &l);
        let right_index = nodes.len() as u32;
        append_shifted(nodes, &r);
        right_index
    } else {
        build_node(nodes, left, left_node, ctx, bins);
        build_node(nodes, right, right_node, ctx, bins)
    };
    nodes[index].index = right_index;
    nodes[index].count = 0;
    index as u32
}

/// A balanced binary tree over `count` primitives in order, in leaves of at most `leaf`, with
/// every node's box `min`..`max`: the brute-force oracle's tree, which every ray that enters
/// the box walks to the end, testing every primitive.
pub(crate) fn flat_tree(count: u32, leaf: u32, min: [f32; 3], max: [f32; 3]) -> Vec<BvhNode> {
    fn add(nodes: &mut Vec<BvhNode>, first: u32, count: u32, leaf: u32, b: ([f32; 3], [f32; 3])) {
        let at = nodes.len();
        nodes.push(BvhNode { min: b.0, index: first, max: b.1, count });
        if count > leaf {
            // Halve in whole leaves, so that every leaf but the last is full.
            let left = count.div_ceil(leaf) / 2 * leaf;
            add(nodes, first, left, leaf, b);
            nodes[at].index = nodes.len() as u32;
            nodes[at].count = 0;
            add(nodes, first + left, count - left, leaf, b);
        }
    }
    let mut nodes = Vec::with_capacity(2 * count.div_ceil(leaf.max(1)) as usize);
    if count > 0 {
        add(&mut nodes, 0, count, leaf.max(1), (min, max));
    }
    nodes
}

/// Appends a subtree built in its own vector; its interior nodes' child links are relative to
/// that vector, so they move by the offset at which it lands.
fn append_shifted(nodes: &mut Vec<BvhNode>, sub: &[BvhNode]) {
    let offset = nodes.len() as u32;
    nodes.extend(sub.iter().map(|n| {
        let mut n = *n;
        if !n.is_leaf() {
            n.index += offset;
        }
        n
    }));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The tree and the primitive order do not depend on the thread count: more primitives
    /// than `PARALLEL_MIN` and `BOUNDS_CHUNK`, so subtrees and the root's bounds run in
    /// parallel, and both the full tree and the merged one.
    #[test]
    fn same_tree_at_one_and_two_threads() {
        use crate::math::Vec3;
        let mut rng = crate::sampler::Pcg32::new(7, 8);
        let boxes: Vec<Aabb> = (0..3 * PARALLEL_MIN.max(BOUNDS_CHUNK))
            .map(|_| {
                let c = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0;
                Aabb::from_points(&[c, c + Vec3::splat(0.05 * rng.next_f32())])
            })
            .collect();
        let built = |threads: usize, merge: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| build_merged(boxes.len(), |i| boxes[i], BuildParams::default(), merge))
        };
        for merge in [0, 8] {
            let (one, two) = (built(1, merge), built(2, merge));
            assert_eq!(one.nodes, two.nodes, "merge {merge}");
            assert_eq!(one.order, two.order, "merge {merge}");
            assert_eq!(one.bounds, two.bounds, "merge {merge}");
        }
    }

    /// Rays start inside the room's box and its halves, not inside a wall or a small box, at
    /// any scale: a scene 1e20 across has a volume beyond f32, which would otherwise make every
    /// box hold origins (or none).
    #[test]
    fn origin_boxes_are_the_roomy_ones_at_any_scale() {
        for scale in [1e-20f32, 1.0, 1e20] {
            let room = OriginBoxes::of_root([0.0; 3], [scale; 3]);
            let s = |v: f32| v * scale;
            assert!(room.holds_origins([0.0; 3], [scale; 3]), "scale {scale}");
            assert!(room.holds_origins([0.0; 3], [s(0.5), scale, scale]), "scale {scale}");
            assert!(!room.holds_origins([0.0; 3], [scale, 0.0, scale]), "a wall, scale {scale}");
            assert!(!room.holds_origins([0.0; 3], [s(0.05); 3]), "a small box, scale {scale}");
        }
        let flat = OriginBoxes::of_root([0.0; 3], [1.0, 0.0, 1.0]);
        assert!(!flat.holds_origins([0.0; 3], [1.0, 0.0, 1.0]), "a flat scene has no inside");
    }

    /// The brute-force tree: leaves of at most `leaf` tile the primitives in order, every
    /// interior node links its second child correctly, and every box is the given one.
    #[test]
    fn flat_tree_tiles_the_primitives() {
        assert!(flat_tree(0, 8, [0.0; 3], [1.0; 3]).is_empty());
        for count in [1u32, 7, 8, 9, 16, 17, 100, 1000] {
            let nodes = flat_tree(count, 8, [0.0; 3], [1.0; 3]);
            let mut next = 0;
            let mut stack = vec![0usize];
            while let Some(i) = stack.pop() {
                let n = &nodes[i];
                assert_eq!((n.min, n.max), ([0.0; 3], [1.0; 3]));
                if n.is_leaf() {
                    assert_eq!(n.index, next, "count {count}");
                    assert!(n.count <= 8);
                    next += n.count;
                } else {
                    stack.push(n.index as usize);
                    stack.push(i + 1);
                }
            }
            assert_eq!(next, count);
        }
    }
}
