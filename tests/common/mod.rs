//! Shared helpers for integration tests.
#![allow(dead_code)]

use std::path::PathBuf;

pub mod bsdf;
pub mod cli;

/// The course scenes: `$PT_SCENES`, else `../shared/scenes/cs184` beside the repository.
/// Returns `None` (and prints "skipped: scenes not found") when they are absent, so tests that
/// need them skip cleanly on a clone without `shared/`. `.ci/run` always has them and sets
/// `PT_REQUIRE_SCENES=1`, which turns a missing directory into a failure.
pub fn scenes_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("PT_SCENES").map(PathBuf::from).unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes/cs184")
    });
    if dir.is_dir() {
        Some(dir)
    } else if std::env::var_os("PT_REQUIRE_SCENES").is_some() {
        panic!("PT_REQUIRE_SCENES is set but {} does not exist", dir.display());
    } else {
        eprintln!("skipped: scenes not found at {}", dir.display());
        None
    }
}

/// A course scene by its path relative to the scenes directory, or `None` (skipped).
pub fn course_scene(rel: &str) -> Option<PathBuf> {
    scenes_dir().map(|d| d.join(rel))
}

/// Every `.dae` under the scenes directory, sorted.
pub fn all_course_scenes() -> Vec<PathBuf> {
    let Some(dir) = scenes_dir() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    let mut stack = vec![dir];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "dae") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

use pathtracer::accel::{Accel, AccelKind};
use pathtracer::integrator::{DirectLighting, Integrator};
use pathtracer::math::Vec3;
use pathtracer::render::{render, RenderConfig};
use pathtracer::scene::{CameraDesc, Light, Material, Scene};

/// Builds small scenes in code for analytic tests.
pub struct SceneBuilder {
    pub scene: Scene,
}

impl SceneBuilder {
    pub fn new() -> Self {
        let camera = CameraDesc { view_dir: Vec3::Y, ..CameraDesc::default() };
        SceneBuilder { scene: Scene { camera, ..Scene::default() } }
    }

    pub fn material(&mut self, m: Material) -> u32 {
        self.scene.materials.push(m);
        self.scene.materials.len() as u32 - 1
    }

    /// A quad with corners a, b, c, d (counter-clockwise seen from its front side).
    pub fn quad(&mut self, corners: [Vec3; 4], material: u32) {
        let base = self.scene.positions.len() as u32;
        let n = (corners[1] - corners[0]).cross(corners[2] - corners[0]).normalize();
        for c in corners {
            self.scene.positions.push(c);
            self.scene.normals.push(n);
        }
        for t in [[0, 1, 2], [0, 2, 3]] {
            self.scene.triangles.push(t.map(|i| base + i));
            self.scene.triangle_materials.push(material);
        }
    }

    /// A horizontal rectangle at height y spanning [x0, x1] x [z0, z1]; `up` sets its front.
    pub fn horizontal_quad(
        &mut self,
        y: f32,
        x: (f32, f32),
        z: (f32, f32),
        up: bool,
        material: u32,
    ) {
        let c = [
            Vec3::new(x.0, y, z.0),
            Vec3::new(x.0, y, z.1),
            Vec3::new(x.1, y, z.1),
            Vec3::new(x.1, y, z.0),
        ];
        // (x0,z0) -> (x0,z1) -> (x1,z1): normal = +y.
        let corners = if up { c } else { [c[0], c[3], c[2], c[1]] };
        self.quad(corners, material);
    }

    pub fn light(&mut self, l: Light) {
        self.scene.lights.push(l);
    }

    pub fn build(self) -> Scene {
        self.scene.validate().unwrap();
        self.scene
    }
}

/// Renders with the given integrator; returns the linear pixels.
pub fn render_pixels(
    scene: &Scene,
    integrator: Integrator,
    f: impl FnOnce(&mut RenderConfig),
) -> Vec<Vec3> {
    let accel = Accel::build(scene, AccelKind::Bvh);
    let mut config = RenderConfig { integrator, threads: 2, ..RenderConfig::default() };
    f(&mut config);
    render(scene, &accel, &config).unwrap().pixels
}

/// Every course scene, then the repository's `assets/cornell.dae`: the set that the
/// whole-renderer comparisons (two ways of rendering, the same bytes) go through.
pub fn course_scenes_and_cornell() -> Vec<PathBuf> {
    let mut scenes = all_course_scenes();
    scenes.push(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/cornell.dae"));
    scenes
}

/// The small render those comparisons make: 40 x 30, 8 spp, 2 threads, `integrator` at depth
/// `max_depth` with `light_samples` light samples and `seed`.
pub fn small_render(
    integrator: Integrator,
    max_depth: u32,
    light_samples: u32,
    seed: u64,
) -> RenderConfig {
    RenderConfig {
        integrator,
        width: 40,
        height: 30,
        spp: 8,
        max_depth,
        light_samples,
        threads: 2,
        seed,
        ..RenderConfig::default()
    }
}

pub const LIGHT: Integrator = Integrator::Path(DirectLighting::LightSampling);
pub const HEMISPHERE: Integrator = Integrator::Path(DirectLighting::Hemisphere);
pub const MIS: Integrator = Integrator::Path(DirectLighting::Mis);

/// Renders and returns the whole output (pixels, per-pixel sample counts, statistics).
pub fn render_output(
    scene: &Scene,
    integrator: Integrator,
    f: impl FnOnce(&mut RenderConfig),
) -> pathtracer::render::RenderOutput {
    let accel = Accel::build(scene, AccelKind::Bvh);
    let mut config = RenderConfig { integrator, threads: 2, ..RenderConfig::default() };
    f(&mut config);
    render(scene, &accel, &config).unwrap()
}

/// A closed box whose ceiling holds a square that is both an emissive quad (radiance L, facing
/// down) and a scene area light of the same rectangle and radiance.
pub fn coincident_light_box() -> Scene {
    let mut b = SceneBuilder::new();
    b.scene.camera.view_dir = Vec3::new(0.3, 0.4, 1.0).normalize();
    let white = b.material(Material::Diffuse { albedo: Vec3::splat(0.7) });
    let red = b.material(Material::Diffuse { albedo: Vec3::new(0.7, 0.1, 0.1) });
    let emit = b.material(Material::Emission { radiance: Vec3::splat(8.0) });
    b.horizontal_quad(0.0, (-1.0, 1.0), (-1.0, 1.0), true, white);
    b.horizontal_quad(2.0, (-1.0, 1.0), (-1.0, 1.0), false, white);
    // Left wall (x = -1) facing +x, back wall (z = -1) facing +z.
    b.quad(
        [
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(-1.0, 2.0, -1.0),
            Vec3::new(-1.0, 2.0, 1.0),
            Vec3::new(-1.0, 0.0, 1.0),
        ],
        red,
    );
    b.quad(
        [
            Vec3::new(-1.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, -1.0),
            Vec3::new(1.0, 2.0, -1.0),
            Vec3::new(-1.0, 2.0, -1.0),
        ],
        white,
    );
    // The light, just below the ceiling so the ceiling does not hide it.
    let y = 1.999;
    b.horizontal_quad(y, (-0.3, 0.3), (-0.4, 0.4), false, emit);
    b.light(Light::Area {
        position: Vec3::new(0.0, y, 0.0),
        direction: Vec3::NEG_Y,
        dim_x: Vec3::new(0.6, 0.0, 0.0),
        dim_y: Vec3::new(0.0, 0.0, 0.8),
        radiance: Vec3::splat(8.0),
    });
    b.build()
}
