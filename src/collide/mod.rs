//! Collisions with analytic shapes (plane, sphere, axis-aligned box, capsule), resolved by
//! projection after each solve.
//!
//! A particle closer to a surface than its contact radius (half the cloth thickness) is pushed out
//! along the surface normal, then Coulomb friction acts on its motion over the step: tangential
//! motion smaller than μ × the push is removed (static friction), larger motion is shortened by
//! μ × the push (kinetic friction), as position-based friction does (Macklin et al. 2014, §6.1).

pub mod particles;
pub mod shell;

pub use shell::ShellCollider;

use crate::scene::{ColliderKind, ColliderSpec};
use glam::{Vec3, Vec4};

/// An analytic shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// Solid half-space below the plane n·x = offset (n unit length).
    Plane { normal: Vec3, offset: f32 },
    /// Solid ball.
    Sphere { center: Vec3, radius: f32 },
    /// Solid axis-aligned box.
    Box { center: Vec3, half: Vec3 },
    /// Solid capsule around the segment `start`–`end`.
    Capsule { start: Vec3, end: Vec3, radius: f32 },
}

/// A static collider with its friction coefficient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Collider {
    pub shape: Shape,
    pub friction: f32,
}

/// Particles inside one collider at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Penetration {
    /// Particles whose centre lies inside the solid (signed distance below zero).
    pub inside: usize,
    /// Deepest such particle below the surface [m] (0 when none).
    pub deepest: f32,
}

impl Collider {
    /// Builds a collider from its (validated) scene spec.
    pub fn from_spec(spec: &ColliderSpec) -> Collider {
        let shape = match spec.kind {
            ColliderKind::Plane => {
                let normal = Vec3::from(spec.normal.unwrap_or([0.0, 1.0, 0.0])).normalize();
                let point = Vec3::from(spec.point.unwrap_or([0.0; 3]));
                Shape::Plane {
                    normal,
                    offset: normal.dot(point),
                }
            }
            ColliderKind::Sphere => Shape::Sphere {
                center: Vec3::from(spec.center.expect("validated")),
                radius: spec.radius.expect("validated"),
            },
            ColliderKind::Box => Shape::Box {
                center: Vec3::from(spec.center.expect("validated")),
                half: Vec3::from(spec.size.expect("validated")) * 0.5,
            },
            ColliderKind::Capsule => Shape::Capsule {
                start: Vec3::from(spec.start.expect("validated")),
                end: Vec3::from(spec.end.expect("validated")),
                radius: spec.radius.expect("validated"),
            },
        };
        Collider {
            shape,
            friction: spec.friction,
        }
    }

    /// Signed distance of `p` from the surface (negative inside) and the outward normal there.
    #[inline]
    pub fn distance(&self, p: Vec3) -> (f32, Vec3) {
        match self.shape {
            Shape::Plane { normal, offset } => (normal.dot(p) - offset, normal),
            Shape::Sphere { center, radius } => ball_distance(p - center, radius),
            Shape::Box { center, half } => box_distance(p - center, half),
            Shape::Capsule { start, end, radius } => {
                let axis = end - start;
                let t = ((p - start).dot(axis) / axis.length_squared().max(1e-12)).clamp(0.0, 1.0);
                ball_distance(p - (start + axis * t), radius)
            }
        }
    }

    /// Resolves a particle that starts the step at `x` and moves by `delta`: pushes it out to
    /// `radius` from the surface and applies friction to its motion over the step. Returns the
    /// corrected displacement (unchanged, bit for bit, when there is no contact).
    #[inline]
    pub fn resolve(&self, x: Vec4, delta: Vec4, radius: f32) -> Vec4 {
        let (dist, n) = self.distance((x + delta).truncate());
        let push = radius - dist;
        if push <= 0.0 {
            return delta;
        }
        let motion = delta.truncate() + n * push;
        let tangent = motion - n * motion.dot(n);
        let t_len = tangent.length();
        let limit = self.friction * push;
        let motion = if t_len <= limit {
            motion - tangent
        } else {
            motion - tangent * (limit / t_len)
        };
        motion.extend(0.0)
    }
}

/// Distance from a ball of `radius` at the origin to `d`, and the outward normal (+Y at the
/// centre).
#[inline]
fn ball_distance(d: Vec3, radius: f32) -> (f32, Vec3) {
    let len = d.length();
    let n = if len > 1e-12 { d / len } else { Vec3::Y };
    (len - radius, n)
}

/// Signed distance from an axis-aligned box of half extents `half` at the origin to `p`, and the
/// outward normal: towards the nearest point outside, along the nearest face's axis inside.
#[inline]
fn box_distance(p: Vec3, half: Vec3) -> (f32, Vec3) {
    let q = p.abs() - half;
    let outside = q.max(Vec3::ZERO);
    let out_len = outside.length();
    if out_len > 0.0 {
        return (out_len, (outside * p.signum()) / out_len);
    }
    // Inside: the face with the largest (least negative) q is nearest.
    let axis = if q.x >= q.y && q.x >= q.z {
        0
    } else if q.y >= q.z {
        1
    } else {
        2
    };
    let mut n = Vec3::ZERO;
    n[axis] = if p[axis] >= 0.0 { 1.0 } else { -1.0 };
    (q[axis], n)
}

/// Penetration of the particles `q` into each collider.
pub fn penetrations(colliders: &[Collider], q: &[Vec4]) -> Vec<Penetration> {
    colliders
        .iter()
        .map(|c| {
            let mut p = Penetration::default();
            for qi in q {
                let (d, _) = c.distance(qi.truncate());
                if d < 0.0 {
                    p.inside += 1;
                    p.deepest = p.deepest.max(-d);
                }
            }
            p
        })
        .collect()
}
