//! Reading a URDF document into the joints and links the import needs, and
//! finding the chain between two links. XML is read with roxmltree, which
//! refuses document type declarations (so no entity expansion, no external
//! entities); the caller bounds the document's size.
//!
//! Owns [`Urdf`], [`UrdfJoint`] and the chain search. Must not depend on the
//! conversion (it only reads).

use std::collections::{BTreeMap, BTreeSet};

use kinserve_kinematics::Transform;

use crate::error::{ModelError, Result};

/// Kind of a URDF joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum UrdfJointKind {
    /// Rotation about the axis, with limits.
    Revolute,
    /// Rotation about the axis, without limits.
    Continuous,
    /// Translation along the axis.
    Prismatic,
    /// No motion.
    Fixed,
    /// `floating` or `planar`: more than one degree of freedom.
    Unsupported(&'static str),
}

/// One `<joint>`.
#[derive(Clone, Debug)]
pub struct UrdfJoint {
    /// Its `name`.
    pub name: String,
    /// Its `type`.
    pub kind: UrdfJointKind,
    /// The parent link.
    pub parent: String,
    /// The child link.
    pub child: String,
    /// `<origin xyz rpy>`: the child's frame in the parent's at zero motion (m, rad).
    pub origin: Transform,
    /// `<axis xyz>` in the joint frame, normalised (default `1 0 0`).
    pub axis: [f64; 3],
    /// `<limit lower upper>` (rad or m), for revolute and prismatic joints.
    pub limits: Option<(f64, f64)>,
    /// `<mimic joint=…>`: the joint it follows.
    pub mimic: Option<String>,
}

/// The parts of a URDF document the import reads.
#[derive(Clone, Debug)]
pub struct Urdf {
    /// `<robot name>`.
    pub name: String,
    /// Every `<link name>`.
    pub links: BTreeSet<String>,
    /// Every joint, by child link (a link has at most one parent joint).
    pub by_child: BTreeMap<String, UrdfJoint>,
}

fn invalid(field: &str, message: impl Into<String>) -> ModelError {
    ModelError::invalid_field(field, message.into())
}

/// Reads `xml` as URDF. Errors name the element (`joint 'elbow'`) on field `urdf`.
pub fn parse(xml: &str) -> Result<Urdf> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| {
        invalid(
            "urdf",
            format!("not a readable XML document: {e} (document type declarations and entities are not accepted)"),
        )
    })?;
    let robot = doc.root_element();
    if robot.tag_name().name() != "robot" {
        return Err(invalid(
            "urdf",
            format!(
                "not URDF: the root element is <{}>, not <robot>",
                robot.tag_name().name()
            ),
        ));
    }
    let mut links = BTreeSet::new();
    let mut by_child = BTreeMap::new();
    for el in robot.children().filter(|n| n.is_element()) {
        match el.tag_name().name() {
            "link" => {
                links.insert(required(&el, "name", "<link>")?.to_string());
            }
            "joint" => {
                let j = joint(&el)?;
                if let Some(other) = by_child.get(&j.child) {
                    let other: &UrdfJoint = other;
                    return Err(invalid(
                        "urdf",
                        format!(
                            "link '{}' has two parent joints ('{}' and '{}'): a URDF is a tree; remove one",
                            j.child, other.name, j.name
                        ),
                    ));
                }
                by_child.insert(j.child.clone(), j);
            }
            _ => {}
        }
    }
    Ok(Urdf {
        name: robot.attribute("name").unwrap_or("").to_string(),
        links,
        by_child,
    })
}

fn required<'a>(el: &roxmltree::Node<'a, '_>, attr: &str, what: &str) -> Result<&'a str> {
    el.attribute(attr)
        .ok_or_else(|| invalid("urdf", format!("{what} without a '{attr}' attribute")))
}

/// `n` numbers from an attribute such as `xyz="0 0 0.1"`.
fn numbers<const N: usize>(text: &str, what: &str) -> Result<[f64; N]> {
    let mut out = [0.0; N];
    let mut parts = text.split_whitespace();
    for slot in &mut out {
        *slot = parts
            .next()
            .and_then(|p| p.parse::<f64>().ok())
            .filter(|v| v.is_finite() && v.abs() <= 1e9)
            .ok_or_else(|| {
                invalid(
                    "urdf",
                    format!("{what}: '{text}' is not {N} finite numbers of magnitude at most 1e9"),
                )
            })?;
    }
    if parts.next().is_some() {
        return Err(invalid(
            "urdf",
            format!("{what}: '{text}' has more than {N} numbers"),
        ));
    }
    Ok(out)
}

fn child<'a, 'i>(el: &roxmltree::Node<'a, 'i>, tag: &str) -> Option<roxmltree::Node<'a, 'i>> {
    el.children().find(|n| n.has_tag_name(tag))
}

