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

/// How far a garment modelled on a character (`on`) may be from the body's size, as a share
/// of the body's height, before it is warned of: a collar or a glove is a tenth of a body, a
/// long cape or a blanket wrapped round it a few bodies; a file in metres read with a
/// character's centimetres is a hundredth (or a hundred times).
pub const ON_BODY_SIZES: std::ops::RangeInclusive<f32> = (1.0 / 30.0)..=10.0;

/// How far past the box around a body, as a share of its height, a garment modelled on it may
/// lie without being warned of (3 cm on a 1.5 m body: rounding, and cloth modelled loose).
pub const ON_BODY_MARGIN: f32 = 0.02;

/// A warning for each garment modelled on a character (`on`) that does not sit on that body as
/// modelled: its placed size far from the body's ([`ON_BODY_SIZES`]: a file in other units,
/// which lands tiny at the feet or huge around it), or its box apart from the body's, grown by
/// [`ON_BODY_MARGIN`] of its height (a file exported with another up axis or placement: a cape
/// turned onto its back lies beside the feet, and its attachments tear it on the first frame).
/// A garment modelled on a body meets the box around it: an `on` garment's file is read in the
/// character file's units and bind-pose frame.
/// `bodies`: each character's name and the box around its body (the bake's first frame for
/// the bake, the bind pose for `drape inspect`).
pub fn on_body_warnings(
    specs: &[crate::scene::GarmentSpec],
    garments: &[Garment],
    bodies: &[(String, (glam::Vec3, glam::Vec3))],
) -> Vec<String> {
    use glam::Vec3;
    let extent = |(lo, hi): (Vec3, Vec3)| (hi - lo).max_element();
    let mut warnings = Vec::new();
    for (spec, g) in specs.iter().zip(garments) {
        let Some(on) = spec.on.as_deref() else {
            continue;
        };
        let Some((_, body)) = bodies.iter().find(|(name, _)| name == on) else {
            continue;
        };
        let tall = body.1.y - body.0.y;
        let placed = super::voxel::bounds(&g.positions);
        let across = extent(placed);
        let share = across / tall;
        if !(tall > 0.0 && share.is_finite()) {
            continue;
        }
        if !ON_BODY_SIZES.contains(&share) {
            warnings.push(format!(
                "garment {} (on {on}): {across:.3} m across where {on} is {tall:.3} m tall ({share:.3} × the body): an `on` garment's file is read in the character file's units and placed by its `scale`; is it in other units (metres against centimetres is 100 ×)?",
                g.name
            ));
            continue;
        }
        let margin = Vec3::splat(ON_BODY_MARGIN * tall);
        let (lo, hi) = (body.0 - margin, body.1 + margin);
        if placed.0.cmpgt(hi).any() || placed.1.cmplt(lo).any() {
            let show = |(a, b): (Vec3, Vec3)| {
                format!(
                    "({:.2}, {:.2}, {:.2})–({:.2}, {:.2}, {:.2}) m",
                    a.x, a.y, a.z, b.x, b.y, b.z
                )
            };
            warnings.push(format!(
                "garment {} (on {on}): it lies at {}, apart from {on}'s body at {}: an `on` garment's file is in the character file's bind-pose frame, and its own `position` and `rotation` move it from there; was it exported with another up axis or placement?",
                g.name,
                show(placed),
                show(*body)
            ));
        }
    }
    warnings
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

    /// A garment modelled on a body is warned of when its size is far from the body's (a file
    /// in other units) or it lies apart from the body (another up axis); not when it is a
    /// garment's size on the body, nor when it is on no character.
    #[test]
    fn an_on_garment_far_from_its_body_size_or_place_is_warned_of() {
        let text = r#"{ "garments": [
            { "name": "cape", "resolution": [6, 6], "size": [0.5, 0.5] },
            { "name": "tiny", "resolution": [6, 6], "size": [0.01, 0.01] },
            { "name": "huge", "resolution": [6, 6], "size": [20, 20] },
            { "name": "loose", "resolution": [6, 6], "size": [0.01, 0.01] } ] }"#;
        let mut scene = Scene::parse(text, "<test>").unwrap();
        let garments = super::super::build_all(&scene, "<test>").unwrap();
        for g in &mut scene.garments[..3] {
            g.on = Some("man".into());
        }
        let body = (
            glam::Vec3::new(-0.3, 0.0, -0.2),
            glam::Vec3::new(0.3, 1.5, 0.2),
        );
        let warned = on_body_warnings(&scene.garments, &garments, &[("man".into(), body)]);
        assert_eq!(warned.len(), 2, "{warned:?}");
        assert!(
            warned[0].starts_with("garment tiny (on man): 0.010 m across"),
            "{warned:?}"
        );
        assert!(
            warned[1].starts_with("garment huge (on man): 20.000 m across"),
            "{warned:?}"
        );
        assert!(
            warned.iter().all(|w| w.contains("1.500 m tall")),
            "{warned:?}"
        );
        // The cape's size, turned onto its back a metre from the body (another up axis).
        scene.garments[0].on = Some("man".into());
        let mut apart = garments.clone();
        for p in &mut apart[0].positions {
            *p = glam::Vec3::new(p.x, p.z, -1.2 - p.y);
        }
        let warned = on_body_warnings(&scene.garments[..1], &apart[..1], &[("man".into(), body)]);
        assert_eq!(warned.len(), 1, "{warned:?}");
        assert!(warned[0].contains("apart from man's body"), "{warned:?}");
        // Touching the body's box grown by `ON_BODY_MARGIN` of its height: not apart.
        let farthest = apart[0]
            .positions
            .iter()
            .map(|p| p.z)
            .fold(f32::MIN, f32::max);
        let shift = (-0.2 - ON_BODY_MARGIN * 1.5 + 0.001) - farthest;
        for p in &mut apart[0].positions {
            p.z += shift;
        }
        let near = on_body_warnings(&scene.garments[..1], &apart[..1], &[("man".into(), body)]);
        assert!(near.is_empty(), "{near:?}");
        // On a character the scene does not have (no body to compare with): nothing.
        let elsewhere = on_body_warnings(&scene.garments, &garments, &[]);
        assert!(elsewhere.is_empty(), "{elsewhere:?}");
    }
}
