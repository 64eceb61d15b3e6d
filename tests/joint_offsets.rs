//! `characters[].joint_offsets`: a rotation added to a joint in every posed frame and never in
//! the bind pose. Checked at rest on a skinned body that rests in its bind pose (CesiumMan: his
//! arm turns by exactly the rotation given, about the file's axes, around the shoulder) and on
//! a rig of rigid parts that rests elsewhere (RobotExpressive: the turn carried from the bind
//! pose to where the shoulder rests, the shoulder's two nodes of one name turned once); in his
//! walk (what the arm moves turns rigidly about the shoulder by the angle given, what it does
//! not move stays to the bit); the pre-roll starts at the bind pose untouched and ends on the
//! offset clip; the FBX and Collada copies of CesiumMan turn as the glTF does; names that are
//! no joint and frame sequences (no joints) are refused.

mod common;

use drape::character::{Asset, Character, CharacterOptions, Preroll};
use glam::{Quat, Vec3};
use std::collections::BTreeMap;
use std::path::Path;

fn offsets(joint: &str, degrees: [f32; 3]) -> BTreeMap<String, [f32; 3]> {
    BTreeMap::from([(joint.to_string(), degrees)])
}

/// Per vertex of [`Asset::pose`]: the share of it `joint` and the nodes below it move.
fn share_moved_by(asset: &Asset, joint: &str) -> Vec<f32> {
    asset.share_moved_by(&asset.nodes_below(&[joint.to_string()]))
}

fn node(asset: &Asset, name: &str) -> usize {
    asset.nodes.iter().position(|n| n.name == name).unwrap()
}

/// Turns `joint` of `path` by Euler `degrees` at rest and checks every vertex: those `joint`
/// does not move stay to the bit, those it wholly moves turn by `world` about the joint.
fn check_rest_turn(path: &Path, joint: &str, degrees: [f32; 3], world: impl Fn(&Asset) -> Quat) {
    let plain = Asset::open(path).unwrap();
    let mut turned = plain.clone();
    turned
        .offset_joints(&offsets(joint, degrees), path)
        .unwrap();
    let centre = plain.node_transforms(None, 0.0)[node(&plain, joint)]
        .w_axis
        .truncate();
    let q = world(&plain);
    let share = share_moved_by(&plain, joint);
    let (before, after) = (plain.pose(None, 0.0), turned.pose(None, 0.0));
    let (mut arm, mut body) = (0, 0);
    for ((p, moved), s) in before.iter().zip(&after).zip(&share) {
        if *s == 0.0 {
            assert_eq!(p, moved, "a vertex {joint} does not move moved");
            body += 1;
        } else if *s > 0.9999 {
            let expected = centre + q * (*p - centre);
            let size = (*p - centre).length().max(1.0);
            assert!(
                moved.distance(expected) < 1e-5 * size,
                "{moved} where {expected} was expected"
            );
            arm += 1;
        }
    }
    assert!(arm > 50 && body > 1000, "arm {arm}, body {body} vertices");
    // The bind pose is never turned.
    assert_eq!(turned.bind_pose(), plain.bind_pose());
}

