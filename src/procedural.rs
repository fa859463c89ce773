//! Deterministic procedural scenes, written in the course's COLLADA dialect
//! (`../shared/docs/SCENE_FORMAT.md`) so that they go through the same loader as the course
//! files and can be handed to other tracers (the peer benchmark reads `.dae` files too).
//!
//! - [`cornell_box`]: the scene in `assets/cornell.dae`: a closed-on-five-sides box whose
//!   emissive ceiling quad and CGL area light are exactly the same rectangle (so every direct
//!   lighting estimator converges to the same image), a mirror sphere and a glass sphere.
//! - [`tori`]: a grid of randomly tilted tori over a floor, for scaling tests. The triangle
//!   count is chosen exactly: 10k, 100k, 1M and 4M are the benchmark's steps.
//!
//! The text depends only on the arguments: numbers are printed as the shortest decimal that
//! round-trips the `f32`, and the random numbers come from [`Pcg32`].

use std::f32::consts::TAU;
use std::fmt::Write;

use crate::math::Vec3;
use crate::sampler::Pcg32;

/// A COLLADA 1.4.1 document under construction: Y up, row-major node matrices.
#[derive(Default)]
pub(crate) struct DaeWriter {
    effects: String,
    materials: String,
    geometries: String,
    lights: String,
    nodes: String,
}

/// A 4x4 row-major matrix as COLLADA's `<matrix>` wants it.
pub(crate) type Matrix = [[f32; 4]; 4];

/// The identity matrix: a node placed where its mesh is.
pub(crate) const IDENTITY: Matrix =
    [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];

/// Half a turn about y: c = M(0, 0, -1) = +z, an eye in front of the scene looking down -z.
const CAMERA_FRONT: Matrix =
    [[-1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];

/// c = (0, 0.6, 0.8): an eye in front of the scene and above it, looking down about 37 degrees.
/// (A rotation about x whose third column is -c.)
const CAMERA_ABOVE: Matrix =
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.8, -0.6, 0.0], [0.0, 0.6, -0.8, 0.0], [0.0, 0.0, 0.0, 1.0]];

/// What a surface is made of, as the CGL profile (or a plain phong diffuse colour) says it.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Bsdf {
    /// Lambertian with this albedo (a plain phong diffuse colour).
    Diffuse(Vec3),
    /// An emitter of this radiance (CGL `<emission>`).
    Emission(Vec3),
    /// A perfect mirror of this reflectance (CGL `<mirror>`).
    Mirror(Vec3),
    /// Smooth glass with white reflectance and transmittance (CGL `<glass>`).
    Glass {
        /// Index of refraction.
        ior: f32,
    },
}

impl DaeWriter {
    /// Declares a material `id` (and its effect).
    pub fn material(&mut self, id: &str, bsdf: Bsdf) {
        let v = |c: Vec3| format!("{} {} {}", c.x, c.y, c.z);
        let (diffuse, cgl) = match bsdf {
            Bsdf::Diffuse(albedo) => (albedo, String::new()),
            Bsdf::Emission(radiance) => (
                Vec3::splat(0.8),
                format!("<emission><radiance>{}</radiance></emission>", v(radiance)),
            ),
            Bsdf::Mirror(reflectance) => (
                Vec3::splat(0.8),
                format!("<mirror><reflectance>{}</reflectance></mirror>", v(reflectance)),
            ),
            Bsdf::Glass { ior } => (
                Vec3::splat(0.8),
                format!(
                    "<glass><reflectance>1 1 1</reflectance><transmittance>1 1 1</transmittance>\
                     <roughness>0</roughness><ior>{ior}</ior></glass>"
                ),
            ),
        };
        let extra = if cgl.is_empty() {
            String::new()
        } else {
            format!("\n      <extra><technique profile=\"CGL\">{cgl}</technique></extra>")
        };
        let _ = writeln!(
            self.effects,
            "    <effect id=\"{id}-effect\">\n      <profile_COMMON><technique sid=\"common\"><phong>\
             <diffuse><color sid=\"diffuse\">{} 1</color></diffuse></phong></technique></profile_COMMON>{extra}\n    </effect>",
            v(diffuse)
        );
        let _ = writeln!(
            self.materials,
            "    <material id=\"{id}-material\" name=\"{id}\"><instance_effect url=\"#{id}-effect\"/></material>"
        );
    }

