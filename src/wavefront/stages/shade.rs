//! Stage 3: turn each hit (or miss) into radiance, continuation rays and shadow rays, by asking
//! the integrator.

use super::super::{PathState, RayQueue, RenderContext, ShadowQueue};
use crate::accel::SPHERE_BIT;
use crate::math::{Hit, Ray, Vec3};
use crate::sampler::DrawBatch;
use crate::scene::Scene;

/// Where the integrator writes the work it creates.
pub struct ShadeOutputs<'q> {
    pub next: &'q mut RayQueue,
    pub shadow: &'q mut ShadowQueue,
    pub probes: &'q mut ShadowQueue,
}

/// What shading needs to know about a hit point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Surface {
    pub p: Vec3,
    /// Geometric normal (unit), as wound for triangles, outward for spheres.
    pub ng: Vec3,
    /// Shading normal (unit): interpolated vertex normals for triangles.
    pub ns: Vec3,
    pub material: u32,
    /// The primitive hit (`Hit::prim`) and the ray parameter of the hit.
    pub prim: u32,
    pub t: f32,
}

impl Surface {
    pub fn at(scene: &Scene, ray: &Ray, hit: &Hit) -> Surface {
        let p = ray.at(hit.t);
        if hit.prim & SPHERE_BIT != 0 {
            let s = &scene.spheres[(hit.prim & !SPHERE_BIT) as usize];
            let n = ((p - s.center) / s.radius).normalize_or(Vec3::Y);
            return Surface { p, ng: n, ns: n, material: s.material, prim: hit.prim, t: hit.t };
        }
        let i = hit.prim as usize;
        let [a, b, c] = scene.triangles[i];
        let [pa, pb, pc] = scene.triangle(i);
        let ng = (pb - pa).cross(pc - pa).normalize_or(Vec3::Y);
        let w = 1.0 - hit.u - hit.v;
        let n = &scene.normals;
        let ns =
            (w * n[a as usize] + hit.u * n[b as usize] + hit.v * n[c as usize]).normalize_or(ng);
        Surface { p, ng, ns, material: scene.triangle_materials[i], prim: hit.prim, t: hit.t }
    }
}

/// Shades every queued ray's hit. The random numbers of all vertices are drawn first, in one
/// pass (`DrawBatch`), then each vertex reads its own.
pub fn shade(
    ctx: &RenderContext,
    depth: u32,
    rays: &RayQueue,
    hits: &[Option<Hit>],
    paths: &mut PathState,
    draws: &mut DrawBatch,
    mut out: ShadeOutputs,
) {
    let layout = ctx.integrator.plan_draws(ctx, depth, draws);
    draws.draw(ctx.sampler, &mut paths.sampler, &rays.path);
    for (q, ((ray, hit), &path)) in rays.rays.iter().zip(hits).zip(&rays.path).enumerate() {
        match hit {
            Some(hit) => {
                let surface = Surface::at(ctx.scene, ray, hit);
                let numbers = (&layout, draws.of(q));
                ctx.integrator.shade_hit(ctx, depth, ray, &surface, path, paths, numbers, &mut out);
            }
            None => ctx.integrator.shade_miss(ctx, depth, ray, path, paths),
        }
    }
}
