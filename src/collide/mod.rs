//! Collisions with analytic shapes (plane, sphere, box, capsule, funnel, wedge), resolved by
//! projection after each solve.
//!
//! A particle closer to a surface than its contact radius (half the cloth thickness) is pushed out
//! along the surface normal, then Coulomb friction acts on its motion over the step: tangential
//! motion smaller than μ × the push is removed (static friction), larger motion is shortened by
//! μ × the push (kinetic friction), as position-based friction does (Macklin et al. 2014, §6.1).
//!
//! The colliders act before the characters' shells. Where a shell then pushes a particle back
//! into a collider, the particle is *pressed* between the two ([`INTO_COLLIDER`]): the collider
//! keeps it off its surface and the skin carries it along it ([`pressed_motion`]).

pub mod crossings;
pub mod mesh;
pub mod particles;
pub mod shell;
pub mod skin;

pub use shell::ShellCollider;

use crate::scene::{ColliderShape, ColliderSpec};
use glam::{EulerRot, Quat, Vec2, Vec3, Vec4};

/// Primes of the spatial hash of a grid cell (Teschner et al. 2003), one set for every grid
/// (the shells' and particle collisions'; `HASH_X`, `HASH_Y` and `HASH_Z` in
/// `shaders/common.wgsl`, checked by `tests/shaders.rs`).
pub const HASH_PRIMES: [i32; 3] = [73_856_093, 19_349_663, 83_492_791];

/// The spatial hash of cell `c` (wrapping 32-bit products, as the GPU computes them:
/// `hash_cell` in `shaders/common.wgsl`).
#[inline]
pub fn hash_cell(c: [i32; 3]) -> u32 {
    (c[0].wrapping_mul(HASH_PRIMES[0])
        ^ c[1].wrapping_mul(HASH_PRIMES[1])
        ^ c[2].wrapping_mul(HASH_PRIMES[2])) as u32
}

/// The lattice cell of a point already divided by the cell's width (`p / cell`, in either
/// vector type: each lane's quotient is the same number): `floor()` per lane as `i32`, without a
/// call to the C library's `floorf` (the default x86-64 target has no SSE4.1 rounding
/// instruction), equal for every input, NaN and out-of-range values included (the shells' grids
/// and the particle collisions' share it).
#[inline]
pub fn floor_cell(q: impl Into<glam::Vec3A>) -> glam::IVec3 {
    let q: glam::Vec3A = q.into();
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of every x86-64 target.
    unsafe {
        use std::arch::x86_64::*;
        // The three lanes at once while each is a number below 2³¹ in size, where truncation
        // is exact and the scalar conversion's saturation never applies (the rest below):
        // truncate, then one less where that rounded up (negative fractions). Three scalar
        // conversions with their checks were a fifth of placing a shell.
        let v: __m128 = q.into();
        let size = _mm_andnot_ps(_mm_set1_ps(-0.0), v);
        if _mm_movemask_ps(_mm_cmple_ps(size, _mm_set1_ps(2_147_483_520.0))) & 7 == 7 {
            let truncated = _mm_cvttps_epi32(v);
            let above = _mm_cmplt_ps(v, _mm_cvtepi32_ps(truncated));
            let cell: [i32; 4] =
                std::mem::transmute(_mm_add_epi32(truncated, _mm_castps_si128(above)));
            return glam::IVec3::new(cell[0], cell[1], cell[2]);
        }
    }
    let floor = |x: f32| {
        let i = x as i32;
        i.saturating_sub((x < i as f32) as i32)
    };
    glam::IVec3::new(floor(q.x), floor(q.y), floor(q.z))
}

/// The part of `motion` along the surface (unit normal `n`) that Coulomb friction removes:
/// all of it up to `limit` (μ × the push: static friction), `limit` of it beyond (kinetic
/// friction). The one definition for colliders and shells (`friction_removed` in
/// `shaders/common.wgsl` is its twin).
#[inline(always)]
pub fn friction_removed(motion: Vec3, n: Vec3, limit: f32) -> Vec3 {
    let tangent = motion - n * motion.dot(n);
    let t_len = tangent.length();
    if t_len <= limit {
        tangent
    } else {
        tangent * (limit / t_len)
    }
}

