//! Counting before building: what expanding the node graph would add to the scene, so that a
//! file whose instancing multiplies geometry past a limit is refused before anything is built.

use roxmltree::Node;

use super::xml::{child, element_children};
use super::{Loader, MAX_NODE_VISITS};
use crate::scene::MAX_TRIANGLES;
use crate::{bail, Result};

/// What expanding part of the node graph adds to the scene, counted before anything is built:
/// instancing multiplies geometry, so a 40 kB file can describe a billion triangles. Counts
/// saturate instead of overflowing.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub(super) struct Expansion {
    nodes: u64,
    triangles: u64,
    positions: u64,
    /// Spheres and lights (one each per instance).
    others: u64,
}

/// Most vertex positions a scene may hold: three per supported triangle.
const MAX_POSITIONS: u64 = 3 * MAX_TRIANGLES as u64;

impl Expansion {
    pub(super) fn plus(self, o: Expansion) -> Expansion {
        Expansion {
            nodes: self.nodes.saturating_add(o.nodes),
            triangles: self.triangles.saturating_add(o.triangles),
            positions: self.positions.saturating_add(o.positions),
            others: self.others.saturating_add(o.others),
        }
    }

    /// Refuses a scene that would exceed a limit, before it is built.
    pub(super) fn check(&self) -> Result<()> {
        let n = |v: u64| if v == u64::MAX { "more than 2^64".to_string() } else { v.to_string() };
        if self.nodes > MAX_NODE_VISITS as u64 {
            bail!(
                "too many node instances ({}, more than {MAX_NODE_VISITS}): nodes instanced too deep",
                n(self.nodes)
            );
        }
        let limits = [
            (self.triangles, MAX_TRIANGLES as u64, "triangles"),
            (self.positions, MAX_POSITIONS, "vertex positions"),
            (self.others, MAX_TRIANGLES as u64, "spheres and lights"),
        ];
        for (count, max, what) in limits {
            if count > max {
                bail!(
                    "the scene would hold {} {what} (counting every instance): at most {max} are supported",
                    n(count)
                );
            }
        }
        Ok(())
    }
}

impl<'a, 'input> Loader<'a, 'input> {
    /// What visiting `node` would add, counted without building anything, each node and
    /// geometry once. A cycle or too deep a nesting is the error the visit would give.
    pub(super) fn count_node(&mut self, node: Node<'a, 'input>) -> Result<Expansion> {
        if let Some(&known) = self.census.get(&node.id()) {
            return Ok(known);
        }
        self.check_nesting(node)?;
        self.open_nodes.push(node.id());
        let mut total = Expansion { nodes: 1, ..Expansion::default() };
        for c in node.children().filter(Node::is_element) {
            let part = match c.tag_name().name() {
                "node" => self.count_node(c),
                // An instance of something that does not exist is the visit's error to report.
                "instance_node" => match c.attribute("url").map(|u| self.resolve(u, "")) {
                    Some(Ok(target)) => self.count_node(target),
                    _ => Ok(Expansion::default()),
                },
                "instance_geometry" => Ok(self.count_instance(c)),
                "instance_controller" => Ok(self.count_controller(c)),
                "instance_light" => Ok(Expansion { others: 1, ..Expansion::default() }),
                _ => Ok(Expansion::default()),
            };
            match part {
                Ok(part) => total = total.plus(part),
                Err(e) => {
                    self.open_nodes.pop();
                    return Err(e);
                }
            }
        }
        self.open_nodes.pop();
        self.census.insert(node.id(), total);
        Ok(total)
    }

    /// What an `instance_geometry` adds: its geometry's triangles and positions, or a sphere.
    pub(super) fn count_instance(&mut self, inst: Node<'a, 'input>) -> Expansion {
        let Some(Ok(geometry)) = inst.attribute("url").map(|u| self.resolve(u, "")) else {
            return Expansion::default();
        };
        self.count_geometry(geometry)
    }

    /// What one instance of `geometry` adds, counted once per geometry.
    pub(super) fn count_geometry(&mut self, geometry: Node<'a, 'input>) -> Expansion {
        if let Some(&known) = self.census.get(&geometry.id()) {
            return known;
        }
        let count = match child(geometry, "mesh") {
            Some(mesh) => count_mesh(mesh),
            None => Expansion { others: 1, ..Expansion::default() },
        };
        self.census.insert(geometry.id(), count);
        count
    }

    /// What an `instance_controller` adds: its skin's (or morph's) source geometry.
    pub(super) fn count_controller(&mut self, inst: Node<'a, 'input>) -> Expansion {
        match self.controller_geometry(inst) {
            Ok((geometry, _)) => self.count_geometry(geometry),
            Err(_) => Expansion::default(),
        }
    }
}

/// The triangles and positions a mesh makes, counted from its text without parsing numbers or
/// allocating. A primitive whose counts do not add up counts as nothing: parsing it reports
/// the problem.
fn count_mesh(mesh: Node) -> Expansion {
    // An upper bound: the positions are one of the mesh's sources, of at least 3 numbers each.
    let positions = element_children(mesh, "source")
        .filter_map(|s| child(s, "float_array"))
        .map(|a| tokens(a) / 3)
        .max()
        .unwrap_or(0);
    let triangles = mesh
        .children()
        .filter(Node::is_element)
        .map(prim_triangles)
        .fold(0u64, u64::saturating_add);
    Expansion { nodes: 0, triangles, positions, others: 0 }
}

/// The triangles the fan triangulation makes of a `polylist`, `triangles` or `polygons`.
fn prim_triangles(prim: Node) -> u64 {
    let stride = prim_stride(prim);
    let corners = |p: Node| tokens(p) / stride;
    match prim.tag_name().name() {
        "triangles" => child(prim, "p").map_or(0, corners) / 3,
        "polygons" => element_children(prim, "p")
            .map(|p| corners(p).saturating_sub(2))
            .fold(0, u64::saturating_add),
        "polylist" => polylist_triangles(prim, stride),
        _ => 0,
    }
}

/// A polylist's triangles: the sum of its polygons' corners less two, if `<vcount>` and `<p>`
/// agree (else 0: parsing reports the mismatch).
fn polylist_triangles(prim: Node, stride: u64) -> u64 {
    let vcount = child(prim, "vcount").and_then(|v| v.text()).unwrap_or("");
    let counts = || vcount.split_ascii_whitespace().map(|t| t.parse::<u64>().unwrap_or(0));
    let corners = counts().fold(0u64, u64::saturating_add);
    let p = child(prim, "p").map_or(0, tokens);
    if corners.saturating_mul(stride) != p {
        return 0;
    }
    counts().map(|n| n.saturating_sub(2)).fold(0, u64::saturating_add)
}

/// Entries per vertex of a primitive's `<p>`: one more than its largest input offset.
fn prim_stride(prim: Node) -> u64 {
    element_children(prim, "input")
        .filter_map(|i| i.attribute("offset")?.trim().parse::<u64>().ok())
        .max()
        .map_or(1, |m| m.saturating_add(1))
}

/// Whitespace-separated words of an element's text.
fn tokens(node: Node) -> u64 {
    node.text().unwrap_or("").split_ascii_whitespace().count() as u64
}
