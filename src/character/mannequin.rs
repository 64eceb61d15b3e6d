//! drape's own mannequin: a 1.8 m humanoid of capsules on a small skeleton, with three clips:
//! raising the arms, sitting down on a stool, and scene P's stand-lift-sit, so scenes need
//! nothing outside the repository.
//!
//! Each body part is a capsule rigidly attached to one bone (the joints overlap, so the surface
//! has no gaps); clips are forward kinematics with smoothstep easing. `drape mannequin --out DIR`
//! writes each clip as an OBJ frame sequence (`DIR/<clip>/frame_0001.obj …`) plus `DIR/stool.obj`;
//! `characters/mannequin/` holds the committed output, which a test regenerates and compares.

use glam::{Mat4, Quat, Vec3};
use std::fmt::Write as _;

/// Frames per second of the stored sequences (scenes at other rates interpolate between frames).
pub const FPS: f32 = 12.0;

/// The two clips: name and duration [s].
pub const CLIPS: [(&str, f32); 3] = [("raise_arms", 1.5), ("sit", 2.0), ("poncho", 4.0)];

/// Seat height of the stool [m], its radius and the centre of its seat in the floor plane.
pub const STOOL_HEIGHT: f32 = 0.37;
pub const STOOL_RADIUS: f32 = 0.20;
pub const STOOL_CENTER: [f32; 2] = [0.0, -0.46];

/// Pelvis joint standing.
const PELVIS_STANDING: Vec3 = Vec3::new(0.0, 1.0, 0.0);
/// Hip joints below the pelvis, thigh length, knee to foot centre, foot centre height.
const HIP_DROP: f32 = 0.05;
const THIGH: f32 = 0.46;
const SHIN: f32 = 0.45;
const FOOT: f32 = 0.04;

/// Capsule segments around and rings per hemisphere: a 5 cm limb gets 3 cm facets, fine enough
/// for collision shells of 1 cm particles, small enough to keep the committed frames at 2 MB.
const SEGMENTS: u32 = 10;
const RINGS: u32 = 3;

/// A capsule on a bone: from the bone's origin along `axis` for `length`, of `radius`, scaled in
/// the bone frame by `squash` (the torso is wider than deep).
struct Part {
    bone: usize,
    offset: Vec3,
    axis: Vec3,
    length: f32,
    radius: f32,
    squash: Vec3,
}

/// Bones: parent, rest offset from the parent [m].
const BONES: [(Option<usize>, [f32; 3]); 11] = [
    (None, [0.0, 0.0, 0.0]),       // 0 pelvis (placed by the clip)
    (Some(0), [0.0, 0.05, 0.0]),   // 1 spine
    (Some(1), [0.0, 0.52, 0.0]),   // 2 neck
    (Some(1), [0.2, 0.42, 0.0]),   // 3 left shoulder
    (Some(3), [0.0, -0.3, 0.0]),   // 4 left elbow
    (Some(1), [-0.2, 0.42, 0.0]),  // 5 right shoulder
    (Some(5), [0.0, -0.3, 0.0]),   // 6 right elbow
    (Some(0), [0.1, -0.05, 0.0]),  // 7 left hip
    (Some(7), [0.0, -0.46, 0.0]),  // 8 left knee
    (Some(0), [-0.1, -0.05, 0.0]), // 9 right hip
    (Some(9), [0.0, -0.46, 0.0]),  // 10 right knee
];

