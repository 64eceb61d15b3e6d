//! glTF morph targets (blend shapes) as the format defines them: a vertex is displaced by its
//! targets' weighted displacements, then skinned. So CesiumMan with a target weighted w must
//! pose exactly as a copy whose base positions were displaced by w × the target, in every pose;
//! with the weight animated, as that copy at the weight the clip reaches. Before drape read
//! them, a body shape left on by default weights was not the body the cloth met.

mod common;

use drape::mesh::import::Asset;
use glam::Vec3;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// CesiumMan's JSON and binary chunk.
fn cesium_man() -> (Value, Vec<u8>) {
    let gltf::Gltf { document, blob } =
        gltf::Gltf::open("characters/CesiumMan/CesiumMan.glb").unwrap();
    (
        serde_json::to_value(document.into_json()).unwrap(),
        blob.unwrap(),
    )
}

/// Appends `data` (f32s) to the binary chunk as a new view and accessor of `kind` ("VEC3",
/// "SCALAR"); returns the accessor's index.
fn append(root: &mut Value, blob: &mut Vec<u8>, data: &[f32], kind: &str) -> usize {
    while blob.len() % 4 != 0 {
        blob.push(0);
    }
    let offset = blob.len();
    blob.extend(data.iter().flat_map(|f| f.to_le_bytes()));
    root["buffers"][0]["byteLength"] = json!(blob.len());
    let views = root["bufferViews"].as_array_mut().unwrap();
    views.push(json!({ "buffer": 0, "byteOffset": offset, "byteLength": 4 * data.len() }));
    let view = views.len() - 1;
    let width = if kind == "VEC3" { 3 } else { 1 };
    let (mut lo, mut hi) = (vec![f32::MAX; width], vec![f32::MIN; width]);
    for chunk in data.chunks(width) {
        for (k, &v) in chunk.iter().enumerate() {
            (lo[k], hi[k]) = (lo[k].min(v), hi[k].max(v));
        }
    }
    let accessors = root["accessors"].as_array_mut().unwrap();
    accessors.push(json!({
        "bufferView": view, "componentType": 5126, "count": data.len() / width,
        "type": kind, "min": lo, "max": hi
    }));
    accessors.len() - 1
}

fn write(root: &Value, blob: &[u8], path: &Path) -> PathBuf {
    let root: gltf::json::Root = serde_json::from_value(root.clone()).unwrap();
    common::write_glb(path, &root, blob);
    path.to_path_buf()
}

/// A body-shape target: each vertex pushed out from the body's axis (the mesh's own
/// coordinates, z up) by 4 % of its distance, and raised 1 cm.
fn heavier(vertices: &[Vec3]) -> Vec<Vec3> {
    (vertices.iter())
        .map(|v| Vec3::new(0.04 * v.x, 0.04 * v.y, 0.01))
        .collect()
}

/// CesiumMan with the target added at `weight` (the mesh's default weights).
fn with_target(dir: &Path, name: &str, weight: f32) -> (Value, Vec<u8>) {
    let (mut root, mut blob) = cesium_man();
    let asset = Asset::open(Path::new("characters/CesiumMan/CesiumMan.glb")).unwrap();
    let flat: Vec<f32> = heavier(&asset.meshes[0].vertices)
        .iter()
        .flat_map(|d| d.to_array())
        .collect();
    let target = append(&mut root, &mut blob, &flat, "VEC3");
    root["meshes"][0]["primitives"][0]["targets"] = json!([{ "POSITION": target }]);
    root["meshes"][0]["weights"] = json!([weight]);
    write(&root, &blob, &dir.join(name));
    (root, blob)
}

/// CesiumMan with its base positions displaced by `weight` × the target, and no target.
fn baked(dir: &Path, name: &str, weight: f32) -> PathBuf {
    let (mut root, mut blob) = cesium_man();
    let asset = Asset::open(Path::new("characters/CesiumMan/CesiumMan.glb")).unwrap();
    let base = &asset.meshes[0].vertices;
    let flat: Vec<f32> = (base.iter().zip(heavier(base)))
        .flat_map(|(v, d)| (*v + d * weight).to_array())
        .collect();
    let positions = append(&mut root, &mut blob, &flat, "VEC3");
    root["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(positions);
    write(&root, &blob, &dir.join(name))
}

fn largest_gap(a: &[Vec3], b: &[Vec3]) -> f32 {
    assert_eq!(a.len(), b.len());
    (a.iter().zip(b))
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max)
}

