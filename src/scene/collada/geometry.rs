//! Meshes, CGL spheres and skinned meshes (`instance_controller`) -> triangles and spheres.

use std::collections::HashMap;

use glam::{Mat4, Vec3};
use roxmltree::Node;

use super::materials::{cgl_technique, material_bindings};
use super::nodes::row_major_matrix;
use super::xml::{
    child, element_children, integers, numbers, parse_attr, required_attr, single_number,
};
use super::{Loader, MAX_CONTROLLER_CHAIN};
use crate::scene::Sphere;
use crate::{bail, Error, Result};

impl<'a, 'input> Loader<'a, 'input> {
    pub(super) fn instance_geometry(&mut self, inst: Node<'a, 'input>, world: Mat4) -> Result<()> {
        let geometry = self.resolve(required_attr(inst, "url")?, "instance_geometry")?;
        self.geometry(geometry, inst, world)
    }

    /// A skinned (or morphed) mesh, as Blender and other tools export characters: its source
    /// geometry in the bind pose. The joints, weights and morph targets are ignored (a
    /// warning says so once: [`Loader::finish`]).
    pub(super) fn instance_controller(
        &mut self,
        inst: Node<'a, 'input>,
        world: Mat4,
    ) -> Result<()> {
        let (geometry, bind_shape) = self.controller_geometry(inst)?;
        self.controllers += 1;
        self.geometry(geometry, inst, world * bind_shape)
    }

    /// The geometry an `instance_controller` deforms and its skin's `bind_shape_matrix` (the
    /// mesh's transform into the bind pose), following a chain of controllers (a skin of a
    /// morph) a few steps.
    pub(super) fn controller_geometry(
        &self,
        inst: Node<'a, 'input>,
    ) -> Result<(Node<'a, 'input>, Mat4)> {
        let mut target = self.resolve(required_attr(inst, "url")?, "instance_controller")?;
        let mut bind_shape = Mat4::IDENTITY;
        for _ in 0..MAX_CONTROLLER_CHAIN {
            if target.tag_name().name() != "controller" {
                return Ok((target, bind_shape));
            }
            let cid = target.attribute("id").unwrap_or("?");
            let deformer = target
                .children()
                .find(|c| matches!(c.tag_name().name(), "skin" | "morph"))
                .ok_or_else(|| {
                    Error::new(format!("controller '{cid}' has no <skin> or <morph>"))
                })?;
            if let Some(m) = child(deformer, "bind_shape_matrix") {
                let m =
                    row_major_matrix(m).map_err(|e| e.context(format!("controller '{cid}'")))?;
                bind_shape *= m;
            }
            let what = format!("controller '{cid}' <{}>", deformer.tag_name().name());
            target = self.resolve(required_attr(deformer, "source")?, &what)?;
        }
        bail!("controllers chained more than {MAX_CONTROLLER_CHAIN} deep")
    }

    /// One instance of `geometry` (a mesh or a CGL sphere), with the materials `inst` binds.
    pub(super) fn geometry(
        &mut self,
        geometry: Node<'a, 'input>,
        inst: Node<'a, 'input>,
        world: Mat4,
    ) -> Result<()> {
        let gname = geometry.attribute("id").unwrap_or("?");
        let bindings = material_bindings(inst);
        if let Some(mesh) = child(geometry, "mesh") {
            return self
                .mesh(mesh, world, &bindings)
                .map_err(|e| e.context(format!("geometry '{gname}'")));
        }
        if let Some(radius) = cgl_technique(geometry)
            .and_then(|t| child(t, "sphere"))
            .and_then(|s| child(s, "radius"))
        {
            let r = single_number(radius, "sphere radius")
                .map_err(|e| e.context(format!("geometry '{gname}'")))?;
            let center = world.transform_point3(Vec3::ZERO);
            let scale = (world.transform_point3(Vec3::X) - center).length();
            let symbol = bindings.keys().next().cloned();
            let material = self.material_for(symbol.as_deref(), &bindings)?;
            if !(r > 0.0) || !(scale > 0.0) {
                bail!("geometry '{gname}': sphere radius must be positive, got {}", r * scale);
            }
            self.scene.spheres.push(Sphere { center, radius: r * scale, material });
            return Ok(());
        }
        self.scene
            .warnings
            .push(format!("geometry '{gname}' is neither a mesh nor a CGL sphere: skipped"));
        Ok(())
    }

