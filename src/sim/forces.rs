//! Force fields (`forces[]` in the scene): wind on the garments' faces and point attractors,
//! turned into an acceleration per particle at the start of each substep, which the prediction
//! adds beside gravity (t = h·(f·v + (g + a)·h)).
//!
//! Wind, per face of area A and unit normal n, with v the air's velocity relative to the face
//! (the wind at the face's centre minus the mean velocity of its corners):
//! F = ½ ρ A |v| (C_n (v·n) n + C_t (v − (v·n) n)), shared equally by its three particles. The
//! normal term is the pressure on an inclined flat plate: its component along the flow is the
//! face's drag, across the flow its lift; the tangential term is skin friction. A sheet hanging
//! in a steady wind U settles where the normal pressure balances the normal part of its weight
//! (mass per area m): tan φ = ρ C_n U² / (2 m g) from the vertical (`tests/forces.rs`).
//! Gusts are a few travelling waves with seeded directions, lengths and phases: smooth in space
//! and time and the same on every run.
//!
//! Faces are the grid garments' own triangles (sheets, ponchos, curtains, flags); a voxelized
//! mesh garment and a rope have none, and only feel attractors.

use super::model::Model;
use crate::scene::force::{AttractorSpec, ForceSpec, WindSpec};
use glam::{Vec3, Vec4};
use rayon::prelude::*;

/// Travelling waves per gust field.
const GUST_WAVES: usize = 4;

/// The force fields of a simulation, with the faces the wind presses on.
#[derive(Clone, Debug)]
pub struct Forces {
    winds: Vec<Wind>,
    attractors: Vec<AttractorSpec>,
    /// Faces (storage indices of their corners).
    faces: Vec<[u32; 3]>,
    /// Each particle's faces (compressed rows: `face_of[face_start[i]..face_start[i + 1]]`).
    face_start: Vec<u32>,
    face_of: Vec<u32>,
    /// Each face's force of the current substep [N] (a buffer kept between substeps).
    face_force: Vec<Vec3>,
}

#[derive(Clone, Debug)]
struct Wind {
    spec: WindSpec,
    waves: Vec<Wave>,
}

/// One travelling wave of a gust field: amplitude · sin(k·x − ω·t + phase).
#[derive(Clone, Copy, Debug)]
struct Wave {
    amplitude: Vec3,
    k: Vec3,
    omega: f32,
    phase: f32,
}

/// SplitMix64: the seeded random numbers of the gusts.
fn next(state: &mut u64) -> f32 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 40) as f32 / (1u64 << 24) as f32
}

fn random_direction(state: &mut u64) -> Vec3 {
    loop {
        let v = Vec3::new(next(state), next(state), next(state)) * 2.0 - Vec3::ONE;
        let l = v.length_squared();
        if l > 1e-4 && l <= 1.0 {
            return v / l.sqrt();
        }
    }
}

impl Wind {
    fn new(spec: &WindSpec) -> Wind {
        let waves = spec
            .turbulence
            .as_ref()
            .map(|t| {
                let mut state = 0x6472_6170_6500_0000 ^ t.seed as u64;
                (0..GUST_WAVES)
                    .map(|_| {
                        let length = t.scale * (0.7 + 0.8 * next(&mut state));
                        let period = t.period * (0.7 + 0.8 * next(&mut state));
                        Wave {
                            k: random_direction(&mut state) * (std::f32::consts::TAU / length),
                            amplitude: random_direction(&mut state)
                                * (t.strength / GUST_WAVES as f32),
                            omega: std::f32::consts::TAU / period,
                            phase: std::f32::consts::TAU * next(&mut state),
                        }
                    })
                    .collect()
            })
            .unwrap_or_default();
        Wind {
            spec: spec.clone(),
            waves,
        }
    }

    /// The steady part at time `t` [s]: `velocity`, or the keyframes interpolated.
    fn steady(&self, t: f32) -> Vec3 {
        let keys = &self.spec.keyframes;
        match keys.iter().position(|k| k.time > t) {
            None if keys.is_empty() => Vec3::from(self.spec.velocity),
            None => Vec3::from(keys[keys.len() - 1].velocity),
            Some(0) => Vec3::from(keys[0].velocity),
            Some(j) => {
                let (a, b) = (&keys[j - 1], &keys[j]);
                let w = (t - a.time) / (b.time - a.time);
                Vec3::from(a.velocity).lerp(Vec3::from(b.velocity), w)
            }
        }
    }

