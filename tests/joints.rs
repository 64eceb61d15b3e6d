//! `characters[].joints`: the triangles a joint selection leaves out of the collisions, against
//! a count made here from the glTF files themselves (the `gltf` crate's accessors, the node
//! hierarchy and the skins' weights), on a skinned body (CesiumMan) and on a rig of rigid parts
//! with skinned hands (RobotExpressive); and a name that is no joint refused.

mod common;

use drape::character::{Asset, Character, CharacterOptions};
use drape::scene::MeshSelection;
use std::path::Path;

/// Triangles of `path` (every mesh instance, skinned meshes once) whose three vertices' mean
/// share moved by the nodes named in `names` or below them is above one half: worked out from
/// the file's accessors, not by drape's importer.
fn triangles_moved_by(path: &Path, names: &[&str]) -> (usize, usize) {
    let (doc, buffers, _) = gltf::import(path).unwrap();
    let mut parent = vec![None; doc.nodes().len()];
    for n in doc.nodes() {
        for c in n.children() {
            parent[c.index()] = Some(n.index());
        }
    }
    let within = |mut node: usize| loop {
        if names.contains(&doc.nodes().nth(node).unwrap().name().unwrap_or("")) {
            return true;
        }
        match parent[node] {
            Some(p) => node = p,
            None => return false,
        }
    };
    let (mut moved, mut all) = (0, 0);
    let mut skinned_meshes_seen = Vec::new();
    for node in doc.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        if node.skin().is_some() {
            if skinned_meshes_seen.contains(&mesh.index()) {
                continue;
            }
            skinned_meshes_seen.push(mesh.index());
        }
        for primitive in mesh.primitives() {
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let count = reader.read_positions().unwrap().count();
            let share: Vec<f32> = match node.skin() {
                None => vec![if within(node.index()) { 1.0 } else { 0.0 }; count],
                Some(skin) => {
                    let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
                    let js = reader.read_joints(0).unwrap().into_u16();
                    let ws = reader.read_weights(0).unwrap().into_f32();
                    js.zip(ws)
                        .map(|(j, w)| {
                            let sum: f32 = w.iter().sum();
                            let on: f32 = (0..4)
                                .filter(|&k| within(joints[j[k] as usize]))
                                .map(|k| w[k])
                                .sum();
                            on / sum
                        })
                        .collect()
                }
            };
            let indices: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
            for t in indices.chunks(3) {
                all += 1;
                let mean = t.iter().map(|&i| share[i as usize]).sum::<f32>() / 3.0;
                if mean > 0.5 {
                    moved += 1;
                }
            }
        }
    }
    (moved, all)
}

fn load(path: &Path, joints: Option<MeshSelection>) -> drape::error::Result<Character> {
    let asset = Asset::open(path).unwrap();
    let options = CharacterOptions {
        joints,
        ..Default::default()
    };
    Character::from_asset(&asset, path, &options, 60.0, 1)
}

fn names(n: &[&str]) -> Vec<String> {
    n.iter().map(|s| s.to_string()).collect()
}

/// Excluding `joints` leaves out exactly the triangles they mostly move; including them keeps
/// exactly those; the exports still show every triangle.
fn check_partition(path: &Path, joints: &[&str]) {
    let (moved, all) = triangles_moved_by(path, joints);
    eprintln!(
        "{}: {joints:?} move {moved} of {all} triangles",
        path.display()
    );
    assert!(moved > 0 && moved < all, "{joints:?} move {moved} of {all}");
    let whole = load(path, None).unwrap();
    assert_eq!(whole.triangles_of(0).len(), all);
    let without = load(path, Some(MeshSelection::Exclude(names(joints)))).unwrap();
    assert_eq!(
        without.triangles_of(0).len(),
        all - moved,
        "{joints:?} excluded"
    );
    assert_eq!(without.visible_triangles(), whole.triangles_of(0));
    let only = load(path, Some(MeshSelection::Include(names(joints)))).unwrap();
    assert_eq!(only.triangles_of(0).len(), moved, "{joints:?} included");
    // Together the two are the whole mesh, each triangle once.
    let mut both: Vec<[u32; 3]> = without.triangles_of(0).to_vec();
    both.extend_from_slice(only.triangles_of(0));
    both.sort();
    let mut every = whole.triangles_of(0).to_vec();
    every.sort();
    assert_eq!(both, every);
}