/// A garment particle that the shells push deeper into an analytic collider than this share of
/// its contact radius is *pressed* between the skin and the collider (a back lying on a cape on
/// the floor, a thigh on a skirt on a stool). Pushed from both sides in turn, the skin's push
/// along its normal, which leans sideways where a body meets a floor, would squeeze the cloth
/// out sideways a little every substep and tear its springs (a robot falling onto its cape
/// stretched a spring 144 % in 15 frames). Instead the collider keeps the particle as far from
/// its surface as its own push left it, and along the surface the skin carries it by friction
/// ([`pressed_motion`]). `INTO_COLLIDER` in `shaders/finish.wgsl` is its twin.
pub const INTO_COLLIDER: f32 = 0.05;

/// The deepest any of `colliders` holds point `p` within `radius` of its surface (radius less
/// the distance; at most 0 when it is clear of all of them; −∞ without colliders), with that
/// collider's surface normal there (the first collider's on a tie).
#[inline]
pub fn deepest(colliders: &[Collider], p: Vec3, radius: f32) -> (f32, Vec3) {
    colliders
        .iter()
        .fold((f32::NEG_INFINITY, Vec3::Y), |best, c| {
            let (distance, n) = c.distance(p);
            if radius - distance > best.0 {
                (radius - distance, n)
            } else {
                best
            }
        })
}

/// When the shells, moving a particle at `x` from displacement `before` (where the colliders
/// left it) to `after`, pushed it deeper into a collider than [`INTO_COLLIDER`] of its contact
/// `radius`: that collider's surface normal where it now is. A move shorter than that cannot
/// have (an exact distance, the plane's, sphere's and capsule's, changes no faster than the
/// point moves; the others come close), and is not tested.
#[inline]
pub fn pressed_into(
    colliders: &[Collider],
    x: Vec4,
    before: Vec4,
    after: Vec4,
    radius: f32,
) -> Option<Vec3> {
    let allowed = INTO_COLLIDER * radius;
    if colliders.is_empty() || (after - before).length_squared() <= allowed * allowed {
        return None;
    }
    let depth = |d: Vec4| deepest(colliders, (x + d).truncate(), radius);
    let (now, n) = depth(after);
    (now > depth(before).0.max(0.0) + allowed).then_some(n)
}

/// The displacement of a particle pressed between a skin and a collider whose surface normal
/// is `n` ([`INTO_COLLIDER`]): `before` (where the colliders left it), less what friction with
/// the skin removes of its motion relative to the skin along the surface (`skin`: the skin's
/// motion where it presses, `squeeze`: how deep, `friction`: its coefficient). Across the
/// surface the collider decides; along it the skin carries the cloth it lies on, as far as
/// friction on the squeeze holds it.
#[inline]
pub fn pressed_motion(before: Vec4, n: Vec3, (skin, squeeze, friction): (Vec3, f32, f32)) -> Vec4 {
    let relative = before.truncate() - skin;
    before - friction_removed(relative, n, friction * squeeze).extend(0.0)
}

/// An analytic shape.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    /// Solid half-space below the plane n·x = offset (n unit length).
    Plane { normal: Vec3, offset: f32 },
    /// Solid ball.
    Sphere { centre: Vec3, radius: f32 },
    /// Solid box, turned by `rotation` about its centre (identity: axis-aligned).
    Box {
        centre: Vec3,
        half: Vec3,
        rotation: Quat,
    },
    /// Solid capsule around the segment `start`–`end`.
    Capsule { start: Vec3, end: Vec3, radius: f32 },
    /// Upright funnel wall: points within `half_thickness` of the cone frustum from the circle
    /// of `radius` at `centre` to the circle of `top_radius` at `height` above it.
    Funnel {
        centre: Vec3,
        radius: f32,
        top_radius: f32,
        height: f32,
        half_thickness: f32,
    },
    /// Solid triangular prism, blade down: top face `half.x` × 2 wide at `half.y` above the
    /// centre, blade at `half.y` below, `half.z` × 2 long; turned by `rotation`.
    Wedge {
        centre: Vec3,
        half: Vec3,
        rotation: Quat,
    },
}

