//! Characters whose triangles face into their bodies as delivered: a rig mirrored by a node
//! scaled by −1 (glTF turns the winding of what such a node places) and a mesh authored inside
//! out. The shell pushes cloth out along the skin's normals, so either, read as wound, pushes
//! cloth into the body: the cape on a mirrored CesiumMan stopped as unstable on its first
//! pre-roll frame. Checked against the unmirrored files' own normals, mirrored here.

mod common;

use drape::character::{Character, CharacterOptions};
use drape::mesh::import::{inside_out_measure, Asset, INSIDE_OUT};
use glam::Vec3;
use std::path::{Path, PathBuf};

/// `file` (a GLB) under a new root node scaled by (−1, 1, 1): the same character mirrored
/// across x, as a DCC mirrors a rig at its root.
fn mirrored(file: &Path, dir: &Path) -> PathBuf {
    let gltf::Gltf { document, blob } = gltf::Gltf::open(file).unwrap();
    let mut root = document.into_json();
    let mut mirror = root.nodes[0].clone();
    let roots = root.scenes[0].nodes.clone();
    mirror.name = Some("Mirror".into());
    (mirror.mesh, mirror.skin, mirror.camera, mirror.weights) = (None, None, None, None);
    (mirror.matrix, mirror.rotation, mirror.translation) = (None, None, None);
    mirror.scale = Some([-1.0, 1.0, 1.0]);
    mirror.children = Some(roots);
    root.nodes.push(mirror);
    let index = gltf::json::Index::new(root.nodes.len() as u32 - 1);
    root.scenes.iter_mut().for_each(|s| s.nodes = vec![index]);
    let path = dir.join(file.file_name().unwrap());
    common::write_glb(&path, &root, blob.as_deref().unwrap());
    path
}

/// How many of `a`'s smooth vertex normals point otherwise than `b`'s turned by `turn` (more
/// than 8° apart), of the vertices where both have one.
fn normals_apart(a: (&[Vec3], &[[u32; 3]]), b: (&[Vec3], &[[u32; 3]]), turn: Vec3) -> usize {
    let na = drape::mesh::smooth_normals(a.0, a.1);
    let nb = drape::mesh::smooth_normals(b.0, b.1);
    (na.iter().zip(&nb))
        .filter(|(x, y)| x.length() > 0.5 && y.length() > 0.5)
        .filter(|(x, y)| x.dot(**y * turn) < 0.99)
        .count()
}

#[test]
fn a_character_mirrored_by_a_node_keeps_its_normals_out() {
    let dir = common::temp_dir();
    let turn = Vec3::new(-1.0, 1.0, 1.0);
    for (file, clip) in [
        ("characters/CesiumMan/CesiumMan.glb", "0"),
        // Skinned hands and rigid parts hung under bones.
        ("characters/RobotExpressive/RobotExpressive.glb", "Running"),
    ] {
        let options = CharacterOptions {
            clip: Some(clip.into()),
            ..Default::default()
        };
        let plain = Character::load(Path::new(file), &options, 60.0, 3).unwrap();
        let path = mirrored(Path::new(file), dir.path());
        let mirror = Character::load(&path, &options, 60.0, 3).unwrap();
        for k in 0..3 {
            let off = (plain.frames[k].iter().zip(&mirror.frames[k]))
                .map(|(p, m)| (*p * turn - *m).length())
                .fold(0.0f32, f32::max);
            assert!(off < 1e-4, "{file} frame {k}: not its mirror ({off} m)");
            let apart = normals_apart(
                (&plain.frames[k], plain.triangles_of(k)),
                (&mirror.frames[k], mirror.triangles_of(k)),
                turn,
            );
            assert_eq!(
                apart, 0,
                "{file} frame {k}: normals not the plain ones mirrored"
            );
        }
        assert!(
            !mirror.warnings.iter().any(|w| w.contains("inside out")),
            "{file}: a mirrored file is right as it is: {:?}",
            mirror.warnings
        );
        // Read without the inside-out rule, every mesh copy already faces out.
        let asset = Asset::open(&path).unwrap();
        let (pose, triangles) = (asset.pose(None, 0.0), asset.triangles());
        for (mesh, range) in asset.mesh_triangle_ranges() {
            let corners = triangles[range].iter().map(|t| t.map(|i| pose[i as usize]));
            let measure = inside_out_measure(corners);
            assert!(
                measure > INSIDE_OUT,
                "{file}: {} measures {measure}",
                mesh.name
            );
        }
    }
}

/// Every triangle as its corners' places (to 10 µm), started at its least corner with its
/// winding kept, sorted: equal for two meshes of the same faces wound alike.
fn oriented(v: &[Vec3], t: &[[u32; 3]]) -> Vec<[[i64; 3]; 3]> {
    let place = |i: u32| (v[i as usize] * 1e5).round().as_i64vec3().to_array();
    let mut out: Vec<[[i64; 3]; 3]> = (t.iter())
        .map(|c| {
            let p = c.map(place);
            let first = (0..3).min_by_key(|&k| p[k]).unwrap();
            [p[first], p[(first + 1) % 3], p[(first + 2) % 3]]
        })
        .collect();
    out.sort();
    out
}

