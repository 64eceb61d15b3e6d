//! Rejects impossible scene values, naming the field (as a JSON path) and the reason.

use super::{FillMode, GarmentKind, GarmentSpec, ParticleSelection, Scene};
use crate::error::{Error, Result};

/// The most particles one scene may hold (about 3 GiB of solver state): a guard against a typo
/// such as a resolution of 100000 asking for all the machine's memory.
pub const MAX_PARTICLES: u64 = 50_000_000;

/// The most frames one bake may ask for (over 4 hours at 60 fps): a typo such as 4294967295
/// must be refused before anything is allocated for it.
pub const MAX_FRAMES: u32 = 1_000_000;

/// The largest frame number a bake may write (`frame_start` + frames − 1).
pub const MAX_FRAME_NUMBER: u32 = 9_999_999;

/// The most substeps per frame (from `substeps` or `timestep`).
pub const MAX_SUBSTEPS: u32 = 100_000;

/// The most outer solver iterations per substep.
pub const MAX_ITERATIONS: u32 = 100_000;

/// The most inner iterations per outer iteration.
pub const MAX_INNER_ITERATIONS: u32 = 1_000;

/// The most particle-iterations a whole bake may ask for (frames × substeps × iterations ×
/// inner iterations × particles): at the 25 ns per particle-iteration measured on a 2-core
/// machine, 10¹⁵ is about a year. A bake that cannot finish is refused up front.
pub const MAX_WORK: f64 = 1e15;

/// The most analytic colliders in one scene (each costs memory for its exported mesh and a test
/// per particle per substep).
pub const MAX_COLLIDERS: usize = 1_000;

/// The longest name (scene, garment, character) in bytes: names become file names.
pub const MAX_NAME_BYTES: usize = 100;

/// Why `name` cannot name output files, or None when it can: not empty, at most
/// [`MAX_NAME_BYTES`] bytes, no path separator or control character, not hidden.
pub fn bad_name(name: &str) -> Option<String> {
    let reason = if name.is_empty() {
        "is empty"
    } else if name.len() > MAX_NAME_BYTES {
        return Some(format!(
            "is {} bytes long; a name becomes a file name and may have at most {MAX_NAME_BYTES}",
            name.len()
        ));
    } else if name.contains(['/', '\\']) {
        "contains a path separator (a name is a file name, never a path)"
    } else if name.chars().any(char::is_control) {
        "contains a control character"
    } else if name.starts_with('.') {
        "starts with a dot (hidden file, or . and ..)"
    } else {
        return None;
    };
    Some(format!("{name:?} cannot name output files: it {reason}"))
}

/// Checks every value of a parsed scene; `file` names the source in the error.
pub fn validate(scene: &Scene, file: &str) -> Result<()> {
    let fail = |field: String, reason: String| Error::InvalidField {
        file: file.to_string(),
        field,
        reason,
    };
    let lift = |(field, reason): Failure| fail(field, reason);
    check_timing(scene).map_err(lift)?;
    let particles = check_garments(scene).map_err(lift)?;
    check_work(scene, particles).map_err(lift)?;
    check_characters(scene).map_err(lift)?;
    for (i, g) in scene.garments.iter().enumerate() {
        for a in &g.attachments {
            if let Some(name) = &a.character {
                let known = (0..scene.characters.len()).any(|k| scene.character_name(k) == *name);
                if !known {
                    return Err(fail(
                        format!("garments[{i}].attachments"),
                        format!("no character named {name:?} in this scene"),
                    ));
                }
            }
        }
    }
    if scene.colliders.len() > MAX_COLLIDERS {
        return Err(fail(
            "colliders".into(),
            format!(
                "{} colliders is more than drape's limit of {MAX_COLLIDERS}",
                scene.colliders.len()
            ),
        ));
    }
    for (i, c) in scene.colliders.iter().enumerate() {
        validate_collider(c).map_err(|(f, r)| fail(format!("colliders[{i}].{f}"), r))?;
    }
    if scene.forces.len() > super::force::MAX_FORCES {
        return Err(fail(
            "forces".into(),
            format!(
                "{} force fields is more than drape's limit of {}",
                scene.forces.len(),
                super::force::MAX_FORCES
            ),
        ));
    }
    for (i, f) in scene.forces.iter().enumerate() {
        super::force::validate(f).map_err(|(f, r)| fail(format!("forces[{i}].{f}"), r))?;
    }
    if let Some(a) = &scene.accuracy {
        for (name, v) in [
            ("max_strain", a.max_strain),
            ("max_penetration", a.max_penetration),
            ("max_shear", a.max_shear),
        ] {
            if let Some(v) = v {
                positive(v).map_err(|r| fail(format!("accuracy.{name}"), r))?;
            }
        }
        if a.max_shear.is_some() && !scene.garments.iter().any(|g| g.stiffness.shear > 0.0) {
            return Err(fail(
                "accuracy.max_shear".into(),
                "no garment has shear springs (stiffness.shear), so no budget can hold its cells square: give them shear springs or drop the target".into(),
            ));
        }
    }
    if let Some(r) = scene.particle_radius {
        length(r).map_err(|r| fail("particle_radius".into(), r))?;
    }
    let [w, h] = scene.output.preview_size;
    if !(1..=8192).contains(&w) || !(1..=8192).contains(&h) {
        return Err(fail(
            "output.preview_size".into(),
            format!("{w}×{h} is outside 1…8192 pixels per side"),
        ));
    }
    Ok(())
}