#[test]
fn a_skinned_body_leaves_out_the_triangles_its_hands_move() {
    let path = Path::new("characters/CesiumMan/CesiumMan.glb");
    check_partition(
        path,
        &["Skeleton_arm_joint_L__2_", "Skeleton_arm_joint_R__3_"],
    );
    // A shoulder takes the whole arm below it.
    let (hand, _) = triangles_moved_by(path, &["Skeleton_arm_joint_L__2_"]);
    let (arm, _) = triangles_moved_by(path, &["Skeleton_arm_joint_L__4_"]);
    assert!(arm > 2 * hand, "arm {arm}, hand {hand}");
    check_partition(path, &["Skeleton_arm_joint_L__4_"]);
}

#[test]
fn a_rig_of_rigid_parts_leaves_out_the_parts_below_a_joint() {
    // Its arms are rigid meshes on nodes below the shoulders; its hands are skinned.
    let path = Path::new("characters/RobotExpressive/RobotExpressive.glb");
    check_partition(path, &["Shoulder.L"]);
    check_partition(path, &["Head"]);
}

#[test]
fn a_name_that_is_no_joint_is_refused_with_the_joints_listed() {
    let path = Path::new("characters/CesiumMan/CesiumMan.glb");
    let err = load(path, Some(MeshSelection::Exclude(names(&["Hand_L"])))).unwrap_err();
    assert_eq!(err.exit_code(), 2);
    let text = err.to_string();
    assert!(
        text.contains("joints") && text.contains("\"Hand_L\"") && text.contains("leg_joint_L_1"),
        "{text}"
    );
    // A selection that keeps no triangle is refused too.
    let err = load(path, Some(MeshSelection::Include(Vec::new()))).unwrap_err();
    assert_eq!(err.exit_code(), 2);
    assert!(err.to_string().contains("keeps no triangle"), "{err}");
}

/// A sheet dropped on RobotExpressive's head, baked with `joints` leaving out `Head` (the joint
/// whose subtree is just the three Head meshes), with `meshes` leaving out the same meshes, and
/// with everything colliding: the first two are the same bake to the bit (the same shell and
/// mesh metric), the third is not.
#[test]
fn a_joint_left_out_bakes_as_its_meshes_left_out() {
    let dir = common::temp_dir();
    let robot = std::fs::canonicalize("characters/RobotExpressive/RobotExpressive.glb").unwrap();
    let bake = |selection: &str| -> serde_json::Value {
        let scene = format!(
            r#"{{ "name": "head", "frames": 12, "substeps": 5,
                "garments": [{{ "name": "sheet", "resolution": [12, 12], "size": [0.3, 0.3],
                                "mass": 0.05, "position": [0, 1.76, 0] }}],
                "characters": [{{ "name": "robot", "file": {robot:?}, "scale": 0.392 {selection} }}] }}"#
        );
        common::write(dir.path(), "scene.json", &scene);
        let _ = std::fs::remove_dir_all(dir.path().join("out"));
        common::bake_report(dir.path())
    };
    let by_joint = bake(r#", "joints": { "exclude": ["Head"] }"#);
    let by_mesh = bake(r#", "meshes": { "exclude": ["Head"] }"#);
    let whole = bake("");
    let shell = |r: &serde_json::Value| r["characters"][0]["shell_particles"].as_u64().unwrap();
    assert_eq!(shell(&by_joint), shell(&by_mesh));
    assert!(
        shell(&by_joint) < shell(&whole),
        "the head's particles are gone"
    );
    assert_eq!(by_joint["frames_hash"], by_mesh["frames_hash"]);
    assert_eq!(
        by_joint["mesh_penetrations_per_frame"],
        by_mesh["mesh_penetrations_per_frame"]
    );
    assert_ne!(by_joint["frames_hash"], whole["frames_hash"]);
}