    /// An indexed triangle mesh placed by `matrix`, made of material `material`.
    pub fn mesh(
        &mut self,
        id: &str,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        material: &str,
        matrix: &Matrix,
    ) {
        let g = &mut self.geometries;
        let _ = write!(
            g,
            "    <geometry id=\"{id}-mesh\" name=\"{id}\">\n      <mesh>\n        <source id=\"{id}-positions\">\n          \
             <float_array id=\"{id}-positions-array\" count=\"{}\">",
            3 * positions.len()
        );
        for (i, p) in positions.iter().enumerate() {
            let sep = if i == 0 { "" } else { " " };
            let _ = write!(g, "{sep}{} {} {}", p.x, p.y, p.z);
        }
        let _ = write!(
            g,
            "</float_array>\n          <technique_common><accessor source=\"#{id}-positions-array\" count=\"{}\" stride=\"3\">\
             <param name=\"X\" type=\"float\"/><param name=\"Y\" type=\"float\"/><param name=\"Z\" type=\"float\"/>\
             </accessor></technique_common>\n        </source>\n        <vertices id=\"{id}-vertices\">\
             <input semantic=\"POSITION\" source=\"#{id}-positions\"/></vertices>\n        \
             <triangles material=\"{material}-material\" count=\"{}\">\
             <input semantic=\"VERTEX\" source=\"#{id}-vertices\" offset=\"0\"/>\n          <p>",
            positions.len(),
            triangles.len()
        );
        for (i, t) in triangles.iter().enumerate() {
            let sep = if i == 0 { "" } else { " " };
            let _ = write!(g, "{sep}{} {} {}", t[0], t[1], t[2]);
        }
        g.push_str("</p>\n        </triangles>\n      </mesh>\n    </geometry>\n");
        self.instance(id, &format!("{id}-mesh"), material, matrix);
    }

    /// A CGL analytic sphere of `radius` at `center`.
    pub fn sphere(&mut self, id: &str, center: Vec3, radius: f32, material: &str) {
        let _ = writeln!(
            self.geometries,
            "    <geometry id=\"{id}-sphere\" name=\"{id}\"><extra><technique profile=\"CGL\">\
             <sphere><radius>{radius}</radius></sphere></technique></extra></geometry>"
        );
        self.instance(id, &format!("{id}-sphere"), material, &translation(center));
    }

    fn instance(&mut self, id: &str, geometry: &str, material: &str, matrix: &Matrix) {
        let _ = writeln!(
            self.nodes,
            "      <node id=\"{id}\" name=\"{id}\" type=\"NODE\">\n        {}\n        \
             <instance_geometry url=\"#{geometry}\"><bind_material><technique_common>\
             <instance_material symbol=\"{material}-material\" target=\"#{material}-material\"/>\
             </technique_common></bind_material></instance_geometry>\n      </node>",
            matrix_element(matrix)
        );
    }

