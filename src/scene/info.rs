//! `pathtracer --info`: what a loaded scene holds, in a few lines.

use std::collections::BTreeMap;
use std::fmt::Write;

use super::{Camera, Scene};

/// Counts by kind, e.g. "2 area, 1 point".
fn by_kind<'a>(kinds: impl Iterator<Item = &'a str>) -> String {
    let mut counts: BTreeMap<&str, usize> = BTreeMap::new();
    for k in kinds {
        *counts.entry(k).or_default() += 1;
    }
    if counts.is_empty() {
        return "none".into();
    }
    counts.iter().map(|(k, n)| format!("{n} {k}")).collect::<Vec<_>>().join(", ")
}

/// A multi-line summary; the camera is framed for a `width` x `height` image.
pub fn summary(scene: &Scene, width: u32, height: u32) -> String {
    let mut s = String::new();
    let b = scene.bounds();
    let cam = Camera::new(&scene.camera, b, width, height);
    let (hfov, vfov) = cam.fov_deg();
    let _ = writeln!(s, "triangles: {}", scene.triangles.len());
    let _ = writeln!(s, "vertices:  {}", scene.positions.len());
    let _ = writeln!(s, "spheres:   {}", scene.spheres.len());
    let _ = writeln!(s, "lights:    {}", by_kind(scene.lights.iter().map(|l| l.kind())));
    let _ = writeln!(s, "materials: {}", by_kind(scene.materials.iter().map(|m| m.kind())));
    if b.is_empty() {
        let _ = writeln!(s, "bounds:    empty");
    } else {
        let _ = writeln!(
            s,
            "bounds:    min {:.4} max {:.4} (diagonal {:.4})",
            b.min,
            b.max,
            b.diagonal()
        );
    }
    let _ = writeln!(
        s,
        "camera:    eye {:.4} target {:.4} fov {hfov:.2} x {vfov:.2} degrees at {width}x{height}",
        cam.eye, cam.target
    );
    for w in &scene.warnings {
        let _ = writeln!(s, "warning:   {w}");
    }
    s
}
