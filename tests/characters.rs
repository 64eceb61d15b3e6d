//! Characters imported (glTF by index, the rest through assimp): the shared assets against their MANIFEST
//! (`shared/assets/MANIFEST.md`, boxes made by two independent evaluators), skinning against an
//! analytic two-bone rig written here, shells against their spacing and coverage contract, and
//! bad files against clear errors.

mod common;

use drape::character::{Asset, Character, CharacterOptions, Shell};
use glam::Vec3;
use std::path::{Path, PathBuf};

fn asset_path(name: &str) -> Option<PathBuf> {
    let p = Path::new("../shared/assets").join(name);
    if p.is_file() {
        Some(p)
    } else {
        eprintln!(
            "skipped: {} is not there (shared/ beside the checkout)",
            p.display()
        );
        None
    }
}

fn clip(asset: &Asset, path: &Path, clip: Option<&str>, frames: usize) -> Character {
    let options = CharacterOptions {
        clip: clip.map(str::to_string),
        ..Default::default()
    };
    Character::from_asset(asset, path, &options, 60.0, frames).expect("clip samples")
}

fn assert_box(c: &Character, frame: usize, lo: [f32; 3], hi: [f32; 3], what: &str) {
    let (a, b) = c.bounds(frame);
    let ok = (a - Vec3::from(lo)).abs().max_element() < 1e-3
        && (b - Vec3::from(hi)).abs().max_element() < 1e-3;
    assert!(ok, "{what}: box {a} … {b}, MANIFEST says {lo:?} … {hi:?}");
}

#[test]
fn cesium_man_matches_its_manifest() {
    let Some(path) = asset_path("CesiumMan/CesiumMan.glb") else {
        return;
    };
    let asset = Asset::open(&path).unwrap();
    let rest = clip(&asset, &path, None, 1);
    assert_eq!(rest.frames[0].len(), 3273);
    assert_eq!(rest.triangles[0].len(), 4672);
    assert_box(
        &rest,
        0,
        [-0.569, 0.000, -0.131],
        [0.569, 1.507, 0.181],
        "rest pose",
    );
    // The one clip has no name: index 0. 2 s at 60 fps.
    let walk = clip(&asset, &path, Some("0"), 121);
    assert_eq!(walk.clips, vec![(String::new(), 2.0)]);
    assert_box(
        &walk,
        0,
        [-0.3105, -0.0106, -0.4466],
        [0.1947, 1.4472, 0.4499],
        "walk at t = 0",
    );
    let step = common::largest_step(&walk);
    assert!(
        step > 0.005 && step <= 0.044 + 1e-3,
        "walk moves {step} m per frame at most (MANIFEST: 0.044)"
    );
}

#[test]
fn robot_expressive_matches_its_manifest() {
    let Some(path) = asset_path("RobotExpressive/RobotExpressive.glb") else {
        return;
    };
    let asset = Asset::open(&path).unwrap();
    assert_eq!(asset.clips.len(), 14);
    let rest = clip(&asset, &path, None, 1);
    assert_eq!(
        (rest.frames[0].len(), rest.triangles[0].len()),
        (7214, 3237)
    );
    assert_box(
        &rest,
        0,
        [-1.5207, -0.0203, -1.2691],
        [1.5788, 4.4409, 1.4160],
        "rest pose",
    );
    let cases = [
        (
            "Dance",
            [-1.5207, -0.0203, -1.2818],
            [1.5788, 4.4765, 1.3461],
            0.69,
        ),
        (
            "Running",
            [-1.1978, 0.8081, -2.1597],
            [1.4476, 4.9964, 2.2070],
            0.67,
        ),
        (
            "Walking",
            [-1.4017, -0.0747, -1.3116],
            [1.6539, 4.3445, 1.5677],
            0.27,
        ),
        (
            "Jump",
            [-1.5207, -0.0203, -1.2818],
            [1.5788, 4.2215, 1.8207],
            0.77,
        ),
        (
            "Wave",
            [-1.3472, -0.0203, -1.2818],
            [1.5788, 4.4765, 1.5658],
            0.41,
        ),
    ];
    for (name, lo, hi, manifest_step) in cases {
        let frames =
            (asset.clips[asset.clip_index(name).unwrap()].duration * 60.0).ceil() as usize + 1;
        let c = clip(&asset, &path, Some(name), frames);
        assert_box(&c, 0, lo, hi, name);
        let step = common::largest_step(&c);
        assert!(step > 0.0, "{name}: the clip should move");
        assert!(
            step <= manifest_step + 0.01,
            "{name}: a vertex moves {step} per frame (MANIFEST: {manifest_step})"
        );
    }
    // Sitting ends seated; past its 0.417 s the last pose holds.
    let sit = clip(&asset, &path, Some("Sitting"), 60);
    assert_box(
        &sit,
        59,
        [-1.5207, -0.0203, -1.9793],
        [1.5788, 3.9807, 0.9947],
        "Sitting at its end",
    );
}

