//! Analytic colliders in a scene: a typed shape per kind ([`ColliderShape`]) with the fields that
//! kind needs, so nothing downstream unwraps an option. The file keeps its flat form (`"kind"`
//! beside every field); parsing checks that each given field belongs to the kind and that the
//! required ones are there, naming the field (`colliders[0].radius`) when not.

use super::KeyframeSpec;
use serde::{Deserialize, Serialize};

/// Shape of an analytic collider.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ColliderKind {
    /// Half-space: everything below the plane through `point` with normal `normal` is solid.
    Plane,
    /// Solid sphere of `radius` around `centre`.
    Sphere,
    /// Solid axis-aligned box of `size` around `centre`.
    Box,
    /// Solid capsule: every point within `radius` of the segment from `start` to `end`.
    Capsule,
    /// A funnel (thesis §5.3.5): an upright cone frustum wall of `thickness`, its spout of
    /// `radius` centred on `centre`, widening to `top_radius` at `height` above it; open at both
    /// ends, so cloth can fall through.
    Funnel,
    /// A wedge: a triangular prism with its blade down, `size` = [width of the top face, height,
    /// length along Z] around `centre`, turned by `rotation`.
    Wedge,
}

/// A static or keyframed analytic collider.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(try_from = "ColliderFields", into = "ColliderFields")]
pub struct ColliderSpec {
    pub shape: ColliderShape,
    /// A keyframed rigid motion of the collider about its centre (a plane's point, a capsule's
    /// midpoint), linear between keys, held after the last. Default none (static).
    pub keyframes: Vec<KeyframeSpec>,
    /// Coulomb friction coefficient against this collider. Default 0.5.
    pub friction: f32,
}

/// A collider's shape and the fields of its kind [m; rotations in Euler degrees X, Y, Z about
/// the centre].
#[derive(Clone, Debug, PartialEq)]
pub enum ColliderShape {
    /// Default point: the origin; default normal: [0, 1, 0] (normalised by drape).
    Plane {
        point: Option<[f32; 3]>,
        normal: Option<[f32; 3]>,
    },
    Sphere {
        centre: [f32; 3],
        radius: f32,
    },
    /// Edge lengths `size` along X, Y, Z; default rotation none (axis-aligned).
    Box {
        centre: [f32; 3],
        size: [f32; 3],
        rotation: Option<[f32; 3]>,
    },
    Capsule {
        start: [f32; 3],
        end: [f32; 3],
        radius: f32,
    },
    /// Wall `thickness` default 0.01.
    Funnel {
        centre: [f32; 3],
        radius: f32,
        top_radius: f32,
        height: f32,
        thickness: Option<f32>,
    },
    Wedge {
        centre: [f32; 3],
        size: [f32; 3],
        rotation: Option<[f32; 3]>,
    },
}

impl ColliderShape {
    pub fn kind(&self) -> ColliderKind {
        match self {
            ColliderShape::Plane { .. } => ColliderKind::Plane,
            ColliderShape::Sphere { .. } => ColliderKind::Sphere,
            ColliderShape::Box { .. } => ColliderKind::Box,
            ColliderShape::Capsule { .. } => ColliderKind::Capsule,
            ColliderShape::Funnel { .. } => ColliderKind::Funnel,
            ColliderShape::Wedge { .. } => ColliderKind::Wedge,
        }
    }
}

impl ColliderKind {
    /// The kind with an article, and the fields it takes.
    fn fields(self) -> (&'static str, &'static [&'static str]) {
        match self {
            ColliderKind::Plane => ("a plane", &["point", "normal"]),
            ColliderKind::Sphere => ("a sphere", &["centre", "radius"]),
            ColliderKind::Box => ("a box", &["centre", "size", "rotation"]),
            ColliderKind::Capsule => ("a capsule", &["start", "end", "radius"]),
            ColliderKind::Funnel => (
                "a funnel",
                &["centre", "radius", "top_radius", "height", "thickness"],
            ),
            ColliderKind::Wedge => ("a wedge", &["centre", "size", "rotation"]),
        }
    }
}

/// Why fields do not make a collider: `.field: reason` (the leading dot tells the scene parser
/// to add the field to the error's path).
fn refuse(field: &str, reason: String) -> String {
    format!(".{field}: {reason}")
}

impl TryFrom<ColliderFields> for ColliderSpec {
    type Error = String;