/// A field that failed and why.
pub(crate) type Failure = (String, String);

/// The name, the clock (fps, frames, substeps or timestep), gravity, damping and the solver.
fn check_timing(scene: &Scene) -> std::result::Result<(), Failure> {
    let fail = |field: String, reason: String| (field, reason);
    if let Some(reason) = bad_name(&scene.name) {
        return Err(fail("name".into(), reason));
    }
    positive(scene.fps).map_err(|r| fail("fps".into(), r))?;
    if scene.frames == 0 || scene.frames > MAX_FRAMES {
        return Err(fail(
            "frames".into(),
            format!("must lie between 1 and {MAX_FRAMES} (got {})", scene.frames),
        ));
    }
    if scene.frame_start > MAX_FRAME_NUMBER - (scene.frames - 1) {
        return Err(fail(
            "frame_start".into(),
            format!(
                "frame {} + {} frames passes frame {MAX_FRAME_NUMBER}",
                scene.frame_start, scene.frames
            ),
        ));
    }
    match (scene.substeps, scene.timestep) {
        (Some(_), Some(_)) => {
            return Err(fail(
                "timestep".into(),
                "give either substeps or timestep, not both".into(),
            ))
        }
        (Some(n), None) if n == 0 || n > MAX_SUBSTEPS => {
            return Err(fail(
                "substeps".into(),
                format!("must lie between 1 and {MAX_SUBSTEPS} per frame (got {n})"),
            ))
        }
        (None, Some(dt)) => {
            positive(dt).map_err(|r| fail("timestep".into(), r))?;
            let per_frame = 1.0 / (scene.fps as f64 * dt as f64);
            if per_frame > MAX_SUBSTEPS as f64 {
                return Err(fail(
                    "timestep".into(),
                    format!(
                        "{dt:e} s at {} fps is {per_frame:.3e} substeps per frame, more than the \
                         {MAX_SUBSTEPS} a bake can run",
                        scene.fps
                    ),
                ));
            }
        }
        _ => {}
    }
    finite3(scene.gravity).map_err(|r| fail("gravity".into(), r))?;
    non_negative(scene.damping).map_err(|r| fail("damping".into(), r))?;
    let solver = &scene.solver;
    for (field, n, most) in [
        ("solver.iterations", solver.iterations, MAX_ITERATIONS),
        (
            "solver.inner_iterations",
            solver.inner_iterations,
            MAX_INNER_ITERATIONS,
        ),
    ] {
        if n == 0 || n > most {
            return Err(fail(
                field.into(),
                format!("must lie between 1 and {most} (got {n})"),
            ));
        }
    }
    if solver.contact_passes == 0 || solver.contact_passes > solver.iterations {
        return Err(fail(
            "solver.contact_passes".into(),
            format!(
                "must lie between 1 and solver.iterations ({}): each pass follows a share of \
                 the iterations (got {})",
                solver.iterations, solver.contact_passes
            ),
        ));
    }
    if let Some(limit) = solver.strain_limit.filter(|l| !(*l > 0.0 && *l <= 1.0)) {
        return Err(fail(
            "solver.strain_limit".into(),
            format!(
                "must lie in (0, 1], a strain (0.2: springs at most 20 % past their rest \
                 length; above 1 the stability rule stops the bake first) (got {limit})"
            ),
        ));
    }
    if !(solver.omega > 0.0 && solver.omega < 2.0) {
        return Err(fail(
            "solver.omega".into(),
            format!(
                "must lie in (0, 2) for over-relaxation to converge (got {})",
                solver.omega
            ),
        ));
    }
    Ok(())
}

