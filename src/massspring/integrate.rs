//! Time integrators for the mass-spring model, each advancing positions and velocities by one step
//! h (stability theory per method: `shared/reference/stability.md`):
//! - explicit Euler: x' = x + h·v, v' = v + h·a(x, v);
//! - midpoint (RK2) and classic RK4 on (x, v);
//! - Verlet in velocity form (symplectic Euler, equivalent to position Verlet):
//!   v' = v + h·a(x, v), x' = x + h·v';
//! - implicit Euler linearised once per step (Baraff and Witkin 1998):
//!   (M − h·∂f/∂v − h²·∂f/∂x)·Δv = h·(f + h·∂f/∂x·v), solved by Jacobi-preconditioned conjugate
//!   gradients with pinned rows filtered out;
//! - Projective Dynamics (Bouaziz et al. 2014) as drape runs it: inertial prediction with drag
//!   exp(−γh), then local/global iterations, the global step one Gauss-Seidel sweep colour by
//!   colour; velocity = displacement / h. Spring dashpots are not part of its model.

// The steps walk several per-particle arrays by index at once (positions, velocities, masses,
// scratch); iterator zips of four or five arrays would read worse.
#![allow(clippy::needless_range_loop)]

use super::forces::{accelerations, apply_springs, spring_blocks, SpringBlock};
use super::MassSpring;
use glam::DVec3;

/// An integration method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    ExplicitEuler,
    Midpoint,
    Rk4,
    Verlet,
    ImplicitEuler,
    /// Projective Dynamics with this many local/global iterations per step.
    ProjectiveDynamics(u32),
}

impl Method {
    /// Every method, in the order charts list them (Projective Dynamics with `pd_iterations`).
    pub fn all(pd_iterations: u32) -> [Method; 6] {
        [
            Method::ExplicitEuler,
            Method::Midpoint,
            Method::Rk4,
            Method::Verlet,
            Method::ImplicitEuler,
            Method::ProjectiveDynamics(pd_iterations),
        ]
    }

    /// A short name for tables, CSV and legends.
    pub fn name(self) -> String {
        match self {
            Method::ExplicitEuler => "explicit_euler".into(),
            Method::Midpoint => "midpoint".into(),
            Method::Rk4 => "rk4".into(),
            Method::Verlet => "verlet".into(),
            Method::ImplicitEuler => "implicit_euler".into(),
            Method::ProjectiveDynamics(k) => format!("pd_{k}it"),
        }
    }
}

/// Relative residual at which conjugate gradients stop.
pub const CG_TOLERANCE: f64 = 1e-8;
/// Most conjugate-gradient iterations per implicit step.
pub const CG_MAX_ITERATIONS: usize = 1000;

/// Advances a [`MassSpring`] with one method, keeping its scratch buffers between steps.
pub struct Integrator {
    pub method: Method,
    scratch: Vec<Vec<DVec3>>,
    blocks: Vec<SpringBlock>,
    /// Projective Dynamics: springs per particle, free particles in sweep order, projections.
    pd: Option<(Adjacency, Vec<u32>)>,
    projection: Vec<DVec3>,
    /// Conjugate-gradient iterations of every implicit step so far.
    pub cg_iterations: u64,
}

impl Integrator {
    pub fn new(method: Method) -> Integrator {
        Integrator {
            method,
            scratch: Vec::new(),
            blocks: Vec::new(),
            pd: None,
            projection: Vec::new(),
            cg_iterations: 0,
        }
    }

    /// Advances `sys` by `h` seconds.
    pub fn step(&mut self, sys: &mut MassSpring, h: f64) {
        let n = sys.len();
        let buffers = match self.method {
            Method::ExplicitEuler | Method::Verlet => 1,
            Method::Midpoint => 3,
            Method::Rk4 => 6,
            Method::ImplicitEuler => 6,
            Method::ProjectiveDynamics(_) => 3,
        };
        if self.scratch.len() < buffers || self.scratch[0].len() != n {
            self.scratch = vec![vec![DVec3::ZERO; n]; buffers];
        }
        match self.method {
            Method::ExplicitEuler => self.explicit_euler(sys, h),
            Method::Midpoint => self.midpoint(sys, h),
            Method::Rk4 => self.rk4(sys, h),
            Method::Verlet => self.verlet(sys, h),
            Method::ImplicitEuler => self.implicit_euler(sys, h),
            Method::ProjectiveDynamics(k) => self.projective_dynamics(sys, h, k),
        }
    }

    fn explicit_euler(&mut self, sys: &mut MassSpring, h: f64) {
        let a = &mut self.scratch[0];
        accelerations(sys, &sys.positions, &sys.velocities, a);
        for i in 0..sys.len() {
            if sys.inv_mass[i] != 0.0 {
                sys.positions[i] += sys.velocities[i] * h;
                sys.velocities[i] += a[i] * h;
            }
        }
    }

