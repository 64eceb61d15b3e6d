//! Attachments: garment particles that follow animated targets. An attached particle is pinned
//! (the solver never moves it); before every substep it is placed where its target is at the
//! end of that substep, so the cloth is pulled after it by its springs and tethers.
//!
//! Targets: a keyframed rigid motion (translation and rotation about a pivot, linear between
//! keys: a curtain rail sliding, a box turning), or a point on a character's skin: at the bind
//! frame the particle is tied to the nearest point of the nearest triangle by barycentric
//! coordinates, and its offset from that point is kept in the skin's frame there (the smooth
//! normal interpolated from the welded vertices' normals, and the triangle's first edge
//! turned into the tangent plane), so it rides the skin as the skin moves and turns.
//!
//! The smooth normal, not the triangle's own: a waistband sits a few centimetres off the skin,
//! and two neighbouring particles bound to the two triangles of a crease (a low-poly hip) would
//! swing apart with the triangles' normals as the crease folds: two waistband particles of a
//! skirt on CesiumMan's walk came 150 % further apart than at rest with facet frames, 51 % with
//! smooth ones. The smooth normal is continuous across the crease, so neighbours stay
//! neighbours.

use crate::garment::Garment;
use crate::mesh::{welded_normals, Weld};
use crate::scene::{GarmentSpec, KeyframeSpec};
use glam::{EulerRot, Quat, Vec3};

/// What an attached particle follows.
#[derive(Clone, Debug)]
pub enum Target {
    /// The particle's rest position carried by track `track`.
    Keyframed { track: usize, rest: Vec3 },
    /// A point of mesh `mesh`'s triangle `triangle` plus an offset in the skin's frame there.
    Surface {
        mesh: usize,
        triangle: [u32; 3],
        bary: Vec3,
        offset: Vec3,
    },
}

/// One attached particle (storage index) and its target.
#[derive(Clone, Debug)]
pub struct Attachment {
    pub particle: u32,
    pub target: Target,
}

/// A rigid motion over time.
#[derive(Clone, Debug)]
pub struct Track {
    pub pivot: Vec3,
    /// (time [s], translation, rotation), times increasing.
    pub keys: Vec<(f32, Vec3, Quat)>,
}

impl Track {
    /// The motion of `keys` about `pivot`.
    pub fn new(keys: &[KeyframeSpec], pivot: Vec3) -> Track {
        Track {
            pivot,
            keys: keys
                .iter()
                .map(|k| {
                    let [x, y, z] = k.rotation.map(f32::to_radians);
                    (
                        k.time,
                        Vec3::from(k.translation),
                        Quat::from_euler(EulerRot::XYZ, x, y, z),
                    )
                })
                .collect(),
        }
    }

    /// Rotation (about the pivot) and translation at time `t` (held before the first and after
    /// the last key).
    pub fn pose(&self, t: f32) -> (Quat, Vec3) {
        let i = self.keys.partition_point(|k| k.0 <= t);
        if i == 0 {
            (self.keys[0].2, self.keys[0].1)
        } else if i == self.keys.len() {
            (self.keys[i - 1].2, self.keys[i - 1].1)
        } else {
            let (a, b) = (self.keys[i - 1], self.keys[i]);
            let w = (t - a.0) / (b.0 - a.0);
            (a.2.slerp(b.2, w), a.1.lerp(b.1, w))
        }
    }

    /// Where the motion takes point `p` at time `t`.
    pub fn apply(&self, p: Vec3, t: f32) -> Vec3 {
        let (rotation, translation) = self.pose(t);
        self.pivot + rotation * (p - self.pivot) + translation
    }
}

