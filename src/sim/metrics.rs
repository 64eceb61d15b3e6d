//! Accuracy and stability metrics, computed in one place and reused by bakes, benches and tests
//! (definitions: `shared/reference/scenes.md`). Sums run serially in f64 so the same positions
//! always give the same numbers, whatever the thread count.

use super::model::Model;
use super::state::State;
use glam::{Vec3, Vec4};

/// How far the structural springs are from their rest lengths.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ConstraintError {
    /// Σ over structural springs of (|q_a − q_b| − L)² [m²] (thesis eq. 4.1).
    pub total_squared_error: f64,
    /// Mean of |l − L| / L over structural springs.
    pub mean_strain: f64,
    /// Largest |l − L| / L over structural springs.
    pub max_strain: f64,
    /// Largest (l − L) / L over structural springs: stretch alone, where `max_strain` also
    /// counts compression (cloth squeezed in a pinch, which a coarse lattice cannot buckle).
    pub max_stretch: f64,
    /// Mean and largest |90° − angle| over the lattice's cell corners (two structural
    /// springs from one particle along different axes, square at rest) [degrees]: the shear
    /// that structural strain does not see.
    pub mean_shear_deg: f64,
    pub max_shear_deg: f64,
    /// Largest |l − L| / L over the structural springs between two free particles: what the
    /// solver alone answers for, and what the stability rule reads. A spring with a pinned or
    /// attached end has that end where the animation puts it, which can be through the body
    /// (a limb passing through the attached edge): the skin then holds its free end out, and
    /// no solver can keep it short.
    #[serde(skip)]
    pub max_free_strain: f64,
}

impl ConstraintError {
    /// True when a spring from a held particle is past 100 % while every spring between free
    /// particles is within it: strain the animation forces, which the stability rule leaves out.
    pub fn forced(&self) -> bool {
        self.max_strain > 1.0 && self.max_free_strain <= 1.0
    }

    /// The strain a budget can act on: the free springs' in a frame with [`Self::forced`]
    /// strain (more iterations cannot shorten a forced spring), else the largest.
    pub fn solvable_strain(&self) -> f64 {
        if self.forced() {
            self.max_free_strain
        } else {
            self.max_strain
        }
    }
}

/// Constraint error of `positions` (storage order) over the model's structural springs that
/// the solver moves: a spring whose two ends are both pinned or attached has the length its
/// targets give it (a waistband riding the skin stretches as the skin does), so it is left out.
pub fn constraint_error(model: &Model, positions: &[Vec4]) -> ConstraintError {
    let driven = |s: &&super::model::ModelSpring| {
        model.inv_mass[s.a as usize] == 0.0 && model.inv_mass[s.b as usize] == 0.0
    };
    let mut e = ConstraintError::default();
    let mut count = 0usize;
    for s in model.springs[..model.structural_springs]
        .iter()
        .filter(|s| !driven(s))
    {
        count += 1;
        let len = (positions[s.a as usize] - positions[s.b as usize]).length() as f64;
        let rest = s.rest as f64;
        let err = len - rest;
        e.total_squared_error += err * err;
        let strain = err.abs() / rest;
        e.mean_strain += strain;
        if strain > e.max_strain || strain.is_nan() {
            e.max_strain = strain;
        }
        let free = model.inv_mass[s.a as usize] != 0.0 && model.inv_mass[s.b as usize] != 0.0;
        if free && (strain > e.max_free_strain || strain.is_nan()) {
            e.max_free_strain = strain;
        }
        let stretch = err / rest;
        if stretch > e.max_stretch || stretch.is_nan() {
            e.max_stretch = stretch;
        }
    }
    if count > 0 {
        e.mean_strain /= count as f64;
    }
    let (mean, max) = shear(model, positions);
    e.mean_shear_deg = mean;
    e.max_shear_deg = max;
    e
}

/// Mean and largest |90° − angle| over the model's cell corners that the solver moves (a
/// corner whose three particles are all pinned or attached has the shape its targets give it).
fn shear(model: &Model, positions: &[Vec4]) -> (f64, f64) {
    let (mut sum, mut max, mut count) = (0.0f64, 0.0f64, 0usize);
    for &[c, a, b] in &model.corners {
        if [c, a, b].iter().all(|&p| model.inv_mass[p as usize] == 0.0) {
            continue;
        }
        let at = positions[c as usize].truncate().as_dvec3();
        let u = positions[a as usize].truncate().as_dvec3() - at;
        let v = positions[b as usize].truncate().as_dvec3() - at;
        let cos = (u.dot(v) / (u.length() * v.length())).clamp(-1.0, 1.0);
        let deviation = (cos.acos().to_degrees() - 90.0).abs();
        sum += deviation;
        if deviation > max || deviation.is_nan() {
            max = deviation;
        }
        count += 1;
    }
    (if count > 0 { sum / count as f64 } else { 0.0 }, max)
}

/// Energies of a state [J].
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Energy {
    /// ½ Σ m |v|².
    pub kinetic: f64,
    /// −Σ m g·x (zero at the origin).
    pub gravitational: f64,
    /// Σ over all springs of w/2 (|q_a − q_b| − L)².
    pub elastic: f64,
}

impl Energy {
    /// Kinetic + gravitational + elastic.
    pub fn total(&self) -> f64 {
        self.kinetic + self.gravitational + self.elastic
    }
}

