//! The course's COLLADA 1.4.1 dialect with its `CGL` profile -> `Scene`
//! (`../shared/docs/SCENE_FORMAT.md`). This is the only file that knows about XML.
//!
//! Every failure is one line naming what is wrong; `load` prefixes it with the file name.

use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

use glam::{Mat4, Vec3, Vec4};
use roxmltree::{Document, Node};

use super::{CameraDesc, Light, Material, Scene, Sphere, MAX_TRIANGLES};
use crate::{bail, Error, Result};

/// The largest scene file [`load`] reads: 1 GiB, far above any course scene (the largest is
/// 14 MB) and below what parsing it would need in memory on a small machine.
pub const DEFAULT_MAX_SCENE_BYTES: u64 = 1 << 30;

/// Reads and parses a scene file of at most [`DEFAULT_MAX_SCENE_BYTES`].
pub fn load(path: &Path) -> Result<Scene> {
    load_with_limit(path, DEFAULT_MAX_SCENE_BYTES)
}

/// Reads and parses a scene file of at most `max_bytes` bytes: a larger file, or a device or
/// pipe that delivers more (`/dev/zero`), is an error once the limit is reached, never an
/// unbounded read.
pub fn load_with_limit(path: &Path, max_bytes: u64) -> Result<Scene> {
    let text = read_capped(path, max_bytes).map_err(|e| e.context(path.display()))?;
    parse(&text).map_err(|e| e.context(path.display()))
}

/// The file's text, refusing it once it holds more than `max_bytes`. A regular file is judged
/// by its size before reading; anything else (a pipe, a device) is read up to the limit.
fn read_capped(path: &Path, max_bytes: u64) -> Result<String> {
    let cannot_read = |e: std::io::Error| Error::new(format!("cannot read: {e}"));
    let too_large = || {
        Error::new(format!(
            "larger than the scene size limit of {max_bytes} bytes (--max-scene-bytes raises it)"
        ))
    };
    let file = std::fs::File::open(path).map_err(cannot_read)?;
    if file.metadata().is_ok_and(|m| m.is_file() && m.len() > max_bytes) {
        return Err(too_large());
    }
    let mut bytes = Vec::new();
    let mut reader = file.take(max_bytes.saturating_add(1));
    let mut chunk = vec![0u8; 1 << 16];
    loop {
        let n = match reader.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(cannot_read(e)),
        };
        bytes.try_reserve(n).map_err(|_| {
            Error::new(format!("cannot read: out of memory after {} bytes", bytes.len()))
        })?;
        bytes.extend_from_slice(&chunk[..n]);
    }
    if bytes.len() as u64 > max_bytes {
        return Err(too_large());
    }
    String::from_utf8(bytes).map_err(|e| {
        Error::new(format!(
            "not a text file (invalid UTF-8 at byte {})",
            e.utf8_error().valid_up_to()
        ))
    })
}

/// Parses a scene from COLLADA text.
pub fn parse(text: &str) -> Result<Scene> {
    let doc = Document::parse(text).map_err(|e| Error::new(format!("not valid XML: {e}")))?;
    let root = doc.root_element();
    if root.tag_name().name() != "COLLADA" {
        bail!("not a COLLADA file (root element is <{}>)", root.tag_name().name());
    }
    let mut loader = Loader {
        ids: root.descendants().filter_map(|n| n.attribute("id").map(|id| (id, n))).collect(),
        scene: Scene::default(),
        materials: HashMap::new(),
        camera: None,
        skipped_polygons: 0,
        open_nodes: Vec::new(),
        node_visits: 0,
        census: HashMap::new(),
        controllers: 0,
        ignored: ignored_features(root),
    };
    let up = up_axis_matrix(root)?;
    let visual_scene = loader.visual_scene(root)?;
    let mut total = Expansion::default();
    for node in element_children(visual_scene, "node") {
        total = total.plus(loader.count_node(node)?);
    }
    total.check()?;
    for node in element_children(visual_scene, "node") {
        loader.visit_node(node, up)?;
    }
    loader.finish()
}