/// A collider with its friction coefficient.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Collider {
    pub shape: Shape,
    pub friction: f32,
    /// How far the collider moved over the current substep [m] (zero when static): the swept
    /// test follows particles relative to it.
    pub moved: Vec3,
    /// Test the path of each particle over the substep, not only its end.
    pub swept: bool,
}

impl Shape {
    /// The reference point a keyframed motion turns the shape about.
    pub fn centre(&self) -> Vec3 {
        match *self {
            Shape::Plane { normal, offset } => normal * offset,
            Shape::Sphere { centre, .. }
            | Shape::Box { centre, .. }
            | Shape::Funnel { centre, .. }
            | Shape::Wedge { centre, .. } => centre,
            Shape::Capsule { start, end, .. } => (start + end) * 0.5,
        }
    }

    /// The shape moved rigidly: turned by `rotation` about `pivot`, then shifted by
    /// `translation`.
    pub fn moved(&self, pivot: Vec3, rotation: Quat, translation: Vec3) -> Shape {
        let point = |p: Vec3| pivot + rotation * (p - pivot) + translation;
        match *self {
            Shape::Plane { normal, offset } => {
                let n = rotation * normal;
                Shape::Plane {
                    normal: n,
                    offset: n.dot(point(normal * offset)),
                }
            }
            Shape::Sphere { centre, radius } => Shape::Sphere {
                centre: point(centre),
                radius,
            },
            Shape::Box {
                centre,
                half,
                rotation: r,
            } => Shape::Box {
                centre: point(centre),
                half,
                rotation: rotation * r,
            },
            Shape::Capsule { start, end, radius } => Shape::Capsule {
                start: point(start),
                end: point(end),
                radius,
            },
            // A funnel stays upright: it follows the translation (its keyframed rotation is
            // rejected by validation).
            Shape::Funnel { centre, .. } => {
                let mut funnel = *self;
                if let Shape::Funnel { centre: c, .. } = &mut funnel {
                    *c = point(centre);
                }
                funnel
            }
            Shape::Wedge {
                centre,
                half,
                rotation: r,
            } => Shape::Wedge {
                centre: point(centre),
                half,
                rotation: rotation * r,
            },
        }
    }
}

/// Particles inside one collider at one instant.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Penetration {
    /// Particles whose centre lies inside the solid (signed distance below zero).
    pub inside: usize,
    /// Deepest such particle below the surface [m] (0 when none).
    pub deepest: f32,
}

impl Penetration {
    /// One particle `depth` inside (none when it is not above zero).
    pub fn of_depth(depth: f32) -> Penetration {
        Penetration {
            inside: (depth > 0.0) as usize,
            deepest: depth.max(0.0),
        }
    }

    /// Both counts together: the sum of the particles inside, the deeper of the two.
    pub fn merge(a: Penetration, b: Penetration) -> Penetration {
        Penetration {
            inside: a.inside + b.inside,
            deepest: a.deepest.max(b.deepest),
        }
    }
}

impl Collider {
    /// Builds a collider from its (validated) scene spec.
    pub fn from_spec(spec: &ColliderSpec) -> Collider {
        let v = Vec3::from;
        let shape = match spec.shape {
            ColliderShape::Plane { point, normal } => {
                let normal = v(normal.unwrap_or([0.0, 1.0, 0.0])).normalize();
                Shape::Plane {
                    normal,
                    offset: normal.dot(v(point.unwrap_or([0.0; 3]))),
                }
            }
            ColliderShape::Sphere { centre, radius } => Shape::Sphere {
                centre: v(centre),
                radius,
            },
            ColliderShape::Box {
                centre,
                size,
                rotation,
            } => Shape::Box {
                centre: v(centre),
                half: v(size) * 0.5,
                rotation: turn(rotation),
            },
            ColliderShape::Wedge {
                centre,
                size,
                rotation,
            } => Shape::Wedge {
                centre: v(centre),
                half: v(size) * 0.5,
                rotation: turn(rotation),
            },
            ColliderShape::Funnel {
                centre,
                radius,
                top_radius,
                height,
                thickness,
            } => Shape::Funnel {
                centre: v(centre),
                radius,
                top_radius,
                height,
                half_thickness: 0.5 * thickness.unwrap_or(0.01),
            },
            ColliderShape::Capsule { start, end, radius } => Shape::Capsule {
                start: v(start),
                end: v(end),
                radius,
            },
        };
        Collider {
            shape,
            friction: spec.friction,
            moved: Vec3::ZERO,
            swept: true,
        }
    }