    fn verlet(&mut self, sys: &mut MassSpring, h: f64) {
        let a = &mut self.scratch[0];
        accelerations(sys, &sys.positions, &sys.velocities, a);
        for i in 0..sys.len() {
            if sys.inv_mass[i] != 0.0 {
                sys.velocities[i] += a[i] * h;
                sys.positions[i] += sys.velocities[i] * h;
            }
        }
    }

    fn midpoint(&mut self, sys: &mut MassSpring, h: f64) {
        let [a, xm, vm] = &mut self.scratch[..3] else {
            unreachable!("three buffers")
        };
        accelerations(sys, &sys.positions, &sys.velocities, a);
        for i in 0..sys.len() {
            xm[i] = sys.positions[i] + sys.velocities[i] * (0.5 * h);
            vm[i] = sys.velocities[i] + a[i] * (0.5 * h);
        }
        accelerations(sys, xm, vm, a);
        for i in 0..sys.len() {
            if sys.inv_mass[i] != 0.0 {
                sys.positions[i] += vm[i] * h;
                sys.velocities[i] += a[i] * h;
            }
        }
    }

    fn rk4(&mut self, sys: &mut MassSpring, h: f64) {
        let [a, xs, vs, dx, dv, _] = &mut self.scratch[..6] else {
            unreachable!("six buffers")
        };
        let (x0, v0) = (&sys.positions, &sys.velocities);
        // Stage k: derivative (vs, a) at (xs, vs); the sums dx, dv collect the weights 1, 2, 2, 1.
        xs.copy_from_slice(x0);
        vs.copy_from_slice(v0);
        for (stage, (weight, next)) in [(1.0, 0.5), (2.0, 0.5), (2.0, 1.0), (1.0, 0.0)]
            .into_iter()
            .enumerate()
        {
            accelerations(sys, xs, vs, a);
            for i in 0..sys.len() {
                let (kx, kv) = (vs[i], a[i]);
                if stage == 0 {
                    dx[i] = kx * weight;
                    dv[i] = kv * weight;
                } else {
                    dx[i] += kx * weight;
                    dv[i] += kv * weight;
                }
                xs[i] = x0[i] + kx * (next * h);
                vs[i] = v0[i] + kv * (next * h);
            }
        }
        for i in 0..sys.len() {
            if sys.inv_mass[i] != 0.0 {
                sys.positions[i] += dx[i] * (h / 6.0);
                sys.velocities[i] += dv[i] * (h / 6.0);
            }
        }
    }

    fn implicit_euler(&mut self, sys: &mut MassSpring, h: f64) {
        let [f, b, r, z, p, q] = &mut self.scratch[..6] else {
            unreachable!("six buffers")
        };
        let n = sys.len();
        accelerations(sys, &sys.positions, &sys.velocities, f);
        spring_blocks(sys, &sys.positions, h, &mut self.blocks);
        // b = h·f + h²·∂f/∂x·v: the stiffness part of each block is S − h·c·n nᵀ, and ∂f/∂x
        // contributes −S_stiff·(v_a − v_b) to row a.
        let c = sys.env.spring_damping;
        for i in 0..n {
            b[i] = f[i] * (sys.mass[i] * h);
        }
        for (s, blk) in sys.springs.iter().zip(&self.blocks) {
            let (ia, ib) = (s.a as usize, s.b as usize);
            let dv = sys.velocities[ia] - sys.velocities[ib];
            let stiff = blk.apply(dv) - blk.n * (h * c * blk.n.dot(dv));
            b[ia] -= stiff;
            b[ib] += stiff;
        }
        // A = M(1 + hγ) + Σ blocks; Jacobi preconditioner from its diagonal.
        let lumped = |i: usize| sys.mass[i] * (1.0 + h * sys.env.drag);
        let mut diagonal = vec![DVec3::ZERO; n];
        for i in 0..n {
            diagonal[i] = DVec3::splat(lumped(i));
        }
        for (s, blk) in sys.springs.iter().zip(&self.blocks) {
            let d = DVec3::splat(blk.iso) + blk.n * blk.n * blk.along;
            diagonal[s.a as usize] += d;
            diagonal[s.b as usize] += d;
        }
        let free = |i: usize| sys.inv_mass[i] != 0.0;
        let blocks = &self.blocks;
        let apply = |p: &[DVec3], y: &mut [DVec3]| {
            for i in 0..n {
                y[i] = p[i] * lumped(i);
            }
            apply_springs(sys, blocks, p, y);
            for (i, y) in y.iter_mut().enumerate() {
                if !free(i) {
                    *y = DVec3::ZERO;
                }
            }
        };
        // Conjugate gradients on A·Δv = b from Δv = 0 (held in f); pinned rows stay zero.
        let dv = f;
        for i in 0..n {
            dv[i] = DVec3::ZERO;
            r[i] = if free(i) { b[i] } else { DVec3::ZERO };
            z[i] = r[i] / diagonal[i];
            p[i] = z[i];
        }
        let dot = |u: &[DVec3], w: &[DVec3]| u.iter().zip(w).map(|(u, w)| u.dot(*w)).sum::<f64>();
        let norm0 = dot(r, r).sqrt();
        let mut rz = dot(r, z);
        let mut iterations = 0;
        while iterations < CG_MAX_ITERATIONS && dot(r, r).sqrt() > CG_TOLERANCE * norm0 {
            apply(p, q);
            let alpha = rz / dot(p, q);
            for i in 0..n {
                dv[i] += p[i] * alpha;
                r[i] -= q[i] * alpha;
                z[i] = r[i] / diagonal[i];
            }
            let rz_next = dot(r, z);
            let beta = rz_next / rz;
            rz = rz_next;
            for i in 0..n {
                p[i] = z[i] + p[i] * beta;
            }
            iterations += 1;
        }
        self.cg_iterations += iterations as u64;
        for i in 0..n {
            if free(i) {
                sys.velocities[i] += dv[i];
                sys.positions[i] += sys.velocities[i] * h;
            }
        }
    }

