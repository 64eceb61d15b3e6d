//! The mass-spring cloth of the integrator literature, as a reference beside drape's solver.
//!
//! The same garment drape simulates (particles, structural/shear/bend springs, pins) becomes a
//! force model: Hooke springs with optional dashpots along each spring, gravity, linear drag and
//! wind. [`integrate`] advances it with explicit Euler, midpoint, RK4, Verlet, linearised implicit
//! Euler (conjugate gradients) and Projective Dynamics, all over the same model in f64, so that
//! differences between them are differences between methods, not between models or precision.
//! [`spectrum`] estimates the highest frequency ω_max that bounds the explicit methods' step.
//! The integrator study (`bench::integrators`) charts them against each other.

pub mod forces;
pub mod integrate;
pub mod spectrum;

use crate::garment::{Garment, SpringFamily};
use crate::sim::metrics::Energy;
use glam::DVec3;

/// A spring of the mass-spring model (grid-order indices).
#[derive(Clone, Copy, Debug)]
pub struct Spring {
    pub a: u32,
    pub b: u32,
    /// Rest length [m].
    pub rest: f64,
    /// Stiffness k [N/m].
    pub stiffness: f64,
    /// True for structural (axis-neighbour) springs, the ones strain is measured on.
    pub structural: bool,
}

/// Wind as the flag scene defines it: each particle feels F = w·A·(n·W)·n, n its unit normal,
/// W the wind velocity and A its share of the cloth's rest area (so w, in kg/(m²·s), does not
/// change with the mesh size).
#[derive(Clone, Copy, Debug)]
pub struct Wind {
    /// W [m/s].
    pub velocity: DVec3,
    /// w [kg/(m²·s)].
    pub coefficient: f64,
}

/// Forces other than the springs.
#[derive(Clone, Copy, Debug)]
pub struct Environment {
    /// Gravity [m/s²].
    pub gravity: DVec3,
    /// Linear drag γ [1/s]: a force −γ·m·v on every particle (drape's `damping`).
    pub drag: f64,
    /// Dashpot along every spring [N·s/m]: −c·((v_a − v_b)·n)·n. Projective Dynamics ignores it.
    pub spring_damping: f64,
    pub wind: Option<Wind>,
}

/// A mass-spring cloth: static topology and the changing state.
#[derive(Clone, Debug)]
pub struct MassSpring {
    /// Positions [m], grid order.
    pub positions: Vec<DVec3>,
    /// Velocities [m/s].
    pub velocities: Vec<DVec3>,
    /// Mass of each particle [kg].
    pub mass: Vec<f64>,
    /// 1/m, 0 for pinned particles (they never move).
    pub inv_mass: Vec<f64>,
    pub springs: Vec<Spring>,
    /// Triangles for normals (wind), grid order.
    pub triangles: Vec<[u32; 3]>,
    /// Rest area per particle [m²] (wind).
    pub particle_area: f64,
    /// Particle colour of the garment's colouring (Projective Dynamics sweeps colour by colour).
    pub colour: Vec<u32>,
    pub colours: u32,
    pub env: Environment,
}

impl MassSpring {
    /// The mass-spring model of `garment` (its springs' weights become stiffnesses) at rest.
    pub fn from_garment(garment: &Garment, env: Environment) -> MassSpring {
        let n = garment.particle_count();
        let mut inv_mass = vec![1.0 / garment.particle_mass as f64; n];
        for &p in &garment.pins {
            inv_mass[p as usize] = 0.0;
        }
        let area: f64 = garment
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| garment.positions[i as usize].as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        MassSpring {
            positions: garment.positions.iter().map(|p| p.as_dvec3()).collect(),
            velocities: vec![DVec3::ZERO; n],
            mass: vec![garment.particle_mass as f64; n],
            inv_mass,
            springs: garment
                .springs
                .iter()
                .map(|s| Spring {
                    a: s.a,
                    b: s.b,
                    rest: s.rest as f64,
                    stiffness: s.weight as f64,
                    structural: s.family == SpringFamily::Stretch,
                })
                .collect(),
            triangles: garment.triangles.clone(),
            particle_area: area / n as f64,
            colour: garment
                .cells
                .iter()
                .map(|&c| garment.colouring.colour(c))
                .collect(),
            colours: garment.colouring.modulus,
            env,
        }
    }

    /// Number of particles.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True without particles.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Kinetic, gravitational and elastic energy [J].
    pub fn energy(&self) -> Energy {
        let mut e = Energy::default();
        for i in 0..self.len() {
            e.kinetic += 0.5 * self.mass[i] * self.velocities[i].length_squared();
            e.gravitational -= self.mass[i] * self.env.gravity.dot(self.positions[i]);
        }
        for s in &self.springs {
            let l = (self.positions[s.b as usize] - self.positions[s.a as usize]).length();
            e.elastic += 0.5 * s.stiffness * (l - s.rest) * (l - s.rest);
        }
        e
    }

    /// Largest |l − L|/L over the structural springs (NaN when a position is not finite).
    pub fn max_strain(&self) -> f64 {
        let mut max = 0.0f64;
        for s in self.springs.iter().filter(|s| s.structural) {
            let l = (self.positions[s.b as usize] - self.positions[s.a as usize]).length();
            let strain = (l - s.rest).abs() / s.rest;
            if strain > max || strain.is_nan() {
                max = strain;
            }
        }
        max
    }

    /// Speed of the fastest particle [m/s].
    pub fn max_speed(&self) -> f64 {
        self.velocities
            .iter()
            .map(|v| v.length())
            .fold(0.0, |a, b| if b > a || b.is_nan() { b } else { a })
    }

    /// True when every position and velocity is finite.
    pub fn is_finite(&self) -> bool {
        self.positions.iter().all(|p| p.is_finite())
            && self.velocities.iter().all(|v| v.is_finite())
    }
}
