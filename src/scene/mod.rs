//! The scene model: plain data that rendering reads, and nothing else (no XML, no accel).
//!
//! All coordinates are world space, Y up (the loader applies the up-axis fix and node
//! transforms). Triangles from every mesh are concatenated into one indexed list so the
//! acceleration structure sees a single array.

pub mod camera;
pub mod collada;
pub mod info;
mod light;
mod material;

pub use camera::{Camera, CameraDesc};
pub use light::Light;
pub use material::Material;

use crate::math::{Aabb, Vec3};

/// Most triangles a scene may hold: what the acceleration structure can address.
pub const MAX_TRIANGLES: usize = 1 << 24;

/// An analytic sphere (CGL `sphere/radius`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// World-space centre.
    pub center: Vec3,
    /// Radius.
    pub radius: f32,
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// Normals per triangle in `Scene::triangle_normals`: the face normal, then the three vertex
/// normals.
pub const NORMALS_PER_TRIANGLE: usize = 4;

/// A loaded scene: triangles and spheres in world space, their materials, the lights and the
/// camera description. [`Scene::load`] reads one from a COLLADA file.
#[derive(Debug, Clone, Default)]
pub struct Scene {
    /// World-space vertex positions of all meshes.
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals (unit length): the area-weighted sum of the normals of the
    /// faces around each vertex, as the course renderer makes them.
    pub normals: Vec<Vec3>,
    /// Vertex indices of each triangle, counter-clockwise as in the file.
    pub triangles: Vec<[u32; 3]>,
    /// Material index of each triangle (parallel to `triangles`).
    pub triangle_materials: Vec<u32>,
    /// The analytic spheres.
    pub spheres: Vec<Sphere>,
    /// Every material, indexed by `triangle_materials` and `Sphere::material`.
    pub materials: Vec<Material>,
    /// The lights (not geometry: only light sampling reaches them).
    pub lights: Vec<Light>,
    /// The file's camera, framed per image size by [`Camera::new`].
    pub camera: CameraDesc,
    /// Non-fatal problems met while loading (e.g. a skipped spot light), printed by the CLI.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Reads a scene from a COLLADA file. A file that cannot be read is [`Error::Io`]; one
    /// that is not a scene we can render is [`Error::Scene`].
    ///
    /// [`Error::Io`]: crate::Error::Io
    /// [`Error::Scene`]: crate::Error::Scene
    pub fn load(path: impl AsRef<std::path::Path>) -> crate::Result<Scene> {
        collada::load(path.as_ref())
    }

    /// Parses a scene from COLLADA text; every failure is [`Error::Scene`](crate::Error::Scene).
    pub fn parse(text: &str) -> crate::Result<Scene> {
        collada::parse(text).map_err(|e| e.in_scene(None))
    }

    /// Bounding box of all geometry (meshes and spheres, not lights), as the camera frames it.
    pub fn bounds(&self) -> Aabb {
        let tris = self
            .triangles
            .iter()
            .flat_map(|t| t.iter())
            .fold(Aabb::EMPTY, |b, &i| b.grow(self.positions[i as usize]));
        self.spheres.iter().fold(tris, |b, s| {
            b.grow(s.center - Vec3::splat(s.radius)).grow(s.center + Vec3::splat(s.radius))
        })
    }

    /// The three corners of triangle `i`.
    #[inline]
    pub fn triangle(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// Each triangle's normals as shading in lanes reads them, `NORMALS_PER_TRIANGLE` (48
    /// bytes) side by side, so that 16 hits take 12 independent gathers (through the vertex
    /// indices it took 15, and the normals' gathers waited on the indices'): the geometric
    /// normal, not normalised, (b - a) x (c - a) of its corners with the same operations as
    /// `Surface::at` (so the same bits), then its three vertex normals. Memory that cannot be
    /// had is an error.
    pub fn triangle_normals(&self) -> crate::Result<Vec<Vec3>> {
        let what = "the triangles' normals";
        let len = self.triangles.len() * NORMALS_PER_TRIANGLE;
        let mut normals = crate::error::try_filled_vec(len, Vec3::ZERO, what)?;
        for (i, n) in normals.chunks_exact_mut(NORMALS_PER_TRIANGLE).enumerate() {
            let [a, b, c] = self.triangle(i);
            n[0] = (b - a).cross(c - a);
            for (k, &v) in self.triangles[i].iter().enumerate() {
                n[1 + k] = self.normals[v as usize];
            }
        }
        Ok(normals)
    }

    /// Whether any material is emissive (emissive geometry seen by camera and BSDF rays).
    pub fn has_emissive_geometry(&self) -> bool {
        self.materials.iter().any(|m| matches!(m, Material::Emission { .. }))
    }

    /// Whether the materials include specular ones (`Material::is_specular`) and surfaces
    /// that are neither specular nor emitters, whose vertices sample lights.
    pub fn mixes_specular(&self) -> bool {
        let smooth = |m: &Material| !m.is_specular() && !matches!(m, Material::Emission { .. });
        self.materials.iter().any(Material::is_specular) && self.materials.iter().any(smooth)
    }

    /// Checks the invariants every consumer relies on: indices in range, finite numbers.
    /// The loader calls this last, so a `Scene` from the loader is always valid. Limits of
    /// the acceleration structure are its own (`Accel::try_build`).
    pub fn validate(&self) -> crate::Result<()> {
        let n = self.positions.len() as u32;
        if self.normals.len() != self.positions.len() {
            crate::bail!("{} normals for {} vertices", self.normals.len(), n);
        }
        if self.triangle_materials.len() != self.triangles.len() {
            crate::bail!("material list does not match the triangle list");
        }
        if let Some(p) = self.positions.iter().find(|p| !p.is_finite()) {
            crate::bail!("vertex position {p} is not finite");
        }
        for (i, t) in self.triangles.iter().enumerate() {
            if t.iter().any(|&v| v >= n) {
                crate::bail!("triangle {i} refers to vertex {t:?} but there are only {n} vertices");
            }
        }
        let nm = self.materials.len() as u32;
        let bad_mat = self
            .triangle_materials
            .iter()
            .chain(self.spheres.iter().map(|s| &s.material))
            .any(|&m| m >= nm);
        if bad_mat {
            crate::bail!("a primitive refers to a material that does not exist");
        }
        if let Some(s) = self
            .spheres
            .iter()
            .find(|s| !s.center.is_finite() || !s.radius.is_finite() || s.radius <= 0.0)
        {
            crate::bail!("sphere at {} has invalid radius {}", s.center, s.radius);
        }
        Ok(())
    }
}
