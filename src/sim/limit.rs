//! Strain limiting (`solver.strain_limit`): after each substep, structural springs stretched
//! past the limit are pulled back to it, the two ends moving by their inverse masses (a held
//! end stays), colour by colour and back ([`LimitOrder`]), sweep after sweep until none is past it or [`SWEEPS`]
//! have run; velocities take the same correction over the substep.
//!
//! Why: collisions are the last word on a particle in a substep, so a body part that drags or
//! squeezes cloth where there is no room for it (a hand swinging into the thigh beside a skirt)
//! stretches springs without bound and the bake stops as unstable. Limited, the cloth holds
//! together and the body part passes through it there instead, which the mesh penetration
//! metric reports. Springs within the limit are never touched, so a scene that never reaches it
//! bakes the same frames as without one.

use super::model::{Model, ModelSpring};
use super::state::State;

/// Sweeps over the springs per substep at the most.
pub const SWEEPS: u32 = 64;

/// The structural springs of a model in the order the limit sweeps them: colour by colour, no
/// two springs of one colour sharing a particle (a greedy edge colouring in storage order), so
/// the springs of a colour can be pulled back all at once, in any order, to the same numbers:
/// one GPU workgroup does a colour in parallel (`shaders/limit.wgsl`) as the CPU does it in
/// storage order. A lattice needs at most 2 × 6 − 1 colours (a particle has at most six
/// structural neighbours); sheets 4 to 7.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LimitOrder {
    /// Structural spring indices, colour by colour, storage order within each.
    pub springs: Vec<u32>,
    /// Where each colour starts in `springs`, and its end.
    pub colour_start: Vec<u32>,
}

impl LimitOrder {
    /// The colouring of `model`'s structural springs.
    pub fn new(model: &Model) -> LimitOrder {
        let springs = &model.springs[..model.structural_springs];
        // The colours each particle's springs have taken so far (a handful each).
        let mut taken: Vec<Vec<u32>> = vec![Vec::new(); model.particle_count()];
        let colours: Vec<u32> = (springs.iter())
            .map(|s| {
                let (a, b) = (s.a as usize, s.b as usize);
                let free = (0..)
                    .find(|c| !taken[a].contains(c) && !taken[b].contains(c))
                    .expect("a free colour");
                taken[a].push(free);
                taken[b].push(free);
                free
            })
            .collect();
        let count = colours.iter().max().map_or(0, |c| c + 1);
        let mut colour_start = vec![0u32; count as usize + 1];
        for &c in &colours {
            colour_start[c as usize + 1] += 1;
        }
        for c in 0..count as usize {
            colour_start[c + 1] += colour_start[c];
        }
        let mut next = colour_start.clone();
        let mut order = vec![0u32; springs.len()];
        for (i, &c) in colours.iter().enumerate() {
            order[next[c as usize] as usize] = i as u32;
            next[c as usize] += 1;
        }
        LimitOrder {
            springs: order,
            colour_start,
        }
    }

    /// How many colours.
    pub fn colours(&self) -> usize {
        self.colour_start.len().saturating_sub(1)
    }

    /// The springs of colour `c`.
    fn colour(&self, c: usize) -> &[u32] {
        &self.springs[self.colour_start[c] as usize..self.colour_start[c + 1] as usize]
    }
}

/// Pulls the structural springs of `model` stretched past `limit` (a strain: 0.2 is 20 %
/// longer than at rest) back to it in `state`, colour by colour in `order` (forward, then
/// backward), correcting velocities over a substep of `step` seconds. Returns how many springs
/// the first sweep found past the limit.
pub fn limit_strain(
    model: &Model,
    order: &LimitOrder,
    state: &mut State,
    limit: f32,
    step: f32,
) -> u32 {
    let mut first = None;
    let colours = order.colours();
    for sweep in 0..SWEEPS {
        let mut pulled = 0u32;
        // Forward, then backward: a correction travels both ways across the colours.
        for k in 0..colours {
            let c = if sweep % 2 == 0 { k } else { colours - 1 - k };
            for &i in order.colour(c) {
                let s = &model.springs[i as usize];
                pulled += pull_back(model, state, s, limit, step) as u32;
            }
        }
        first.get_or_insert(pulled);
        if pulled == 0 {
            break;
        }
    }
    first.unwrap_or(0)
}

/// Pulls spring `s` back to `limit` if it is past it (as `shaders/limit.wgsl`'s
/// `pull_back`); whether it was.
fn pull_back(model: &Model, state: &mut State, s: &ModelSpring, limit: f32, step: f32) -> bool {
    let (a, b) = (s.a as usize, s.b as usize);
    let (wa, wb) = (model.inv_mass[a], model.inv_mass[b]);
    let longest = s.rest * (1.0 + limit);
    let d = state.positions[b].truncate() - state.positions[a].truncate();
    let length = d.length();
    if length <= longest || wa + wb == 0.0 {
        return false;
    }
    let c = d * ((length - longest) / (length * (wa + wb)));
    let (da, db) = ((c * wa).extend(0.0), (-c * wb).extend(0.0));
    state.positions[a] += da;
    state.positions[b] += db;
    state.velocities[a] += da / step;
    state.velocities[b] += db / step;
    true
}