/// A character's skin over the bake's frames (frame 0 at the start), for surface targets.
#[derive(Clone, Debug)]
pub struct Skin {
    pub name: String,
    pub triangles: Vec<[u32; 3]>,
    pub frames: Vec<Vec<Vec3>>,
    /// The vertices in the character's bind pose, where garments modelled on it bind.
    pub bind: Option<Vec<Vec3>>,
    /// The welding of the first frame, for the smooth normals.
    weld: Weld,
    /// The vertices of the triangles targets ride, ascending ([`Skin::ride`]).
    ridden: Vec<u32>,
    /// Their smooth normals on each frame: `normals[frame][k]` for `ridden[k]`.
    normals: Vec<Vec<Vec3>>,
}

impl Skin {
    /// A skin of `triangles` over `frames`, bound in `bind` when garments are modelled on it.
    pub fn new(
        name: String,
        triangles: Vec<[u32; 3]>,
        frames: Vec<Vec<Vec3>>,
        bind: Option<Vec<Vec3>>,
    ) -> Skin {
        let weld = frames.first().map(|f| Weld::of(f)).unwrap_or_default();
        Skin {
            name,
            triangles,
            frames,
            bind,
            weld,
            ridden: Vec::new(),
            normals: Vec::new(),
        }
    }

    /// Keeps, frame by frame, the smooth normals of the vertices of `triangles` (the ones
    /// targets ride), and only those: a skin of 50 000 vertices over 1 000 frames would
    /// otherwise hold 600 MB of normals for a waistband's few hundred. Each is summed from its
    /// slot's triangles in triangle order, as [`welded_normals`] sums it, to the same bits.
    fn ride(&mut self, triangles: impl Iterator<Item = [u32; 3]>) {
        let mut ridden: Vec<u32> = triangles.flatten().collect();
        ridden.sort_unstable();
        ridden.dedup();
        let (start, faces) = self.weld.slot_faces(&self.triangles);
        self.normals = (self.frames.iter())
            .map(|vertices| {
                (ridden.iter())
                    .map(|&v| {
                        let slot = self.weld.slot[v as usize] as usize;
                        (faces[start[slot] as usize..start[slot + 1] as usize].iter())
                            .map(|&t| {
                                let [a, b, c] =
                                    self.triangles[t as usize].map(|i| vertices[i as usize]);
                                (b - a).cross(c - a)
                            })
                            .fold(Vec3::ZERO, |sum, n| sum + n)
                            .normalize_or_zero()
                    })
                    .collect()
            })
            .collect();
        self.ridden = ridden;
    }

    /// Frames `k` and `j` around fractional frame `f` and the weight of `j` (held after the
    /// last).
    pub fn span(&self, f: f32) -> (usize, usize, f32) {
        let k = (f.floor().max(0.0) as usize).min(self.frames.len() - 1);
        let j = (k + 1).min(self.frames.len() - 1);
        (k, j, (f - k as f32).clamp(0.0, 1.0))
    }

    /// How many vertices targets ride ([`Skin::ride`]).
    pub fn ridden_count(&self) -> usize {
        self.ridden.len()
    }

    /// Frame `frame`'s ridden vertices, ascending: position and smooth normal of each.
    pub fn ridden_at(&self, frame: usize) -> impl Iterator<Item = (Vec3, Vec3)> + '_ {
        (self.ridden.iter().zip(&self.normals[frame]))
            .map(move |(&v, &n)| (self.frames[frame][v as usize], n))
    }

    /// The point at `bary` on `triangle` and the skin's frame there at fractional frame `f`.
    fn surface(&self, triangle: [u32; 3], bary: Vec3, f: f32) -> (Vec3, [Vec3; 3]) {
        let (k, j, w) = self.span(f);
        let at =
            |frames: &[Vec<Vec3>], v: u32| frames[k][v as usize].lerp(frames[j][v as usize], w);
        let corners = triangle.map(|v| at(&self.frames, v));
        let normals = triangle.map(|v| {
            let r = self.ridden.binary_search(&v).expect("a ridden vertex") as u32;
            at(&self.normals, r)
        });
        surface_frame(corners, normals, bary)
    }

    /// The smooth normals of `vertices` (the bind pose or one frame) with the skin's welding.
    fn normals_of(&self, vertices: &[Vec3]) -> Vec<Vec3> {
        welded_normals(vertices, &self.triangles, &self.weld)
    }
}