#[test]
fn an_arm_at_rest_turns_by_the_rotation_given_about_the_files_axes() {
    // CesiumMan rests in his bind pose (every joint where its inverse bind matrix puts it), so
    // a turn about the file's Z axis turns his arm about Z, around the shoulder.
    let cesium = Path::new("characters/CesiumMan/CesiumMan.glb");
    let asset = Asset::open(cesium).unwrap();
    let shoulder = node(&asset, "Skeleton_arm_joint_L__4_");
    let rest = asset.node_transforms(None, 0.0)[shoulder];
    assert!(rest.abs_diff_eq(asset.bind_transforms()[shoulder], 1e-4));
    check_rest_turn(cesium, "Skeleton_arm_joint_L__4_", [0.0, 0.0, 25.0], |_| {
        Quat::from_rotation_z(25f32.to_radians())
    });
    check_rest_turn(cesium, "Skeleton_arm_joint_R", [10.0, 0.0, 0.0], |_| {
        Quat::from_rotation_x(10f32.to_radians())
    });
    // RobotExpressive, a rig of rigid parts, rests elsewhere than its bind pose: the turn is
    // about the file's axes as the shoulder lies in the bind pose, carried to where it rests
    // (R B⁻¹ Q B R⁻¹, R and B its rotations at rest and in the bind pose).
    let robot = Path::new("characters/RobotExpressive/RobotExpressive.glb");
    check_rest_turn(robot, "Shoulder.L", [0.0, 0.0, 30.0], |asset| {
        let i = node(asset, "Shoulder.L");
        let rotation = |m: glam::Mat4| m.to_scale_rotation_translation().1.normalize();
        let (r, b) = (
            rotation(asset.node_transforms(None, 0.0)[i]),
            rotation(asset.bind_transforms()[i]),
        );
        r * b.inverse() * Quat::from_rotation_z(30f32.to_radians()) * b * r.inverse()
    });
}

#[test]
fn a_skinned_arm_turns_rigidly_about_its_shoulder_through_the_walk() {
    let path = Path::new("characters/CesiumMan/CesiumMan.glb");
    let plain = Asset::open(path).unwrap();
    let joint = "Skeleton_arm_joint_L__4_";
    let mut turned = plain.clone();
    turned
        .offset_joints(&offsets(joint, [0.0, 0.0, 25.0]), path)
        .unwrap();
    let share = share_moved_by(&plain, joint);
    let shoulder = node(&plain, joint);
    let clip = plain.clip_index("0");
    for t in [0.0, 0.37, 0.81, 1.6] {
        let centre = plain.node_transforms(clip, t)[shoulder].w_axis.truncate();
        let (before, after) = (plain.pose(clip, t), turned.pose(clip, t));
        let mut largest = 0.0f32;
        let mut arm = 0;
        for ((p, moved), s) in before.iter().zip(&after).zip(&share) {
            if *s == 0.0 {
                assert_eq!(p, moved, "t {t}: a vertex the arm does not move moved");
            } else if *s > 0.999 {
                let (a, b) = (*p - centre, *moved - centre);
                assert!((a.length() - b.length()).abs() < 1e-4, "t {t}: not rigid");
                if a.length() > 0.05 {
                    largest = largest.max(a.angle_between(b).to_degrees());
                }
                arm += 1;
            }
        }
        assert!(arm > 100, "t {t}: {arm} arm vertices");
        // Turned by 25° about one axis: no vertex further, those across the axis by all of it.
        assert!(
            (24.0..=25.01).contains(&largest),
            "t {t}: turned by {largest}°"
        );
    }
}

#[test]
fn fbx_and_collada_copies_turn_as_the_gltf_does() {
    // tests/assets/CesiumMan: Blender's FBX (centimetres) and assimp's Collada from it, read
    // through assimp, give the glTF's frames (tests/characters.rs); turned by the same offsets
    // (about the file's axes in the bind pose) they still give the glTF's, and not its
    // unturned frames.
    let spread = BTreeMap::from([
        ("Skeleton_arm_joint_L__4_".to_string(), [0.0, 0.0, 25.0]),
        ("Skeleton_arm_joint_R".to_string(), [10.0, 0.0, -25.0]),
    ]);
    let frames = 40;
    let gltf = Path::new("characters/CesiumMan/CesiumMan.glb");
    let sample = |path: &Path, scale: f32, offsets: &BTreeMap<String, [f32; 3]>| {
        let options = CharacterOptions {
            clip: Some("0".into()),
            scale,
            joint_offsets: offsets.clone(),
            ..Default::default()
        };
        Character::load(path, &options, 60.0, frames).unwrap()
    };
    let turned = sample(gltf, 1.0, &spread);
    let plain = sample(gltf, 1.0, &BTreeMap::new());
    for name in ["CesiumMan.fbx", "CesiumMan.dae"] {
        let path = Path::new("tests/assets/CesiumMan").join(name);
        let other = sample(&path, 0.01, &spread);
        let worst = common::worst_corner_distance(&other, &turned);
        assert!(
            worst < 1e-5,
            "{name}: {worst} m from the glTF's turned frames"
        );
        let apart = common::worst_corner_distance(&other, &plain);
        assert!(apart > 0.05, "{name}: {apart} m from the unturned frames");
    }
}