#[test]
fn a_weighted_target_poses_as_the_shape_it_makes() {
    let dir = common::temp_dir();
    with_target(dir.path(), "shaped.glb", 0.6);
    let shaped = Asset::open(&dir.path().join("shaped.glb")).unwrap();
    let reference = Asset::open(&baked(dir.path(), "baked.glb", 0.6)).unwrap();
    let plain = Asset::open(Path::new("characters/CesiumMan/CesiumMan.glb")).unwrap();
    for t in [0.0, 0.37, 1.2, 1.9] {
        let (a, b) = (shaped.pose(Some(0), t), reference.pose(Some(0), t));
        assert!(largest_gap(&a, &b) < 1e-5, "t {t}: {}", largest_gap(&a, &b));
        // The shape is no rounding: it moves the body by centimetres.
        assert!(largest_gap(&a, &plain.pose(Some(0), t)) > 0.01);
    }
    let gap = largest_gap(&shaped.bind_pose(), &reference.bind_pose());
    assert!(gap < 1e-5, "bind pose: {gap}");
    let half = largest_gap(
        &shaped.blended_pose(Some(0), 0.5, 0.5),
        &reference.blended_pose(Some(0), 0.5, 0.5),
    );
    assert!(half < 1e-5, "half-way from the bind pose: {half}");
}

#[test]
fn an_animated_weight_poses_as_the_shape_it_reaches() {
    let dir = common::temp_dir();
    let (mut root, mut blob) = with_target(dir.path(), "unused.glb", 0.0);
    // The walk (2 s) turns the target on linearly: weight t / 2; a second, stepped channel in
    // another clip holds 0.25 until 1 s, then 0.75.
    let times = append(&mut root, &mut blob, &[0.0, 2.0], "SCALAR");
    let values = append(&mut root, &mut blob, &[0.0, 1.0], "SCALAR");
    let walk = &mut root["animations"][0];
    let sampler = walk["samplers"].as_array().unwrap().len();
    walk["samplers"]
        .as_array_mut()
        .unwrap()
        .push(json!({ "input": times, "output": values }));
    let mesh_node = 2;
    (walk["channels"].as_array_mut().unwrap())
        .push(json!({ "sampler": sampler, "target": { "node": mesh_node, "path": "weights" } }));
    let values = append(&mut root, &mut blob, &[0.25, 0.75], "SCALAR");
    let times = append(&mut root, &mut blob, &[0.0, 1.0], "SCALAR");
    (root["animations"].as_array_mut().unwrap()).push(json!({
        "name": "Stepped",
        "samplers": [{ "input": times, "output": values, "interpolation": "STEP" }],
        "channels": [{ "sampler": 0, "target": { "node": mesh_node, "path": "weights" } }]
    }));
    let animated = Asset::open(&write(&root, &blob, &dir.path().join("animated.glb"))).unwrap();
    for (t, w) in [(0.5, 0.25), (1.2, 0.6)] {
        let reference = Asset::open(&baked(dir.path(), "b.glb", w)).unwrap();
        let gap = largest_gap(&animated.pose(Some(0), t), &reference.pose(Some(0), t));
        assert!(gap < 1e-5, "walk at {t} s: {gap}");
    }
    let stepped = animated.clip_index("Stepped").unwrap();
    for (t, w) in [(0.9, 0.25), (1.1, 0.75)] {
        let reference = Asset::open(&baked(dir.path(), "b.glb", w)).unwrap();
        let gap = largest_gap(&animated.pose(Some(stepped), t), &reference.pose(None, 0.0));
        assert!(gap < 1e-5, "stepped at {t} s: {gap}");
    }
}

#[test]
fn weights_that_do_not_match_the_targets_are_refused_naming_the_field() {
    let dir = common::temp_dir();
    let (mut root, blob) = with_target(dir.path(), "unused.glb", 0.5);
    root["meshes"][0]["weights"] = json!([0.5, 0.5]);
    let path = write(&root, &blob, &dir.path().join("two.glb"));
    let err = Asset::open(&path).unwrap_err().to_string();
    assert!(
        err.contains("two.glb")
            && err.contains("meshes[0].weights")
            && err.contains("2 weights for 1"),
        "{err}"
    );
}