/// The point at `bary` of a triangle with `corners` and an orthonormal frame there: the first
/// edge turned into the tangent plane, the in-plane perpendicular, and the normal interpolated
/// from the corners' smooth `normals` (the facet's where they cancel).
fn surface_frame(corners: [Vec3; 3], normals: [Vec3; 3], bary: Vec3) -> (Vec3, [Vec3; 3]) {
    let [a, b, c] = corners;
    let facet = (b - a).cross(c - a).normalize_or(Vec3::Y);
    let n = (normals[0] * bary.x + normals[1] * bary.y + normals[2] * bary.z).normalize_or(facet);
    let edge = b - a;
    let e = (edge - n * edge.dot(n)).normalize_or(n.any_orthonormal_vector());
    (a * bary.x + b * bary.y + c * bary.z, [e, n.cross(e), n])
}

/// An attachment that rides a skin, as a backend that places it itself reads it: its
/// triangle's corners are indices into the skin's ridden vertices ([`Skin::ridden_at`]).
#[derive(Clone, Copy, Debug)]
pub struct Riding {
    pub particle: u32,
    pub skin: u32,
    pub corners: [u32; 3],
    pub bary: Vec3,
    /// The offset in the skin's frame at the point (tangent, bitangent, normal) [m].
    pub offset: Vec3,
}

/// Every attachment of a simulation, with the motions and skins they follow.
#[derive(Clone, Debug, Default)]
pub struct Attachments {
    /// The keyframed attachments first, then those that ride a skin (bound after them).
    pub list: Vec<Attachment>,
    pub tracks: Vec<Track>,
    pub skins: Vec<Skin>,
    /// Character attachments still to bind.
    pending: Vec<PendingBinding>,
    /// Particles (storage order) that started inside the body and were bound outside it: the
    /// bake starts them at their targets, so the first substep does not fling them out.
    pub lifted: Vec<u32>,
}

/// A character attachment waiting for the character's skin.
#[derive(Clone, Debug)]
struct PendingBinding {
    garment: String,
    character: String,
    frame: u32,
    /// The garment is `on` this character: bind in its bind pose rather than at `frame`.
    bind_pose: bool,
    /// Particles (storage order) with their rest positions.
    particles: Vec<(u32, Vec3)>,
}

impl Attachments {
    /// The keyframed attachments of `garments` (bound now) and their character attachments
    /// (bound later by [`Attachments::bind_skins`]). `storage` maps a garment's grid index to
    /// its storage index.
    pub fn new(
        specs: &[GarmentSpec],
        garments: &[Garment],
        storage: impl Fn(usize, u32) -> u32,
    ) -> Attachments {
        let mut out = Attachments::default();
        for (g, (spec, garment)) in specs.iter().zip(garments).enumerate() {
            for (a, particles) in spec.attachments.iter().zip(&garment.attached) {
                let rest: Vec<(u32, Vec3)> = particles
                    .iter()
                    .map(|&p| (storage(g, p), garment.positions[p as usize]))
                    .collect();
                match &a.character {
                    Some(name) => out.pending.push(PendingBinding {
                        garment: garment.name.clone(),
                        character: name.clone(),
                        frame: a.frame,
                        bind_pose: spec.on.as_ref() == Some(name),
                        particles: rest,
                    }),
                    None => {
                        let centroid =
                            rest.iter().map(|r| r.1).sum::<Vec3>() / rest.len().max(1) as f32;
                        let pivot = a.pivot.map_or(centroid, Vec3::from);
                        out.tracks.push(Track::new(&a.keyframes, pivot));
                        let track = out.tracks.len() - 1;
                        out.list
                            .extend(rest.into_iter().map(|(particle, rest)| Attachment {
                                particle,
                                target: Target::Keyframed { track, rest },
                            }));
                    }
                }
            }
        }
        out
    }

