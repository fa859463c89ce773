//! Reading XML elements: children by name, attributes, and numbers, each failure one line.

use glam::Vec3;
use roxmltree::Node;

use crate::{bail, Error, Result};

pub(super) fn child<'a, 'i>(node: Node<'a, 'i>, name: &str) -> Option<Node<'a, 'i>> {
    node.children().find(|c| c.is_element() && c.tag_name().name() == name)
}

pub(super) fn element_children<'a, 'i>(
    node: Node<'a, 'i>,
    name: &'static str,
) -> impl Iterator<Item = Node<'a, 'i>> {
    node.children().filter(move |c| c.is_element() && c.tag_name().name() == name)
}

pub(super) fn required_attr<'a>(node: Node<'a, '_>, name: &str) -> Result<&'a str> {
    node.attribute(name).ok_or_else(|| {
        Error::new(format!("<{}> has no '{name}' attribute", node.tag_name().name()))
    })
}

pub(super) fn parse_attr<T: std::str::FromStr>(node: Node, name: &str) -> Result<Option<T>> {
    node.attribute(name)
        .map(|v| {
            v.trim().parse().map_err(|_| {
                Error::new(format!(
                    "<{}> {name}='{v}' is not a valid number",
                    node.tag_name().name()
                ))
            })
        })
        .transpose()
}

/// Whitespace-separated finite numbers; NaN and infinities are rejected by name.
pub(super) fn numbers(node: Node, what: &str) -> Result<Vec<f32>> {
    node.text()
        .unwrap_or("")
        .split_ascii_whitespace()
        .map(|t| match t.parse::<f32>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => bail!("{what}: '{t}' is not a finite number"),
            Err(_) => bail!("{what}: '{t}' is not a number"),
        })
        .collect()
}

pub(super) fn single_number(node: Node, what: &str) -> Result<f32> {
    match numbers(node, what)?.as_slice() {
        [v] => Ok(*v),
        v => bail!("{what}: expected one number, found {}", v.len()),
    }
}

/// The first three numbers of a colour (a fourth, alpha, is ignored). Every colour the
/// dialect has (reflectances, transmittances, radiances, a conductor's eta and k) is
/// non-negative: a negative component is an error, not light taken away.
pub(super) fn rgb(node: Node, what: &str) -> Result<Vec3> {
    let v = numbers(node, what)?;
    if v.len() < 3 {
        bail!("{what}: expected 3 numbers, found {}", v.len());
    }
    if let Some(c) = v[..3].iter().find(|c| **c < 0.0) {
        bail!("{what}: {c} is negative");
    }
    Ok(Vec3::new(v[0], v[1], v[2]))
}

/// Non-negative integer indices.
pub(super) fn integers(node: Node, what: &str) -> Result<Vec<u32>> {
    node.text()
        .unwrap_or("")
        .split_ascii_whitespace()
        .map(|t| {
            t.parse::<u32>().map_err(|_| {
                Error::new(format!("<{what}>: '{t}' is not a non-negative integer index"))
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use roxmltree::Document;

    #[test]
    fn colours_reject_negative_components() {
        let doc = Document::parse("<a>0.5 -0.25 1 1</a>").unwrap();
        let e = rgb(doc.root_element(), "diffuse color").unwrap_err().to_string();
        assert!(e.contains("diffuse color: -0.25 is negative"), "{e}");
        let doc = Document::parse("<a>0.5 0 1 -1</a>").unwrap();
        assert_eq!(
            rgb(doc.root_element(), "c").unwrap(),
            Vec3::new(0.5, 0.0, 1.0),
            "alpha is ignored"
        );
    }

    #[test]
    fn numbers_reject_nan_and_words() {
        let doc = Document::parse("<a>1 nan 2</a>").unwrap();
        assert!(numbers(doc.root_element(), "x")
            .unwrap_err()
            .to_string()
            .contains("not a finite number"));
        let doc = Document::parse("<a>1 two</a>").unwrap();
        assert!(numbers(doc.root_element(), "x").unwrap_err().to_string().contains("not a number"));
    }
}
