//! Strain limiting (`solver.strain_limit`): after each substep, structural springs stretched
//! past the limit are pulled back to it, the two ends moving by their inverse masses (a held
//! end stays), in storage order and back, sweep after sweep until none is past it or [`SWEEPS`]
//! have run; velocities take the same correction over the substep.
//!
//! Why: collisions are the last word on a particle in a substep, so a body part that drags or
//! squeezes cloth where there is no room for it (a hand swinging into the thigh beside a skirt)
//! stretches springs without bound and the bake stops as unstable. Limited, the cloth holds
//! together and the body part passes through it there instead, which the mesh penetration
//! metric reports. Springs within the limit are never touched, so a scene that never reaches it
//! bakes the same frames as without one.

use super::model::Model;
use super::state::State;

/// Sweeps over the springs per substep at the most.
pub const SWEEPS: u32 = 32;

/// Pulls the structural springs of `model` stretched past `limit` (a strain: 0.2 is 20 %
/// longer than at rest) back to it in `state`, correcting velocities over a substep of `step`
/// seconds. Returns how many springs the first sweep found past the limit.
pub fn limit_strain(model: &Model, state: &mut State, limit: f32, step: f32) -> u32 {
    let mut first = None;
    let springs = &model.springs[..model.structural_springs];
    for sweep in 0..SWEEPS {
        let mut pulled = 0u32;
        // Forward, then backward: a correction travels the whole sheet either way in a sweep.
        let order: &mut dyn Iterator<Item = _> = if sweep % 2 == 0 {
            &mut springs.iter()
        } else {
            &mut springs.iter().rev()
        };
        for s in order {
            let (a, b) = (s.a as usize, s.b as usize);
            let (wa, wb) = (model.inv_mass[a], model.inv_mass[b]);
            let longest = s.rest * (1.0 + limit);
            let d = state.positions[b].truncate() - state.positions[a].truncate();
            let length = d.length();
            if length <= longest || wa + wb == 0.0 {
                continue;
            }
            pulled += 1;
            let c = d * ((length - longest) / (length * (wa + wb)));
            let (da, db) = ((c * wa).extend(0.0), (-c * wb).extend(0.0));
            state.positions[a] += da;
            state.positions[b] += db;
            state.velocities[a] += da / step;
            state.velocities[b] += db / step;
        }
        first.get_or_insert(pulled);
        if pulled == 0 {
            break;
        }
    }
    first.unwrap_or(0)
}