#[test]
fn the_preroll_starts_at_the_untouched_bind_pose_and_ends_on_the_offset_clip() {
    let path = Path::new("characters/CesiumMan/CesiumMan.glb");
    let asset = Asset::open(path).unwrap();
    let spread = offsets("Skeleton_arm_joint_R", [0.0, 0.0, -25.0]);
    let (lead, shot) = (6, 4);
    let options = CharacterOptions {
        clip: Some("0".into()),
        preroll: Some(Preroll {
            settle: 2,
            blend: 4,
        }),
        lead_in: lead,
        joint_offsets: spread.clone(),
        ..Default::default()
    };
    let dressed = Character::from_asset(&asset, path, &options, 60.0, lead + shot).unwrap();
    assert_eq!(dressed.frames[0], asset.bind_pose());
    assert_eq!(dressed.bind, asset.bind_pose());
    let mut turned = asset.clone();
    turned.offset_joints(&spread, path).unwrap();
    let clip = asset.clip_index("0");
    for k in 0..shot {
        let t = k as f64 / 60.0;
        assert_eq!(
            dressed.frames[lead + k],
            turned.pose(clip, t),
            "shot frame {k}"
        );
        assert_ne!(
            dressed.frames[lead + k],
            asset.pose(clip, t),
            "frame {k} turned"
        );
    }
    // Through the blend the offset comes in with it: none at its start (the bind pose), more
    // at each frame, all of it where the clip starts.
    let without = CharacterOptions {
        joint_offsets: BTreeMap::new(),
        ..options
    };
    let plain = Character::from_asset(&asset, path, &without, 60.0, lead + shot).unwrap();
    let apart = |k: usize| {
        (dressed.frames[k].iter().zip(&plain.frames[k]))
            .map(|(a, b)| a.distance(*b))
            .fold(0.0f32, f32::max)
    };
    assert_eq!(apart(2), 0.0, "the blend starts at the bind pose");
    for k in 3..=lead {
        assert!(apart(k) > apart(k - 1), "frame {k}: {} m", apart(k));
    }
}

#[test]
fn names_that_are_no_joint_and_frame_sequences_are_refused() {
    let path = Path::new("characters/CesiumMan/CesiumMan.glb");
    let asset = Asset::open(path).unwrap();
    let options = CharacterOptions {
        joint_offsets: offsets("Hand_L", [0.0, 0.0, 10.0]),
        ..Default::default()
    };
    let err = Character::from_asset(&asset, path, &options, 60.0, 1).unwrap_err();
    assert_eq!(err.exit_code(), 2);
    let text = err.to_string();
    assert!(
        text.contains("joint_offsets")
            && text.contains("\"Hand_L\"")
            && text.contains("leg_joint_L_1"),
        "{text}"
    );
    // A frame sequence has no joints to turn.
    let dir = common::temp_dir();
    for k in 0..2 {
        let (v, t) = common::cuboid(Vec3::splat(-0.1), Vec3::splat(0.1 + k as f32 * 0.01));
        common::write_obj(&dir.path().join(format!("body_{k:04}.obj")), &v, &t);
    }
    let options = CharacterOptions {
        joint_offsets: offsets("root", [0.0, 0.0, 10.0]),
        ..Default::default()
    };
    let err = Character::load(dir.path(), &options, 60.0, 2).unwrap_err();
    assert_eq!(err.exit_code(), 2);
    assert!(err.to_string().contains("joint_offsets"), "{err}");
    // Through a scene file: the bake refuses it with exit code 2 and writes nothing.
    let scene = format!(
        r#"{{ "name": "bad", "frames": 2,
             "garments": [{{ "name": "sheet", "resolution": [4, 4], "size": [0.2, 0.2], "position": [0, 2, 0] }}],
             "characters": [{{ "file": {:?}, "joint_offsets": {{ "Hand_L": [0, 0, 10] }} }}] }}"#,
        std::fs::canonicalize(path).unwrap()
    );
    common::write(dir.path(), "scene.json", &scene);
    let out = common::drape(dir.path(), &["bake", "scene.json", "--out", "out"]);
    assert_eq!(out.status.code(), Some(2), "{}", common::stderr(&out));
    assert!(
        common::stderr(&out).contains("characters[0].joint_offsets"),
        "{}",
        common::stderr(&out)
    );
    assert!(!dir.path().join("out/report.json").exists());
}