    fn projective_dynamics(&mut self, sys: &mut MassSpring, h: f64, iterations: u32) {
        let [target, q, external] = &mut self.scratch[..3] else {
            unreachable!("three buffers")
        };
        let n = sys.len();
        let (adjacency, order) = self.pd.get_or_insert_with(|| {
            let mut order: Vec<u32> = (0..n as u32)
                .filter(|&i| sys.inv_mass[i as usize] != 0.0)
                .collect();
            order.sort_by_key(|&i| sys.colour[i as usize]);
            (Adjacency::of(sys), order)
        });
        self.projection.resize(sys.springs.len(), DVec3::ZERO);
        let keep = (-sys.env.drag * h).exp();
        // External accelerations (gravity, wind) at the start of the step; the prediction.
        external.fill(sys.env.gravity);
        if let Some(wind) = super::forces::wind_forces(sys, &sys.positions) {
            for i in 0..n {
                external[i] += wind[i] * sys.inv_mass[i];
            }
        }
        for i in 0..n {
            target[i] = if sys.inv_mass[i] != 0.0 {
                sys.positions[i] + (sys.velocities[i] * keep + external[i] * h) * h
            } else {
                sys.positions[i]
            };
            q[i] = target[i];
        }
        let inv_h2 = 1.0 / (h * h);
        for _ in 0..iterations {
            // Local step: each spring's rest-length vector along its current direction.
            for (s, p) in sys.springs.iter().zip(self.projection.iter_mut()) {
                let d = q[s.b as usize] - q[s.a as usize];
                *p = d.normalize_or_zero() * s.rest;
            }
            // Global step: one Gauss-Seidel sweep, colour by colour.
            for &i in order.iter() {
                let i = i as usize;
                let inertia = sys.mass[i] * inv_h2;
                let mut sum = target[i] * inertia;
                let mut weight = inertia;
                for &(j, spring, sign) in adjacency.of_particle(i) {
                    let k = sys.springs[spring as usize].stiffness;
                    // The spring vector from this particle to j is sign·projection at rest.
                    sum += (q[j as usize] - self.projection[spring as usize] * sign) * k;
                    weight += k;
                }
                q[i] = sum / weight;
            }
        }
        for i in 0..n {
            if sys.inv_mass[i] != 0.0 {
                sys.velocities[i] = (q[i] - sys.positions[i]) / h;
                sys.positions[i] = q[i];
            }
        }
    }
}

/// Springs of each particle: (other particle, spring, +1 when the particle is the spring's a).
struct Adjacency {
    start: Vec<u32>,
    entries: Vec<(u32, u32, f64)>,
}

impl Adjacency {
    fn of(sys: &MassSpring) -> Adjacency {
        let mut count = vec![0u32; sys.len() + 1];
        for s in &sys.springs {
            count[s.a as usize + 1] += 1;
            count[s.b as usize + 1] += 1;
        }
        for i in 0..sys.len() {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut entries = vec![(0, 0, 0.0); 2 * sys.springs.len()];
        for (k, s) in sys.springs.iter().enumerate() {
            entries[fill[s.a as usize] as usize] = (s.b, k as u32, 1.0);
            fill[s.a as usize] += 1;
            entries[fill[s.b as usize] as usize] = (s.a, k as u32, -1.0);
            fill[s.b as usize] += 1;
        }
        Adjacency {
            start: count,
            entries,
        }
    }

    fn of_particle(&self, i: usize) -> &[(u32, u32, f64)] {
        &self.entries[self.start[i] as usize..self.start[i + 1] as usize]
    }
}
