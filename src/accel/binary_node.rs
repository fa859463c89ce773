//! One node of the binary SAH tree, named by a path of L/R steps from the root: what the
//! write-up's BVH previews show (`--bvh-node`). The tree is the full binary SAH tree over the
//! same primitive boxes with the same `BuildParams`, split down to single primitives; it
//! collapses to the same wide tree as the one `Accel::build` makes (which stops splitting at
//! nodes small enough to be one wide leaf, `build::build_merged`).

use rayon::prelude::*;

use super::build::{self, BuildParams};
use super::node::BvhNode;
use crate::math::Aabb;
use crate::scene::Scene;
use crate::{Error, Result};

/// A node of the binary tree and what lies under it.
#[derive(Debug, Clone, PartialEq)]
pub struct BinaryNode {
    /// The path as given, normalised: `root`, or the L/R steps (`LLR`).
    pub path: String,
    /// The node's box (empty for an empty scene).
    pub bounds: Aabb,
    /// Scene triangle indices under the node, ascending.
    pub prims: Vec<u32>,
    /// SAH cost of the subtree under the node, in triangle tests: a leaf costs its triangle
    /// count; an interior node `traversal_cost + (A_L C_L + A_R C_R) / A`, the expected work
    /// of a ray that enters its box (child boxes entered with their area ratio).
    pub sah_cost: f32,
    /// Whether the node is a leaf of the binary tree (no step below it is possible).
    pub is_leaf: bool,
}

/// A step down the tree.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Step {
    Left,
    Right,
}

/// The node of `scene`'s binary SAH tree at `path`: L/R steps from the root (`""` or `root`
/// is the root; lower case is accepted). A step below a leaf, or any other character, is an
/// error naming the path.
pub fn binary_node(scene: &Scene, path: &str, params: BuildParams) -> Result<BinaryNode> {
    let steps = parse_path(path)?;
    let name = if steps.is_empty() { "root".to_string() } else { path_text(&steps) };
    if scene.triangles.is_empty() {
        if let Some(&first) = steps.first() {
            let root = "the root, an empty leaf (the scene has no triangles),";
            return Err(off_tree(path, 1, first, root));
        }
        let (bounds, prims) = (Aabb::EMPTY, Vec::new());
        return Ok(BinaryNode { path: name, bounds, prims, sah_cost: 0.0, is_leaf: true });
    }
    let built = build::build(&triangle_boxes(scene), params);
    let nodes = &built.nodes;
    let mut at = 0;
    for (k, &step) in steps.iter().enumerate() {
        let node = &nodes[at];
        if node.is_leaf() {
            let here = if k == 0 { "root".to_string() } else { path_text(&steps[..k]) };
            let what = format!("node {here}, a leaf of {} triangle(s),", node.count);
            return Err(off_tree(path, k + 1, step, &what));
        }
        at = match step {
            Step::Left => at + 1,
            Step::Right => node.index as usize,
        };
    }
    let (first, count, sah_cost) = subtree(nodes, at, params.traversal_cost);
    let mut prims = built.order[first as usize..(first + count) as usize].to_vec();
    prims.sort_unstable();
    let n = &nodes[at];
    let bounds = Aabb { min: n.min.into(), max: n.max.into() };
    Ok(BinaryNode { path: name, bounds, prims, sah_cost, is_leaf: n.is_leaf() })
}

fn parse_path(path: &str) -> Result<Vec<Step>> {
    if path.is_empty() || path == "root" {
        return Ok(Vec::new());
    }
    path.chars()
        .enumerate()
        .map(|(k, c)| match c {
            'L' | 'l' => Ok(Step::Left),
            'R' | 'r' => Ok(Step::Right),
            _ => Err(Error::new(format!(
                "BVH path '{path}': step {} is '{c}'; a path is L and R steps from the root (or 'root')",
                k + 1
            ))),
        })
        .collect()
}

fn path_text(steps: &[Step]) -> String {
    steps.iter().map(|s| if *s == Step::Left { 'L' } else { 'R' }).collect()
}

fn off_tree(path: &str, step_number: usize, step: Step, node: &str) -> Error {
    let side = path_text(&[step]);
    Error::new(format!(
        "BVH path '{path}': step {step_number} ({side}) leaves the tree: {node} has no children"
    ))
}

fn triangle_boxes(scene: &Scene) -> Vec<Aabb> {
    (0..scene.triangles.len())
        .into_par_iter()
        .map(|i| Aabb::from_points(&scene.triangle(i)))
        .collect()
}