    /// The keyframed attachments, which lead [`Attachments::list`]: (particle, track, rest
    /// position).
    pub fn keyframed(&self) -> Vec<(u32, usize, Vec3)> {
        (self.list[..self.keyframed_count()].iter())
            .filter_map(|a| match a.target {
                Target::Keyframed { track, rest } => Some((a.particle, track, rest)),
                Target::Surface { .. } => None,
            })
            .collect()
    }

    /// The attachments that ride skins, in [`Attachments::list`]'s order (after the keyframed
    /// ones).
    pub fn riding(&self) -> Vec<Riding> {
        (self.list[self.keyframed_count()..].iter())
            .filter_map(|a| match a.target {
                Target::Surface {
                    mesh,
                    triangle,
                    bary,
                    offset,
                } => {
                    let ridden = &self.skins[mesh].ridden;
                    let corner = |v: u32| ridden.binary_search(&v).expect("a ridden vertex") as u32;
                    Some(Riding {
                        particle: a.particle,
                        skin: mesh as u32,
                        corners: triangle.map(corner),
                        bary,
                        offset,
                    })
                }
                Target::Keyframed { .. } => None,
            })
            .collect()
    }

    /// How many keyframed attachments lead [`Attachments::list`] (the rest ride skins).
    pub fn keyframed_count(&self) -> usize {
        let keyed = (self.list.iter())
            .take_while(|a| matches!(a.target, Target::Keyframed { .. }))
            .count();
        debug_assert!(self.list[keyed..]
            .iter()
            .all(|a| matches!(a.target, Target::Surface { .. })));
        keyed
    }

