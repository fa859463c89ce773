//! Materials: `bind_material` symbols -> effects -> the CGL BSDFs or a diffuse colour.

use std::collections::HashMap;

use glam::Vec3;
use roxmltree::Node;

use super::xml::{child, element_children, rgb, single_number};
use super::Loader;
use crate::scene::Material;
use crate::{bail, Error, Result};

impl<'a, 'input> Loader<'a, 'input> {
    /// The scene material for a primitive's material symbol, resolved through the instance's
    /// `bind_material`. An unbound or absent symbol gets the default 0.5-grey Lambertian.
    pub(super) fn material_for(
        &mut self,
        symbol: Option<&str>,
        bindings: &HashMap<String, String>,
    ) -> Result<u32> {
        let Some(target) = symbol.and_then(|s| bindings.get(s)) else {
            return Ok(self.intern_material("", Material::Diffuse { albedo: Vec3::splat(0.5) }));
        };
        if let Some(&i) = self.materials.get(target.trim_start_matches('#')) {
            return Ok(i);
        }
        let material = self.resolve(target, "instance_material")?;
        let mid = material.attribute("id").unwrap_or("?").to_string();
        let effect_url = child(material, "instance_effect")
            .and_then(|e| e.attribute("url"))
            .ok_or_else(|| Error::new(format!("material '{mid}' has no <instance_effect url>")))?;
        let effect = self.resolve(effect_url, &format!("material '{mid}'"))?;
        let m = effect_material(effect).map_err(|e| {
            e.context(format!("effect '{}'", effect.attribute("id").unwrap_or("?")))
        })?;
        Ok(self.intern_material(&mid, m))
    }

    pub(super) fn intern_material(&mut self, id: &str, m: Material) -> u32 {
        if let Some(&i) = self.materials.get(id) {
            return i;
        }
        self.scene.materials.push(m);
        let i = self.scene.materials.len() as u32 - 1;
        self.materials.insert(id.to_string(), i);
        i
    }
}

/// symbol -> material reference, from `bind_material/technique_common/instance_material`.
pub(super) fn material_bindings(inst: Node) -> HashMap<String, String> {
    child(inst, "bind_material")
        .and_then(|b| child(b, "technique_common"))
        .map(|t| {
            element_children(t, "instance_material")
                .filter_map(|m| {
                    Some((m.attribute("symbol")?.to_string(), m.attribute("target")?.to_string()))
                })
                .collect()
        })
        .unwrap_or_default()
}

/// The BSDF an effect describes: its CGL technique, else the phong/lambert/blinn diffuse colour.
pub(super) fn effect_material(effect: Node) -> Result<Material> {
    if let Some(kind) = cgl_technique(effect).and_then(|t| t.children().find(Node::is_element)) {
        let name = kind.tag_name().name();
        let color = |field: &str| -> Result<Vec3> {
            let n = child(kind, field)
                .ok_or_else(|| Error::new(format!("CGL {name} has no <{field}>")))?;
            rgb(n, &format!("CGL {name} {field}"))
        };
        let scalar = |field: &str, default: f32| -> Result<f32> {
            child(kind, field)
                .map_or(Ok(default), |n| single_number(n, &format!("CGL {name} {field}")))
        };
        return Ok(match name {
            "emission" => Material::Emission { radiance: color("radiance")? },
            "mirror" => Material::Mirror { reflectance: color("reflectance")? },
            "glass" => Material::Glass {
                reflectance: color("reflectance")?,
                transmittance: color("transmittance")?,
                roughness: scalar("roughness", 0.0)?,
                ior: positive(scalar("ior", 1.5)?, "CGL glass ior")?,
            },
            "refraction" => Material::Refraction {
                transmittance: color("transmittance")?,
                roughness: scalar("roughness", 0.0)?,
                ior: positive(scalar("ior", 1.5)?, "CGL refraction ior")?,
            },
            "microfacet" => Material::Microfacet {
                alpha: positive(scalar("alpha", 0.5)?, "CGL microfacet alpha")?,
                eta: color("eta")?,
                k: color("k")?,
            },
            other => bail!("unknown CGL material <{other}>"),
        });
    }
    let diffuse = child(effect, "profile_COMMON")
        .and_then(|p| child(p, "technique"))
        .and_then(|t| {
            t.children().find(|c| matches!(c.tag_name().name(), "phong" | "lambert" | "blinn"))
        })
        .and_then(|s| child(s, "diffuse"))
        .and_then(|d| child(d, "color"));
    let albedo = match diffuse {
        Some(c) => rgb(c, "diffuse color")?,
        None => Vec3::splat(0.5),
    };
    Ok(Material::Diffuse { albedo })
}

pub(super) fn positive(v: f32, what: &str) -> Result<f32> {
    if v > 0.0 {
        Ok(v)
    } else {
        bail!("{what} must be positive, got {v}")
    }
}

/// `extra/technique[@profile='CGL']` of an element. The oldest course files call the profile
/// `CMU462` (the course's earlier name); it means the same.
pub(super) fn cgl_technique<'a, 'i>(node: Node<'a, 'i>) -> Option<Node<'a, 'i>> {
    element_children(node, "extra")
        .flat_map(|e| element_children(e, "technique"))
        .find(|t| matches!(t.attribute("profile"), Some("CGL") | Some("CMU462")))
}
