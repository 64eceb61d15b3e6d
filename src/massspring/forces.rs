//! Forces of the mass-spring model and the linearisation implicit Euler needs.
//!
//! A spring from a to b with d = x_b − x_a, l = |d|, n = d/l pulls a with
//! f_a = k·(l − L)·n + c·((v_b − v_a)·n)·n and b with −f_a. Its stiffness block is
//! J = k·n nᵀ + k·(1 − L/l)·(I − n nᵀ) (∂f_a/∂x_a = −J, ∂f_a/∂x_b = J); the second term is
//! negative for a compressed spring, which makes the system indefinite, so it is clamped at zero
//! (Choi and Ko 2002): the linear system stays symmetric positive definite for conjugate gradients.

use super::MassSpring;
use glam::DVec3;

/// Accelerations at positions `x` and velocities `v` into `a` (zero for pinned particles).
pub fn accelerations(sys: &MassSpring, x: &[DVec3], v: &[DVec3], a: &mut [DVec3]) {
    let env = &sys.env;
    for (i, a) in a.iter_mut().enumerate() {
        *a = env.gravity - env.drag * v[i];
    }
    if let Some(wind) = wind_forces(sys, x) {
        for (i, f) in wind.iter().enumerate() {
            a[i] += *f * sys.inv_mass[i];
        }
    }
    for s in &sys.springs {
        let (ia, ib) = (s.a as usize, s.b as usize);
        let d = x[ib] - x[ia];
        let l = d.length();
        let n = d / l;
        let mut f = s.stiffness * (l - s.rest);
        if env.spring_damping != 0.0 {
            f += env.spring_damping * (v[ib] - v[ia]).dot(n);
        }
        a[ia] += n * (f * sys.inv_mass[ia]);
        a[ib] -= n * (f * sys.inv_mass[ib]);
    }
    for (i, a) in a.iter_mut().enumerate() {
        if sys.inv_mass[i] == 0.0 {
            *a = DVec3::ZERO;
        }
    }
}

/// The wind's force on every particle at positions `x` [N], None without wind.
pub fn wind_forces(sys: &MassSpring, x: &[DVec3]) -> Option<Vec<DVec3>> {
    let wind = sys.env.wind?;
    let scale = wind.coefficient * sys.particle_area;
    let mut forces = vertex_normals(sys, x);
    for n in &mut forces {
        *n *= scale * n.dot(wind.velocity);
    }
    Some(forces)
}

/// Unit normal of every particle: the area-weighted sum of its triangles' normals (zero for a
/// particle in no triangle, as on a rope).
pub fn vertex_normals(sys: &MassSpring, x: &[DVec3]) -> Vec<DVec3> {
    let mut normals = vec![DVec3::ZERO; x.len()];
    for t in &sys.triangles {
        let [a, b, c] = t.map(|i| i as usize);
        let n = (x[b] - x[a]).cross(x[c] - x[a]);
        normals[a] += n;
        normals[b] += n;
        normals[c] += n;
    }
    for n in &mut normals {
        *n = n.normalize_or_zero();
    }
    normals
}

/// One spring's contribution to A = M − h·∂f/∂v − h²·∂f/∂x, as S·(p_a − p_b) added to row a
/// and subtracted from row b, with S = iso·I + along·n nᵀ.
#[derive(Clone, Copy, Debug)]
pub struct SpringBlock {
    pub n: DVec3,
    pub iso: f64,
    pub along: f64,
}

impl SpringBlock {
    /// S·p.
    #[inline]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        p * self.iso + self.n * (self.along * self.n.dot(p))
    }
}

/// The spring blocks of A at positions `x` for a step `h`.
pub fn spring_blocks(sys: &MassSpring, x: &[DVec3], h: f64, blocks: &mut Vec<SpringBlock>) {
    blocks.clear();
    let c = sys.env.spring_damping;
    blocks.extend(sys.springs.iter().map(|s| {
        let d = x[s.b as usize] - x[s.a as usize];
        let l = d.length();
        let geometric = s.stiffness * (1.0 - s.rest / l).max(0.0);
        SpringBlock {
            n: d / l,
            iso: h * h * geometric,
            along: h * h * (s.stiffness - geometric) + h * c,
        }
    }));
}

/// y = K_s·p for the spring part of a matrix given by `blocks` (rows of pinned particles are
/// left to the caller).
pub fn apply_springs(sys: &MassSpring, blocks: &[SpringBlock], p: &[DVec3], y: &mut [DVec3]) {
    for (s, b) in sys.springs.iter().zip(blocks) {
        let (ia, ib) = (s.a as usize, s.b as usize);
        let t = b.apply(p[ia] - p[ib]);
        y[ia] += t;
        y[ib] -= t;
    }
}
