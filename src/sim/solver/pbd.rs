//! Position Based Dynamics, Jacobi with averaging (thesis algorithm 3; Macklin et al. 2014 §4.2):
//! every particle gathers the corrections of its distance constraints from the previous iterate and
//! moves by ω times their mean. Every spring acts as a hard distance constraint (PBD has no
//! stiffness weight: its stiffness comes from the iteration count and step size).

use super::PARALLEL_CHUNK;
use crate::sim::constraint::pbd_distance_correction;
use crate::sim::model::Model;
use glam::Vec4;
use rayon::prelude::*;

/// One Jacobi iteration over every particle.
pub fn iterate(model: &Model, q: &mut [Vec4], scratch: &mut [Vec4], omega: f32) {
    let old: &[Vec4] = q;
    scratch
        .par_iter_mut()
        .with_min_len(PARALLEL_CHUNK)
        .enumerate()
        .for_each(|(i, out)| {
            let wi = model.inv_mass[i];
            let slots = model.slots(i);
            if wi == 0.0 || slots.is_empty() {
                *out = old[i];
                return;
            }
            let n = slots.len() as f32;
            let mut sum = Vec4::ZERO;
            for s in slots {
                let j = s.neighbour as usize;
                sum += pbd_distance_correction(old[i], wi, old[j], model.inv_mass[j], s.rest);
            }
            *out = old[i] + sum * (omega / n);
        });
    q.copy_from_slice(scratch);
}