fn joint(el: &roxmltree::Node<'_, '_>) -> Result<UrdfJoint> {
    let name = required(el, "name", "<joint>")?.to_string();
    let what = |part: &str| format!("joint '{name}' {part}");
    let kind = match required(el, "type", &what(""))? {
        "revolute" => UrdfJointKind::Revolute,
        "continuous" => UrdfJointKind::Continuous,
        "prismatic" => UrdfJointKind::Prismatic,
        "fixed" => UrdfJointKind::Fixed,
        "floating" => UrdfJointKind::Unsupported("floating"),
        "planar" => UrdfJointKind::Unsupported("planar"),
        other => {
            return Err(invalid(
                "urdf",
                format!("{}: unknown type '{other}'", what("")),
            ));
        }
    };
    let link = |tag: &str| -> Result<String> {
        child(el, tag)
            .and_then(|n| n.attribute("link"))
            .map(str::to_string)
            .ok_or_else(|| invalid("urdf", format!("{} has no <{tag} link=…>", what(""))))
    };
    let (parent, child_link) = (link("parent")?, link("child")?);
    let origin = match child(el, "origin") {
        None => Transform::IDENTITY,
        Some(o) => {
            let xyz = o
                .attribute("xyz")
                .map_or(Ok([0.0; 3]), |t| numbers(t, &what("origin xyz")))?;
            let rpy = o
                .attribute("rpy")
                .map_or(Ok([0.0; 3]), |t| numbers(t, &what("origin rpy")))?;
            Transform::from_translation_rpy(xyz, rpy)
        }
    };
    // A fixed joint's axis is never used (makers' files write `0 0 0` there).
    let axis = match kind {
        UrdfJointKind::Fixed | UrdfJointKind::Unsupported(_) => [1.0, 0.0, 0.0],
        _ => axis(el, &what("axis"))?,
    };
    let limits = match (kind, child(el, "limit")) {
        (UrdfJointKind::Revolute | UrdfJointKind::Prismatic, Some(l)) => {
            let lo = l
                .attribute("lower")
                .map_or(Ok([0.0]), |t| numbers::<1>(t, &what("limit lower")))?[0];
            let hi = l
                .attribute("upper")
                .map_or(Ok([0.0]), |t| numbers::<1>(t, &what("limit upper")))?[0];
            (lo < hi).then_some((lo, hi))
        }
        _ => None,
    };
    let mimic = child(el, "mimic").map(|m| m.attribute("joint").unwrap_or("?").to_string());
    Ok(UrdfJoint {
        name,
        kind,
        parent,
        child: child_link,
        origin,
        axis,
        limits,
        mimic,
    })
}

fn axis(el: &roxmltree::Node<'_, '_>, what: &str) -> Result<[f64; 3]> {
    let raw = match child(el, "axis").and_then(|a| a.attribute("xyz")) {
        None => return Ok([1.0, 0.0, 0.0]),
        Some(t) => numbers::<3>(t, what)?,
    };
    let norm = raw.iter().map(|v| v * v).sum::<f64>().sqrt();
    if norm < 1e-9 {
        return Err(invalid("urdf", format!("{what} is the zero vector")));
    }
    Ok(raw.map(|v| v / norm))
}

impl Urdf {
    /// The links with no parent joint.
    pub fn roots(&self) -> Vec<&str> {
        self.links
            .iter()
            .filter(|l| !self.by_child.contains_key(*l))
            .map(String::as_str)
            .collect()
    }

    /// The links that are no joint's parent.
    pub fn leaves(&self) -> Vec<&str> {
        let parents: BTreeSet<&str> = self.by_child.values().map(|j| j.parent.as_str()).collect();
        self.links
            .iter()
            .map(String::as_str)
            .filter(|l| !parents.contains(l))
            .collect()
    }

    /// The joints from `base` down to `tip`, in order.
    pub fn chain(&self, base: &str, tip: &str) -> Result<Vec<&UrdfJoint>> {
        for (field, link) in [("base_link", base), ("tip_link", tip)] {
            if !self.links.contains(link) {
                return Err(invalid(
                    field,
                    format!(
                        "no link '{link}' in the URDF (its links: {})",
                        list(self.links.iter().map(String::as_str))
                    ),
                ));
            }
        }
        let mut joints = Vec::new();
        let mut at = tip;
        while at != base {
            let Some(j) = self.by_child.get(at) else {
                return Err(invalid(
                    "tip_link",
                    format!(
                        "link '{tip}' is not below '{base}': choose a tip among the links under the base"
                    ),
                ));
            };
            if joints.len() > self.by_child.len() {
                return Err(invalid("urdf", "the joints form a cycle: a URDF is a tree"));
            }
            joints.push(j);
            at = &j.parent;
        }
        joints.reverse();
        Ok(joints)
    }
}

/// Up to 20 names, comma-separated.
pub fn list<'a>(names: impl Iterator<Item = &'a str>) -> String {
    let all: Vec<&str> = names.collect();
    let mut s = all
        .iter()
        .take(20)
        .map(|n| format!("'{n}'"))
        .collect::<Vec<_>>()
        .join(", ");
    if all.len() > 20 {
        s.push_str(&format!(" and {} more", all.len() - 20));
    }
    s
}