    /// True when nothing is attached.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty() && self.pending.is_empty()
    }

    /// Names of the characters whose skins attachments still wait for.
    pub fn unbound(&self) -> Vec<String> {
        self.pending.iter().map(|p| p.character.clone()).collect()
    }

    /// Binds the character attachments to `skins`: each particle to the nearest point of the
    /// nearest triangle at its bind frame, or in the character's bind pose for a garment
    /// modelled on it (`on`); one that starts inside the body there 1 mm outside it
    /// (`lifted_out`). Returns a warning for each attachment with particles inside the body,
    /// and for each whose skin carries neighbouring particles apart ([`Spread`]); `frame_start`
    /// numbers the skins' frames for it (their first is the bake's start, before that frame).
    pub fn bind_skins(
        &mut self,
        skins: Vec<Skin>,
        frame_start: u32,
    ) -> Result<Vec<String>, String> {
        let mut warnings = Vec::new();
        // Each attachment's place in `list`, its rest positions and names, to measure once
        // the skins keep their normals.
        let mut groups = Vec::new();
        for PendingBinding {
            garment,
            character: name,
            frame,
            bind_pose,
            particles,
        } in std::mem::take(&mut self.pending)
        {
            let mesh = skins
                .iter()
                .position(|s| s.name == name)
                .ok_or_else(|| format!("character {name:?} has no skin to attach to (its topology changes between frames)"))?;
            let skin = &skins[mesh];
            let f = (frame as usize).min(skin.frames.len() - 1);
            let vertices = match (&skin.bind, bind_pose) {
                (Some(bind), true) => bind,
                _ => &skin.frames[f],
            };
            let normals = skin.normals_of(vertices);
            let rests: Vec<Vec3> = particles.iter().map(|p| p.1).collect();
            let (lifted, lift) = lifted_out(vertices, &skin.triangles, &rests);
            if let Some(w) = lift.warning(&garment, &name) {
                warnings.push(w);
            }
            groups.push((self.list.len(), lifted.clone(), garment, name));
            for ((particle, first), rest) in particles.into_iter().zip(lifted) {
                if rest != first {
                    self.lifted.push(particle);
                }
                let (triangle, _, bary) = nearest_on(vertices, &skin.triangles, rest);
                let corners = triangle.map(|i| vertices[i as usize]);
                let normals = triangle.map(|i| normals[i as usize]);
                let (point, frame) = surface_frame(corners, normals, bary);
                let world = rest - point;
                let offset = Vec3::new(
                    world.dot(frame[0]),
                    world.dot(frame[1]),
                    world.dot(frame[2]),
                );
                self.list.push(Attachment {
                    particle,
                    target: Target::Surface {
                        mesh,
                        triangle,
                        bary,
                        offset,
                    },
                });
            }
        }
        self.skins = skins;
        for (m, skin) in self.skins.iter_mut().enumerate() {
            skin.ride(self.list.iter().filter_map(|a| match a.target {
                Target::Surface { mesh, triangle, .. } if mesh == m => Some(triangle),
                _ => None,
            }));
        }
        for (start, rests, garment, name) in groups {
            let attached = &self.list[start..start + rests.len()];
            warnings.extend(self.spread(attached, &rests).map(|s| {
                let frame = i64::from(frame_start) + s.frame as i64 - 1;
                format!(
                    "garment {garment:?}'s attachment to character {name:?}: the skin its particles follow carries two neighbours {:.1} cm apart to {:.1} cm apart at frame {frame} (+{:.0} %; {} of its {} particles follow skin that moves apart from a neighbour's by more than {:.0} %), which stretches the garment's edge between them: the edge is bound to parts of the body that move apart (an arm beside the hips, a leg and the other): attach fewer particles, or model the edge closer to the skin it should follow",
                    100.0 * s.rest,
                    100.0 * s.farthest,
                    100.0 * (s.farthest / s.rest - 1.0),
                    s.particles,
                    rests.len(),
                    100.0 * SPREAD_WARNING,
                )
            }));
        }
        Ok(warnings)
    }

    /// How the skin carries the `attached` particles (rest positions `rests`) apart over its
    /// frames; None when no two neighbours move apart by more than [`SPREAD_WARNING`] of their
    /// distance, for a single particle, or for more than 5 000 (every pair would be compared).
    fn spread(&self, attached: &[Attachment], rests: &[Vec3]) -> Option<Spread> {
        if rests.len() > 5_000 || rests.len() < 2 {
            return None;
        }
        let Target::Surface { mesh, .. } = attached[0].target else {
            return None;
        };
        let skin = &self.skins[mesh];
        // Neighbours: within 1.5 of the group's spacing (its shortest distance between two).
        let mut spacing = f32::INFINITY;
        for (i, a) in rests.iter().enumerate() {
            for b in &rests[i + 1..] {
                let d = a.distance(*b);
                if d > 1e-6 {
                    spacing = spacing.min(d);
                }
            }
        }
        let mut pairs = Vec::new();
        for (i, a) in rests.iter().enumerate() {
            for (j, b) in rests.iter().enumerate().skip(i + 1) {
                let d = a.distance(*b);
                if d > 1e-6 && d <= 1.5 * spacing {
                    pairs.push((i, j, d));
                }
            }
        }
        let mut worst: Option<Spread> = None;
        let mut spread = vec![false; rests.len()];
        // The frames the bake shows (the first skin frame is its start, before them).
        for frame in 1..skin.frames.len() {
            let targets: Vec<Vec3> = (attached.iter())
                .map(|a| self.position(a, frame as f32, 1.0))
                .collect();
            for &(i, j, rest) in &pairs {
                let apart = targets[i].distance(targets[j]);
                if apart <= (1.0 + SPREAD_WARNING) * rest {
                    continue;
                }
                (spread[i], spread[j]) = (true, true);
                if worst
                    .as_ref()
                    .is_none_or(|w| apart / rest > w.farthest / w.rest)
                {
                    worst = Some(Spread {
                        rest,
                        farthest: apart,
                        frame,
                        particles: 0,
                    });
                }
            }
        }
        worst.map(|w| Spread {
            particles: spread.iter().filter(|&&s| s).count(),
            ..w
        })
    }

    /// Where attachment `a` is at time `t` seconds, `fps` frames per second.
    pub fn position(&self, a: &Attachment, t: f32, fps: f32) -> Vec3 {
        match &a.target {
            Target::Keyframed { track, rest } => self.tracks[*track].apply(*rest, t),
            Target::Surface {
                mesh,
                triangle,
                bary,
                offset,
            } => {
                let (point, [e, f, n]) = self.skins[*mesh].surface(*triangle, *bary, t * fps);
                point + e * offset.x + f * offset.y + n * offset.z
            }
        }
    }
}