/// Every garment, and their names; returns the particles of the sheets and ropes.
fn check_garments(scene: &Scene) -> std::result::Result<u64, Failure> {
    let fail = |field: String, reason: String| (field, reason);
    if scene.garments.is_empty() {
        return Err(fail(
            "garments".into(),
            "a scene needs at least one garment".into(),
        ));
    }
    let mut names = std::collections::HashSet::new();
    let mut particles = 0u64;
    for (i, g) in scene.garments.iter().enumerate() {
        let at = |f: &str| format!("garments[{i}].{f}");
        particles = particles.saturating_add(validate_garment(g).map_err(|(f, r)| fail(at(f), r))?);
        if let (Some(tear), Some(limit)) = (g.tear_strain, scene.solver.strain_limit) {
            if tear >= limit {
                return Err(fail(
                    at("tear_strain"),
                    format!(
                        "{tear} would never be reached: solver.strain_limit pulls every \
                         structural spring back to {limit} after each substep; set it below \
                         the limit, or raise the limit"
                    ),
                ));
            }
        }
        let name = scene.garment_name(i);
        if let Some(reason) = bad_name(&name) {
            return Err(fail(at("name"), reason));
        }
        if !names.insert(name.clone()) {
            return Err(fail(
                at("name"),
                format!("{name:?} is used by two garments"),
            ));
        }
    }
    if particles > MAX_PARTICLES {
        return Err(fail(
            "garments".into(),
            format!("{particles} particles in all is more than drape's limit of {MAX_PARTICLES}"),
        ));
    }
    Ok(particles)
}

/// The whole bake's work: refused when it could not finish.
pub(crate) fn check_work(scene: &Scene, particles: u64) -> std::result::Result<(), Failure> {
    let fail = |field: String, reason: String| (field, reason);
    let solver = &scene.solver;
    let work = scene.frames as f64
        * scene.substeps_per_frame() as f64
        * solver.iterations as f64
        * solver.inner_iterations as f64
        * particles.max(1) as f64;
    if work > MAX_WORK {
        let field = match scene.timestep {
            Some(_) => "timestep",
            None => "substeps",
        };
        return Err(fail(
            field.into(),
            format!(
                "{} frames × {} substeps × {} × {} iterations × {particles} particles is \
                 {work:.2e} particle-iterations, more than drape's limit of {MAX_WORK:.0e} \
                 (about a year on a 2-core machine): the bake could not finish",
                scene.frames,
                scene.substeps_per_frame(),
                solver.iterations,
                solver.inner_iterations
            ),
        ));
    }
    Ok(())
}

/// Every character: file, a unique name, import options, shell radius and friction.
fn check_characters(scene: &Scene) -> std::result::Result<(), Failure> {
    let fail = |field: String, reason: String| (field, reason);
    let mut character_names = std::collections::HashSet::new();
    for (i, c) in scene.characters.iter().enumerate() {
        let at = |f: &str| format!("characters[{i}].{f}");
        if c.file.is_empty() {
            return Err(fail(
                at("file"),
                "a character needs a file, folder or %04d pattern".into(),
            ));
        }
        let name = scene.character_name(i);
        if let Some(reason) = bad_name(&name) {
            return Err(fail(at("name"), reason));
        }
        if !character_names.insert(name.clone()) {
            return Err(fail(
                at("name"),
                format!("{name:?} is used by two characters (attachments name characters)"),
            ));
        }
        c.options()
            .check()
            .map_err(|(field, r)| fail(at(field), r))?;
        length(c.radius).map_err(|r| fail(at("radius"), r))?;
        non_negative(c.friction).map_err(|r| fail(at("friction"), r))?;
        if let Some(p) = c.preroll {
            check_preroll(scene, p).map_err(|r| fail(at("preroll"), r))?;
        }
    }
    for (i, g) in scene.garments.iter().enumerate() {
        let Some(on) = &g.on else { continue };
        let known = (0..scene.characters.len()).any(|k| scene.character_name(k) == *on);
        if !known {
            return Err(fail(
                format!("garments[{i}].on"),
                format!("no character named {on:?} in this scene"),
            ));
        }
    }
    Ok(())
}

