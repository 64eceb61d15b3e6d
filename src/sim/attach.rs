//! Attachments: garment particles that follow animated targets. An attached particle is pinned
//! (the solver never moves it); before every substep it is placed where its target is at the
//! end of that substep, so the cloth is pulled after it by its springs and tethers.
//!
//! Targets: a keyframed rigid motion (translation and rotation about a pivot, linear between
//! keys: a curtain rail sliding, a box turning), or a point on a character's skin: at the bind
//! frame the particle is tied to the nearest point of the nearest triangle by barycentric
//! coordinates, and its offset from that point is kept in the triangle's own frame (edge,
//! normal), so it rides the skin as the triangle moves and turns.

use crate::garment::Garment;
use crate::scene::{GarmentSpec, KeyframeSpec};
use glam::{EulerRot, Quat, Vec3};

/// What an attached particle follows.
#[derive(Clone, Debug)]
pub enum Target {
    /// The particle's rest position carried by track `track`.
    Keyframed { track: usize, rest: Vec3 },
    /// A point of mesh `mesh`'s triangle `triangle` plus an offset in that triangle's frame.
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
}

impl Skin {
    /// Vertex `v` at fractional frame `f` (linear between frames, held after the last).
    fn vertex(&self, v: u32, f: f32) -> Vec3 {
        let k = (f.floor().max(0.0) as usize).min(self.frames.len() - 1);
        let j = (k + 1).min(self.frames.len() - 1);
        let w = (f - k as f32).clamp(0.0, 1.0);
        self.frames[k][v as usize].lerp(self.frames[j][v as usize], w)
    }
}

/// An orthonormal frame of a triangle: first edge, in-plane perpendicular, normal.
fn triangle_frame(a: Vec3, b: Vec3, c: Vec3) -> [Vec3; 3] {
    let e = (b - a).normalize_or(Vec3::X);
    let n = (b - a).cross(c - a).normalize_or(Vec3::Y);
    [e, n.cross(e), n]
}

/// Every attachment of a simulation, with the motions and skins they follow.
#[derive(Clone, Debug, Default)]
pub struct Attachments {
    pub list: Vec<Attachment>,
    pub tracks: Vec<Track>,
    pub skins: Vec<Skin>,
    /// Character attachments still to bind.
    pending: Vec<PendingBinding>,
}

/// A character attachment waiting for the character's skin.
#[derive(Clone, Debug)]
struct PendingBinding {
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
    /// modelled on it (`on`).
    pub fn bind_skins(&mut self, skins: Vec<Skin>) -> Result<(), String> {
        for PendingBinding {
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
            for (particle, rest) in particles {
                let mut best = (f32::MAX, [0u32; 3], Vec3::X);
                for t in &skin.triangles {
                    let [a, b, c] = t.map(|i| vertices[i as usize]);
                    let bary = crate::collide::mesh::closest_barycentric(rest, a, b, c);
                    let d = (a * bary.x + b * bary.y + c * bary.z).distance_squared(rest);
                    if d < best.0 {
                        best = (d, *t, bary);
                    }
                }
                let (_, triangle, bary) = best;
                let [a, b, c] = triangle.map(|i| vertices[i as usize]);
                let frame = triangle_frame(a, b, c);
                let world = rest - (a * bary.x + b * bary.y + c * bary.z);
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
        Ok(())
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
                let skin = &self.skins[*mesh];
                let [a, b, c] = triangle.map(|v| skin.vertex(v, t * fps));
                let [e, f, n] = triangle_frame(a, b, c);
                a * bary.x + b * bary.y + c * bary.z + e * offset.x + f * offset.y + n * offset.z
            }
        }
    }
}