/// Held particles that start inside the body they are bound to: how many, and the deepest.
#[derive(Default)]
struct Lift {
    inside: usize,
    deepest: f32,
}

impl Lift {
    /// What the bake says of them, when there are any.
    fn warning(&self, garment: &str, character: &str) -> Option<String> {
        (self.inside > 0).then(|| {
            format!(
                "garment {garment:?}'s attachment to character {character:?}: {} of its particles start inside the body ({:.1} mm deep at the most); each is bound 1 mm outside the nearest skin instead, so it follows the body from outside",
                self.inside,
                self.deepest * 1e3
            )
        })
    }
}

/// How far out of the body a held particle that starts inside it is bound [m].
const LIFTED_CLEAR: f32 = 1e-3;

/// `rests` with those inside the body (`triangles` on `vertices`, by the mesh metric's inside
/// test) moved out along the nearest surface's normal to [`LIFTED_CLEAR`] outside it: a held particle follows its target and nothing pushes it out
/// later, so one bound inside stays inside (a waistband voxelized a centimetre inward of the
/// modelled band).
fn lifted_out(vertices: &[Vec3], triangles: &[[u32; 3]], rests: &[Vec3]) -> (Vec<Vec3>, Lift) {
    let surface = crate::collide::mesh::Surface::new(vertices, triangles);
    // On an open mesh, as the metric does: inside only within its reach of the surface (far
    // from it, a pseudonormal at a hole's rim says nothing of inside).
    let reach = match surface.closed() {
        true => f32::INFINITY,
        false => crate::collide::mesh::REACH,
    };
    let mut lift = Lift::default();
    let lifted = (rests.iter())
        .zip(surface.nearest_signed(rests))
        .map(|(&rest, n)| {
            if n.distance >= 0.0 || -n.distance > reach {
                return rest;
            }
            lift.inside += 1;
            lift.deepest = lift.deepest.max(-n.distance);
            n.point + n.normal * LIFTED_CLEAR
        })
        .collect();
    (lifted, lift)
}

/// The nearest point of `triangles` (on `vertices`) to `p`: its triangle, the point and its
/// barycentric coordinates.
fn nearest_on(vertices: &[Vec3], triangles: &[[u32; 3]], p: Vec3) -> ([u32; 3], Vec3, Vec3) {
    let mut best = (f32::MAX, [0u32; 3], p, Vec3::X);
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i as usize]);
        let bary = crate::collide::mesh::closest_barycentric(p, a, b, c);
        let q = a * bary.x + b * bary.y + c * bary.z;
        let d = q.distance_squared(p);
        if d < best.0 {
            best = (d, *t, q, bary);
        }
    }
    (best.1, best.2, best.3)
}

/// Where the skin an attachment rides carries two neighbouring particles (within 1.5 of the
/// group's spacing at rest) the farthest apart: their distance at rest and at its farthest [m],
/// the skin frame, and how many particles of the group some neighbour moves away from by more
/// than [`SPREAD_WARNING`]. A garment edge bound to two parts of the body that move apart is
/// stretched between them (on CesiumMan a skirt's waistband modelled 5 to 8 cm out was bound to
/// his arm); skin that deforms as it bends carries its neighbours apart by less.
#[derive(Clone, Debug, PartialEq)]
struct Spread {
    rest: f32,
    farthest: f32,
    frame: usize,
    particles: usize,
}