/// A pre-roll: some frames, numbered before `frame_start` without going below frame 0.
fn check_preroll(scene: &Scene, p: super::Preroll) -> std::result::Result<(), String> {
    if p.frames() == 0 {
        return Err("needs settle or blend frames (both are 0)".into());
    }
    if p.frames() > MAX_FRAMES {
        return Err(format!(
            "{} frames is more than drape's limit of {MAX_FRAMES}",
            p.frames()
        ));
    }
    let lead = scene.preroll_frames();
    if lead > scene.frame_start {
        return Err(format!(
            "its {lead} frames are numbered before the first frame, down to {}: set \
             frame_start to at least {lead} (shots usually start at 1001)",
            scene.frame_start as i64 - lead as i64
        ));
    }
    Ok(())
}

/// Checks one garment; returns its particle count, or (field, reason).
fn validate_garment(g: &GarmentSpec) -> std::result::Result<u64, (&'static str, String)> {
    if let Some(t) = g.tear_strain {
        positive(t).map_err(|r| ("tear_strain", r))?;
    }
    let axes = match g.kind {
        GarmentKind::Sheet => 2,
        GarmentKind::Rope => 1,
        GarmentKind::Mesh => return validate_mesh_garment(g).map(|()| 0),
    };
    if g.mesh.is_some() || g.spacing.is_some() || g.scale != 1.0 || g.fill != FillMode::Auto {
        return Err((
            "mesh",
            "mesh, spacing, scale and fill belong to mesh garments (kind \"mesh\")".into(),
        ));
    }
    if g.on.is_some() || g.mesh_name.is_some() {
        return Err((
            if g.on.is_some() { "on" } else { "mesh_name" },
            "on and mesh_name belong to mesh garments (kind \"mesh\"), modelled in a file".into(),
        ));
    }
    check_common(g)?;
    let kind = format!("{:?}", g.kind).to_lowercase();
    if g.resolution.len() != axes {
        return Err((
            "resolution",
            format!("a {kind} needs {axes} values, got {}", g.resolution.len()),
        ));
    }
    if let Some(&n) = g.resolution.iter().find(|&&n| n < 2) {
        return Err((
            "resolution",
            format!("needs at least 2 particles per axis, got {n}"),
        ));
    }
    let size = g.size();
    if size.len() != axes {
        return Err((
            "size",
            format!("a {kind} needs {axes} values, got {}", size.len()),
        ));
    }
    for &s in &size {
        length(s).map_err(|r| ("size", r))?;
    }
    if g.hole_radius > 0.0 {
        if g.kind != GarmentKind::Sheet {
            return Err((
                "hole_radius",
                format!("only sheets have holes, not a {kind}"),
            ));
        }
        let half = 0.5 * size[0].min(size[1]);
        if g.hole_radius >= half {
            return Err((
                "hole_radius",
                format!(
                    "{} m leaves no cloth in a {:?} m sheet",
                    g.hole_radius, size
                ),
            ));
        }
    }
    check_cells(&g.pins, axes, &g.resolution, "pins")?;
    for a in &g.attachments {
        if let ParticleSelection::Cells(cells) = &a.particles {
            check_cells(cells, axes, &g.resolution, "attachments")?
        }
    }
    check_attachments(g, &super::REGIONS)?;
    Ok(g.resolution.iter().map(|&n| n as u64).product())
}

