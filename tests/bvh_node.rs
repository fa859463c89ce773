//! `--bvh-node PATH`, the write-up's BVH previews: the node's primitives are split exactly
//! between its children, a path off the tree is a one-line error, and the preview differs from
//! the plain normals render exactly on the node's pixels (and its box's outline).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use pathtracer::accel::{binary_node, Accel, AccelKind, BuildParams, TraceStats};
use pathtracer::geometry::prim;
use pathtracer::math::Vec3;
use pathtracer::scene::{collada, Camera, Scene};

mod common;

fn pathtracer(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pathtracer")).args(args).output().expect("run pathtracer")
}

fn scratch_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pt-bvh-node-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `pathtracer gen cornell -o DIR/cornell.dae`.
fn generated_cornell(dir: &Path) -> PathBuf {
    let path = dir.join("cornell.dae");
    let out = pathtracer(&["gen", "cornell", "-o", path.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    path
}

/// The primitive count the CLI prints for `path` (rendering a tiny image).
fn printed_count(scene: &Path, path: &str, dir: &Path) -> usize {
    let image = dir.join(format!("n{path}.png"));
    let args = ["--bvh-node", path, "-r", "16", "12", "-f", image.to_str().unwrap()];
    let out = pathtracer(&[&args[..], &[scene.to_str().unwrap()]].concat());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout.lines().find(|l| l.contains("BVH node")).expect("a BVH node line");
    // "[PathTracer] BVH node L: 7 primitives, SAH cost 4.1234"
    let after = line.split(": ").nth(1).unwrap();
    assert!(line.contains("SAH cost"), "{line}");
    after.split(' ').next().unwrap().parse().unwrap()
}

#[test]
fn children_hold_their_parents_primitives() {
    let dir = scratch_dir("counts");
    let scene = generated_cornell(&dir);
    let count = |p: &str| printed_count(&scene, p, &dir);
    let root = count("root");
    assert_eq!(root, 12, "the Cornell box's six quads (its spheres are not in the BVH)");
    assert_eq!(count(""), root);
    assert_eq!(count("L") + count("R"), root);
    std::fs::remove_dir_all(&dir).unwrap();

    // A course scene through the library, several levels down.
    let Some(path) = common::course_scene("meshedit/maxplanck.dae") else { return };
    let scene = collada::load(&path).unwrap();
    let node = |p: &str| binary_node(&scene, p, BuildParams::default()).unwrap();
    assert_eq!(node("root").prims.len(), scene.triangles.len());
    for parent in ["root", "L", "R", "LL", "LR", "LLL", "RRR"] {
        let prefix = parent.trim_start_matches("root");
        let (p, l, r) = (node(parent), node(&format!("{prefix}L")), node(&format!("{prefix}R")));
        assert_eq!(l.prims.len() + r.prims.len(), p.prims.len(), "{parent}");
        assert!(l.sah_cost < p.sah_cost && r.sah_cost > 0.0, "{parent}");
    }
}

/// Asserts exit code 2, one `error:` line containing `want`, and no image written.
fn assert_refused(args: &[&str], image: &Path, want: &str) {
    let out = pathtracer(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{stderr}");
    assert!(lines[0].starts_with("error: ") && lines[0].contains(want), "{stderr}");
    assert!(!image.exists(), "{args:?} wrote {}", image.display());
}

#[test]
fn a_path_off_the_tree_is_a_one_line_error() {
    let dir = scratch_dir("off");
    let scene = generated_cornell(&dir);
    let s = scene.to_str().unwrap();
    let image = dir.join("x.png");
    let f = image.to_str().unwrap();
    // The first leaf down the left spine, then one step further.
    let loaded = collada::load(&scene).unwrap();
    let mut leaf = String::from("L");
    while !binary_node(&loaded, &leaf, BuildParams::default()).unwrap().is_leaf {
        leaf.push('L');
    }
    let below = format!("{leaf}R");
    assert_refused(&["--bvh-node", &below, "-f", f, s], &image, "leaves the tree");
    assert_refused(&["--bvh-node", &"L".repeat(80), "-f", f, s], &image, "leaves the tree");
    assert_refused(&["--bvh-node", "LQ", "-f", f, s], &image, "--bvh-node");
    assert_refused(&["--bvh-node", "L", "--shading", "mis", "-f", f, s], &image, "conflicts");
    assert_refused(&["--bvh-node", "L", "-H", "-f", f, s], &image, "conflicts");
    assert_refused(&["-f", f, s, "--bvh-node"], &image, "needs a value");
    std::fs::remove_dir_all(&dir).unwrap();
}

fn read_exr(path: &Path) -> Vec<[f32; 3]> {
    let img = image::open(path).unwrap().to_rgb32f();
    img.pixels().map(|p| p.0).collect()
}

/// Pixel coordinates of world point `p` (x right, y down), computed here from the camera's
/// basis rather than by the code under test.
fn project(camera: &Camera, p: Vec3) -> (f32, f32) {
    let v = p - camera.eye;
    let depth = -v.dot(camera.z);
    assert!(depth > 0.0, "the node's box is in front of the camera");
    let sx = (v.dot(camera.x) / depth / camera.tan_half_h + 1.0) / 2.0;
    let sy = (v.dot(camera.y) / depth / camera.tan_half_v + 1.0) / 2.0;
    (sx * camera.width as f32, (1.0 - sy) * camera.height as f32)
}

fn distance_to_segment(p: (f32, f32), a: (f32, f32), b: (f32, f32)) -> f32 {
    let (dx, dy) = (b.0 - a.0, b.1 - a.1);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 {
        (((p.0 - a.0) * dx + (p.1 - a.1) * dy) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let (x, y) = (a.0 + t * dx - p.0, a.1 + t * dy - p.1);
    (x * x + y * y).sqrt()
}

/// Whether pixel (x, y) can be touched by the outline of the box with these corners: its
/// centre lies within one pixel diagonal of an edge.
fn near_outline(corners: &[(f32, f32); 8], x: u32, y: u32) -> bool {
    let centre = (x as f32 + 0.5, y as f32 + 0.5);
    (0..8).flat_map(|i| [1, 2, 4].map(move |bit| (i, i | bit))).filter(|(i, j)| i != j).any(
        |(i, j)| distance_to_segment(centre, corners[i], corners[j]) <= std::f32::consts::SQRT_2,
    )
}

/// Whether the closest hit through pixel (x, y)'s centre is a triangle in `prims`.
fn hits_node(scene_accel: &(Scene, Accel), camera: &Camera, prims: &[u32], x: u32, y: u32) -> bool {
    let ray = camera.ray_through_pixel(x as f32 + 0.5, y as f32 + 0.5);
    let hit = scene_accel.1.intersect(&ray, &mut TraceStats::default());
    hit.is_some_and(|h| !prim::is_sphere(h.prim) && prims.contains(&h.prim))
}

#[test]
fn the_preview_differs_from_plain_normals_exactly_on_the_nodes_pixels() {
    let dir = scratch_dir("pixels");
    let scene_path = generated_cornell(&dir);
    // Wide enough to see the side walls and both spheres (a smaller image is a crop of this).
    let (w, h) = (400u32, 300u32);
    let render = |name: &str, extra: &[&str]| {
        let image = dir.join(name);
        let size = ["-r", &w.to_string(), &h.to_string()].map(String::from);
        let mut args: Vec<&str> = size.iter().map(String::as_str).collect();
        args.extend_from_slice(extra);
        args.extend_from_slice(&["-t", "2", "-f", image.to_str().unwrap()]);
        args.push(scene_path.to_str().unwrap());
        let out = pathtracer(&args);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        read_exr(&image)
    };
    let plain = render("plain.exr", &["--shading", "normals"]);
    let scene = collada::load(&scene_path).unwrap();
    let accel = Accel::build(&scene, AccelKind::Bvh);
    let camera = Camera::new(&scene.camera, scene.bounds(), w, h);
    let both = (scene, accel);
    for path in ["L", "R", "LR"] {
        let Ok(node) = binary_node(&both.0, path, BuildParams::default()) else { continue };
        let preview = render(&format!("{path}.exr"), &["--bvh-node", path]);
        let b = node.bounds;
        let corners: [(f32, f32); 8] = std::array::from_fn(|i| {
            let pick = |bit: usize, lo: f32, hi: f32| if i & bit == 0 { lo } else { hi };
            let c = Vec3::new(
                pick(1, b.min.x, b.max.x),
                pick(2, b.min.y, b.max.y),
                pick(4, b.min.z, b.max.z),
            );
            project(&camera, c)
        });
        let (mut inside, mut outside) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                let i = (y * w + x) as usize;
                let differs = preview[i] != plain[i];
                let in_node = hits_node(&both, &camera, &node.prims, x, y);
                if near_outline(&corners, x, y) {
                    continue; // the outline may paint it, whatever it shows
                }
                assert_eq!(differs, in_node, "node {path}, pixel ({x}, {y})");
                if in_node {
                    inside += 1;
                } else {
                    outside += 1;
                }
            }
        }
        // Both sides of the claim are exercised: tinted pixels, and untouched ones.
        assert!(inside > 50 && outside > 50, "node {path}: {inside} inside, {outside} outside");
        // And pixels that differ away from the node's triangles are on its outline.
        let outline_only = (0..w * h)
            .filter(|&i| preview[i as usize] != plain[i as usize])
            .filter(|&i| !hits_node(&both, &camera, &node.prims, i % w, i / w))
            .count();
        assert!(outline_only > 0, "node {path}: the box is outlined");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