/// (first position in the leaf order, primitive count, SAH cost) of the subtree at `i`. Leaves
/// are in depth-first order, so a subtree's primitives are one contiguous range.
fn subtree(nodes: &[BvhNode], i: usize, traversal_cost: f32) -> (u32, u32, f32) {
    let n = &nodes[i];
    if n.is_leaf() {
        return (n.index, n.count, n.count as f32);
    }
    let (lf, lc, l_cost) = subtree(nodes, i + 1, traversal_cost);
    let r = n.index as usize;
    let (_, rc, r_cost) = subtree(nodes, r, traversal_cost);
    let area = half_area(n).max(f32::MIN_POSITIVE);
    let cost =
        traversal_cost + (half_area(&nodes[i + 1]) * l_cost + half_area(&nodes[r]) * r_cost) / area;
    (lf, lc + rc, cost)
}

fn half_area(n: &BvhNode) -> f32 {
    let d = [n.max[0] - n.min[0], n.max[1] - n.min[1], n.max[2] - n.min[2]];
    d[0] * d[1] + d[1] * d[2] + d[2] * d[0]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;

    /// A row of `n` small triangles along x, one unit apart.
    fn row_of_triangles(n: usize) -> Scene {
        let mut scene = Scene::default();
        for i in 0..n {
            let x = i as f32;
            let base = scene.positions.len() as u32;
            for p in [Vec3::new(x, 0.0, 0.0), Vec3::new(x + 0.5, 0.0, 0.0), Vec3::new(x, 0.5, 0.0)]
            {
                scene.positions.push(p);
                scene.normals.push(Vec3::Z);
            }
            scene.triangles.push([base, base + 1, base + 2]);
            scene.triangle_materials.push(0);
        }
        scene
    }

    fn node(scene: &Scene, path: &str) -> Result<BinaryNode> {
        binary_node(scene, path, BuildParams::default())
    }

    #[test]
    fn children_split_their_parent_and_the_cost_follows_the_sah() {
        let scene = row_of_triangles(100);
        let root = node(&scene, "").unwrap();
        assert_eq!(root, node(&scene, "root").unwrap());
        assert_eq!(root.prims, (0..100).collect::<Vec<u32>>());
        for parent in ["root", "L", "R", "LL", "LR", "RL"] {
            let p = node(&scene, parent).unwrap();
            let prefix = if parent == "root" { "" } else { parent };
            let l = node(&scene, &format!("{prefix}L")).unwrap();
            let r = node(&scene, &format!("{prefix}r")).unwrap();
            assert_eq!(l.prims.len() + r.prims.len(), p.prims.len(), "{parent}");
            let mut both = [l.prims.clone(), r.prims.clone()].concat();
            both.sort_unstable();
            assert_eq!(both, p.prims, "{parent}: the children hold exactly the parent's triangles");
            // Interior cost: one box test plus each child's cost weighted by its area share.
            let ha = |b: &Aabb| {
                let d = b.max - b.min;
                d.x * d.y + d.y * d.z + d.z * d.x
            };
            let want =
                1.0 + (ha(&l.bounds) * l.sah_cost + ha(&r.bounds) * r.sah_cost) / ha(&p.bounds);
            assert!((p.sah_cost - want).abs() <= 1e-4 * want, "{parent}: {} vs {want}", p.sah_cost);
            assert!(!p.is_leaf);
        }
    }

    #[test]
    fn a_leaf_costs_its_triangles_and_a_step_below_it_is_an_error() {
        let scene = row_of_triangles(3);
        let mut path = String::new();
        let leaf = loop {
            let n = node(&scene, &path).unwrap();
            if n.is_leaf {
                break n;
            }
            path.push('L');
        };
        assert_eq!(leaf.sah_cost, leaf.prims.len() as f32);
        let below = format!("{path}R");
        let err = node(&scene, &below).unwrap_err().to_string();
        assert!(err.contains("leaves the tree") && err.contains(&below), "{err}");
        assert!(!err.contains('\n'));
    }

    #[test]
    fn bad_paths_and_empty_scenes() {
        let scene = row_of_triangles(10);
        let err = node(&scene, "LXR").unwrap_err().to_string();
        assert!(err.contains("step 2 is 'X'"), "{err}");
        let empty = Scene::default();
        let root = node(&empty, "root").unwrap();
        assert!(root.prims.is_empty() && root.is_leaf);
        let err = node(&empty, "L").unwrap_err().to_string();
        assert!(err.contains("no triangles"), "{err}");
    }
}