/// Energies of `state` under `gravity`.
pub fn energy(model: &Model, state: &State, gravity: Vec3) -> Energy {
    let mut e = Energy::default();
    let g = gravity.as_dvec3();
    // Pinned and attached particles are moved by the scene, not the simulation: their energy is
    // not the cloth's.
    for i in (0..model.particle_count()).filter(|&i| model.inv_mass[i] != 0.0) {
        let m = model.mass[i] as f64;
        let x = state.positions[i].truncate().as_dvec3();
        let v = state.velocities[i].truncate().as_dvec3();
        e.kinetic += 0.5 * m * v.length_squared();
        e.gravitational -= m * g.dot(x);
    }
    for (s, &w) in model.springs.iter().zip(&model.spring_weight) {
        let len = (state.positions[s.a as usize] - state.positions[s.b as usize]).length() as f64;
        let err = len - s.rest as f64;
        e.elastic += 0.5 * w as f64 * err * err;
    }
    e
}

/// Why a run counts as unstable (`scenes.md`: non-finite positions, strain above 1, or kinetic
/// energy above 10 × the potential energy released so far), or `None` while it is stable.
pub fn instability(
    state: &State,
    error: &ConstraintError,
    energy: &Energy,
    initial: &Energy,
    supplied: f64,
    integrating: bool,
) -> Option<String> {
    if !state.is_finite() {
        return Some(NOT_FINITE.into());
    }
    if !integrating {
        return (!error.max_strain.is_finite()).then(|| NOT_FINITE.into());
    }
    unstable_reason(true, error.max_free_strain, energy, initial, supplied)
}

const NOT_FINITE: &str = "positions are no longer finite";

/// The stability rule of `scenes.md` on plain numbers, shared by every solver and integrator:
/// `finite` (every position), the largest structural strain, the energies now and at the start,
/// and the energy `supplied` from outside so far (work of the wind, of animated attachments),
/// which counts as released like the potential energy.
pub fn unstable_reason(
    finite: bool,
    max_strain: f64,
    energy: &Energy,
    initial: &Energy,
    supplied: f64,
) -> Option<String> {
    if !finite || !max_strain.is_finite() || !energy.kinetic.is_finite() {
        return Some(NOT_FINITE.into());
    }
    if max_strain > 1.0 {
        let percent = max_strain * 100.0;
        let shown = if percent < 1e5 {
            format!("{percent:.0}")
        } else {
            format!("{percent:.1e}")
        };
        return Some(format!(
            "a spring is stretched {shown} % past its rest length (the limit is 100 %)"
        ));
    }
    // Energy released so far: by gravity, and by springs that started stretched (scene E).
    let released = (initial.gravitational - energy.gravitational).max(0.0)
        + (initial.elastic - energy.elastic).max(0.0)
        + supplied.max(0.0);
    // A floor of 1 µJ keeps the first steps, which have released almost nothing, from counting.
    if energy.kinetic > 10.0 * released + 1e-6 {
        return Some(format!(
            "kinetic energy {:.3e} J exceeds 10 × the {:.3e} J of energy released or supplied",
            energy.kinetic, released
        ));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::garment::Garment;

    /// A 3 × 1 rope's positions with its two springs at `first` and `second` times their rest.
    fn rope(first: f32, second: f32) -> ConstraintError {
        rope_pinned(first, second, "")
    }

    /// [`rope`] with `pins` (a scene's `"pins"` field and a comma, or nothing).
    fn rope_pinned(first: f32, second: f32, pins: &str) -> ConstraintError {
        let text = format!(
            r#"{{ "garments": [{{ "kind": "rope", "resolution": [3], "size": [0.2] {pins} }}] }}"#
        );
        let scene = crate::scene::Scene::parse(&text, "<test>").unwrap();
        let garments: Vec<Garment> = crate::garment::build_all(&scene, "<test>").unwrap();
        let model = Model::new(&garments);
        let x = [0.0, 0.1 * first, 0.1 * first + 0.1 * second];
        let mut positions = vec![Vec4::ZERO; 3];
        for (k, &s) in model.storage_of.iter().enumerate() {
            positions[s as usize] = Vec4::new(x[k], 1.0, 0.0, 0.0);
        }
        constraint_error(&model, &positions)
    }

    #[test]
    fn stretch_leaves_compression_out_and_strain_counts_both() {
        let squeezed = rope(0.8, 1.05);
        assert!((squeezed.max_strain - 0.2).abs() < 1e-6, "{squeezed:?}");
        assert!((squeezed.max_stretch - 0.05).abs() < 1e-6, "{squeezed:?}");
        let pulled = rope(1.1, 0.95);
        assert!((pulled.max_strain - 0.1).abs() < 1e-6, "{pulled:?}");
        assert!((pulled.max_stretch - 0.1).abs() < 1e-6, "{pulled:?}");
    }

    /// A spring from a held particle stretched past 100 % counts in the strain but not in the
    /// stability rule; one between two free particles counts in both.
    #[test]
    fn springs_from_held_particles_are_left_out_of_the_stability_rule() {
        let quiet = Energy::default();
        let unstable =
            |e: &ConstraintError| unstable_reason(true, e.max_free_strain, &quiet, &quiet, 1.0);
        let held = rope_pinned(2.5, 1.5, r#", "pins": [[0]]"#);
        assert!((held.max_strain - 1.5).abs() < 1e-6, "{held:?}");
        assert!((held.max_free_strain - 0.5).abs() < 1e-6, "{held:?}");
        assert_eq!(unstable(&held), None);
        let free = rope_pinned(1.5, 2.5, r#", "pins": [[0]]"#);
        assert!((free.max_free_strain - 1.5).abs() < 1e-6, "{free:?}");
        assert!(
            unstable(&free).is_some_and(|r| r.contains("150 %")),
            "{free:?}"
        );
    }
}
