//! TEMPORARY stub.
use super::Scene;
pub fn summary(scene: &Scene, _w: u32, _h: u32) -> String {
    format!("triangles: {}\n", scene.triangles.len())
}