/// What the loader has gathered so far.
struct Loader<'a, 'input> {
    ids: HashMap<&'a str, Node<'a, 'input>>,
    scene: Scene,
    /// Scene material index by COLLADA material id ("" is the default grey).
    materials: HashMap<String, u32>,
    camera: Option<CameraDesc>,
    skipped_polygons: usize,
    /// The nodes being visited, outermost first: an `instance_node` naming one of them is a
    /// cycle, and its length bounds the recursion (deep recursion overflows the stack, which
    /// aborts the process instead of returning an error).
    open_nodes: Vec<roxmltree::NodeId>,
    /// Nodes visited so far, instances included: bounds the work of instancing chains, which
    /// can multiply geometry exponentially without any cycle.
    node_visits: usize,
    /// What each node and geometry expands to, counted once ([`Loader::count_node`]).
    census: HashMap<roxmltree::NodeId, Expansion>,
    /// `instance_controller`s loaded in their bind pose.
    controllers: usize,
    /// What the file holds that rendering ignores (animation, textures), named once.
    ignored: Vec<&'static str>,
}

/// What expanding part of the node graph adds to the scene, counted before anything is built:
/// instancing multiplies geometry, so a 40 kB file can describe a billion triangles. Counts
/// saturate instead of overflowing.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Expansion {
    nodes: u64,
    triangles: u64,
    positions: u64,
    /// Spheres and lights (one each per instance).
    others: u64,
}

/// Most vertex positions a scene may hold: three per supported triangle.
const MAX_POSITIONS: u64 = 3 * MAX_TRIANGLES as u64;

impl Expansion {
    fn plus(self, o: Expansion) -> Expansion {
        Expansion {
            nodes: self.nodes.saturating_add(o.nodes),
            triangles: self.triangles.saturating_add(o.triangles),
            positions: self.positions.saturating_add(o.positions),
            others: self.others.saturating_add(o.others),
        }
    }