/// A two-bone rig: Bone1 at the origin, Bone2 one metre up, rotating 90° about Z over one second.
/// Vertex 0 follows Bone1, vertex 1 Bone2, vertex 2 (off the bones' plane) half of each;
/// written as glTF + .bin here.
fn write_rig(dir: &Path) -> PathBuf {
    let mut bin: Vec<u8> = Vec::new();
    let f32s = |bin: &mut Vec<u8>, v: &[f32]| {
        v.iter()
            .for_each(|x| bin.extend_from_slice(&x.to_le_bytes()))
    };
    f32s(&mut bin, &[0.5, 0.0, 0.0, 0.5, 2.0, 0.0, 0.5, 1.0, 1.0]); // 0: positions, 36 B
    for j in [[0u16, 1, 0, 0], [1, 0, 0, 0], [0, 1, 0, 0]] {
        j.iter()
            .for_each(|x| bin.extend_from_slice(&x.to_le_bytes())); // 36: joints, 24 B
    }
    f32s(
        &mut bin,
        &[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.5, 0.5, 0.0, 0.0],
    ); // 60: weights, 48 B
    [0u16, 1, 2, 0]
        .iter()
        .for_each(|x| bin.extend_from_slice(&x.to_le_bytes())); // 108: indices + pad
    let identity = glam::Mat4::IDENTITY.to_cols_array();
    let down = glam::Mat4::from_translation(Vec3::new(0.0, -1.0, 0.0)).to_cols_array();
    f32s(&mut bin, &identity); // 116: inverse bind matrices, 128 B
    f32s(&mut bin, &down);
    f32s(&mut bin, &[0.0, 1.0]); // 244: key times
    let s = std::f32::consts::FRAC_1_SQRT_2;
    f32s(&mut bin, &[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, s, s]); // 252: rotations (x, y, z, w)
    std::fs::write(dir.join("rig.bin"), &bin).unwrap();
    let gltf = format!(
        r#"{{
  "asset": {{ "version": "2.0" }},
  "scene": 0, "scenes": [{{ "nodes": [0] }}],
  "nodes": [
    {{ "name": "Root", "children": [1, 3] }},
    {{ "name": "Bone1", "children": [2] }},
    {{ "name": "Bone2", "translation": [0, 1, 0] }},
    {{ "name": "Skin", "mesh": 0, "skin": 0, "translation": [5, 5, 5] }}
  ],
  "skins": [{{ "joints": [1, 2], "inverseBindMatrices": 4 }}],
  "meshes": [{{ "primitives": [{{ "attributes": {{ "POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2 }}, "indices": 3 }}] }}],
  "animations": [{{ "name": "Bend",
    "samplers": [{{ "input": 5, "output": 6, "interpolation": "LINEAR" }}],
    "channels": [{{ "sampler": 0, "target": {{ "node": 2, "path": "rotation" }} }}] }}],
  "buffers": [{{ "uri": "rig.bin", "byteLength": {len} }}],
  "bufferViews": [
    {{ "buffer": 0, "byteOffset": 0, "byteLength": 36 }},
    {{ "buffer": 0, "byteOffset": 36, "byteLength": 24 }},
    {{ "buffer": 0, "byteOffset": 60, "byteLength": 48 }},
    {{ "buffer": 0, "byteOffset": 108, "byteLength": 6 }},
    {{ "buffer": 0, "byteOffset": 116, "byteLength": 128 }},
    {{ "buffer": 0, "byteOffset": 244, "byteLength": 8 }},
    {{ "buffer": 0, "byteOffset": 252, "byteLength": 32 }}
  ],
  "accessors": [
    {{ "bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0.5, 0, 0], "max": [0.5, 2, 1] }},
    {{ "bufferView": 1, "componentType": 5123, "count": 3, "type": "VEC4" }},
    {{ "bufferView": 2, "componentType": 5126, "count": 3, "type": "VEC4" }},
    {{ "bufferView": 3, "componentType": 5123, "count": 3, "type": "SCALAR" }},
    {{ "bufferView": 4, "componentType": 5126, "count": 2, "type": "MAT4" }},
    {{ "bufferView": 5, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1] }},
    {{ "bufferView": 6, "componentType": 5126, "count": 2, "type": "VEC4" }}
  ]
}}"#,
        len = bin.len()
    );
    let path = dir.join("rig.gltf");
    std::fs::write(&path, gltf).unwrap();
    path
}

#[test]
fn two_bone_skinning_is_analytic() {
    let dir = common::temp_dir();
    let path = write_rig(dir.path());
    let asset = Asset::open(&path).expect("assimp reads the rig");
    let bend = asset.clip_index("Bend").expect("clip Bend");
    for (t, angle) in [(0.0f64, 0.0f32), (0.5, 45.0), (1.0, 90.0)] {
        let p = asset.pose(Some(bend), t);
        let (s, c) = angle.to_radians().sin_cos();
        // Bone2 turns about (0, 1, 0): a point (0.5, 1 + y, 0) goes to (0.5c − y s, 1 + 0.5 s + y c).
        let on_bone2 = |y: f32| Vec3::new(0.5 * c - y * s, 1.0 + 0.5 * s + y * c, 0.0);
        let expected = [
            Vec3::new(0.5, 0.0, 0.0),
            on_bone2(1.0),
            (Vec3::new(0.5, 1.0, 1.0) + on_bone2(0.0) + Vec3::Z) * 0.5,
        ];
        for (k, (got, want)) in p.iter().zip(expected).enumerate() {
            assert!(
                got.distance(want) < 1e-5,
                "t = {t}: vertex {k} at {got}, expected {want}"
            );
        }
    }
}

#[test]
fn shells_keep_their_spacing_and_cover_the_body() {
    let Some(path) = asset_path("CesiumMan/CesiumMan.glb") else {
        return;
    };
    let asset = Asset::open(&path).unwrap();
    let walk = clip(&asset, &path, Some("0"), 30);
    let r = 0.02;
    let shell = Shell::sample(&walk.frames[0], &walk.triangles[0], r);
    assert!(shell.len() > 100);
    assert_eq!(
        shell,
        Shell::sample(&walk.frames[0], &walk.triangles[0], r),
        "deterministic"
    );
    let p = shell.positions(&walk.frames[0], &walk.triangles[0]);
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            assert!(
                p[i].distance(p[j]) >= drape::character::shell::SPACING * r * (1.0 - 1e-5),
                "particles {i} and {j} closer than the shell's spacing"
            );
        }
    }
    // Coverage: dense surface points (a finer shell) against their nearest particle.
    let probes = Shell::sample(&walk.frames[0], &walk.triangles[0], r / 4.0)
        .positions(&walk.frames[0], &walk.triangles[0]);
    let mut gaps: Vec<f32> = probes
        .iter()
        .map(|q| p.iter().map(|x| x.distance(*q)).fold(f32::MAX, f32::min) / r)
        .collect();
    gaps.sort_by(f32::total_cmp);
    let (median, p95, max) = (
        gaps[gaps.len() / 2],
        gaps[gaps.len() * 95 / 100],
        gaps[gaps.len() - 1],
    );
    eprintln!("coverage in r: median {median:.2}, p95 {p95:.2}, max {max:.2}");
    assert!(
        median <= 0.6 && p95 <= 0.9 && max <= 1.25,
        "coverage median {median}, p95 {p95}, max {max} (in r)"
    );
    // Carried through the clip, particles stay on the moving skin and move continuously.
    let later = shell.positions(&walk.frames[10], &walk.triangles[0]);
    let next = shell.positions(&walk.frames[11], &walk.triangles[0]);
    let step = later
        .iter()
        .zip(&next)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(
        step > 0.0 && step < 0.05,
        "shell particles move {step} m between frames"
    );
}

/// A UV sphere of radius 0.3 m with `segments` × `segments / 2` quads (outward winding); with
/// `split`, every triangle has its own three vertices, as a faceted export writes them.
fn uv_sphere(segments: usize, split: bool) -> (Vec<glam::Vec3>, Vec<[u32; 3]>) {
    let rings = segments / 2;
    let at = |i: usize, j: usize| {
        let (theta, phi) = (
            std::f32::consts::PI * j as f32 / rings as f32,
            std::f32::consts::TAU * i as f32 / segments as f32,
        );
        0.3 * glam::Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            theta.sin() * phi.sin(),
        )
    };
    let mut vertices = Vec::new();
    for j in 0..=rings {
        for i in 0..=segments {
            vertices.push(at(i, j));
        }
    }
    let index = |i: usize, j: usize| (j * (segments + 1) + i) as u32;
    let mut triangles = Vec::new();
    for j in 0..rings {
        for i in 0..segments {
            let (a, b, c, d) = (
                index(i, j),
                index(i + 1, j),
                index(i, j + 1),
                index(i + 1, j + 1),
            );
            triangles.push([a, b, c]);
            triangles.push([b, d, c]);
        }
    }
    if !split {
        return (vertices, triangles);
    }
    common::flat_shaded(&vertices, &triangles)
}

#[test]
fn shell_normals_follow_the_smooth_surface() {
    // On a coarse sphere (16 × 8 quads, faces 22.5° apart) the shell particles' normals are the
    // surface's smooth normal, not their facet's: each within a few degrees of the true radial
    // direction, where facet normals are off by up to half a facet; a faceted export (split
    // vertices) gives the same normals.
    for split in [false, true] {
        let (v, t) = uv_sphere(16, split);
        let shell = Shell::sample(&v, &t, 0.01);
        let p = shell.positions(&v, &t);
        let n = shell.normals(&v, &t);
        let worst = p
            .iter()
            .zip(&n)
            .map(|(p, n)| p.normalize().dot(*n).clamp(-1.0, 1.0).acos().to_degrees())
            .fold(0.0f32, f32::max);
        let facet_worst = shell
            .triangle
            .iter()
            .zip(&p)
            .map(|(&k, p)| {
                let [a, b, c] = t[k as usize].map(|i| v[i as usize]);
                let facet = (b - a).cross(c - a).normalize();
                p.normalize()
                    .dot(facet)
                    .clamp(-1.0, 1.0)
                    .acos()
                    .to_degrees()
            })
            .fold(0.0f32, f32::max);
        eprintln!("split {split}: {} particles, normals within {worst:.1}° of radial (facets {facet_worst:.1}°)", p.len());
        assert!(worst < 6.0, "normals {worst}° off the radial direction");
        assert!(
            worst < 0.5 * facet_worst,
            "smooth {worst}°, facets {facet_worst}°"
        );
    }
}

#[test]
fn bad_files_give_clear_errors() {
    let dir = common::temp_dir();
    let missing = Asset::open(&dir.path().join("nobody.glb")).unwrap_err();
    assert_eq!(missing.exit_code(), 2);
    assert!(missing.to_string().contains("nobody.glb"), "{missing}");

    let corrupt = common::write(dir.path(), "broken.glb", "glTF this is not a binary glTF");
    let err = Asset::open(&corrupt).unwrap_err();
    assert_eq!(err.exit_code(), 2);
    assert!(
        err.to_string().contains("broken.glb") && err.to_string().contains("not readable glTF"),
        "{err}"
    );

    let lines = common::write(
        dir.path(),
        "lines.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2 3\n",
    );
    let err = Asset::open(&lines).unwrap_err();
    assert!(err.to_string().contains("lines.obj"), "{err}");

    let rig = write_rig(dir.path());
    let asset = Asset::open(&rig).unwrap();
    let options = CharacterOptions {
        clip: Some("Dance".into()),
        ..Default::default()
    };
    let err = Character::from_asset(&asset, &rig, &options, 60.0, 10).unwrap_err();
    assert!(
        err.to_string().contains("Dance") && err.to_string().contains("Bend"),
        "{err}"
    );
}

#[test]
fn a_folder_of_frames_is_a_sequence() {
    let dir = common::temp_dir();
    for k in 1..=3 {
        let y = k as f32 * 0.1;
        common::write(
            dir.path(),
            &format!("frame_{k:04}.obj"),
            &format!("v 0 {y} 0\nv 1 {y} 0\nv 0 {y} 1\nf 1 2 3\n"),
        );
    }
    let options = CharacterOptions {
        scale: 2.0,
        ..Default::default()
    };
    let c = Character::load(dir.path(), &options, 60.0, 10).unwrap();
    assert_eq!(c.frames.len(), 3);
    assert!(c.same_topology());
    assert!(
        (c.frame(2)[0].y - 0.6).abs() < 1e-6,
        "scaled second frame: {}",
        c.frame(2)[0]
    );
    assert_eq!(c.frame(9), c.frame(2), "the last frame holds");
    let pattern = Character::load(
        &dir.path().join("frame_%04d.obj"),
        &CharacterOptions::default(),
        60.0,
        10,
    )
    .unwrap();
    assert_eq!(pattern.frames.len(), 3);
    assert!(
        (pattern.vertices_at(0.5)[0].y - 0.15).abs() < 1e-6,
        "substep interpolation"
    );
}

#[test]
fn shell_caches_round_trip_and_go_stale_when_inputs_change() {
    let dir = common::temp_dir();
    let rig = write_rig(dir.path());
    let out = dir.path().join("rig.shell");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "shell",
            rig.to_str().unwrap(),
            "--clip",
            "Bend",
            "--radius",
            "0.05",
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let o = common::drape(dir.path(), &args);
        assert!(o.status.success(), "{}", common::stderr(&o));
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let first = run(&[]);
    assert!(first.contains("particles"), "{first}");
    let cache = drape::character::ShellCache::read(&out).unwrap();
    assert!(cache.shell.len() > 3);
    assert_eq!(cache.frames.len(), 61, "one second at 60 fps, both ends");
    assert_eq!(
        drape::character::ShellCache::from_bytes(&cache.to_bytes(), "again").unwrap(),
        cache
    );
    // The particles follow the rig: at the end of the clip they match the shell on the posed mesh.
    let asset = Asset::open(&rig).unwrap();
    let end = asset.pose(asset.clip_index("Bend"), 1.0);
    let expected = cache.shell.positions(&end, &asset.triangles());
    for (a, b) in cache.frames[60].iter().zip(&expected) {
        assert!(a.distance(*b) < 1e-5);
    }
    assert!(run(&[]).contains("up to date"));
    assert!(
        !run(&["--scale", "2"]).contains("up to date"),
        "a changed option rebuilds the cache"
    );
    // A file that is not a cache is refused clearly.
    let junk = common::write(dir.path(), "junk.shell", "not a cache");
    let err = drape::character::ShellCache::read(&junk).unwrap_err();
    assert!(
        err.to_string().contains("junk.shell") && err.to_string().contains("DRAPESHL"),
        "{err}"
    );
}

#[test]
fn a_sequence_that_changes_topology_is_resampled_per_frame() {
    let dir = common::temp_dir();
    common::write(
        dir.path(),
        "a_0001.obj",
        "v 0 0 0\nv 1 0 0\nv 0 0 1\nf 1 2 3\n",
    );
    common::write(
        dir.path(),
        "a_0002.obj",
        "v 0 0 0\nv 2 0 0\nv 0 0 2\nv 2 0 2\nf 1 2 3\nf 2 4 3\n",
    );
    let c = Character::load(dir.path(), &CharacterOptions::default(), 60.0, 2).unwrap();
    assert!(!c.same_topology());
    let shells = c.shell_frames(0.05);
    assert!(
        shells[1].len() > 3 * shells[0].len(),
        "8× the area, many more particles: {} vs {}",
        shells[1].len(),
        shells[0].len()
    );
}

#[test]
fn the_command_line_reports_bad_characters_with_exit_2() {
    let dir = common::temp_dir();
    let out = common::drape(dir.path(), &["shell", "missing.glb", "--out", "x.shell"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(common::stderr(&out).contains("missing.glb"));
    let rig = write_rig(dir.path());
    let out = common::drape(
        dir.path(),
        &["inspect", rig.to_str().unwrap(), "--clip", "Nope"],
    );
    assert_eq!(out.status.code(), Some(2));
    assert!(
        common::stderr(&out).contains("Nope") && common::stderr(&out).contains("Bend"),
        "{}",
        common::stderr(&out)
    );
    assert!(!dir.path().join("x.shell").exists());
}

/// CesiumMan as committed (the tests that need it never skip).
fn cesium_man() -> PathBuf {
    PathBuf::from("characters/CesiumMan/CesiumMan.glb")
}

/// CesiumMan with its mesh node renamed to the pelvis bone's name and moved before the bone
/// in depth-first order: a name lookup now finds the mesh node first.
fn cesium_man_with_a_duplicate_name(dir: &Path) -> PathBuf {
    let gltf::Gltf { document, blob } = gltf::Gltf::open(cesium_man()).unwrap();
    let mut root = document.into_json();
    let (mesh, bone) = (2, 3);
    assert_eq!(root.nodes[mesh].mesh.map(|m| m.value()), Some(0));
    let bone_name = root.nodes[bone].name.clone().unwrap();
    root.nodes[mesh].name = Some(bone_name);
    // The armature's children: the mesh node first, then the skeleton.
    let armature = root
        .nodes
        .iter()
        .position(|n| {
            n.children
                .as_ref()
                .is_some_and(|c| c.iter().any(|i| i.value() == mesh))
        })
        .unwrap();
    root.nodes[armature].children = Some(vec![
        gltf::json::Index::new(mesh as u32),
        gltf::json::Index::new(bone as u32),
    ]);
    let path = dir.join("duplicate_name.glb");
    common::write_glb(&path, &root, blob.as_deref().unwrap());
    path
}

#[test]
fn a_mesh_node_named_like_a_bone_binds_by_index() {
    let dir = common::temp_dir();
    let renamed = cesium_man_with_a_duplicate_name(dir.path());
    let frames = 40;
    let original = clip(
        &Asset::open(&cesium_man()).unwrap(),
        &cesium_man(),
        Some("0"),
        frames,
    );
    // glTF is read by index: the same vertices in every frame, to the bit.
    let by_index = clip(&Asset::open(&renamed).unwrap(), &renamed, Some("0"), frames);
    assert_eq!(by_index.frames, original.frames);
    // Through assimp (by name) the bone wins over the mesh node, with a warning naming it.
    let asset = Asset::open_with_assimp(&renamed).unwrap();
    assert!(
        asset
            .warnings
            .iter()
            .any(|w| w.contains("Skeleton_torso_joint_1")),
        "{:?}",
        asset.warnings
    );
    let by_name = clip(&asset, &renamed, Some("0"), frames);
    let worst = by_name
        .frames
        .iter()
        .zip(&original.frames)
        .flat_map(|(a, b)| a.iter().zip(b).map(|(p, q)| p.distance(*q)))
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-5, "assimp's frames {worst} m from the original");
    // A walk moves: the check above compares frames that differ from one another.
    assert!(original.frames[0] != original.frames[20]);
}

#[test]
fn clip_names_match_whatever_their_case_when_only_one_does() {
    let path = Path::new("characters/RobotExpressive/RobotExpressive.glb");
    let asset = Asset::open(path).unwrap();
    let exact = asset.clip_index("Running").unwrap();
    assert_eq!(asset.clip_index("running"), Some(exact));
    assert_eq!(asset.clip_index("RUNNING"), Some(exact));
    assert_eq!(asset.clip_index("runnin"), None);
    let options = CharacterOptions {
        clip: Some("walk".into()),
        ..Default::default()
    };
    let err = Character::from_asset(&asset, path, &options, 60.0, 2).unwrap_err();
    assert!(err.to_string().contains("\"Walking\""), "{err}");
}

#[test]
fn meshes_are_chosen_by_mesh_node_or_material_name() {
    use drape::character::MeshSelection;
    let path = Path::new("characters/RobotExpressive/RobotExpressive.glb");
    let asset = Asset::open(path).unwrap();
    let load = |meshes: Option<MeshSelection>| {
        let options = CharacterOptions {
            meshes,
            ..Default::default()
        };
        Character::from_asset(&asset, path, &options, 60.0, 1)
    };
    let all = load(None).unwrap();
    let count = |pick: &dyn Fn(&drape::mesh::import::Mesh) -> bool| -> usize {
        asset
            .mesh_triangle_ranges()
            .iter()
            .filter(|(m, _)| pick(m))
            .map(|(_, r)| r.len())
            .sum()
    };
    // "Head" is a mesh (three primitives) and a node name.
    let no_head = load(Some(MeshSelection::Exclude(vec!["Head".into()]))).unwrap();
    assert_eq!(
        no_head.triangles_of(0).len(),
        all.triangles_of(0).len() - count(&|m| m.name == "Head")
    );
    assert_eq!(
        no_head.visible_triangles(),
        all.triangles_of(0),
        "exports show it all"
    );
    // A material name picks every primitive made of it.
    let grey = load(Some(MeshSelection::Include(vec!["Grey".into()]))).unwrap();
    assert_eq!(grey.triangles_of(0).len(), count(&|m| m.material == "Grey"));
    assert!(grey.triangles_of(0).len() < all.triangles_of(0).len());
    // The kept triangles are the file's own, not renumbered.
    assert!(grey
        .triangles_of(0)
        .iter()
        .all(|t| all.triangles_of(0).contains(t)));
    // A name that matches nothing is refused, naming the field and listing the meshes.
    let err = load(Some(MeshSelection::Exclude(vec!["Hair".into()]))).unwrap_err();
    assert_eq!(err.exit_code(), 2);
    let text = err.to_string();
    assert!(
        text.contains("meshes") && text.contains("\"Hair\"") && text.contains("\"Torso\""),
        "{text}"
    );
}

#[test]
fn a_flat_shaded_character_is_measured_as_its_smooth_original() {
    use drape::collide::mesh::{penetration, Surface};
    // The bind pose: a walk's frames fold the mesh into itself (hands into thighs), where
    // neither parity nor a nearest-surface test means "inside".
    let rest = clip(&Asset::open(&cesium_man()).unwrap(), &cesium_man(), None, 1);
    let (v, t) = (rest.frame(0), rest.triangles_of(0));
    // The same frame flat-shaded: three vertices of its own per triangle.
    let (fv, ft) = common::flat_shaded(v, t);
    // Probes in and out along each 7th triangle's normal, 2 mm to 3 cm from its centroid.
    let mut points = Vec::new();
    for tri in t.iter().step_by(7) {
        let [a, b, c] = tri.map(|i| v[i as usize]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        let centre = (a + b + c) / 3.0;
        for d in [0.002, 0.006, 0.015, 0.03] {
            points.push(centre + n * d);
            points.push(centre - n * d);
        }
    }
    let smooth = penetration(v, t, &points);
    let flat = penetration(&fv, &ft, &points);
    assert_eq!(
        flat.inside, smooth.inside,
        "flat-shaded and smooth copies count alike"
    );
    assert!((flat.deepest - smooth.deepest).abs() < 1e-6);
    // Against ray parity, point by point, where the welded mesh is closed.
    let surface = Surface::new(v, t);
    eprintln!(
        "CesiumMan bind pose: {} of {} probes inside, deepest {:.4} m; welded mesh closed: {}",
        smooth.inside,
        points.len(),
        smooth.deepest,
        surface.closed()
    );
    if surface.closed() {
        let disagree = points
            .iter()
            .filter(|&&p| (surface.penetration(&[p]).inside == 1) != common::parity_inside(v, t, p))
            .count();
        assert_eq!(disagree, 0, "probes judged otherwise than by ray parity");
    }
    assert!(surface.closed(), "CesiumMan welds into a closed mesh");
    assert!(smooth.inside > points.len() / 4 && smooth.inside < 3 * points.len() / 4);
}

/// Each mesh copy's (name, vertex range) in [`Asset::pose`]'s layout; assimp's "-N" suffix
/// on a primitive's name taken off.
fn vertex_ranges(asset: &Asset) -> Vec<(String, std::ops::Range<usize>)> {
    let mut out = Vec::new();
    let mut start = 0;
    for m in &asset.meshes {
        let name = match m.name.rsplit_once('-') {
            Some((base, n)) if n.parse::<u32>().is_ok() => base.to_string(),
            _ => m.name.clone(),
        };
        for _ in 0..m.copies() {
            out.push((name.clone(), start..start + m.vertices.len()));
            start += m.vertices.len();
        }
    }
    out
}

#[test]
fn gltf_by_index_gives_assimps_frames_for_every_shipped_clip() {
    // Both readers on the same files agree on the skinning and sampling of every clip. assimp
    // orders some meshes otherwise (RobotExpressive's Foot.R after the legs) and names
    // primitives "Torso-0", so mesh copies are paired by name, in order.
    for file in [
        "characters/CesiumMan/CesiumMan.glb",
        "characters/RobotExpressive/RobotExpressive.glb",
    ] {
        let path = Path::new(file);
        let (by_index, by_name) = (
            Asset::open(path).unwrap(),
            Asset::open_with_assimp(path).unwrap(),
        );
        assert_eq!(by_index.clips.len(), by_name.clips.len(), "{file}: clips");
        let (ra, mut rb) = (vertex_ranges(&by_index), vertex_ranges(&by_name));
        assert_eq!(ra.len(), rb.len(), "{file}: meshes");
        let pairs: Vec<_> = ra
            .into_iter()
            .map(|(name, a)| {
                let k = rb
                    .iter()
                    .position(|(n, _)| *n == name)
                    .expect("a mesh of that name");
                (a, rb.remove(k).1)
            })
            .collect();
        for (k, c) in by_index.clips.iter().enumerate() {
            let name = k.to_string();
            let a = clip(&by_index, path, Some(&name), 30);
            let b = clip(&by_name, path, Some(&name), 30);
            let mut worst = 0.0f32;
            for (p, q) in a.frames.iter().zip(&b.frames) {
                for (ra, rb) in &pairs {
                    assert_eq!(ra.len(), rb.len(), "{file}: a mesh's vertex count");
                    let d = p[ra.clone()]
                        .iter()
                        .zip(&q[rb.clone()])
                        .map(|(u, v)| u.distance(*v));
                    worst = d.fold(worst, f32::max);
                }
            }
            assert!(worst < 1e-5, "{file} clip {:?}: {worst} m apart", c.name);
        }
    }
}

#[test]
fn fbx_and_collada_copies_give_the_gltf_frames() {
    // tests/assets/CesiumMan/README.md says how they were written (Blender 3.4's FBX exporter,
    // in centimetres; assimp's Collada exporter from that FBX).
    let frames = 121;
    let gltf = clip(
        &Asset::open(&cesium_man()).unwrap(),
        &cesium_man(),
        Some("0"),
        frames,
    );
    for name in ["CesiumMan.fbx", "CesiumMan.dae"] {
        let path = Path::new("tests/assets/CesiumMan").join(name);
        let asset = Asset::open(&path).unwrap();
        let options = CharacterOptions {
            clip: Some("0".into()),
            scale: 0.01,
            ..Default::default()
        };
        let other = Character::from_asset(&asset, &path, &options, 60.0, frames).unwrap();
        assert!(
            other.size_warning(0.01).is_none(),
            "{name}: 1.46 m at scale 0.01"
        );
        // At scale 1 the centimetres read as a 146 m body, and the warning says what they are.
        let metres = CharacterOptions {
            clip: Some("0".into()),
            ..Default::default()
        };
        let raw = Character::from_asset(&asset, &path, &metres, 60.0, 1).unwrap();
        let warning = raw.size_warning(1.0).expect("a 146 m body is warned of");
        assert!(
            warning.contains("read as centimetres (scale 0.01)"),
            "{warning}"
        );
        let worst = common::worst_corner_distance(&other, &gltf);
        eprintln!("{name}: frames within {worst:.2e} m of the glTF's");
        assert!(worst < 1e-5, "{name}: frames {worst} m from the glTF's");
    }
}

#[test]
fn a_flat_shaded_copy_of_a_character_bakes_the_frames_of_its_smooth_original() {
    // characters/CesiumManFlat (written by characters/flat_shade.py): every triangle of
    // CesiumMan with three vertices of its own and its face normal. Shells, skin bindings and
    // the mesh metric weld by position, so the poncho walking on either bakes the same frames,
    // to the bit, with no garment particle inside either body.
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let flat = Asset::open(&root.join("characters/CesiumManFlat/CesiumManFlat.glb")).unwrap();
    let smooth = Asset::open(&cesium_man()).unwrap();
    let vertices = |a: &Asset| a.bind_pose().len();
    assert!(
        vertices(&flat) > 4 * vertices(&smooth),
        "the copy is split at every edge ({} vertices, the original {})",
        vertices(&flat),
        vertices(&smooth)
    );
    let dir = common::temp_dir();
    let bake = |scene: &str| {
        let file = root.join("scenes").join(scene);
        let out = dir.path().join(scene);
        let args = [
            "bake",
            file.to_str().unwrap(),
            "--frames",
            "30",
            "--gltf",
            "none",
        ];
        let run = common::drape(
            dir.path(),
            &[&args[..], &["--out", out.to_str().unwrap()]].concat(),
        );
        assert!(run.status.success(), "{scene}: {}", common::stderr(&run));
        let text = std::fs::read_to_string(out.join("report.json")).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()
    };
    let (a, b) = (bake("poncho_walk.json"), bake("poncho_walk_flat.json"));
    assert_eq!(
        a["frames_hash"], b["frames_hash"],
        "frames of the flat copy"
    );
    for report in [&a, &b] {
        let worst = report["worst_mesh_penetrations"].as_array().unwrap();
        assert!(!worst.is_empty());
        for w in worst {
            assert_eq!(w["inside"].as_u64(), Some(0), "{w}");
        }
    }
}

#[test]
fn the_gpu_uploads_a_flat_shaded_character_as_its_smooth_original() {
    // The GPU holds one position per weld slot when a slot's vertices share their bits in
    // every frame: the flat copy's 14 016 vertices go up as the original's 2 338 places, the
    // same bytes per frame, and the shells placed from them give the same cloth.
    let Some(ctx) = common::gpu_context() else {
        return;
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let dir = common::temp_dir();
    let run = |scene: &str| {
        let mut scene = drape::scene::Scene::load(&root.join("scenes").join(scene)).unwrap();
        scene.frames = 4;
        let mut sim = common::simulation(&scene, dir.path());
        let mut gpu = drape::gpu::GpuSimulation::new(ctx.clone(), &sim).expect("GPU simulation");
        let mut uploaded = Vec::new();
        for _ in 0..scene.frames {
            gpu.step_frame(sim.frame_parts()).expect("GPU frame");
            uploaded.push(gpu.uploaded_last_frame());
        }
        (sim.export_positions(), uploaded)
    };
    let (smooth, smooth_bytes) = run("poncho_walk.json");
    let (flat, flat_bytes) = run("poncho_walk_flat.json");
    assert_eq!(flat_bytes, smooth_bytes, "bytes uploaded per frame");
    assert_eq!(flat, smooth, "the cloth on the flat copy");
    // One character frame of 2 338 places a frame after the first, and the substeps' times.
    assert!(smooth_bytes[3] < 3273 * 16, "{smooth_bytes:?}");
}