    /// A one-sided CGL area light: the rectangle centred at `center` with edges `x_len` along
    /// +x and `z_len` along z, emitting downwards (-y) with `radiance`.
    pub fn ceiling_area_light(
        &mut self,
        id: &str,
        center: Vec3,
        x_len: f32,
        z_len: f32,
        radiance: Vec3,
    ) {
        let _ = writeln!(
            self.lights,
            "    <light id=\"{id}-light\" name=\"{id}\"><technique_common><point><color sid=\"color\">{r} {g} {b}</color>\
             </point></technique_common><extra><technique profile=\"CGL\"><area><color sid=\"color\">{r} {g} {b}</color>\
             </area></technique></extra></light>",
            r = radiance.x,
            g = radiance.y,
            b = radiance.z
        );
        // SCENE_FORMAT.md: the light faces M(0,0,-1) - P and spans M(-1,0,0) - P by
        // M(0,1,0) - P. A rotation of -90 degrees about x sends (0,0,-1) to (0,-1,0) (down) and
        // (0,1,0) to (0,0,-1); with the entries exactly 0 and +-1 the rectangle is exact.
        let m = [
            [x_len, 0.0, 0.0, center.x],
            [0.0, 0.0, 1.0, center.y],
            [0.0, -z_len, 0.0, center.z],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let _ = writeln!(
            self.nodes,
            "      <node id=\"{id}\" name=\"{id}\" type=\"NODE\">\n        {}\n        \
             <instance_light url=\"#{id}-light\"/>\n      </node>",
            matrix_element(&m)
        );
    }

    /// The whole document. The course ignores the camera's position and places the eye at
    /// target + r c, c = unit(M(0, 0, -1)) (SCENE_FORMAT.md "Camera"): `camera` is the camera
    /// node's rotation, chosen so that c is the unit direction from the scene to the eye.
    pub fn finish(self, title: &str, camera: &Matrix) -> String {
        format!(
            "<?xml version=\"1.0\" encoding=\"utf-8\"?>\n\
             <!-- {title}: written by `pathtracer gen` (src/procedural.rs); regenerate, do not edit. -->\n\
             <COLLADA xmlns=\"http://www.collada.org/2005/11/COLLADASchema\" version=\"1.4.1\">\n\
             \x20 <asset><unit name=\"meter\" meter=\"1\"/><up_axis>Y_UP</up_axis></asset>\n\
             \x20 <library_cameras>\n    <camera id=\"camera\" name=\"camera\"><optics><technique_common><perspective>\
             <xfov sid=\"xfov\">49.13434</xfov><aspect_ratio>1.333333</aspect_ratio><znear sid=\"znear\">0.1</znear>\
             <zfar sid=\"zfar\">100</zfar></perspective></technique_common></optics></camera>\n  </library_cameras>\n\
             \x20 <library_lights>\n{}  </library_lights>\n\
             \x20 <library_effects>\n{}  </library_effects>\n\
             \x20 <library_materials>\n{}  </library_materials>\n\
             \x20 <library_geometries>\n{}  </library_geometries>\n\
             \x20 <library_visual_scenes>\n    <visual_scene id=\"scene\" name=\"scene\">\n\
             \x20     <node id=\"camera-node\" name=\"camera\" type=\"NODE\">\n        {}\n        \
             <instance_camera url=\"#camera\"/>\n      </node>\n{}    </visual_scene>\n  </library_visual_scenes>\n\
             \x20 <scene><instance_visual_scene url=\"#scene\"/></scene>\n</COLLADA>\n",
            self.lights,
            self.effects,
            self.materials,
            self.geometries,
            matrix_element(camera),
            self.nodes
        )
    }
}

fn matrix_element(m: &Matrix) -> String {
    let numbers: Vec<String> = m.iter().flatten().map(|x| x.to_string()).collect();
    format!("<matrix sid=\"transform\">{}</matrix>", numbers.join(" "))
}

/// The matrix that translates by `t`.
pub(crate) fn translation(t: Vec3) -> Matrix {
    [[1.0, 0.0, 0.0, t.x], [0.0, 1.0, 0.0, t.y], [0.0, 0.0, 1.0, t.z], [0.0, 0.0, 0.0, 1.0]]
}

/// An axis-aligned rectangle as two triangles whose winding normal is `normal` (one of the
/// six axis directions); `a` and `b` are opposite corners with equal `normal` coordinate.
fn axis_quad(a: Vec3, b: Vec3, normal: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    // Two in-plane axes (u, v) with u x v = normal.
    let (u, v) = if normal.x != 0.0 {
        (Vec3::Y, Vec3::Z)
    } else if normal.y != 0.0 {
        (Vec3::Z, Vec3::X)
    } else {
        (Vec3::X, Vec3::Y)
    };
    let corner = |su: f32, sv: f32| {
        let pick = |axis: Vec3, s: f32| axis * if s == 0.0 { a } else { b };
        let fixed = a * normal.abs();
        fixed + pick(u, su) + pick(v, sv)
    };
    let positions = vec![corner(0.0, 0.0), corner(1.0, 0.0), corner(1.0, 1.0), corner(0.0, 1.0)];
    let flip = u.cross(v).dot(normal) < 0.0;
    let tris = if flip { vec![[0, 2, 1], [0, 3, 2]] } else { vec![[0, 1, 2], [0, 2, 3]] };
    (positions, tris)
}

/// The project's Cornell box (`assets/cornell.dae`).
///
/// Inner box [-1, 1] x [0, 2] x [-1, 1], open towards +z where the camera is. The emissive
/// quad and the area light are one rectangle, 0.5 x 0.5 at y = 1.98 with radiance 12: the
/// course's conventions count it once either way, and light sampling, hemisphere sampling
/// and MIS must agree on this scene (tests/lighting.rs does the same with a box built in code).
pub fn cornell_box() -> String {
    let mut w = DaeWriter::default();
    let radiance = Vec3::splat(12.0);
    w.material("white", Bsdf::Diffuse(Vec3::splat(0.725)));
    w.material("red", Bsdf::Diffuse(Vec3::new(0.63, 0.065, 0.05)));
    w.material("green", Bsdf::Diffuse(Vec3::new(0.14, 0.45, 0.091)));
    w.material("light", Bsdf::Emission(radiance));
    w.material("mirror", Bsdf::Mirror(Vec3::splat(0.95)));
    w.material("glass", Bsdf::Glass { ior: 1.5 });

    let walls = [
        ("floor", Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::Y, "white"),
        ("ceiling", Vec3::new(-1.0, 2.0, -1.0), Vec3::new(1.0, 2.0, 1.0), Vec3::NEG_Y, "white"),
        ("back", Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, -1.0), Vec3::Z, "white"),
        ("left", Vec3::new(-1.0, 0.0, -1.0), Vec3::new(-1.0, 2.0, 1.0), Vec3::X, "red"),
        ("right", Vec3::new(1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0), Vec3::NEG_X, "green"),
    ];
    for (id, a, b, n, material) in walls {
        let (p, t) = axis_quad(a, b, n);
        w.mesh(id, &p, &t, material, &IDENTITY);
    }
    let (y, half) = (1.98, 0.25);
    let (p, t) = axis_quad(Vec3::new(-half, y, -half), Vec3::new(half, y, half), Vec3::NEG_Y);
    w.mesh("emitter", &p, &t, "light", &IDENTITY);
    w.ceiling_area_light("area", Vec3::new(0.0, y, 0.0), 2.0 * half, 2.0 * half, radiance);
    w.sphere("mirror-ball", Vec3::new(-0.45, 0.4, -0.35), 0.4, "mirror");
    w.sphere("glass-ball", Vec3::new(0.45, 0.4, 0.3), 0.4, "glass");
    w.finish("Cornell box with a coincident emissive quad and area light", &CAMERA_FRONT)
}