    /// Refuses a scene that would exceed a limit, before it is built.
    fn check(&self) -> Result<()> {
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

/// Deepest node nesting (including instancing) we follow; the course files nest 3 deep.
const MAX_NODE_DEPTH: usize = 256;
/// Longest chain of controllers (a skin of a morph of a mesh) followed to the mesh.
const MAX_CONTROLLER_CHAIN: usize = 8;
/// Most node visits (instances included) in one file.
const MAX_NODE_VISITS: usize = 1 << 20;

impl<'a, 'input> Loader<'a, 'input> {
    /// The element a `#id` reference (`url`, `source`, `target`) names.
    fn resolve(&self, reference: &str, what: &str) -> Result<Node<'a, 'input>> {
        let id = reference.strip_prefix('#').unwrap_or(reference);
        self.ids.get(id).copied().ok_or_else(|| {
            Error::new(format!("{what} refers to '{reference}', which does not exist"))
        })
    }

    /// What visiting `node` would add, counted without building anything, each node and
    /// geometry once. A cycle or too deep a nesting is the error the visit would give.
    fn count_node(&mut self, node: Node<'a, 'input>) -> Result<Expansion> {
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
    fn count_instance(&mut self, inst: Node<'a, 'input>) -> Expansion {
        let Some(Ok(geometry)) = inst.attribute("url").map(|u| self.resolve(u, "")) else {
            return Expansion::default();
        };
        self.count_geometry(geometry)
    }

    /// What one instance of `geometry` adds, counted once per geometry.
    fn count_geometry(&mut self, geometry: Node<'a, 'input>) -> Expansion {
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
    fn count_controller(&mut self, inst: Node<'a, 'input>) -> Expansion {
        match self.controller_geometry(inst) {
            Ok((geometry, _)) => self.count_geometry(geometry),
            Err(_) => Expansion::default(),
        }
    }

    /// Refuses to enter `node` if it is already open (a cycle) or nesting is too deep.
    fn check_nesting(&self, node: Node) -> Result<()> {
        if self.open_nodes.contains(&node.id()) {
            let name = node.attribute("id").or(node.attribute("name")).unwrap_or("?");
            bail!("node '{name}' instances itself (an instance_node cycle)");
        }
        if self.open_nodes.len() >= MAX_NODE_DEPTH {
            bail!("nodes nested or instanced too deep (more than {MAX_NODE_DEPTH} levels)");
        }
        Ok(())
    }

    fn visual_scene(&self, root: Node<'a, 'input>) -> Result<Node<'a, 'input>> {
        let instance = child(root, "scene").and_then(|s| child(s, "instance_visual_scene"));
        if let Some(inst) = instance {
            let url = required_attr(inst, "url")?;
            return self.resolve(url, "instance_visual_scene");
        }
        root.descendants()
            .find(|n| {
                n.has_tag_name(("http://www.collada.org/2005/11/COLLADASchema", "visual_scene"))
                    || n.tag_name().name() == "visual_scene"
            })
            .ok_or_else(|| Error::new("no <visual_scene>: the file describes no scene"))
    }

    fn visit_node(&mut self, node: Node<'a, 'input>, parent: Mat4) -> Result<()> {
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

    fn visit_node_children(
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

    fn instance_geometry(&mut self, inst: Node<'a, 'input>, world: Mat4) -> Result<()> {
        let geometry = self.resolve(required_attr(inst, "url")?, "instance_geometry")?;
        self.geometry(geometry, inst, world)
    }

    /// A skinned (or morphed) mesh, as Blender and other tools export characters: its source
    /// geometry in the bind pose. The joints, weights and morph targets are ignored (a
    /// warning says so once: [`Loader::finish`]).
    fn instance_controller(&mut self, inst: Node<'a, 'input>, world: Mat4) -> Result<()> {
        let (geometry, bind_shape) = self.controller_geometry(inst)?;
        self.controllers += 1;
        self.geometry(geometry, inst, world * bind_shape)
    }

    /// The geometry an `instance_controller` deforms and its skin's `bind_shape_matrix` (the
    /// mesh's transform into the bind pose), following a chain of controllers (a skin of a
    /// morph) a few steps.
    fn controller_geometry(&self, inst: Node<'a, 'input>) -> Result<(Node<'a, 'input>, Mat4)> {
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
    fn geometry(
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

    fn mesh(
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
    fn read_polygons(
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
    fn read_points(&self, source: Node) -> Result<Vec<Vec3>> {
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

    /// The scene material for a primitive's material symbol, resolved through the instance's
    /// `bind_material`. An unbound or absent symbol gets the default 0.5-grey Lambertian.
    fn material_for(
        &mut self,
        symbol: Option<&str>,
        bindings: &HashMap<String, String>,
    ) -> Result<u32> {
        let Some(target) = symbol.and_then(|s| bindings.get(s)) else {
            return Ok(self.intern_material("", Material::Diffuse { albedo: Vec3::splat(0.5) }));
        };
        if let Some(&i) = self.materials.get(target.trim_start_matches('#')) {
            return Ok(i);
        }
        let material = self.resolve(target, "instance_material")?;
        let mid = material.attribute("id").unwrap_or("?").to_string();
        let effect_url = child(material, "instance_effect")
            .and_then(|e| e.attribute("url"))
            .ok_or_else(|| Error::new(format!("material '{mid}' has no <instance_effect url>")))?;
        let effect = self.resolve(effect_url, &format!("material '{mid}'"))?;
        let m = effect_material(effect).map_err(|e| {
            e.context(format!("effect '{}'", effect.attribute("id").unwrap_or("?")))
        })?;
        Ok(self.intern_material(&mid, m))
    }

    fn intern_material(&mut self, id: &str, m: Material) -> u32 {
        if let Some(&i) = self.materials.get(id) {
            return i;
        }
        self.scene.materials.push(m);
        let i = self.scene.materials.len() as u32 - 1;
        self.materials.insert(id.to_string(), i);
        i
    }

    fn instance_light(&mut self, inst: Node, world: Mat4) -> Result<()> {
        let light = self.resolve(required_attr(inst, "url")?, "instance_light")?;
        let lid = light.attribute("id").unwrap_or("?");
        // The CGL technique wins over technique_common.
        let technique = cgl_technique(light).or_else(|| child(light, "technique_common"));
        let Some(kind_node) = technique.and_then(|t| t.children().find(Node::is_element)) else {
            self.scene.warnings.push(format!("light '{lid}' has no technique: skipped"));
            return Ok(());
        };
        let color = || -> Result<Vec3> {
            let c = child(kind_node, "color")
                .ok_or_else(|| Error::new(format!("light '{lid}' has no <color>")))?;
            rgb(c, &format!("light '{lid}' color"))
        };
        let origin = world.transform_point3(Vec3::ZERO);
        let light = match kind_node.tag_name().name() {
            "area" => Light::Area {
                position: origin,
                direction: (world.transform_point3(Vec3::NEG_Z) - origin).normalize_or(Vec3::NEG_Y),
                dim_x: world.transform_point3(Vec3::NEG_X) - origin,
                dim_y: world.transform_point3(Vec3::Y) - origin,
                radiance: color()?,
            },
            "point" => Light::Point { position: origin, radiance: color()? },
            "directional" => Light::Directional {
                direction: world.transform_point3(Vec3::NEG_Z).normalize_or(Vec3::Y),
                radiance: color()?,
            },
            "ambient" => Light::Ambient { radiance: color()? },
            "spot" => {
                self.scene.warnings.push(format!(
                    "light '{lid}': spot lights are not supported (the course skips them): skipped"
                ));
                return Ok(());
            }
            other => {
                self.scene.warnings.push(format!("light '{lid}': unknown kind <{other}>: skipped"));
                return Ok(());
            }
        };
        self.scene.lights.push(light);
        Ok(())
    }

    fn instance_camera(&mut self, inst: Node, world: Mat4) -> Result<()> {
        if self.camera.is_some() {
            return Ok(()); // The first camera is the one.
        }
        let camera = self.resolve(required_attr(inst, "url")?, "instance_camera")?;
        let cid = camera.attribute("id").unwrap_or("?");
        let persp = child(camera, "optics")
            .and_then(|o| child(o, "technique_common"))
            .and_then(|t| child(t, "perspective"))
            .ok_or_else(|| Error::new(format!("camera '{cid}' has no perspective optics")))?;
        let value = |name: &str| {
            child(persp, name)
                .map(|n| single_number(n, &format!("camera '{cid}' {name}")))
                .transpose()
        };
        let (xfov, yfov, aspect) = (value("xfov")?, value("yfov")?, value("aspect_ratio")?);
        let half_tan = |deg: f32| (deg.to_radians() / 2.0).tan();
        let from_tan = |t: f32| 2.0 * t.atan().to_degrees();
        let (hfov, vfov) = match (xfov, yfov, aspect) {
            (Some(x), Some(y), _) => (x, y),
            (Some(x), None, Some(a)) if a > 0.0 => (x, from_tan(half_tan(x) / a)),
            (None, Some(y), Some(a)) if a > 0.0 => (from_tan(half_tan(y) * a), y),
            _ => bail!("camera '{cid}' needs xfov or yfov and a positive aspect_ratio"),
        };
        if !(hfov > 0.0 && hfov < 180.0 && vfov > 0.0 && vfov < 180.0) {
            bail!("camera '{cid}': field of view {hfov} x {vfov} degrees is not in (0, 180)");
        }
        // The course renderer reads the view direction as the transformed point (0, 0, -1):
        // the translation leaks in. Reproduced as SCENE_FORMAT.md says.
        let view_dir = world.transform_point3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
        self.camera = Some(CameraDesc { hfov_deg: hfov, vfov_deg: vfov, view_dir });
        Ok(())
    }

    fn finish(mut self) -> Result<Scene> {
        if self.skipped_polygons > 0 {
            self.scene.warnings.push(format!(
                "{} polygons with fewer than 3 corners were skipped",
                self.skipped_polygons
            ));
        }
        if self.controllers > 0 {
            let n = self.controllers;
            self.ignored.insert(
                0,
                if n == 1 {
                    "skinning (1 skinned mesh drawn in its bind pose)"
                } else {
                    "skinning (skinned meshes drawn in their bind pose)"
                },
            );
        }
        if !self.ignored.is_empty() {
            self.scene.warnings.push(format!("ignored: {}", self.ignored.join("; ")));
        }
        if self.scene.triangles.is_empty() && self.scene.spheres.is_empty() {
            self.scene.warnings.push(
                "nothing to render: the scene has 0 triangles and 0 spheres (the image will be black)"
                    .into(),
            );
        }
        match self.camera {
            Some(c) => self.scene.camera = c,
            None => self
                .scene
                .warnings
                .push("no camera: looking down -Z with a 50-degree field of view".into()),
        }
        self.scene.normals = vertex_normals(&self.scene.positions, &self.scene.triangles);
        // Unreferenced positions (from a degenerate or skipped polygon) are harmless; positions
        // that no triangle uses are kept so indices stay simple.
        self.scene.validate()?;
        // Finite numbers can still multiply to infinity through node transforms (the fuzzer's
        // 3.4e38 entries); a light at infinity would turn every pixel it reaches into NaN.
        for (i, light) in self.scene.lights.iter().enumerate() {
            if !light_is_finite(light) {
                bail!("light {i} ({}) is not finite after its node transforms", light.kind());
            }
        }
        Ok(self.scene)
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

/// What a file holds that rendering ignores, for one warning: animation (the scene is drawn
/// at rest) and textures (surfaces take their effect's flat colour).
fn ignored_features(root: Node) -> Vec<&'static str> {
    let has = |name: &str| root.descendants().any(|n| n.tag_name().name() == name);
    let mut ignored = Vec::new();
    if has("animation") {
        ignored.push("animation (the scene is drawn at rest)");
    }
    if has("texture") {
        ignored.push("textures (surfaces take their flat diffuse colour)");
    }
    ignored
}

/// A `<bind_shape_matrix>`: 16 numbers, row-major like a node's `<matrix>`.
fn row_major_matrix(m: Node) -> Result<Mat4> {
    let v = numbers(m, m.tag_name().name())?;
    if v.len() != 16 {
        bail!("<{}> has {} numbers, expected 16", m.tag_name().name(), v.len());
    }
    let cols: [f32; 16] = std::array::from_fn(|i| v[i]);
    Ok(Mat4::from_cols_array(&cols).transpose())
}

/// Whether every number of a light is finite.
pub fn light_is_finite(light: &Light) -> bool {
    match *light {
        Light::Area { position, direction, dim_x, dim_y, radiance } => {
            [position, direction, dim_x, dim_y, radiance].iter().all(|v| v.is_finite())
        }
        Light::Point { position, radiance } => position.is_finite() && radiance.is_finite(),
        Light::Directional { direction, radiance } => direction.is_finite() && radiance.is_finite(),
        Light::Ambient { radiance } => radiance.is_finite(),
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

/// G: the file's up axis -> our Y-up world.
fn up_axis_matrix(root: Node) -> Result<Mat4> {
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
fn node_transform(node: Node, warnings: &mut Vec<String>) -> Result<Mat4> {
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

/// symbol -> material reference, from `bind_material/technique_common/instance_material`.
fn material_bindings(inst: Node) -> HashMap<String, String> {
    child(inst, "bind_material")
        .and_then(|b| child(b, "technique_common"))
        .map(|t| {
            element_children(t, "instance_material")
                .filter_map(|m| {
                    Some((m.attribute("symbol")?.to_string(), m.attribute("target")?.to_string()))
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The BSDF an effect describes: its CGL technique, else the phong/lambert/blinn diffuse colour.
fn effect_material(effect: Node) -> Result<Material> {
    if let Some(kind) = cgl_technique(effect).and_then(|t| t.children().find(Node::is_element)) {
        let name = kind.tag_name().name();
        let color = |field: &str| -> Result<Vec3> {
            let n = child(kind, field)
                .ok_or_else(|| Error::new(format!("CGL {name} has no <{field}>")))?;
            rgb(n, &format!("CGL {name} {field}"))
        };
        let scalar = |field: &str, default: f32| -> Result<f32> {
            child(kind, field)
                .map_or(Ok(default), |n| single_number(n, &format!("CGL {name} {field}")))
        };
        return Ok(match name {
            "emission" => Material::Emission { radiance: color("radiance")? },
            "mirror" => Material::Mirror { reflectance: color("reflectance")? },
            "glass" => Material::Glass {
                reflectance: color("reflectance")?,
                transmittance: color("transmittance")?,
                roughness: scalar("roughness", 0.0)?,
                ior: positive(scalar("ior", 1.5)?, "CGL glass ior")?,
            },
            "refraction" => Material::Refraction {
                transmittance: color("transmittance")?,
                roughness: scalar("roughness", 0.0)?,
                ior: positive(scalar("ior", 1.5)?, "CGL refraction ior")?,
            },
            "microfacet" => Material::Microfacet {
                alpha: positive(scalar("alpha", 0.5)?, "CGL microfacet alpha")?,
                eta: color("eta")?,
                k: color("k")?,
            },
            other => bail!("unknown CGL material <{other}>"),
        });
    }
    let diffuse = child(effect, "profile_COMMON")
        .and_then(|p| child(p, "technique"))
        .and_then(|t| {
            t.children().find(|c| matches!(c.tag_name().name(), "phong" | "lambert" | "blinn"))
        })
        .and_then(|s| child(s, "diffuse"))
        .and_then(|d| child(d, "color"));
    let albedo = match diffuse {
        Some(c) => rgb(c, "diffuse color")?,
        None => Vec3::splat(0.5),
    };
    Ok(Material::Diffuse { albedo })
}

fn positive(v: f32, what: &str) -> Result<f32> {
    if v > 0.0 {
        Ok(v)
    } else {
        bail!("{what} must be positive, got {v}")
    }
}

/// `extra/technique[@profile='CGL']` of an element. The oldest course files call the profile
/// `CMU462` (the course's earlier name); it means the same.
fn cgl_technique<'a, 'i>(node: Node<'a, 'i>) -> Option<Node<'a, 'i>> {
    element_children(node, "extra")
        .flat_map(|e| element_children(e, "technique"))
        .find(|t| matches!(t.attribute("profile"), Some("CGL") | Some("CMU462")))
}

fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|c| c.is_element() && c.tag_name().name() == name)
}

fn element_children<'a, 'i>(
    node: Node<'a, 'i>,
    name: &'static str,
) -> impl Iterator<Item = Node<'a, 'i>> {
    node.children().filter(move |c| c.is_element() && c.tag_name().name() == name)
}

fn required_attr<'a>(node: Node<'a, '_>, name: &str) -> Result<&'a str> {
    node.attribute(name).ok_or_else(|| {
        Error::new(format!("<{}> has no '{name}' attribute", node.tag_name().name()))
    })
}

fn parse_attr<T: std::str::FromStr>(node: Node, name: &str) -> Result<Option<T>> {
    node.attribute(name)
        .map(|v| {
            v.trim().parse().map_err(|_| {
                Error::new(format!(
                    "<{}> {name}='{v}' is not a valid number",
                    node.tag_name().name()
                ))
            })
        })
        .transpose()
}

/// Whitespace-separated finite numbers; NaN and infinities are rejected by name.
fn numbers(node: Node, what: &str) -> Result<Vec<f32>> {
    node.text()
        .unwrap_or("")
        .split_ascii_whitespace()
        .map(|t| match t.parse::<f32>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => bail!("{what}: '{t}' is not a finite number"),
            Err(_) => bail!("{what}: '{t}' is not a number"),
        })
        .collect()
}

fn single_number(node: Node, what: &str) -> Result<f32> {
    match numbers(node, what)?.as_slice() {
        [v] => Ok(*v),
        v => bail!("{what}: expected one number, found {}", v.len()),
    }
}

/// The first three numbers of a colour (a fourth, alpha, is ignored).
fn rgb(node: Node, what: &str) -> Result<Vec3> {
    let v = numbers(node, what)?;
    if v.len() < 3 {
        bail!("{what}: expected 3 numbers, found {}", v.len());
    }
    Ok(Vec3::new(v[0], v[1], v[2]))
}

/// Non-negative integer indices.
fn integers(node: Node, what: &str) -> Result<Vec<u32>> {
    node.text()
        .unwrap_or("")
        .split_ascii_whitespace()
        .map(|t| {
            t.parse::<u32>().map_err(|_| {
                Error::new(format!("<{what}>: '{t}' is not a non-negative integer index"))
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

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

    #[test]
    fn numbers_reject_nan_and_words() {
        let doc = Document::parse("<a>1 nan 2</a>").unwrap();
        assert!(numbers(doc.root_element(), "x")
            .unwrap_err()
            .to_string()
            .contains("not a finite number"));
        let doc = Document::parse("<a>1 two</a>").unwrap();
        assert!(numbers(doc.root_element(), "x").unwrap_err().to_string().contains("not a number"));
    }
}
