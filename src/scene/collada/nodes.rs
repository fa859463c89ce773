//! The node graph: nesting and instancing bounded, node transforms, and the up axis.

use glam::{Mat4, Vec3, Vec4};
use roxmltree::Node;

use super::xml::{child, numbers, required_attr};
use super::{Loader, MAX_NODE_DEPTH, MAX_NODE_VISITS};
use crate::{bail, Result};

impl<'a, 'input> Loader<'a, 'input> {
    /// Refuses to enter `node` if it is already open (a cycle) or nesting is too deep.
    pub(super) fn check_nesting(&self, node: Node) -> Result<()> {
        if self.open_nodes.contains(&node.id()) {
            let name = node.attribute("id").or(node.attribute("name")).unwrap_or("?");
            bail!("node '{name}' instances itself (an instance_node cycle)");
        }
        if self.open_nodes.len() >= MAX_NODE_DEPTH {
            bail!("nodes nested or instanced too deep (more than {MAX_NODE_DEPTH} levels)");
        }
        Ok(())
    }

    pub(super) fn visit_node(&mut self, node: Node<'a, 'input>, parent: Mat4) -> Result<()> {
        let name = node.attribute("id").or(node.attribute("name")).unwrap_or("?");
        self.check_nesting(node)?;
        self.node_visits += 1;
        if self.node_visits > MAX_NODE_VISITS {
            bail!(
                "too many node instances (more than {MAX_NODE_VISITS}): nodes instanced too deep"
            );
        }
        self.open_nodes.push(node.id());
        let result = self.visit_node_children(node, name, parent);
        self.open_nodes.pop();
        result
    }

    pub(super) fn visit_node_children(
        &mut self,
        node: Node<'a, 'input>,
        name: &str,
        parent: Mat4,
    ) -> Result<()> {
        let local = node_transform(node, &mut self.scene.warnings)
            .map_err(|e| e.context(format!("node '{name}'")))?;
        let world = parent * local;
        for c in node.children().filter(Node::is_element) {
            let result = match c.tag_name().name() {
                "instance_geometry" => self.instance_geometry(c, world),
                "instance_controller" => self.instance_controller(c, world),
                "instance_light" => self.instance_light(c, world),
                "instance_camera" => self.instance_camera(c, world),
                "node" => self.visit_node(c, world),
                "instance_node" => {
                    let target = self.resolve(required_attr(c, "url")?, "instance_node")?;
                    self.visit_node(target, world)
                }
                _ => Ok(()),
            };
            result.map_err(|e| {
                if c.tag_name().name() == "node" {
                    e
                } else {
                    e.context(format!("node '{name}'"))
                }
            })?;
        }
        Ok(())
    }
}

/// G: the file's up axis -> our Y-up world.
pub(super) fn up_axis_matrix(root: Node) -> Result<Mat4> {
    let up = child(root, "asset")
        .and_then(|a| child(a, "up_axis"))
        .and_then(|u| u.text())
        .map(str::trim);
    let rows = match up {
        None | Some("Y_UP") => return Ok(Mat4::IDENTITY),
        // (x, y, z) -> (-x, z, y)
        Some("Z_UP") => [[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]],
        // (x, y, z) -> (y, x, -z)
        Some("X_UP") => [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]],
        Some(other) => bail!("unknown up_axis '{other}' (expected X_UP, Y_UP or Z_UP)"),
    };
    Ok(Mat4::from_cols(
        Vec4::new(rows[0][0], rows[1][0], rows[2][0], 0.0),
        Vec4::new(rows[0][1], rows[1][1], rows[2][1], 0.0),
        Vec4::new(rows[0][2], rows[1][2], rows[2][2], 0.0),
        Vec4::W,
    ))
}

