//! Everything a simulation carries from one frame to the next, taken out and put back: what a
//! checkpoint holds, so that a bake resumed from one continues bit for bit as if it had never
//! stopped (on the CPU backend).
//!
//! What a frame start depends on, besides the model and settings the scene rebuilds: positions
//! and velocities; the clock (substeps so far: characters, keyframes, attachments); the nearby
//! shell particles each garment particle found at the end of the last substep (the next
//! substep's collision passes test only those); the fastest driven speed (the stability rule);
//! and the topology tearing has left. Everything else is rebuilt inside every substep (the
//! prediction, projections, the particle grid, the shells' positions and grids).

use super::Simulation;
use glam::Vec4;

/// The state of a [`Simulation`] between two frames.
#[derive(Clone, Debug, PartialEq)]
pub struct Snapshot {
    /// Positions and velocities, storage order.
    pub positions: Vec<Vec4>,
    pub velocities: Vec<Vec4>,
    /// Substeps simulated so far, counted in substeps of the budget it was taken at.
    pub elapsed_substeps: u64,
    /// That budget's substeps per frame (0: the restoring simulation's own, as in checkpoints
    /// written before drape recorded it). An accuracy target retries a frame at another budget
    /// from a snapshot taken at the old one: the clock must be read in the old one's substeps.
    pub substeps: u32,
    /// Fastest any attached particle, keyframed collider or shell has moved [m/s].
    pub driven_speed: f32,
    /// Springs broken so far.
    pub torn_springs: usize,
    /// Work of the force fields so far [J].
    pub force_work: f64,
    /// Per garment that has torn: what is left of it.
    pub torn: Vec<TornGarment>,
    /// Each garment particle's nearby shell particles, per shell (shell-major; empty with one
    /// collision pass).
    pub nearby: Vec<crate::collide::shell::Nearby>,
    /// The storage order the state is in ([`Model::layout`](super::model::Model::layout)); None
    /// in checkpoints written before drape recorded it (models laid out colour by colour).
    pub layout: Option<u64>,
}

/// What tearing has left of one garment: its springs (as particle pairs, in order) and faces.
#[derive(Clone, Debug, PartialEq)]
pub struct TornGarment {
    pub garment: usize,
    pub springs: Vec<[u32; 2]>,
    pub triangles: Vec<[u32; 3]>,
    /// Tearing drops a garment's long-range attachments.
    pub tethers: bool,
}

impl Simulation {
    /// The state to resume from after the current frame.
    pub fn snapshot(&self) -> Snapshot {
        let torn = self
            .tearing
            .garments
            .iter()
            .enumerate()
            .filter(|(g, _)| self.tearing.strain[*g].is_some())
            .map(|(garment, g)| TornGarment {
                garment,
                springs: g.springs.iter().map(|s| [s.a, s.b]).collect(),
                triangles: g.triangles.clone(),
                tethers: !g.tethers.is_empty(),
            })
            .collect();
        Snapshot {
            positions: self.state.positions.clone(),
            velocities: self.state.velocities.clone(),
            elapsed_substeps: self.drivers.clock.elapsed,
            substeps: self.drivers.clock.substeps,
            driven_speed: self.drivers.driven_speed,
            torn_springs: self.tearing.torn_springs,
            force_work: self.fields.work,
            torn,
            nearby: self.nearby_lists().to_vec(),
            layout: Some(self.model.layout()),
        }
    }