    pub(super) fn mesh(
        &mut self,
        mesh: Node<'a, 'input>,
        world: Mat4,
        bindings: &HashMap<String, String>,
    ) -> Result<()> {
        let vertices =
            child(mesh, "vertices").ok_or_else(|| Error::new("mesh has no <vertices>"))?;
        let pos_input = element_children(vertices, "input")
            .find(|i| i.attribute("semantic") == Some("POSITION"))
            .ok_or_else(|| Error::new("<vertices> has no POSITION input"))?;
        let positions =
            self.read_points(self.resolve(required_attr(pos_input, "source")?, "POSITION input")?)?;
        let base = self.scene.positions.len() as u32;
        self.scene.positions.extend(positions.iter().map(|&p| world.transform_point3(p)));

        for prim in mesh.children().filter(Node::is_element) {
            let kind = prim.tag_name().name();
            if !matches!(kind, "polylist" | "triangles" | "polygons") {
                continue;
            }
            let polygons = self.read_polygons(prim, vertices, positions.len())?;
            let material = self.material_for(prim.attribute("material"), bindings)?;
            for poly in polygons {
                if poly.len() < 3 {
                    self.skipped_polygons += 1;
                    continue;
                }
                // Fan triangulation around the first corner.
                for i in 1..poly.len() - 1 {
                    self.scene.triangles.push([base + poly[0], base + poly[i], base + poly[i + 1]]);
                    self.scene.triangle_materials.push(material);
                }
            }
        }
        Ok(())
    }

    /// The position indices of each polygon of a `polylist`, `triangles` or `polygons` element.
    pub(super) fn read_polygons(
        &self,
        prim: Node,
        vertices: Node,
        n_positions: usize,
    ) -> Result<Vec<Vec<u32>>> {
        let kind = prim.tag_name().name();
        let inputs: Vec<Node> = element_children(prim, "input").collect();
        let mut stride = 0;
        let mut vertex_offset = None;
        for input in &inputs {
            let offset: usize = parse_attr(*input, "offset")?.unwrap_or(0);
            // Offsets index a tuple of one entry per input; anything larger is malformed (and
            // offset + 1 or n * stride would overflow).
            if offset >= inputs.len().max(1) * 64 {
                bail!("<{kind}> input offset {offset} is larger than its inputs allow");
            }
            stride = stride.max(offset + 1);
            if input.attribute("semantic") == Some("VERTEX") {
                let source = self.resolve(required_attr(*input, "source")?, "VERTEX input")?;
                if source != vertices {
                    bail!("<{kind}> VERTEX input does not name the mesh's <vertices>");
                }
                vertex_offset = Some(offset);
            } else if let Some(src) = input.attribute("source") {
                self.resolve(
                    src,
                    &format!("{} input", input.attribute("semantic").unwrap_or("?")),
                )?;
            }
        }
        let vertex_offset =
            vertex_offset.ok_or_else(|| Error::new(format!("<{kind}> has no VERTEX input")))?;
        let corner = |tuple: &[u32]| -> Result<u32> {
            let i = tuple[vertex_offset];
            if i as usize >= n_positions {
                bail!("<{kind}> index {i} out of range ({n_positions} positions)");
            }
            Ok(i)
        };
        let corners_of = |p: &[u32],
                          counts: &mut dyn Iterator<Item = usize>|
         -> Result<Vec<Vec<u32>>> {
            let mut polys = Vec::new();
            let mut at = 0;
            for n in counts {
                let Some(end) = n.checked_mul(stride).and_then(|k| k.checked_add(at)) else {
                    bail!("<{kind}> polygon of {n} corners is larger than any <p>");
                };
                if end > p.len() {
                    bail!("<{kind}> needs {end} indices but <p> has only {}", p.len());
                }
                polys.push(
                    p[at..end].chunks_exact(stride).map(corner).collect::<Result<Vec<u32>>>()?,
                );
                at = end;
            }
            if at != p.len() {
                bail!(
                    "<{kind}> <p> has {} indices, {} more than its polygons use",
                    p.len(),
                    p.len() - at
                );
            }
            Ok(polys)
        };
        match kind {
            "polylist" => {
                let vcount = integers(
                    child(prim, "vcount")
                        .ok_or_else(|| Error::new("<polylist> has no <vcount>"))?,
                    "vcount",
                )?;
                let p = integers(
                    child(prim, "p").ok_or_else(|| Error::new("<polylist> has no <p>"))?,
                    "p",
                )?;
                corners_of(&p, &mut vcount.iter().map(|&n| n as usize))
            }
            "triangles" => {
                let Some(p) = child(prim, "p") else { return Ok(Vec::new()) };
                let p = integers(p, "p")?;
                if p.len() % (3 * stride) != 0 {
                    bail!(
                        "<triangles> <p> has {} indices, not a multiple of 3 x {stride}",
                        p.len()
                    );
                }
                corners_of(&p, &mut std::iter::repeat_n(3, p.len() / (3 * stride)))
            }
            _ => {
                let mut polys = Vec::new();
                for p in element_children(prim, "p") {
                    let p = integers(p, "p")?;
                    if p.len() % stride != 0 {
                        bail!("<polygons> <p> has {} indices, not a multiple of {stride}", p.len());
                    }
                    polys.extend(corners_of(&p, &mut std::iter::once(p.len() / stride))?);
                }
                Ok(polys)
            }
        }
    }