    fn try_from(c: ColliderFields) -> Result<ColliderSpec, String> {
        let kind = c
            .kind
            .ok_or_else(|| refuse("kind", "every collider needs a kind".into()))?;
        let (name, allowed) = kind.fields();
        let given = [
            ("point", c.point.is_some()),
            ("normal", c.normal.is_some()),
            ("centre", c.centre.is_some()),
            ("radius", c.radius.is_some()),
            ("size", c.size.is_some()),
            ("start", c.start.is_some()),
            ("end", c.end.is_some()),
            ("rotation", c.rotation.is_some()),
            ("top_radius", c.top_radius.is_some()),
            ("height", c.height.is_some()),
            ("thickness", c.thickness.is_some()),
        ];
        if let Some((field, _)) = given.iter().find(|(f, set)| *set && !allowed.contains(f)) {
            return Err(refuse(
                field,
                format!("{name} takes {}, not {field}", allowed.join(", ")),
            ));
        }
        let need3 = |v: Option<[f32; 3]>, field: &str| {
            v.ok_or_else(|| refuse(field, format!("{name} needs {field}")))
        };
        let need = |v: Option<f32>, field: &str| {
            let what = if field == "radius" { "a radius" } else { field };
            v.ok_or_else(|| refuse(field, format!("{name} needs {what}")))
        };
        let shape = match kind {
            ColliderKind::Plane => ColliderShape::Plane {
                point: c.point,
                normal: c.normal,
            },
            ColliderKind::Sphere => ColliderShape::Sphere {
                centre: need3(c.centre, "centre")?,
                radius: need(c.radius, "radius")?,
            },
            ColliderKind::Box => ColliderShape::Box {
                centre: need3(c.centre, "centre")?,
                size: need3(c.size, "size")?,
                rotation: c.rotation,
            },
            ColliderKind::Wedge => ColliderShape::Wedge {
                centre: need3(c.centre, "centre")?,
                size: need3(c.size, "size")?,
                rotation: c.rotation,
            },
            ColliderKind::Capsule => ColliderShape::Capsule {
                start: need3(c.start, "start")?,
                end: need3(c.end, "end")?,
                radius: need(c.radius, "radius")?,
            },
            ColliderKind::Funnel => ColliderShape::Funnel {
                centre: need3(c.centre, "centre")?,
                radius: need(c.radius, "radius")?,
                top_radius: need(c.top_radius, "top_radius")?,
                height: need(c.height, "height")?,
                thickness: c.thickness,
            },
        };
        Ok(ColliderSpec {
            shape,
            keyframes: c.keyframes,
            friction: c.friction,
        })
    }
}

impl From<ColliderSpec> for ColliderFields {
    fn from(c: ColliderSpec) -> ColliderFields {
        let mut f = ColliderFields {
            kind: Some(c.shape.kind()),
            keyframes: c.keyframes,
            friction: c.friction,
            ..ColliderFields::default()
        };
        match c.shape {
            ColliderShape::Plane { point, normal } => (f.point, f.normal) = (point, normal),
            ColliderShape::Sphere { centre, radius } => {
                (f.centre, f.radius) = (Some(centre), Some(radius))
            }
            ColliderShape::Box {
                centre,
                size,
                rotation,
            }
            | ColliderShape::Wedge {
                centre,
                size,
                rotation,
            } => (f.centre, f.size, f.rotation) = (Some(centre), Some(size), rotation),
            ColliderShape::Capsule { start, end, radius } => {
                (f.start, f.end, f.radius) = (Some(start), Some(end), Some(radius))
            }
            ColliderShape::Funnel {
                centre,
                radius,
                top_radius,
                height,
                thickness,
            } => {
                (f.centre, f.radius, f.top_radius, f.height, f.thickness) = (
                    Some(centre),
                    Some(radius),
                    Some(top_radius),
                    Some(height),
                    thickness,
                )
            }
        }
        f
    }
}

/// A collider as the scene file writes it: every kind's fields side by side. Parsing turns it
/// into a [`ColliderSpec`], refusing a field that does not belong to its kind or a required one
/// that is missing.
#[derive(Clone, Debug, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
struct ColliderFields {
    /// `"plane"`, `"sphere"`, `"box"`, `"capsule"`, `"funnel"` or `"wedge"`. Required.
    kind: Option<ColliderKind>,
    /// Plane: a point on the plane [m]. Default the origin.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    point: Option<[f32; 3]>,
    /// Plane: outward normal (normalised by drape). Default [0, 1, 0].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    normal: Option<[f32; 3]>,
    /// Sphere, box: centre [m]. Required for them.
    /// Also read as `center` (drape's keys are spelt as in British English; the American
    /// spelling is accepted).
    #[serde(default, alias = "center", skip_serializing_if = "Option::is_none")]
    centre: Option<[f32; 3]>,
    /// Sphere, capsule: radius [m]. Required for them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    radius: Option<f32>,
    /// Box: edge lengths along X, Y, Z [m]. Required for boxes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    size: Option<[f32; 3]>,
    /// Capsule: the ends of its axis [m]. Required for capsules.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    start: Option<[f32; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    end: Option<[f32; 3]>,
    /// Funnel: radius of the wide top [m]. Required for funnels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    top_radius: Option<f32>,
    /// Funnel: height from the spout to the top [m]. Required for funnels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    height: Option<f32>,
    /// Funnel: wall thickness [m]. Default 0.01.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    thickness: Option<f32>,
    /// Box, wedge: orientation, Euler degrees (X, Y, Z) about its centre. Default none
    /// (axis-aligned).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    rotation: Option<[f32; 3]>,
    /// A keyframed rigid motion of the collider about its centre (a plane's point, a capsule's
    /// midpoint), linear between keys, held after the last. Default none (static).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    keyframes: Vec<KeyframeSpec>,
    /// Coulomb friction coefficient against this collider. Default 0.5.
    #[serde(default = "default_friction")]
    friction: f32,
}

fn default_friction() -> f32 {
    0.5
}
