//! The emissive primitives under a structure of their own, for rays that can only add
//! emission: a path's last segment (under MIS, and after a specular bounce at the last depth),
//! uniform hemisphere sampling's probes and the extra camera rays on emitter outlines. Such a
//! ray adds something only where its closest hit is the front face of an emitter, and the
//! emitters are a few primitives of the scene (the course's boxes: two triangles of a quad). So
//! instead of its closest hit among all primitives, the ray's closest hit among the emitters is
//! found (a walk of a tree of a few primitives), and only where that hit is a front face, one
//! occlusion query over the whole scene up to it (`wavefront::stages::extend_to_emitters`).
//! Both ask the same question; only hits at exactly the emitter's distance can be told apart
//! (where the whole scene's walk would keep the primitive of smallest id, this keeps the
//! emitter), which coplanar overlaps alone produce.

use crate::accel::Accel;
use crate::geometry::prim;
use crate::math::Hit;
use crate::scene::Scene;

/// Emitters above this share of the scene's primitives keep the whole scene's closest-hit
/// walk: every emission-only ray walks the emitters' tree, and the rays that reach an emitter
/// also walk the scene's for occlusion, so the split pays where the emitters' tree is small
/// against the scene's.
const MAX_EMITTER_SHARE: f32 = 0.25;

/// The emissive triangles and spheres of a scene, in a structure of their own.
pub struct EmitterAccel {
    /// Over the emitters alone; `None` when the scene has none.
    accel: Option<Accel>,
    /// Scene triangle index of each of `accel`'s triangles.
    triangles: Vec<u32>,
    /// Scene sphere index of each of `accel`'s spheres.
    spheres: Vec<u32>,
}

impl EmitterAccel {
    /// The emitters of `scene` (primitives whose material emits), or `None` when they are more
    /// than `MAX_EMITTER_SHARE` of its primitives.
    pub fn for_scene(scene: &Scene) -> Option<EmitterAccel> {
        let emits = |material: u32| {
            scene.materials[material as usize].emission() != crate::math::Vec3::ZERO
        };
        let triangles: Vec<u32> = (0..scene.triangles.len() as u32)
            .filter(|&i| emits(scene.triangle_materials[i as usize]))
            .collect();
        let spheres: Vec<u32> = (0..scene.spheres.len() as u32)
            .filter(|&i| emits(scene.spheres[i as usize].material))
            .collect();
        let all = scene.triangles.len() + scene.spheres.len();
        let count = triangles.len() + spheres.len();
        if count as f32 > MAX_EMITTER_SHARE * all as f32 {
            return None;
        }
        if count == 0 {
            return Some(EmitterAccel { accel: None, triangles, spheres });
        }
        // A scene of the emitters alone: three corners of its own per triangle.
        let mut sub = Scene {
            materials: scene.materials.clone(),
            spheres: spheres.iter().map(|&i| scene.spheres[i as usize]).collect(),
            ..Scene::default()
        };
        for &i in &triangles {
            let base = sub.positions.len() as u32;
            sub.positions.extend(scene.triangle(i as usize));
            sub.triangles.push([base, base + 1, base + 2]);
            sub.triangle_materials.push(scene.triangle_materials[i as usize]);
        }
        Some(EmitterAccel { accel: Some(Accel::new(&sub)), triangles, spheres })
    }

    /// How many primitives (triangles and spheres) the tree holds.
    pub fn primitive_count(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }

    /// The structure to trace, `None` when the scene has no emitters (no ray sees emission).
    pub fn accel(&self) -> Option<&Accel> {
        self.accel.as_ref()
    }

    /// A hit of `accel()` as the scene's primitive id.
    #[inline]
    pub fn scene_hit(&self, hit: Hit) -> Hit {
        let prim = if prim::is_sphere(hit.prim) {
            prim::sphere(self.spheres[prim::sphere_index(hit.prim) as usize])
        } else {
            prim::triangle(self.triangles[prim::triangle_index(hit.prim) as usize])
        };
        Hit { prim, ..hit }
    }
}