/// A rig of one rigid part: a root, a joint at (1, 0, 0) with `linear` as its bind transform's
/// linear part, and a triangle on a node below it.
fn one_part(linear: glam::Mat3) -> Asset {
    use drape::mesh::import::{Mesh, Node};
    let node = |name: &str, parent, local| Node {
        name: name.into(),
        parent,
        local,
    };
    let joint = glam::Mat4::from_translation(Vec3::X) * glam::Mat4::from_mat3(linear);
    Asset {
        nodes: vec![
            node("root", None, glam::Mat4::IDENTITY),
            node("joint", Some(0), joint),
            node("part", Some(1), glam::Mat4::IDENTITY),
        ],
        meshes: vec![Mesh {
            name: "part".into(),
            node: "part".into(),
            material: String::new(),
            vertices: vec![Vec3::new(0.5, 0.0, 0.0), Vec3::Y, Vec3::new(0.2, 0.3, 0.7)],
            triangles: vec![[0, 1, 2]],
            bones: Vec::new(),
            weights: Vec::new(),
            instances: vec![2],
            ..Mesh::default()
        }],
        clips: Vec::new(),
        warnings: Vec::new(),
        offsets: Vec::new(),
    }
}

#[test]
fn scaled_and_mirrored_joints_turn_about_the_files_axes_and_euler_angles_compose_in_order() {
    // Euler [30, 40, 0] is the scene's `rotation` convention: about X, then the turned Y.
    let two_axes =
        Quat::from_rotation_x(30f32.to_radians()) * Quat::from_rotation_y(40f32.to_radians());
    for (linear, what) in [
        (glam::Mat3::IDENTITY, "plain"),
        (
            glam::Mat3::from_diagonal(Vec3::new(2.0, 1.0, 0.5)),
            "scaled unevenly",
        ),
        (
            glam::Mat3::from_diagonal(Vec3::new(-1.0, 1.0, 1.0)),
            "mirrored",
        ),
        (
            glam::Mat3::from_rotation_z(0.7) * glam::Mat3::from_diagonal(Vec3::splat(3.0)),
            "turned and scaled",
        ),
    ] {
        let plain = one_part(linear);
        let mut turned = plain.clone();
        turned
            .offset_joints(&offsets("joint", [30.0, 40.0, 0.0]), Path::new("rig"))
            .unwrap();
        let pivot = Vec3::X;
        for (p, moved) in plain.pose(None, 0.0).iter().zip(turned.pose(None, 0.0)) {
            let expected = pivot + two_axes * (*p - pivot);
            assert!(
                moved.distance(expected) < 1e-5,
                "{what}: {moved} where {expected}"
            );
        }
        let uneven = turned
            .warnings
            .iter()
            .any(|w| w.contains("scaled unevenly"));
        assert_eq!(
            uneven,
            what == "scaled unevenly",
            "{what}: {:?}",
            turned.warnings
        );
    }
}