    /// Puts `snapshot` back into this simulation, freshly built from the same scene: the torn
    /// topology first (rebuilding model and solver as tearing does), then the state, the clock
    /// and the colliders' poses. Errors say what does not fit (another garment layout).
    pub fn restore(&mut self, snapshot: &Snapshot) -> Result<(), String> {
        let n = self.model.particle_count();
        // Before drape recorded the layout, every model was stored colour by colour, as a
        // larger one still is; a small one now is not.
        let layout_fits = match snapshot.layout {
            Some(layout) => layout == self.model.layout(),
            None => self.model.domains.is_none(),
        };
        if !layout_fits {
            return Err(
                "its particles are stored in another order (a checkpoint of another \
                        drape version): bake again without --resume"
                    .into(),
            );
        }
        let elapsed_substeps = self.elapsed_substeps_of(snapshot)?;
        if snapshot.positions.len() != n || snapshot.velocities.len() != n {
            return Err(format!(
                "it holds {} particles, the scene has {n}",
                snapshot.positions.len()
            ));
        }
        let expected_nearby = if self.solver.settings.contact_passes > 1 {
            self.drivers.shells.len() * n
        } else {
            0
        };
        if !snapshot.nearby.is_empty() && snapshot.nearby.len() != expected_nearby {
            return Err("its collision lists do not fit the scene's characters".into());
        }
        // Nothing to rebuild when the topology is what it was (an accuracy target's retry).
        let same = snapshot.torn.iter().all(|t| {
            self.tearing.garments.get(t.garment).is_some_and(|g| {
                g.springs.len() == t.springs.len()
                    && g.triangles.len() == t.triangles.len()
                    && g.tethers.is_empty() != t.tethers
            })
        });
        if !same {
            for t in &snapshot.torn {
                let g =
                    self.tearing.garments.get_mut(t.garment).ok_or_else(|| {
                        format!("it tears garment {}, which is not there", t.garment)
                    })?;
                // Tearing only removes springs, keeping the order of the rest.
                let mut kept = t.springs.iter().peekable();
                g.springs.retain(|s| {
                    let keep = kept.peek() == Some(&&[s.a, s.b]);
                    if keep {
                        kept.next();
                    }
                    keep
                });
                if kept.next().is_some() {
                    return Err(format!(
                        "garment {}'s springs are not those of the scene",
                        t.garment
                    ));
                }
                g.triangles = t.triangles.clone();
                if !t.tethers {
                    g.tethers.clear();
                }
            }
            self.rebuild_model();
            if self.model.particle_count() != n {
                return Err("the torn garments do not fit the scene".into());
            }
        }
        self.state.positions = snapshot.positions.clone();
        self.state.velocities = snapshot.velocities.clone();
        self.set_nearby_lists(snapshot.nearby.clone());
        self.drivers.clock.elapsed = elapsed_substeps;
        self.settling.end();
        self.tearing.torn_springs = snapshot.torn_springs;
        self.fields.work = snapshot.force_work;
        if self.drivers.clock.elapsed > 0 {
            // Keyframed colliders in their pose at the end of the last substep (the next one
            // measures its motion from there).
            let t = self.drivers.clock.time();
            self.drivers.pose_colliders(t);
        } else {
            // At the start: at rest, as a new bake's (a first frame simulated again would
            // otherwise measure its first motion from where the rejected attempt left them).
            self.drivers.rest_colliders();
        }
        self.drivers.driven_speed = snapshot.driven_speed;
        Ok(())
    }

    /// `snapshot`'s clock in this simulation's substeps: the same count when they are the
    /// snapshot's, else its whole frames (a snapshot is taken between frames) times ours.
    fn elapsed_substeps_of(&self, snapshot: &Snapshot) -> Result<u64, String> {
        let theirs = snapshot.substeps as u64;
        let ours = self.drivers.clock.substeps as u64;
        if theirs == 0 || theirs == ours {
            return Ok(snapshot.elapsed_substeps);
        }
        if snapshot.elapsed_substeps % theirs != 0 {
            return Err(format!(
                "it was taken within a frame ({} substeps of {theirs} per frame), at another \
                 budget than the scene's {ours}",
                snapshot.elapsed_substeps
            ));
        }
        Ok(snapshot.elapsed_substeps / theirs * ours)
    }
}

#[cfg(test)]
mod tests {
    use crate::scene::Scene;
    use crate::sim::Simulation;

    /// A state fits only a model of its layout: another layout's is refused, and so is one from
    /// before drape recorded layouts in a small model (stored in two sides since); a larger
    /// model's such state still fits.
    #[test]
    fn a_state_of_another_layout_is_refused() {
        for (resolution, small) in [([20, 13], true), ([41, 29], false)] {
            let scene = Scene::parse(
                &format!(
                    r#"{{ "garments": [{{ "resolution": {resolution:?}, "size": [1, 1] }}] }}"#
                ),
                "<test>",
            )
            .expect("scene");
            let mut sim = Simulation::new(&scene).expect("simulation");
            assert_eq!(sim.model().domains.is_some(), small);
            let mut s = sim.snapshot();
            assert!(sim.restore(&s).is_ok());
            s.layout = s.layout.map(|l| l ^ 1);
            let refused = sim.restore(&s).expect_err("another layout");
            assert!(refused.contains("another order"), "{refused}");
            s.layout = None;
            assert_eq!(sim.restore(&s).is_ok(), !small, "{resolution:?}");
        }
    }
}