/// The fields every kind of garment has.
fn check_common(g: &GarmentSpec) -> std::result::Result<(), (&'static str, String)> {
    if let Some(c) = g.colour {
        if !c.iter().all(|v| (0.0..=1.0).contains(v)) {
            return Err(("colour", format!("{c:?}: each channel must lie in 0…1")));
        }
    }
    positive(g.mass).map_err(|r| ("mass", r))?;
    finite3(g.position).map_err(|r| ("position", r))?;
    finite3(g.rotation).map_err(|r| ("rotation", r))?;
    positive(g.initial_stretch).map_err(|r| ("initial_stretch", r))?;
    if g.initial_stretch > MAX_STRETCH {
        return Err((
            "initial_stretch",
            format!(
                "{} is more than {MAX_STRETCH}: the cloth would start farther apart than any bake can pull together",
                g.initial_stretch
            ),
        ));
    }
    non_negative(g.thickness).map_err(|r| ("thickness", r))?;
    positive(g.stiffness.stretch).map_err(|r| ("stiffness.stretch", r))?;
    non_negative(g.stiffness.shear).map_err(|r| ("stiffness.shear", r))?;
    non_negative(g.stiffness.bend).map_err(|r| ("stiffness.bend", r))?;
    non_negative(g.hole_radius).map_err(|r| ("hole_radius", r))?;
    Ok(())
}

/// Checks a mesh garment's own fields (its cells are checked once it is voxelized).
fn validate_mesh_garment(g: &GarmentSpec) -> std::result::Result<(), (&'static str, String)> {
    if g.mesh.as_deref().is_none_or(str::is_empty) {
        return Err(("mesh", "a mesh garment needs a mesh file".into()));
    }
    if let Some(s) = g.spacing {
        length(s).map_err(|r| ("spacing", r))?;
    }
    positive(g.scale).map_err(|r| ("scale", r))?;
    if g.on.is_some() && g.scale != 1.0 {
        return Err((
            "scale",
            "a garment on a character is in the character's units: its `scale` applies".into(),
        ));
    }
    if g.mesh_name.as_deref() == Some("") {
        return Err(("mesh_name", "names no mesh (empty)".into()));
    }
    check_common(g)?;
    if g.hole_radius > 0.0 {
        return Err(("hole_radius", "only sheets have holes, not a mesh".into()));
    }
    if g.initial_stretch != 1.0 {
        return Err((
            "initial_stretch",
            "a mesh garment starts at its rest shape (scale it with `scale`)".into(),
        ));
    }
    check_attachments(g, &super::MESH_REGIONS)
}

/// Regions, proximity selections and targets of a garment's attachments.
fn check_attachments(
    g: &GarmentSpec,
    regions: &[&str],
) -> std::result::Result<(), (&'static str, String)> {
    for a in &g.attachments {
        match &a.particles {
            ParticleSelection::Region(r) => {
                if !regions.contains(&r.as_str()) {
                    return Err((
                        "attachments",
                        format!("unknown region {r:?} (known: {})", regions.join(", ")),
                    ));
                }
            }
            ParticleSelection::Near(n) => {
                finite3(n.near).map_err(|r| ("attachments", format!("near: {r}")))?;
                length(n.radius).map_err(|r| ("attachments", format!("radius: {r}")))?;
            }
            ParticleSelection::Cells(_) => {}
        }
        match (&a.character, a.keyframes.is_empty()) {
            (Some(_), false) | (None, true) => {
                return Err((
                    "attachments",
                    "an attachment follows either a character or keyframes, exactly one".into(),
                ))
            }
            _ => {}
        }
        check_keyframes(&a.keyframes, "attachments")?;
        if let Some(p) = a.pivot {
            finite3(p).map_err(|r| ("attachments", format!("pivot: {r}")))?;
        }
    }
    Ok(())
}

/// Keyframes of a rigid motion: finite, times from 0 on and strictly increasing.
fn check_keyframes(
    keys: &[super::KeyframeSpec],
    field: &'static str,
) -> std::result::Result<(), (&'static str, String)> {
    for (k, key) in keys.iter().enumerate() {
        let finite = key.time.is_finite()
            && key
                .translation
                .iter()
                .chain(&key.rotation)
                .all(|v| v.is_finite());
        if !finite || key.time < 0.0 || (k > 0 && key.time <= keys[k - 1].time) {
            return Err((
                field,
                format!("keyframe {k}: times must be finite, at least 0 and increasing"),
            ));
        }
        finite3(key.translation).map_err(|r| (field, format!("keyframe {k}: translation {r}")))?;
    }
    Ok(())
}