/// How much farther apart than at rest the skin may carry two attached neighbours before the
/// bind is warned of: the stability rule's 100 %, past which the springs between them are
/// forced (`forced_strain_per_frame`). Skin that bends stretches less: over their clips the
/// shipped attachments' neighbours move apart by 0.0 % (the robot's capes), 1.1 % (`top_walk`),
/// 17.7 % (`cape_walk`) and 44.8 % (`skirt_walk`'s waistband, over his hips), where the same
/// skirt widened 1.5 × is bound partly to his arms and its neighbours move 791 % apart.
const SPREAD_WARNING: f32 = 1.0;

#[cfg(test)]
mod tests {
    use super::*;

    /// Particles 0 and 1 at `rests`, waiting to bind to the skin of "body" at frame 0.
    fn band_of_two(rests: [Vec3; 2]) -> Attachments {
        Attachments {
            pending: vec![PendingBinding {
                garment: "band".into(),
                character: "body".into(),
                frame: 0,
                bind_pose: false,
                particles: vec![(0, rests[0]), (1, rests[1])],
            }],
            ..Attachments::default()
        }
    }

    /// A strip of two panels meeting along the z axis, each panel folded up by `angle` about
    /// it (a valley, like a hip crease closing).
    fn hinge(angle: f32) -> Vec<Vec3> {
        let (c, s) = (angle.cos(), angle.sin());
        [-0.3f32, 0.0, 0.3]
            .iter()
            .flat_map(|&x| [-0.5f32, 0.5].map(|z| Vec3::new(x * c, x.abs() * s, z)))
            .collect()
    }

    #[test]
    fn neighbours_either_side_of_a_folding_crease_stay_neighbours() {
        // Vertices: 0, 1 at x = -0.3; 2, 3 on the crease; 4, 5 at x = 0.3 (z = -0.5, 0.5).
        let triangles = vec![[0, 1, 3], [0, 3, 2], [2, 3, 5], [2, 5, 4]];
        let folded = 45f32.to_radians();
        let frames = vec![hinge(0.0), hinge(folded)];
        let up = |t: [u32; 3]| {
            let [a, b, c] = t.map(|i| frames[0][i as usize]);
            (b - a).cross(c - a).y
        };
        assert!(triangles.iter().all(|&t| up(t) > 0.0), "the strip faces +Y");
        // Two particles 3 cm above the skin, 1 cm either side of the crease.
        let rests = [Vec3::new(-0.01, 0.03, 0.0), Vec3::new(0.01, 0.03, 0.0)];
        let mut attachments = band_of_two(rests);
        let skin = Skin::new("body".into(), triangles.clone(), frames.clone(), None);
        assert_eq!(
            attachments.bind_skins(vec![skin], 1).unwrap(),
            Vec::<String>::new()
        );
        let at = |frame: f32| {
            let [a, b] = [0, 1].map(|i| attachments.position(&attachments.list[i], frame, 1.0));
            (a, b)
        };
        let (a0, b0) = at(0.0);
        assert!(a0.distance(rests[0]) < 1e-6 && b0.distance(rests[1]) < 1e-6);
        let (a1, b1) = at(1.0);
        // The skin points they ride, 1 cm either side of the crease along the folded panels.
        let (c, s) = (folded.cos(), folded.sin());
        let skin = [
            Vec3::new(-0.01 * c, 0.01 * s, 0.0),
            Vec3::new(0.01 * c, 0.01 * s, 0.0),
        ];
        let apart = skin[0].distance(skin[1]);
        let smooth = a1.distance(b1);
        // Each offset kept along its own facet's normal instead.
        let facet = [Vec3::new(s, c, 0.0), Vec3::new(-s, c, 0.0)];
        let (fa, fb) = (skin[0] + facet[0] * 0.03, skin[1] + facet[1] * 0.03);
        assert!(
            a1.x < b1.x && (smooth - apart).abs() < 0.25 * apart,
            "smooth frames: {a1} and {b1}, {smooth} m apart, riding skin {apart} m apart"
        );
        assert!(
            fa.x > fb.x && (fa.distance(fb) - apart).abs() > 0.25 * apart,
            "facet frames would keep them too ({fa}, {fb}): the case tests nothing"
        );
    }

