//! Position Based Dynamics, Jacobi with averaging (thesis algorithm 3; Macklin et al. 2014 §4.2):
//! every particle gathers the corrections of its distance constraints from the previous iterate and
//! moves by ω times their mean. Every spring acts as a hard distance constraint (PBD has no
//! stiffness weight: its stiffness comes from the iteration count and step size).

use super::Buffers;
use crate::sim::constraint::pbd_distance_correction;
use crate::sim::model::Model;
use crate::sim::team::Member;
use glam::Vec4;

/// One Jacobi iteration over every particle.
#[inline(never)] // a reference method: its code stays out of red-black Gauss-Seidel's loop
pub fn iterate(m: &Member, model: &Model, b: &Buffers, omega: f32) {
    // SAFETY: this stage reads x and Δ and writes only scratch, each index by one thread.
    let mine = model.particles_of(m.index, m.count);
    {
        let (x, q) = unsafe { (b.x.read_all(), b.delta.read_all()) };
        for i in mine.clone() {
            let wi = model.inv_mass[i];
            let slots = model.slots(i);
            let new = if wi == 0.0 || slots.is_empty() {
                q[i]
            } else {
                let mut sum = Vec4::ZERO;
                for s in slots {
                    let j = s.neighbour as usize;
                    let rest = model.springs[s.spring_index()].rest;
                    // The edge from start positions and displacements, which keeps its precision.
                    let edge = (x[i] - x[j]) + (q[i] - q[j]);
                    sum += pbd_distance_correction(edge, wi, Vec4::ZERO, model.inv_mass[j], rest);
                }
                q[i] + sum * (omega / slots.len() as f32)
            };
            unsafe { b.scratch.set(i, new) };
        }
    }
    m.sync();
    for i in mine {
        // SAFETY: each index copied by its own thread; nobody reads Δ in this stage.
        unsafe { b.delta.set(i, b.scratch.get(i)) };
    }
    m.sync();
}
