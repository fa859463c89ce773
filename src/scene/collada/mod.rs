//! The course's COLLADA 1.4.1 dialect with its `CGL` profile -> `Scene`
//! (`../shared/docs/SCENE_FORMAT.md`). This module is the only one that knows about XML.
//!
//! Every failure is one line naming what is wrong; `load` prefixes it with the file name.
//! Loading counts what the node graph expands to first (`census.rs`), then visits the nodes
//! (`nodes.rs`), building geometry (`geometry.rs`), materials (`materials.rs`), lights and the
//! camera (`lights_cameras.rs`) from the XML (`xml.rs`).

mod census;
mod geometry;
mod lights_cameras;
mod materials;
mod nodes;
mod xml;

use std::collections::HashMap;
use std::path::Path;

use roxmltree::{Document, Node};

pub use geometry::vertex_normals;
pub use lights_cameras::light_is_finite;

use super::{CameraDesc, Scene};
use crate::{bail, Error, Result};
use census::Expansion;
use nodes::up_axis_matrix;
use xml::{child, element_children, required_attr};

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
    // Reading errors are `Error::Io`, what the file holds `Error::Scene`; both name the file.
    let text = read_capped(path, max_bytes).map_err(|e| e.in_scene(Some(path)))?;
    parse(&text).map_err(|e| e.in_scene(Some(path)))
}

/// The file's text, refusing it once it holds more than `max_bytes` (`error::read_capped`).
fn read_capped(path: &Path, max_bytes: u64) -> Result<String> {
    let too_large = || {
        Error::new(format!(
            "larger than the scene size limit of {max_bytes} bytes (--max-scene-bytes raises it)"
        ))
    };
    let bytes = crate::error::read_capped(path, max_bytes, too_large)?;
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
