//! Lights and the camera of a scene.

use glam::{Mat4, Vec3};
use roxmltree::Node;

use super::materials::cgl_technique;
use super::xml::{child, required_attr, rgb, single_number};
use super::Loader;
use crate::scene::{CameraDesc, Light};
use crate::{bail, Error, Result};

impl<'a, 'input> Loader<'a, 'input> {
    pub(super) fn instance_light(&mut self, inst: Node, world: Mat4) -> Result<()> {
        let light = self.resolve(required_attr(inst, "url")?, "instance_light")?;
        let lid = light.attribute("id").unwrap_or("?");
        // The CGL technique wins over technique_common.
        let technique = cgl_technique(light).or_else(|| child(light, "technique_common"));
        let Some(kind_node) = technique.and_then(|t| t.children().find(Node::is_element)) else {
            self.scene.warnings.push(format!("light '{lid}' has no technique: skipped"));
            return Ok(());
        };
        let color = || -> Result<Vec3> {
            let c = child(kind_node, "color")
                .ok_or_else(|| Error::new(format!("light '{lid}' has no <color>")))?;
            rgb(c, &format!("light '{lid}' color"))
        };
        let origin = world.transform_point3(Vec3::ZERO);
        let light = match kind_node.tag_name().name() {
            "area" => Light::Area {
                position: origin,
                direction: (world.transform_point3(Vec3::NEG_Z) - origin).normalize_or(Vec3::NEG_Y),
                dim_x: world.transform_point3(Vec3::NEG_X) - origin,
                dim_y: world.transform_point3(Vec3::Y) - origin,
                radiance: color()?,
            },
            "point" => Light::Point { position: origin, radiance: color()? },
            "directional" => Light::Directional {
                direction: world.transform_point3(Vec3::NEG_Z).normalize_or(Vec3::Y),
                radiance: color()?,
            },
            "ambient" => Light::Ambient { radiance: color()? },
            "spot" => {
                self.scene.warnings.push(format!(
                    "light '{lid}': spot lights are not supported (the course skips them): skipped"
                ));
                return Ok(());
            }
            other => {
                self.scene.warnings.push(format!("light '{lid}': unknown kind <{other}>: skipped"));
                return Ok(());
            }
        };
        self.scene.lights.push(light);
        Ok(())
    }

    pub(super) fn instance_camera(&mut self, inst: Node, world: Mat4) -> Result<()> {
        if self.camera.is_some() {
            return Ok(()); // The first camera is the one.
        }
        let camera = self.resolve(required_attr(inst, "url")?, "instance_camera")?;
        let cid = camera.attribute("id").unwrap_or("?");
        let persp = child(camera, "optics")
            .and_then(|o| child(o, "technique_common"))
            .and_then(|t| child(t, "perspective"))
            .ok_or_else(|| Error::new(format!("camera '{cid}' has no perspective optics")))?;
        let value = |name: &str| {
            child(persp, name)
                .map(|n| single_number(n, &format!("camera '{cid}' {name}")))
                .transpose()
        };
        let (xfov, yfov, aspect) = (value("xfov")?, value("yfov")?, value("aspect_ratio")?);
        let half_tan = |deg: f32| (deg.to_radians() / 2.0).tan();
        let from_tan = |t: f32| 2.0 * t.atan().to_degrees();
        let (hfov, vfov) = match (xfov, yfov, aspect) {
            (Some(x), Some(y), _) => (x, y),
            (Some(x), None, Some(a)) if a > 0.0 => (x, from_tan(half_tan(x) / a)),
            (None, Some(y), Some(a)) if a > 0.0 => (from_tan(half_tan(y) * a), y),
            _ => bail!("camera '{cid}' needs xfov or yfov and a positive aspect_ratio"),
        };
        if !(hfov > 0.0 && hfov < 180.0 && vfov > 0.0 && vfov < 180.0) {
            bail!("camera '{cid}': field of view {hfov} x {vfov} degrees is not in (0, 180)");
        }
        // The course renderer reads the view direction as the transformed point (0, 0, -1):
        // the translation leaks in. Reproduced as SCENE_FORMAT.md says.
        let view_dir = world.transform_point3(Vec3::NEG_Z).normalize_or(Vec3::NEG_Z);
        self.camera = Some(CameraDesc { hfov_deg: hfov, vfov_deg: vfov, view_dir });
        Ok(())
    }
}

/// Whether every number of a light is finite.
pub fn light_is_finite(light: &Light) -> bool {
    match *light {
        Light::Area { position, direction, dim_x, dim_y, radiance } => {
            [position, direction, dim_x, dim_y, radiance].iter().all(|v| v.is_finite())
        }
        Light::Point { position, radiance } => position.is_finite() && radiance.is_finite(),
        Light::Directional { direction, radiance } => direction.is_finite() && radiance.is_finite(),
        Light::Ambient { radiance } => radiance.is_finite(),
    }
}