    /// The air's velocity at `x` [m] and time `t` [s], with `steady` = [`Wind::steady`].
    fn at(&self, steady: Vec3, x: Vec3, t: f32) -> Vec3 {
        self.waves.iter().fold(steady, |v, w| {
            v + w.amplitude * (w.k.dot(x) - w.omega * t + w.phase).sin()
        })
    }
}

/// The force fields of a running simulation: the fields, their acceleration of each particle in
/// the current substep, and the work they have done so far.
#[derive(Default)]
pub(super) struct FieldState {
    /// Wind and attractors, when the scene has force fields.
    pub(super) fields: Option<Forces>,
    /// Their acceleration of each particle in the current substep (empty without).
    pub(super) external: Vec<Vec4>,
    /// Work the force fields have done on the garments so far, the positive part of each
    /// substep's [J] (energy supplied, for the stability rule).
    pub(super) work: f64,
}

impl FieldState {
    /// Adds the positive part of the work `external` did on particles of `mass` moving at
    /// `velocities` over a substep of `h` seconds (each moved by v·h: Σ m a·v h).
    pub(super) fn add_substep_work(&mut self, velocities: &[Vec4], mass: &[f32], h: f64) {
        let work: f64 = (self.external.iter().zip(velocities))
            .zip(mass)
            .map(|((a, v), &m)| m as f64 * a.dot(*v) as f64 * h)
            .sum();
        self.work += work.max(0.0);
    }
}

impl Forces {
    /// The fields of `specs` on `model`'s garments; None without any.
    pub fn new(specs: &[ForceSpec], model: &Model) -> Option<Forces> {
        if specs.is_empty() {
            return None;
        }
        let mut forces = Forces {
            winds: Vec::new(),
            attractors: Vec::new(),
            faces: Vec::new(),
            face_start: Vec::new(),
            face_of: Vec::new(),
            face_force: Vec::new(),
        };
        for s in specs {
            match s {
                ForceSpec::Wind(w) => forces.winds.push(Wind::new(w)),
                ForceSpec::Attractor(a) => forces.attractors.push(a.clone()),
            }
        }
        forces.set_faces(model);
        Some(forces)
    }

