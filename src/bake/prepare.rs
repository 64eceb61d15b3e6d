//! A scene and its loaded characters made into a complete simulation: the one place that wires
//! garments, colliders, characters' shells (swept as the scene says) and attachments to skins
//! together, for the bake and for the tests alike.

use super::characters::LoadedCharacter;
use crate::error::{Error, Result};
use crate::mesh::AnimatedMesh;
use crate::report::CharacterReport;
use crate::scene::Scene;
use crate::sim::attach::Skin;
use crate::sim::Simulation;

/// A simulation ready to step, with what the bake reports and exports of its characters.
pub struct Prepared {
    pub sim: Simulation,
    /// What the report says of each character.
    pub characters: Vec<CharacterReport>,
    /// The characters' meshes over frames 0…N (those whose topology holds), for the exports.
    pub character_meshes: Vec<AnimatedMesh>,
    /// What the report warns of (skin attachments bound far from the skin, sheets that
    /// self-collide with nothing holding their cells square).
    pub warnings: Vec<String>,
}

/// Builds the complete simulation of a (validated) scene with its loaded characters; `file`
/// names the scene in errors (an attachment that selects nothing, a skin that is not there).
pub fn simulation(scene: &Scene, characters: Vec<LoadedCharacter>, file: &str) -> Result<Prepared> {
    let garments = crate::garment::build_all(scene, file)?;
    let mut sim = Simulation::from_garments(scene, &garments, scene.solver.clone());
    let mut reports = Vec::new();
    let mut character_meshes = Vec::new();
    let mut binds = Vec::new();
    for mut c in characters {
        c.shell.swept = scene.swept_collisions;
        sim.drivers.shells.push(c.shell);
        reports.push(c.report);
        if c.mesh.is_some() {
            binds.push(c.bind);
        }
        character_meshes.extend(c.mesh);
    }
    let mut warnings = folding_warnings(scene, &garments);
    if !sim.drivers.attachments.unbound().is_empty() {
        let skins = character_meshes
            .iter()
            .zip(binds)
            .map(|(m, bind)| {
                Skin::new(
                    m.name.clone(),
                    m.triangles.clone(),
                    m.frames.clone(),
                    Some(bind),
                )
            })
            .collect();
        let bound = sim
            .drivers
            .attachments
            .bind_skins(skins)
            .map_err(|reason| Error::InvalidField {
                file: file.to_string(),
                field: "garments[].attachments".into(),
                reason,
            })?;
        warnings.extend(bound);
        sim.drivers.start_lifted(&mut sim.state);
    }
    Ok(Prepared {
        sim,
        characters: reports,
        character_meshes,
        warnings,
    })
}

/// A warning for each sheet or solid that collides with itself without shear springs. The
/// self-collisions skip a particle's lattice neighbours, diagonal ones included (springs hold
/// them, and at rest they already touch), so without shear springs nothing keeps a cell from
/// shearing flat and its triangles from folding through their neighbours': on scene P that was
/// 2 617 crossing triangle pairs over the bake, and none with `stiffness.shear` 300
/// (`docs/benchmarks.md`, "Cells that shear flat fold through themselves").
pub fn folding_warnings(scene: &Scene, garments: &[crate::garment::Garment]) -> Vec<String> {
    use crate::garment::stencil::SpringFamily;
    if !scene.particle_collisions {
        return Vec::new();
    }
    garments
        .iter()
        .filter(|g| g.dims.iter().filter(|&&n| n > 1).count() >= 2)
        .filter(|g| !(g.stencil.offsets.iter()).any(|(_, f)| *f == SpringFamily::Shear))
        .map(|g| {
            format!(
                "garment {}: self-collisions without shear springs: nothing keeps its cells from shearing flat, and cloth folded that tightly passes through itself where no collision looks (give it stiffness.shear, e.g. 3 % of stretch)",
                g.name
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The warnings for a sheet, a rope and a sheet with shear springs, with self-collisions
    /// on or off: the garments named.
    fn warned(collisions: bool) -> Vec<String> {
        let text = format!(
            r#"{{ "particle_collisions": {collisions}, "garments": [
                {{ "name": "bare", "resolution": [6, 6], "size": [0.5, 0.5] }},
                {{ "name": "rope", "kind": "rope", "resolution": [8], "size": [0.5] }},
                {{ "name": "held", "resolution": [6, 6], "size": [0.5, 0.5],
                   "stiffness": {{ "stretch": 10000, "shear": 300 }} }} ] }}"#
        );
        let scene = Scene::parse(&text, "<test>").unwrap();
        let garments = crate::garment::build_all(&scene, "<test>").unwrap();
        folding_warnings(&scene, &garments)
    }

    #[test]
    fn only_a_self_colliding_sheet_without_shear_springs_is_warned_of() {
        let found = warned(true);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].starts_with("garment bare: self-collisions without shear springs"));
        assert!(warned(false).is_empty());
    }
}
