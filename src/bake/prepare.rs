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
    /// What the report warns of (skin attachments whose skin carries neighbours apart, sheets
    /// that self-collide with nothing holding their cells square).
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
    let mut warnings =
        crate::garment::advice::folding_warnings(&garments, scene.particle_collisions);
    let bodies: Vec<_> = (character_meshes.iter())
        .filter_map(|m| {
            Some((
                m.name.clone(),
                crate::garment::voxel::bounds(m.frames.first()?),
            ))
        })
        .collect();
    warnings.extend(crate::garment::advice::on_body_warnings(
        &scene.garments,
        &garments,
        &bodies,
    ));
    warnings.extend(crate::collide::crossings::modelled_warnings(&garments));
    warnings.extend(crate::collide::crossings::between_warnings(&garments));
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
            .bind_skins(skins, scene.frame_start)
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
