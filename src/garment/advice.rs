//! What a scene's garments are warned of before a bake, by the bake and `drape inspect` alike:
//! valid settings that give broken-looking cloth.

use super::stencil::SpringFamily;
use super::Garment;

/// A warning for each sheet or solid that collides with itself (`particle_collisions`) without
/// shear springs. The self-collisions skip a particle's lattice neighbours, diagonal ones
/// included (springs hold them, and at rest they already touch), so without shear springs
/// nothing keeps a cell from shearing flat and its triangles from folding through their
/// neighbours': on scene P that was 2 617 crossing triangle pairs over the bake, and none with
/// `stiffness.shear` 300 (`docs/benchmarks.md`, "Cells that shear flat fold through
/// themselves").
pub fn folding_warnings(garments: &[Garment], particle_collisions: bool) -> Vec<String> {
    if !particle_collisions {
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
    use crate::scene::Scene;

    /// The warnings for a sheet, a rope and a sheet with shear springs, with self-collisions
    /// on or off.
    fn warned(collisions: bool) -> Vec<String> {
        let text = format!(
            r#"{{ "particle_collisions": {collisions}, "garments": [
                {{ "name": "bare", "resolution": [6, 6], "size": [0.5, 0.5] }},
                {{ "name": "rope", "kind": "rope", "resolution": [8], "size": [0.5] }},
                {{ "name": "held", "resolution": [6, 6], "size": [0.5, 0.5],
                   "stiffness": {{ "stretch": 10000, "shear": 300 }} }} ] }}"#
        );
        let scene = Scene::parse(&text, "<test>").unwrap();
        let garments = super::super::build_all(&scene, "<test>").unwrap();
        folding_warnings(&garments, scene.particle_collisions)
    }

    #[test]
    fn only_a_self_colliding_sheet_without_shear_springs_is_warned_of() {
        let found = warned(true);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!(found[0].starts_with("garment bare: self-collisions without shear springs"));
        assert!(warned(false).is_empty());
    }
}