/// Grid coordinates (pins, attachments): one per grid axis, inside the grid.
fn check_cells(
    cells: &[Vec<i64>],
    axes: usize,
    resolution: &[u32],
    field: &'static str,
) -> std::result::Result<(), (&'static str, String)> {
    for cell in cells {
        if cell.len() != axes {
            return Err((field, format!("{cell:?} needs {axes} grid coordinates")));
        }
        for (&c, &n) in cell.iter().zip(resolution) {
            if c >= n as i64 || c < -(n as i64) {
                return Err((
                    field,
                    format!("{cell:?} lies outside the {resolution:?} grid"),
                ));
            }
        }
    }
    Ok(())
}

/// The values of a collider (its fields already match its kind: parsing checked them).
fn validate_collider(c: &super::ColliderSpec) -> std::result::Result<(), (&'static str, String)> {
    use super::ColliderShape as S;
    non_negative(c.friction).map_err(|r| ("friction", r))?;
    let point = |v: [f32; 3], field: &'static str| finite3(v).map_err(|r| (field, r));
    let size = |v: f32, field: &'static str| length(v).map_err(|r| (field, r));
    let rotation = |r: Option<[f32; 3]>| r.map_or(Ok(()), |r| point(r, "rotation"));
    check_keyframes(&c.keyframes, "keyframes")?;
    match c.shape {
        S::Plane { point: p, normal } => {
            if let Some(p) = p {
                point(p, "point")?;
            }
            if let Some(n) = normal {
                point(n, "normal")?;
                if glam::Vec3::from(n).length() < 1e-6 {
                    return Err(("normal", "must not be the zero vector".into()));
                }
            }
        }
        S::Sphere { centre, radius } => {
            point(centre, "centre")?;
            size(radius, "radius")?;
        }
        S::Funnel {
            centre,
            radius,
            top_radius,
            height,
            thickness,
        } => {
            if c.keyframes.iter().any(|k| k.rotation != [0.0; 3]) {
                return Err((
                    "keyframes",
                    "a funnel stays upright: its keyframes may translate it, not turn it".into(),
                ));
            }
            point(centre, "centre")?;
            size(radius, "radius")?;
            size(top_radius, "top_radius")?;
            size(height, "height")?;
            if let Some(t) = thickness {
                size(t, "thickness")?;
            }
        }
        S::Box {
            centre,
            size: edges,
            rotation: r,
        }
        | S::Wedge {
            centre,
            size: edges,
            rotation: r,
        } => {
            point(centre, "centre")?;
            point(edges, "size")?;
            if edges.iter().any(|&e| e <= 0.0) {
                return Err((
                    "size",
                    format!("{edges:?}: every edge must be longer than 0"),
                ));
            }
            for &e in &edges {
                size(e, "size")?;
            }
            rotation(r)?;
        }
        S::Capsule { start, end, radius } => {
            point(start, "start")?;
            point(end, "end")?;
            size(radius, "radius")?;
        }
    }
    Ok(())
}

pub(crate) fn positive(v: f32) -> std::result::Result<(), String> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(format!("must be a finite number above zero (got {v})"))
    }
}

fn non_negative(v: f32) -> std::result::Result<(), String> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(format!("must be a finite number, zero or above (got {v})"))
    }
}

/// The largest coordinate or length [m] a scene may hold: single-precision positions resolve
/// 100 km to 8 mm, and nothing a cloth bake models is larger.
pub const MAX_EXTENT: f32 = 1e5;

pub(crate) fn finite3(v: [f32; 3]) -> std::result::Result<(), String> {
    if !v.iter().all(|x| x.is_finite()) {
        Err(format!("must be finite (got {v:?})"))
    } else if v.iter().any(|x| x.abs() > MAX_EXTENT) {
        Err(format!(
            "{v:?} lies beyond ±{MAX_EXTENT:.0e}, where single precision cannot resolve a cloth"
        ))
    } else {
        Ok(())
    }
}

/// The largest `initial_stretch` (scene E lays its cloth at 5).
pub const MAX_STRETCH: f32 = 1000.0;

/// A length [m]: above zero and at most [`MAX_EXTENT`].
pub fn length(v: f32) -> std::result::Result<(), String> {
    positive(v)?;
    if v > MAX_EXTENT {
        return Err(format!(
            "{v} m is beyond {MAX_EXTENT:.0e} m, where single precision cannot resolve a cloth"
        ));
    }
    Ok(())
}