    /// 3D points from a `<source>`: its float_array read through its accessor's stride.
    pub(super) fn read_points(&self, source: Node) -> Result<Vec<Vec3>> {
        let sid = source.attribute("id").unwrap_or("?");
        let array = child(source, "float_array")
            .ok_or_else(|| Error::new(format!("source '{sid}' has no <float_array>")))?;
        let values = numbers(array, &format!("source '{sid}'"))?;
        let accessor = child(source, "technique_common").and_then(|t| child(t, "accessor"));
        let (count, stride) = match accessor {
            Some(a) => (
                parse_attr(a, "count")?.unwrap_or(values.len() / 3),
                parse_attr(a, "stride")?.unwrap_or(3),
            ),
            None => (values.len() / 3, 3),
        };
        if stride < 3 || count.checked_mul(stride).is_none_or(|n| n > values.len()) {
            bail!("source '{sid}': accessor count {count} x stride {stride} does not fit its {} numbers", values.len());
        }
        Ok(values.chunks_exact(stride).take(count).map(|c| Vec3::new(c[0], c[1], c[2])).collect())
    }
}

/// Per-vertex shading normals as the course makes them: the sum of the (area-weighted, i.e.
/// unnormalised cross product) normals of the faces around each vertex, normalised. A vertex
/// whose faces cancel or have no area gets +Y rather than NaN.
pub fn vertex_normals(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut sum = vec![Vec3::ZERO; positions.len()];
    for t in triangles {
        let [a, b, c] = t.map(|i| positions[i as usize]);
        let n = (b - a).cross(c - a);
        for &i in t {
            sum[i as usize] += n;
        }
    }
    sum.into_iter().map(|n| n.normalize_or(Vec3::Y)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertex_normals_weight_faces_by_area_and_never_nan() {
        let pos = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::new(0.0, 0.0, 1.0), Vec3::splat(7.0)];
        // A big triangle in the z = 0 plane and a small one in the x = 0 plane share vertex 0.
        let tris = [[0, 1, 2], [0, 2, 3]];
        let n = vertex_normals(&pos, &tris);
        assert!((n[1] - Vec3::Z).length() < 1e-6);
        assert!((n[0] - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-6);
        assert_eq!(n[4], Vec3::Y, "unused vertex gets a unit fallback");
    }
}