/// Triangles per torus in [`tori`] and the segment counts that make them.
fn torus_segments(target: usize, count: usize) -> (usize, usize) {
    // A torus of `major` x `minor` segments has 2 * major * minor triangles; major = 2 minor.
    let minor = ((target as f64 / (4.0 * count as f64)).sqrt().round() as usize).max(3);
    (2 * minor, minor)
}

/// How many tori [`tori`] uses for a target triangle count: one per 10,000 triangles.
fn torus_count(target: usize) -> usize {
    target.div_ceil(10_000).max(1)
}

/// Exact triangle count of `tori(target, _)` (the floor's two triangles included).
pub fn tori_triangle_count(target: usize) -> usize {
    let count = torus_count(target);
    let (major, minor) = torus_segments(target, count);
    count * 2 * major * minor + 2
}

/// A torus with `major` x `minor` segments in its own frame (ring in the xz plane).
fn torus_mesh(major: usize, minor: usize, ring: f32, tube: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut positions = Vec::with_capacity(major * minor);
    for i in 0..major {
        let a = TAU * i as f32 / major as f32;
        for j in 0..minor {
            let b = TAU * j as f32 / minor as f32;
            let r = ring + tube * b.cos();
            positions.push(Vec3::new(r * a.cos(), tube * b.sin(), r * a.sin()));
        }
    }
    let index = |i: usize, j: usize| ((i % major) * minor + j % minor) as u32;
    let mut tris = Vec::with_capacity(2 * major * minor);
    for i in 0..major {
        for j in 0..minor {
            let (a, b, c, d) = (index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1));
            // Wound so that the normals point out of the tube.
            tris.push([a, c, b]);
            tris.push([a, d, c]);
        }
    }
    (positions, tris)
}