fn parts() -> Vec<Part> {
    let down = Vec3::NEG_Y;
    let part = |bone, offset: [f32; 3], axis: Vec3, length, radius, squash: [f32; 3]| Part {
        bone,
        offset: Vec3::from(offset),
        axis,
        length,
        radius,
        squash: Vec3::from(squash),
    };
    vec![
        part(0, [-0.1, -0.05, 0.0], Vec3::X, 0.2, 0.12, [1.0, 1.0, 0.8]), // pelvis
        part(1, [0.0, 0.0, 0.0], Vec3::Y, 0.4, 0.15, [1.2, 1.0, 0.7]),    // torso
        part(2, [0.0, 0.0, 0.0], Vec3::Y, 0.06, 0.05, [1.0, 1.0, 1.0]),   // neck
        part(2, [0.0, 0.13, 0.0], Vec3::Y, 0.0, 0.11, [0.9, 1.1, 1.0]),   // head
        part(3, [0.0, 0.0, 0.0], down, 0.3, 0.05, [1.0, 1.0, 1.0]),       // left upper arm
        part(4, [0.0, 0.0, 0.0], down, 0.26, 0.04, [1.0, 1.0, 1.0]),      // left forearm and hand
        part(5, [0.0, 0.0, 0.0], down, 0.3, 0.05, [1.0, 1.0, 1.0]),       // right upper arm
        part(6, [0.0, 0.0, 0.0], down, 0.26, 0.04, [1.0, 1.0, 1.0]),      // right forearm and hand
        part(7, [0.0, 0.0, 0.0], down, 0.46, 0.075, [1.0, 1.0, 1.0]),     // left thigh
        part(8, [0.0, 0.0, 0.0], down, 0.44, 0.055, [1.0, 1.0, 1.0]),     // left shin
        part(9, [0.0, 0.0, 0.0], down, 0.46, 0.075, [1.0, 1.0, 1.0]),     // right thigh
        part(10, [0.0, 0.0, 0.0], down, 0.44, 0.055, [1.0, 1.0, 1.0]),    // right shin
        part(8, [0.0, -0.45, 0.05], Vec3::Z, 0.12, 0.045, [1.0, 0.8, 1.0]), // left foot
        part(
            10,
            [0.0, -0.45, 0.05],
            Vec3::Z,
            0.12,
            0.045,
            [1.0, 0.8, 1.0],
        ), // right foot
    ]
}