    /// Takes `model`'s faces afresh (after tearing removed some).
    pub fn set_faces(&mut self, model: &Model) {
        self.faces.clear();
        if !self.winds.is_empty() {
            for g in model.garments.iter().filter(|g| g.embedding.is_none()) {
                let storage = |v: u32| model.storage_of[g.export.start + v as usize];
                self.faces
                    .extend(g.triangles.iter().map(|t| t.map(storage)));
            }
        }
        let n = model.particle_count();
        let mut count = vec![0u32; n + 1];
        for f in &self.faces {
            for &i in f {
                count[i as usize + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let mut next = count.clone();
        self.face_of = vec![0; self.faces.len() * 3];
        for (k, f) in self.faces.iter().enumerate() {
            for &i in f {
                self.face_of[next[i as usize] as usize] = k as u32;
                next[i as usize] += 1;
            }
        }
        self.face_start = count;
        self.face_force = vec![Vec3::ZERO; self.faces.len()];
    }

    /// The fields as the GPU reads them (`shaders/forces.wgsl`).
    pub fn gpu_tables(&self) -> GpuFieldTables {
        let mut rows = self.face_start.clone();
        rows.extend_from_slice(&self.face_of);
        GpuFieldTables {
            faces: self.faces.iter().map(|&[a, b, c]| [a, b, c, 0]).collect(),
            rows,
            winds: (self.winds.iter())
                .map(|w| GpuWind {
                    density: w.spec.density,
                    drag: w.spec.drag,
                    friction: w.spec.friction,
                    waves: w.waves.len() as u32,
                })
                .collect(),
            waves: (self.winds.iter())
                .flat_map(|w| {
                    let mut waves: Vec<GpuWave> = (w.waves.iter())
                        .map(|v| GpuWave {
                            amplitude_phase: v.amplitude.extend(v.phase).to_array(),
                            k_omega: v.k.extend(v.omega).to_array(),
                        })
                        .collect();
                    waves.resize(GUST_WAVES, GpuWave::default());
                    waves
                })
                .collect(),
            attractors: (self.attractors.iter())
                .flat_map(|a| {
                    let p = a.position;
                    [[p[0], p[1], p[2], a.strength], [a.radius, 0.0, 0.0, 0.0]]
                })
                .collect(),
        }
    }

    /// Each wind's steady velocity at time `t` [s] (xyz) with `t` itself (w): what the GPU
    /// reads per substep.
    pub fn steady_at(&self, t: f32) -> Vec<Vec4> {
        self.winds.iter().map(|w| w.steady(t).extend(t)).collect()
    }

    /// Winds.
    pub fn winds(&self) -> usize {
        self.winds.len()
    }

    /// True when the wind has faces to press on.
    pub fn has_faces(&self) -> bool {
        !self.faces.is_empty()
    }

    /// Every particle's acceleration [m/s²] at time `t` [s] from positions `x` and velocities
    /// `v` (storage order) into `out`; zero for particles that never move.
    pub fn accelerations(
        &mut self,
        model: &Model,
        x: &[Vec4],
        v: &[Vec4],
        t: f32,
        out: &mut Vec<Vec4>,
    ) {
        let steady: Vec<Vec3> = self.winds.iter().map(|w| w.steady(t)).collect();
        let winds = &self.winds;
        self.face_force
            .par_iter_mut()
            .zip(&self.faces)
            .with_min_len(1024)
            .for_each(|(force, f)| {
                let [a, b, c] = f.map(|i| x[i as usize].truncate());
                let cross = (b - a).cross(c - a);
                let twice_area = cross.length();
                *force = Vec3::ZERO;
                if twice_area <= 0.0 {
                    return;
                }
                let n = cross / twice_area;
                let centre = (a + b + c) / 3.0;
                let motion = f.iter().map(|&i| v[i as usize].truncate()).sum::<Vec3>() / 3.0;
                for (w, &s) in winds.iter().zip(&steady) {
                    let rel = w.at(s, centre, t) - motion;
                    let normal = rel.dot(n);
                    let tangential = rel - normal * n;
                    let scale = 0.25 * w.spec.density * twice_area * rel.length();
                    *force += scale * (w.spec.drag * normal * n + w.spec.friction * tangential);
                }
            });
        out.resize(x.len(), Vec4::ZERO);
        let (faces, starts, face_force) = (&self.face_of, &self.face_start, &self.face_force);
        let attractors = &self.attractors;
        out.par_iter_mut()
            .enumerate()
            .with_min_len(1024)
            .for_each(|(i, a)| {
                let w = model.inv_mass[i];
                if w == 0.0 {
                    *a = Vec4::ZERO;
                    return;
                }
                let range = starts[i] as usize..starts[i + 1] as usize;
                let push: Vec3 = faces[range].iter().map(|&k| face_force[k as usize]).sum();
                let mut acc = push * (w / 3.0);
                let p = x[i].truncate();
                for at in attractors {
                    let to = Vec3::from(at.position) - p;
                    let d2 = to.length_squared() / (at.radius * at.radius);
                    if d2 < 1.0 && d2 > 0.0 {
                        let fade = (1.0 - d2) * (1.0 - d2);
                        acc += to.normalize() * (at.strength * fade);
                    }
                }
                *a = acc.extend(0.0);
            });
    }
}

/// A wind's constants on the GPU (WGSL `FieldWind`); its waves are `GUST_WAVES` entries of
/// the wave table from `GUST_WAVES` × its index.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuWind {
    pub density: f32,
    pub drag: f32,
    pub friction: f32,
    pub waves: u32,
}

/// One travelling wave of a gust field on the GPU (WGSL `FieldWave`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuWave {
    /// Amplitude [m/s] (xyz) and phase (w).
    pub amplitude_phase: [f32; 4],
    /// Wave vector [1/m] (xyz) and angular frequency [1/s] (w).
    pub k_omega: [f32; 4],
}

/// Every table the GPU's force kernels read.
pub struct GpuFieldTables {
    /// Faces' corners (storage indices; w unused).
    pub faces: Vec<[u32; 4]>,
    /// Each particle's first face entry (particles + 1 words), then the faces' indices.
    pub rows: Vec<u32>,
    pub winds: Vec<GpuWind>,
    /// `GUST_WAVES` per wind (unused ones zero).
    pub waves: Vec<GpuWave>,
    /// Per attractor: position and strength, then radius.
    pub attractors: Vec<[f32; 4]>,
}

/// Waves per gust field, as the GPU lays them out.
pub const GPU_WAVES: usize = GUST_WAVES;