    /// Two particles 2 cm apart bound 3 cm over two separate patches of skin: warned of only
    /// when the patches move apart (carrying the particles' targets from 2 cm to 5 cm apart,
    /// in the second frame), not when they move together, turned and carried away.
    #[test]
    fn an_attachment_whose_skin_carries_neighbours_apart_is_warned_of() {
        // Two unit-square patches in the plane y = 0, facing up, 2 cm apart.
        let patch = |x: f32| {
            [[0.0, 0.0], [0.01, 0.0], [0.0, 0.01], [0.01, 0.01]]
                .map(|[dx, dz]| Vec3::new(x + dx, 0.0, dz))
        };
        let [a, b] = [patch(-0.015), patch(0.005)];
        let rest: Vec<Vec3> = a.iter().chain(&b).copied().collect();
        let triangles = vec![[0, 2, 1], [1, 2, 3], [4, 6, 5], [5, 6, 7]];
        let particles = [Vec3::new(-0.01, 0.03, 0.005), Vec3::new(0.01, 0.03, 0.005)];
        let warned = |second: Vec<Vec3>| {
            let mut attachments = band_of_two(particles);
            let frames = vec![rest.clone(), second];
            let skin = Skin::new("body".into(), triangles.clone(), frames, None);
            attachments.bind_skins(vec![skin], 1001).unwrap()
        };
        let apart: Vec<Vec3> = (rest.iter().enumerate())
            .map(|(i, &v)| if i < 4 { v } else { v + Vec3::X * 0.03 })
            .collect();
        let warnings = warned(apart);
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert!(
            warnings[0].contains("2.0 cm apart to 5.0 cm apart at frame 1001 (+150 %; 2 of its 2"),
            "{}",
            warnings[0]
        );
        let turn = glam::Quat::from_rotation_z(1.0);
        let carried = rest.iter().map(|&v| turn * v + Vec3::splat(0.3)).collect();
        assert_eq!(warned(carried), Vec::<String>::new());
    }

    #[test]
    fn a_held_particle_inside_the_body_is_bound_just_outside_it() {
        // A closed 20 cm cube, its top face at y = 0.2, outward-facing triangles.
        let v: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32) * 0.2)
            .collect();
        let triangles = vec![
            [0, 4, 6],
            [0, 6, 2],
            [1, 3, 7],
            [1, 7, 5], // x = 0, x = 0.2
            [0, 1, 5],
            [0, 5, 4],
            [2, 6, 7],
            [2, 7, 3], // y = 0, y = 0.2
            [0, 2, 3],
            [0, 3, 1],
            [4, 5, 7],
            [4, 7, 6], // z = 0, z = 0.2
        ];
        // One 3 mm below the top face (inside), one 2 cm above it.
        let rests = [Vec3::new(0.1, 0.197, 0.1), Vec3::new(0.1, 0.22, 0.1)];
        let mut attachments = band_of_two(rests);
        let skin = Skin::new("body".into(), triangles, vec![v.clone(), v], None);
        let warnings = attachments.bind_skins(vec![skin], 1).unwrap();
        assert_eq!(warnings.len(), 1, "{warnings:?}");
        assert_eq!(
            attachments.lifted,
            vec![0],
            "the bake starts it at its target"
        );
        assert!(
            warnings[0].contains("1 of its particles start inside")
                && warnings[0].contains("3.0 mm")
        );
        let at = |i: usize| attachments.position(&attachments.list[i], 0.0, 1.0);
        assert!(
            (at(0) - Vec3::new(0.1, 0.2 + LIFTED_CLEAR, 0.1)).length() < 1e-5,
            "{}",
            at(0)
        );
        assert!(
            (at(1) - rests[1]).length() < 1e-5,
            "outside: where it was, {}",
            at(1)
        );
    }
}