/// 0 → 1 with zero slope at both ends.
fn smoothstep(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// Pelvis placement and each bone's rotation at time `t` [s] of clip `clip`.
fn pose(clip: &str, t: f32) -> (Vec3, [Quat; 11]) {
    let mut rot = [Quat::IDENTITY; 11];
    let duration = CLIPS.iter().find(|c| c.0 == clip).map_or(1.0, |c| c.1);
    let s = smoothstep(t / duration);
    let mut pelvis = PELVIS_STANDING;
    match clip {
        "raise_arms" => {
            // Abduction from hanging (arms down, slightly out) to overhead.
            let angle = (10.0 + 160.0 * s).to_radians();
            rot[3] = Quat::from_rotation_z(angle);
            rot[5] = Quat::from_rotation_z(-angle);
            rot[4] = Quat::from_rotation_z(0.3 * s);
            rot[6] = Quat::from_rotation_z(-0.3 * s);
        }
        "sit" => {
            // Hips flex by θ (thighs forward) and knees by θ back, so the shins stay vertical; the
            // pelvis follows the legs with the feet planted: y = foot + shin + thigh·cos θ + hip
            // drop, z = −thigh·sin θ. At θ = 90° the pelvis rests on the stool. A slight forward
            // lean in the middle of the motion.
            let theta = std::f32::consts::FRAC_PI_2 * s;
            let hip = Quat::from_rotation_x(-theta);
            let knee = Quat::from_rotation_x(std::f32::consts::FRAC_PI_2 * s);
            rot[7] = hip;
            rot[9] = hip;
            rot[8] = knee;
            rot[10] = knee;
            rot[1] = Quat::from_rotation_x(0.35 * (std::f32::consts::PI * s).sin());
            rot[3] = Quat::from_rotation_z(10f32.to_radians());
            rot[5] = Quat::from_rotation_z(-10f32.to_radians());
            pelvis = Vec3::new(
                0.0,
                FOOT + SHIN + THIGH * theta.cos() + HIP_DROP,
                -THIGH * theta.sin(),
            );
        }
        "poncho" => {
            // Scene P: stand while the poncho settles (0–0.6 s), lift the arms sideways to 80°
            // and lower them (0.6–2.0 s), then sit on the stool (2.0–4.0 s).
            let lift = (smoothstep((t - 0.6) / 0.7) - smoothstep((t - 1.3) / 0.7)).max(0.0);
            let angle = (10.0 + 70.0 * lift).to_radians();
            rot[3] = Quat::from_rotation_z(angle);
            rot[5] = Quat::from_rotation_z(-angle);
            let (sit_pelvis, sit_rot) = pose("sit", (t - 2.0).max(0.0));
            for b in [1, 7, 8, 9, 10] {
                rot[b] = sit_rot[b];
            }
            pelvis = sit_pelvis;
        }
        _ => {}
    }
    (pelvis, rot)
}

/// Global transforms of the bones.
fn bone_transforms(pelvis: Vec3, rot: &[Quat; 11]) -> Vec<Mat4> {
    let mut global: Vec<Mat4> = Vec::with_capacity(BONES.len());
    for (i, (parent, offset)) in BONES.iter().enumerate() {
        let local = Mat4::from_rotation_translation(rot[i], Vec3::from(*offset));
        global.push(match parent {
            Some(p) => global[*p] * local,
            None => Mat4::from_translation(pelvis) * local,
        });
    }
    global
}

/// A capsule mesh in the bone frame: rings of `SEGMENTS` vertices from the start cap through the
/// end cap, plus two pole vertices.
fn capsule(p: &Part, vertices: &mut Vec<Vec3>, triangles: &mut Vec<[u32; 3]>, to_world: Mat4) {
    let base = vertices.len() as u32;
    let axis = p.axis.normalize();
    let side = if axis.abs().dot(Vec3::Y) > 0.9 {
        Vec3::X
    } else {
        Vec3::Y
    };
    let u = axis.cross(side).normalize();
    let v = axis.cross(u);
    let put = |q: Vec3| to_world.transform_point3(p.offset + q * p.squash);
    vertices.push(put(-axis * p.radius));
    let rings: Vec<(f32, f32)> = (1..=RINGS)
        .map(|k| {
            let a = std::f32::consts::FRAC_PI_2 * (1.0 - k as f32 / RINGS as f32);
            (-a.sin() * p.radius, a.cos() * p.radius)
        })
        .chain((0..RINGS).map(|k| {
            let a = std::f32::consts::FRAC_PI_2 * k as f32 / RINGS as f32;
            (p.length + a.sin() * p.radius, a.cos() * p.radius)
        }))
        .collect();
    for &(along, r) in &rings {
        for s in 0..SEGMENTS {
            let phi = std::f32::consts::TAU * s as f32 / SEGMENTS as f32;
            vertices.push(put(axis * along + (u * phi.cos() + v * phi.sin()) * r));
        }
    }
    vertices.push(put(axis * (p.length + p.radius)));
    let ring = |k: u32, s: u32| base + 1 + k * SEGMENTS + s % SEGMENTS;
    let top = base + 1 + rings.len() as u32 * SEGMENTS;
    for s in 0..SEGMENTS {
        triangles.push([base, ring(0, s + 1), ring(0, s)]);
        for k in 0..rings.len() as u32 - 1 {
            triangles.push([ring(k, s), ring(k, s + 1), ring(k + 1, s + 1)]);
            triangles.push([ring(k, s), ring(k + 1, s + 1), ring(k + 1, s)]);
        }
        let last = rings.len() as u32 - 1;
        triangles.push([ring(last, s), ring(last, s + 1), top]);
    }
}

/// The mannequin's mesh at time `t` of `clip` ("raise_arms", "sit" or "poncho").
pub fn mesh(clip: &str, t: f32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (pelvis, rot) = pose(clip, t);
    let bones = bone_transforms(pelvis, &rot);
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    for p in parts() {
        capsule(&p, &mut vertices, &mut triangles, bones[p.bone]);
    }
    (vertices, triangles)
}

/// The stool: a closed cylinder standing on the floor.
pub fn stool() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let part = Part {
        bone: 0,
        offset: Vec3::new(STOOL_CENTER[0], 0.0, STOOL_CENTER[1]),
        axis: Vec3::Y,
        length: STOOL_HEIGHT,
        radius: STOOL_RADIUS,
        squash: Vec3::ONE,
    };
    // A flat-topped cylinder: a capsule squashed to zero cap height.
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    capsule(&part, &mut vertices, &mut triangles, Mat4::IDENTITY);
    for q in &mut vertices {
        q.y = q.y.clamp(0.0, STOOL_HEIGHT);
    }
    (vertices, triangles)
}