/// A node's local transform: its `matrix` (row-major), else its `translate`, `rotate` and
/// `scale` children composed in document order. A matrix missing entries of its last row (the
/// course's `CBgems.dae` camera has 15 numbers) gets zeros there, as the course's reader
/// leaves them, with a warning; fewer than 12 numbers is an error.
pub(super) fn node_transform(node: Node, warnings: &mut Vec<String>) -> Result<Mat4> {
    if let Some(m) = child(node, "matrix") {
        let mut v = numbers(m, "matrix")?;
        if v.len() > 16 || v.len() < 12 {
            bail!("<matrix> has {} numbers, expected 16", v.len());
        }
        if v.len() < 16 {
            let name = node.attribute("id").unwrap_or("?");
            warnings.push(format!(
                "node '{name}': <matrix> has {} numbers, expected 16: the rest taken as 0",
                v.len()
            ));
            v.resize(16, 0.0);
        }
        let cols: [f32; 16] = std::array::from_fn(|i| v[i]);
        return Ok(Mat4::from_cols_array(&cols).transpose());
    }
    let mut m = Mat4::IDENTITY;
    for c in node.children().filter(Node::is_element) {
        let name = c.tag_name().name();
        let expect = |n: usize| -> Result<Vec<f32>> {
            let v = numbers(c, name)?;
            if v.len() != n {
                bail!("<{name}> has {} numbers, expected {n}", v.len());
            }
            Ok(v)
        };
        m *= match name {
            "translate" => Mat4::from_translation(Vec3::from_slice(&expect(3)?)),
            "scale" => Mat4::from_scale(Vec3::from_slice(&expect(3)?)),
            "rotate" => {
                let v = expect(4)?;
                let axis = Vec3::new(v[0], v[1], v[2]);
                if axis.length_squared() == 0.0 {
                    bail!("<rotate> has a zero axis");
                }
                Mat4::from_axis_angle(axis.normalize(), v[3].to_radians())
            }
            _ => continue,
        };
    }
    Ok(m)
}

/// A `<bind_shape_matrix>`: 16 numbers, row-major like a node's `<matrix>`.
pub(super) fn row_major_matrix(m: Node) -> Result<Mat4> {
    let v = numbers(m, m.tag_name().name())?;
    if v.len() != 16 {
        bail!("<{}> has {} numbers, expected 16", m.tag_name().name(), v.len());
    }
    let cols: [f32; 16] = std::array::from_fn(|i| v[i]);
    Ok(Mat4::from_cols_array(&cols).transpose())
}

#[cfg(test)]
mod tests {
    use super::*;
    use roxmltree::Document;

    #[test]
    fn z_up_maps_x_y_z_to_minus_x_z_y() {
        let doc =
            Document::parse("<COLLADA><asset><up_axis>Z_UP</up_axis></asset></COLLADA>").unwrap();
        let g = up_axis_matrix(doc.root_element()).unwrap();
        assert_eq!(g.transform_point3(Vec3::new(1.0, 2.0, 3.0)), Vec3::new(-1.0, 3.0, 2.0));
        let doc =
            Document::parse("<COLLADA><asset><up_axis>X_UP</up_axis></asset></COLLADA>").unwrap();
        let g = up_axis_matrix(doc.root_element()).unwrap();
        assert_eq!(g.transform_point3(Vec3::new(1.0, 2.0, 3.0)), Vec3::new(2.0, 1.0, -3.0));
    }

    #[test]
    fn matrices_are_row_major() {
        let doc = Document::parse("<node><matrix>1 0 0 5 0 1 0 6 0 0 1 7 0 0 0 1</matrix></node>")
            .unwrap();
        let m = node_transform(doc.root_element(), &mut Vec::new()).unwrap();
        assert_eq!(m.transform_point3(Vec3::ZERO), Vec3::new(5.0, 6.0, 7.0));
    }

    #[test]
    fn translate_rotate_scale_compose_in_document_order() {
        let doc = Document::parse(
            "<node><translate>1 0 0</translate><rotate>0 0 1 90</rotate><scale>2 2 2</scale></node>",
        )
        .unwrap();
        let m = node_transform(doc.root_element(), &mut Vec::new()).unwrap();
        // Scale first, then rotate (x -> y), then translate.
        let p = m.transform_point3(Vec3::X);
        assert!((p - Vec3::new(1.0, 2.0, 0.0)).length() < 1e-6, "{p}");
    }
}