    /// True when [`Collider::distance`] is the exact distance to the surface (planes, spheres,
    /// capsules), so it changes no faster than the point moves.
    fn exact(&self) -> bool {
        matches!(
            self.shape,
            Shape::Plane { .. } | Shape::Sphere { .. } | Shape::Capsule { .. }
        )
    }

    /// True for a collider that stands still, with the swept test and an exact distance: its
    /// [`Collider::resolve`] returns the displacement unchanged when the particle starts
    /// farther from it than it moves (a floor, for cloth that never comes near it).
    pub fn is_quiet(&self) -> bool {
        self.swept && self.exact() && self.moved == Vec3::ZERO
    }

    /// Signed distance of `p` from the surface (negative inside) and the outward normal there.
    #[inline]
    pub fn distance(&self, p: Vec3) -> (f32, Vec3) {
        match self.shape {
            Shape::Plane { normal, offset } => (normal.dot(p) - offset, normal),
            Shape::Sphere { centre, radius } => ball_distance(p - centre, radius),
            Shape::Box {
                centre,
                half,
                rotation,
            } => {
                let (d, n) = box_distance(rotation.inverse() * (p - centre), half);
                (d, rotation * n)
            }
            Shape::Capsule { start, end, radius } => {
                let axis = end - start;
                let t = ((p - start).dot(axis) / axis.length_squared().max(1e-12)).clamp(0.0, 1.0);
                ball_distance(p - (start + axis * t), radius)
            }
            Shape::Funnel {
                centre,
                radius,
                top_radius,
                height,
                half_thickness,
            } => funnel_distance(p - centre, radius, top_radius, height, half_thickness),
            Shape::Wedge {
                centre,
                half,
                rotation,
            } => {
                let (d, n) = wedge_distance(rotation.inverse() * (p - centre), half);
                (d, rotation * n)
            }
        }
    }

    /// Resolves a particle that starts the step at `x` and moves by `delta`: pushes it out to
    /// `radius` from the surface and applies friction to its motion over the step. With the swept
    /// test on, a particle whose path (relative to the collider) enters the solid part-way is
    /// stopped where it first touches, so a thin or fast collider cannot be passed through.
    /// Returns the corrected displacement (unchanged, bit for bit, when there is no contact).
    #[inline]
    pub fn resolve(&self, x: Vec4, delta: Vec4, radius: f32) -> Vec4 {
        let mut delta = delta;
        if self.swept && self.exact() {
            // Farther from the surface than the path is long: no point of it comes within
            // `radius` (an exact distance changes no faster than the point moves), so neither
            // test below can act: the answer they give, without their second distance.
            let (x3, d3) = (x.truncate(), delta.truncate());
            if self.distance(x3 + self.moved).0 - radius >= (d3 - self.moved).length() {
                return delta;
            }
        }
        if self.swept {
            if let Some(s) = self.first_contact(x.truncate(), delta.truncate(), radius) {
                // Stop at the touching point of the path, carried along with the collider.
                delta = (delta.truncate() * s + self.moved * (1.0 - s)).extend(0.0);
            }
        }
        let (dist, n) = self.distance((x + delta).truncate());
        let push = radius - dist;
        if push <= 0.0 {
            return delta;
        }
        let motion = delta.truncate() + n * push;
        (motion - friction_removed(motion, n, self.friction * push)).extend(0.0)
    }