/// A grid of randomly tilted and sized tori over a floor, lit by an area light: about
/// `target` triangles (exactly [`tori_triangle_count`]). Deterministic in (`target`, `seed`).
pub fn tori(target: usize, seed: u64) -> String {
    let count = torus_count(target);
    let (major, minor) = torus_segments(target, count);
    let side = (count as f32).sqrt().ceil() as usize;
    let spacing = 2.5;
    let extent = side as f32 * spacing;
    let mut rng = Pcg32::new(seed, 0x7041);
    let mut w = DaeWriter::default();
    let palette = [
        Vec3::new(0.8, 0.3, 0.2),
        Vec3::new(0.2, 0.6, 0.3),
        Vec3::new(0.2, 0.3, 0.8),
        Vec3::new(0.8, 0.7, 0.2),
        Vec3::splat(0.7),
    ];
    for (i, c) in palette.iter().enumerate() {
        w.material(&format!("paint{i}"), Bsdf::Diffuse(*c));
    }
    let (floor_p, floor_t) = axis_quad(
        Vec3::new(-0.5 * extent, 0.0, -0.5 * extent),
        Vec3::new(0.5 * extent, 0.0, 0.5 * extent),
        Vec3::Y,
    );
    w.mesh("floor", &floor_p, &floor_t, "paint4", &IDENTITY);
    let light_y = 3.0 + 0.25 * extent;
    w.ceiling_area_light(
        "area",
        Vec3::new(0.0, light_y, 0.0),
        0.3 * extent,
        0.3 * extent,
        Vec3::splat(8.0),
    );

    for k in 0..count {
        let (gx, gz) = (k % side, k / side);
        let ring = 0.6 + 0.3 * rng.next_f32();
        let tube = 0.12 + 0.2 * rng.next_f32();
        let (mesh_p, mesh_t) = torus_mesh(major, minor, ring, tube);
        // A random tilt about a random horizontal axis, then a lift so the torus clears the floor.
        let tilt = 1.2 * rng.next_f32();
        let heading = TAU * rng.next_f32();
        let rot = glam::Mat3::from_axis_angle(Vec3::new(heading.cos(), 0.0, heading.sin()), tilt);
        let centre = Vec3::new(
            (gx as f32 + 0.5) * spacing - 0.5 * extent,
            ring + tube + 0.1,
            (gz as f32 + 0.5) * spacing - 0.5 * extent,
        );
        let c = rot.to_cols_array_2d();
        let m = [
            [c[0][0], c[1][0], c[2][0], centre.x],
            [c[0][1], c[1][1], c[2][1], centre.y],
            [c[0][2], c[1][2], c[2][2], centre.z],
            [0.0, 0.0, 0.0, 1.0],
        ];
        let paint = format!("paint{}", rng.next_u32() % 4);
        w.mesh(&format!("torus{k}"), &mesh_p, &mesh_t, &paint, &m);
    }
    let title = format!("{count} tori, {} triangles, seed {seed}", tori_triangle_count(target));
    w.finish(&title, &CAMERA_ABOVE)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::collada::parse;

    #[test]
    fn axis_quads_face_their_normal() {
        for n in [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z] {
            let (a, b) = (-Vec3::ONE + n + n.abs(), Vec3::ONE + n - n.abs());
            let (p, t) = axis_quad(a * (Vec3::ONE - n.abs()) + n, b * (Vec3::ONE - n.abs()) + n, n);
            for [i, j, k] in t {
                let (p0, p1, p2) = (p[i as usize], p[j as usize], p[k as usize]);
                let normal = (p1 - p0).cross(p2 - p0).normalize();
                assert!((normal - n).length() < 1e-6, "{n}: {normal}");
            }
        }
    }

    #[test]
    fn tori_hit_the_requested_counts_and_load() {
        for target in [10_000, 100_000] {
            let n = tori_triangle_count(target);
            assert!((n as f64 / target as f64 - 1.0).abs() < 0.01, "{target} -> {n}");
            let scene = parse(&tori(target, 1)).unwrap();
            assert_eq!(scene.triangles.len(), n);
            assert_eq!(scene.lights.len(), 1);
            // Every torus stands on or above the floor.
            assert!(scene.bounds().min.y >= -1e-4, "{:?}", scene.bounds());
        }
        assert_eq!(tori(10_000, 3), tori(10_000, 3));
        assert_ne!(tori(10_000, 3), tori(10_000, 4));
        for target in [1_000_000, 4_000_000] {
            let n = tori_triangle_count(target);
            assert!((n as f64 / target as f64 - 1.0).abs() < 0.01, "{target} -> {n}");
        }
    }

    #[test]
    fn cornell_light_and_emitter_are_one_rectangle() {
        let scene = parse(&cornell_box()).unwrap();
        assert_eq!(scene.spheres.len(), 2);
        let crate::scene::Light::Area { position, direction, dim_x, dim_y, .. } = scene.lights[0]
        else {
            panic!("{:?}", scene.lights);
        };
        assert_eq!(direction, Vec3::NEG_Y);
        // The emitter's corners are exactly the light's corners.
        let corners: Vec<Vec3> = [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)]
            .iter()
            .map(|&(u, v)| position + u * dim_x + v * dim_y)
            .collect();
        let emitter =
            scene.materials.iter().position(|m| m.emission() != Vec3::ZERO).unwrap() as u32;
        let tris: Vec<usize> = (0..scene.triangles.len())
            .filter(|&i| scene.triangle_materials[i] == emitter)
            .collect();
        assert_eq!(tris.len(), 2);
        for i in tris {
            for p in scene.triangle(i) {
                assert!(corners.contains(&p), "{p} not a light corner {corners:?}");
            }
            let [a, b, c] = scene.triangle(i);
            assert!(
                (b - a).cross(c - a).dot(direction) > 0.0,
                "emitter must face the light's direction"
            );
        }
    }
}