/// OBJ text of a mesh, coordinates to 0.1 mm.
pub fn obj_text(name: &str, vertices: &[Vec3], triangles: &[[u32; 3]]) -> String {
    let mut s = format!("# drape mannequin: {name}\no {name}\n");
    for v in vertices {
        let _ = writeln!(s, "v {:.4} {:.4} {:.4}", v.x, v.y, v.z);
    }
    for t in triangles {
        let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

/// Every file of the mannequin: (relative path, text).
pub fn files() -> Vec<(String, String)> {
    let mut out = Vec::new();
    for (clip, duration) in CLIPS {
        let frames = (duration * FPS).round() as u32 + 1;
        for k in 0..frames {
            let (v, t) = mesh(clip, k as f32 / FPS);
            out.push((
                format!("{clip}/frame_{:04}.obj", k + 1),
                obj_text(clip, &v, &t),
            ));
        }
    }
    let (v, t) = stool();
    out.push(("stool.obj".into(), obj_text("stool", &v, &t)));
    out
}

/// Writes the files scene P needs (the `poncho` clip and the stool) under
/// `cache/mannequin-<hash>/characters/mannequin/`, unless an earlier run did, and returns
/// `cache/mannequin-<hash>`: the embedded default scene reads them from there, as
/// `scenes/poncho.json` reads the committed copies. The hash covers every file's text, so a
/// changed mannequin gets a new folder; files are written into a temporary folder first and
/// moved into place whole, so a crash never leaves half a clip.
pub fn materialise(cache: &std::path::Path) -> crate::error::Result<std::path::PathBuf> {
    use crate::error::Error;
    let files: Vec<(String, String)> = files()
        .into_iter()
        .filter(|(name, _)| name.starts_with("poncho/") || name == "stool.obj")
        .collect();
    let hash = files.iter().fold(0xcbf2_9ce4_8422_2325, |h, (name, text)| {
        super::cache::fnv(super::cache::fnv(h, name.as_bytes()), text.as_bytes())
    });
    let root = cache.join(format!("mannequin-{hash:016x}"));
    if root.join("complete").is_file() {
        return Ok(root);
    }
    let staging = cache.join(format!(".mannequin-{hash:016x}-{}", std::process::id()));
    let write = || -> crate::error::Result<()> {
        for (name, text) in &files {
            let path = staging.join("characters/mannequin").join(name);
            let dir = path.parent().expect("a file in a folder");
            std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, "cannot create", e))?;
            std::fs::write(&path, text).map_err(|e| Error::io(&path, "cannot write", e))?;
        }
        let scenes = staging.join("scenes");
        std::fs::create_dir_all(&scenes).map_err(|e| Error::io(&scenes, "cannot create", e))?;
        let done = staging.join("complete");
        std::fs::write(&done, "").map_err(|e| Error::io(&done, "cannot write", e))
    };
    let written = write().and_then(|()| {
        std::fs::rename(&staging, &root).or_else(|e| {
            // Another run may have put the same files in place meanwhile.
            if root.join("complete").is_file() {
                Ok(())
            } else {
                Err(Error::io(&root, "cannot create", e))
            }
        })
    });
    let _ = std::fs::remove_dir_all(&staging);
    written.map(|()| root)
}

impl crate::scene::Scene {
    /// The embedded default scene, scene P, with the mannequin clip and stool it needs written
    /// under `cache` (see [`materialise`]).
    pub fn default_scene(cache: &std::path::Path) -> crate::error::Result<crate::scene::Scene> {
        let root = materialise(cache)?;
        crate::scene::Scene::parse_in(
            crate::scene::DEFAULT_SCENE,
            crate::scene::DEFAULT_SCENE_FILE,
            &root.join("scenes"),
        )
    }
}