    /// The fraction of the step at which a particle starting at `x` (outside) and moving by
    /// `delta` first comes within `radius` of the surface, following its path relative to the
    /// collider (sphere tracing), when the path then goes into the solid and the end point has
    /// passed back out (so the end-point test alone would miss it). None otherwise.
    #[inline]
    fn first_contact(&self, x: Vec3, delta: Vec3, radius: f32) -> Option<f32> {
        // Relative to the collider's pose at the end of the step, the particle goes from
        // x + moved to x + delta.
        let at = |s: f32| x + delta * s + self.moved * (1.0 - s);
        let length = (delta - self.moved).length();
        let (start, n0) = self.distance(at(0.0));
        let start = start - radius;
        // Far away, or barely moving: the end-point test is enough.
        if start >= length || length < 1e-9 {
            return None;
        }
        let (end, n1) = self.distance(at(1.0));
        if end < radius {
            return None; // ends inside: the push-out handles it
        }
        if start <= 0.0 {
            // Touching at the start and clear at the end: through the solid if the surface
            // faces the other way there.
            return (n0.dot(n1) < 0.0).then_some(0.0);
        }
        // March to where the path first comes within `radius` of the surface, then on to see
        // whether it enters the solid itself: a path that only grazes the contact layer (a
        // chord across a curved surface) is left to the end-point test, so cloth still slides.
        let mut s = 0.0f32;
        let mut touch = None;
        for _ in 0..64 {
            let d = self.distance(at(s)).0;
            match touch {
                None if d - radius <= 1e-6 => touch = Some(s),
                Some(t) if d <= 0.0 => return Some(t),
                _ => {}
            }
            let gap = if touch.is_none() { d - radius } else { d };
            s += gap.max(1e-4 * radius) / length;
            if s >= 1.0 {
                return None;
            }
        }
        None
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

/// Rotation from Euler degrees (X, then Y, then Z); none gives the identity.
fn turn(degrees: Option<[f32; 3]>) -> Quat {
    degrees.map_or(Quat::IDENTITY, |r| {
        let [x, y, z] = r.map(f32::to_radians);
        Quat::from_euler(EulerRot::XYZ, x, y, z)
    })
}

/// Closest point to `q` on the segment `a`–`b` (2-D).
#[inline]
fn closest_on_segment(q: Vec2, a: Vec2, b: Vec2) -> Vec2 {
    let ab = b - a;
    let t = ((q - a).dot(ab) / ab.length_squared().max(1e-12)).clamp(0.0, 1.0);
    a + ab * t
}

/// Signed distance from an upright funnel wall at the origin to `p`, and the outward normal:
/// in the half-plane (r, y) through `p` and the axis, the wall is the segment from (radius, 0)
/// to (top_radius, height), thickened by `half_thickness`.
#[inline]
fn funnel_distance(
    p: Vec3,
    radius: f32,
    top_radius: f32,
    height: f32,
    half_thickness: f32,
) -> (f32, Vec3) {
    let r = (p.x * p.x + p.z * p.z).sqrt();
    let radial = if r > 1e-9 {
        Vec3::new(p.x / r, 0.0, p.z / r)
    } else {
        Vec3::X
    };
    let (a, b) = (Vec2::new(radius, 0.0), Vec2::new(top_radius, height));
    let q = Vec2::new(r, p.y);
    let off = q - closest_on_segment(q, a, b);
    let len = off.length();
    let n2 = if len > 1e-9 {
        off / len
    } else {
        // On the wall's middle surface: the side facing away from the axis.
        let e = (b - a).normalize();
        Vec2::new(e.y, -e.x)
    };
    (len - half_thickness, radial * n2.x + Vec3::Y * n2.y)
}

/// Signed distance from a wedge of half extents `half` at the origin (blade down, along Z) to
/// `p`, and the outward normal: the triangle's 2-D distance in XY extruded along Z.
#[inline]
fn wedge_distance(p: Vec3, half: Vec3) -> (f32, Vec3) {
    // Triangle counter-clockwise: blade, top right, top left.
    let corners = [
        Vec2::new(0.0, -half.y),
        Vec2::new(half.x, half.y),
        Vec2::new(-half.x, half.y),
    ];
    let q = Vec2::new(p.x, p.y);
    let mut best = (f32::MAX, Vec2::ZERO, Vec2::Y);
    let mut inside = true;
    for k in 0..3 {
        let (a, b) = (corners[k], corners[(k + 1) % 3]);
        let e = b - a;
        let outward = Vec2::new(e.y, -e.x).normalize();
        inside &= (q - a).dot(outward) <= 0.0;
        let c = closest_on_segment(q, a, b);
        let d = q.distance_squared(c);
        if d < best.0 {
            best = (d, c, outward);
        }
    }
    let (d2, c, edge_normal) = best;
    let d2 = d2.sqrt();
    let n2 = if d2 > 1e-9 {
        if inside {
            (c - q) / d2
        } else {
            (q - c) / d2
        }
    } else {
        edge_normal
    };
    let flat = if inside { -d2 } else { d2 };
    let along = p.z.abs() - half.z;
    let z = Vec3::Z * if p.z >= 0.0 { 1.0 } else { -1.0 };
    if flat <= 0.0 && along <= 0.0 {
        // Inside: the nearer of the side faces and the end caps.
        return if flat >= along {
            (flat, Vec3::new(n2.x, n2.y, 0.0))
        } else {
            (along, z)
        };
    }
    let (u, v) = (flat.max(0.0), along.max(0.0));
    let d = (u * u + v * v).sqrt();
    (d, (Vec3::new(n2.x, n2.y, 0.0) * u + z * v) / d)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn floor() -> Vec<Collider> {
        vec![Collider {
            shape: Shape::Plane {
                normal: Vec3::Y,
                offset: 0.0,
            },
            friction: 0.5,
            moved: Vec3::ZERO,
            swept: true,
        }]
    }

    /// A particle on the floor (contact radius 5 mm, resting at its radius) that a skin moves
    /// from `before` to `after`.
    fn pressed(before: Vec3, after: Vec3) -> Option<Vec3> {
        let x = Vec4::new(0.0, 0.005, 0.0, 0.0);
        pressed_into(&floor(), x, before.extend(0.0), after.extend(0.0), 0.005)
    }

    #[test]
    fn a_skin_pushing_cloth_into_the_floor_presses_it_and_one_pushing_it_along_does_not() {
        // 1 mm down: a fifth of the radius, past the twentieth allowed.
        assert_eq!(
            pressed(Vec3::ZERO, Vec3::new(0.0, -0.001, 0.0)),
            Some(Vec3::Y)
        );
        // Down by less than a twentieth of the radius, along the floor, or up: not pressed.
        assert_eq!(pressed(Vec3::ZERO, Vec3::new(0.0, -0.0002, 0.0)), None);
        assert_eq!(pressed(Vec3::ZERO, Vec3::new(0.01, 0.0, 0.0)), None);
        assert_eq!(pressed(Vec3::ZERO, Vec3::new(0.0, 0.004, 0.0)), None);
        // Deeper than the colliders left it counts from there (they left it 1 mm in).
        let sunk = Vec3::new(0.0, -0.001, 0.0);
        assert_eq!(pressed(sunk, sunk + Vec3::new(0.0, -0.0002, 0.0)), None);
        assert_eq!(
            pressed(sunk, sunk + Vec3::new(0.0, -0.001, 0.0)),
            Some(Vec3::Y)
        );
        // Without colliders nothing is pressed.
        let x = Vec4::new(0.0, 0.005, 0.0, 0.0);
        assert_eq!(pressed_into(&[], x, Vec4::ZERO, -Vec4::Y, 0.005), None);
    }

    #[test]
    fn pressed_cloth_keeps_its_height_and_moves_with_the_skin_as_far_as_friction_holds() {
        let before = Vec4::new(0.0, 0.0002, 0.0, 0.0);
        // Skin moving 1 mm along x and 3 mm down, pressing 4 mm: μ × squeeze = 2 mm holds it.
        let skin = Vec3::new(0.001, -0.003, 0.0);
        let d = pressed_motion(before, Vec3::Y, (skin, 0.004, 0.5));
        assert!(
            (d - Vec4::new(0.001, 0.0002, 0.0, 0.0)).length() < 1e-9,
            "{d}"
        );
        // Skin moving 5 mm along x: friction holds 2 mm of the 5 mm it slips.
        let fast = Vec3::new(0.005, 0.0, 0.0);
        let d = pressed_motion(before, Vec3::Y, (fast, 0.004, 0.5));
        assert!(
            (d - Vec4::new(0.002, 0.0002, 0.0, 0.0)).length() < 1e-9,
            "{d}"
        );
    }
}
