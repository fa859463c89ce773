//! TEMPORARY stub until the film module lands from the `assets` branch.
use crate::math::Vec3;
use std::path::Path;

pub fn write_image(path: &Path, width: u32, height: u32, pixels: &[Vec3]) -> crate::Result<()> {
    let mut img = image::RgbImage::new(width, height);
    for (p, l) in img.pixels_mut().zip(pixels) {
        let t = |x: f32| {
            ((std::f32::consts::SQRT_2 * x).max(0.0).powf(1.0 / 2.2).clamp(0.0, 1.0) * 255.0 + 0.5)
                as u8
        };
        *p = image::Rgb([t(l.x), t(l.y), t(l.z)]);
    }
    img.save(path).map_err(|e| crate::Error::new(format!("{}: {e}", path.display())))
}