#[test]
fn a_rigid_part_mirrored_by_its_own_node_faces_out() {
    // RobotExpressive's rigid parts hang under his bones, one node each: the first of them
    // mirrored in its own frame (a left part made from a right one), the rest as they are.
    let dir = common::temp_dir();
    let file = Path::new("characters/RobotExpressive/RobotExpressive.glb");
    let gltf::Gltf { document, blob } = gltf::Gltf::open(file).unwrap();
    let mut root = document.into_json();
    let part = (root.nodes.iter())
        .position(|n| n.mesh.is_some() && n.skin.is_none() && n.matrix.is_none())
        .expect("a rigid part");
    let [x, y, z] = root.nodes[part].scale.unwrap_or([1.0; 3]);
    root.nodes[part].scale = Some([-x, y, z]);
    let path = dir.path().join("one_part_mirrored.glb");
    common::write_glb(&path, &root, blob.as_deref().unwrap());
    let asset = Asset::open(&path).unwrap();
    let (pose, triangles) = (asset.pose(None, 0.0), asset.triangles());
    let mut parts = 0;
    for (mesh, range) in asset.mesh_triangle_ranges() {
        let corners = triangles[range].iter().map(|t| t.map(|i| pose[i as usize]));
        let measure = inside_out_measure(corners);
        assert!(measure > INSIDE_OUT, "{} measures {measure}", mesh.name);
        parts += 1;
    }
    assert_eq!(parts, 19, "every copy of the robot's meshes measured");
}

#[test]
fn a_character_wound_inside_out_is_turned_and_warned_of() {
    let dir = common::temp_dir();
    let body = Path::new("characters/mannequin/stool.obj");
    let (v, t) = common::read_obj(body);
    let turned: Vec<[u32; 3]> = t.iter().map(|&[a, b, c]| [a, c, b]).collect();
    let inside_out = dir.path().join("inside_out.obj");
    common::write_obj(&inside_out, &v, &turned);
    let options = CharacterOptions::default();
    let plain = Character::load(body, &options, 60.0, 1).unwrap();
    let read = Character::load(&inside_out, &options, 60.0, 1).unwrap();
    // assimp gives each face its own corners in face order, so compare triangles by place.
    assert_eq!(
        oriented(&read.frames[0], read.triangles_of(0)),
        oriented(&plain.frames[0], plain.triangles_of(0)),
        "turned back to face out"
    );
    assert!(
        read.warnings
            .iter()
            .any(|w| w.contains("inside out") && w.contains("inside_out.obj")),
        "{:?}",
        read.warnings
    );
    assert!(!plain.warnings.iter().any(|w| w.contains("inside out")));
    // `drape inspect` says so too.
    let run = common::drape(dir.path(), &["inspect", inside_out.to_str().unwrap()]);
    assert!(run.status.success());
    assert!(
        common::stderr(&run).contains("is wound inside out"),
        "{}",
        common::stderr(&run)
    );
    // A sequence of such files warns once, with the count of the others.
    let frames = dir.path().join("frames");
    std::fs::create_dir(&frames).unwrap();
    for k in 1..=3 {
        common::write_obj(&frames.join(format!("f_{k:04}.obj")), &v, &turned);
    }
    let options = CharacterOptions {
        sequence_fps: Some(12.0),
        ..Default::default()
    };
    let read = Character::load(&frames, &options, 12.0, 3).unwrap();
    let said: Vec<&String> = (read.warnings.iter())
        .filter(|w| w.contains("inside out"))
        .collect();
    assert_eq!(said.len(), 1, "{said:?}");
    assert!(
        said[0].contains("f_0001.obj") && said[0].contains("2 more"),
        "{}",
        said[0]
    );
    // A sheet has no inside: either winding is read as written, with no warning.
    let sheet = dir.path().join("sheet.obj");
    let square = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.0, 1.0), Vec3::Z];
    for quad in [[[0, 1, 2], [0, 2, 3]], [[0, 2, 1], [0, 3, 2]]] {
        common::write_obj(&sheet, &square, &quad);
        let read = Character::load(&sheet, &options, 60.0, 1).unwrap();
        assert_eq!(
            oriented(&read.frames[0], read.triangles_of(0)),
            oriented(&square, &quad)
        );
        assert!(!read.warnings.iter().any(|w| w.contains("inside out")));
    }
}

#[test]
fn a_cape_on_a_mirrored_character_bakes_as_on_the_plain_one() {
    // `cape_walk` on CesiumMan mirrored at his root: before his winding was turned, the
    // cape was pushed into him and the bake stopped on its first pre-roll frame.
    let dir = common::temp_dir();
    let cwd = std::env::current_dir().unwrap();
    let man = mirrored(&cwd.join("characters/CesiumMan/CesiumMan.glb"), dir.path());
    let text = std::fs::read_to_string("scenes/cape_walk.json").unwrap();
    let text = text
        .replace(
            "../characters/CesiumMan/CesiumMan.glb",
            &man.display().to_string(),
        )
        .replace("../garments/", &format!("{}/garments/", cwd.display()))
        .replace("\"frames\": 120", "\"frames\": 12");
    common::write(dir.path(), "scene.json", &text);
    let report = common::bake_report(dir.path());
    assert_eq!(report["stable"], true);
    assert_eq!(report["frames_baked"], 12);
    // Every frame, the pre-roll's included: nothing deeper than half a shell radius.
    let frames = report["mesh_penetrations_per_frame"].as_array().unwrap();
    assert_eq!(frames.len(), 50 + 12);
    for f in frames {
        assert!(f["deepest_m"][0].as_f64().unwrap() < 0.005, "{f}");
    }
}
