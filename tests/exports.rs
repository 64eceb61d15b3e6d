//! Baked exports read back by readers drape did not write: the `gltf` crate for glTF (frame k of
//! the morph-target animation equals OBJ frame k), a PC2 reader written here from
//! the format's spec, the USD text's time samples and usd-core (points, velocities, extents),
//! and the Khronos glTF validator, which `.ci/deps` installs with usd-core. Bad output folders fail clearly and leave nothing behind.

mod common;

use glam::Vec3;
use std::path::{Path, PathBuf};

/// A hanging sheet and a rope, 6 frames, every export on.
const SCENE: &str = r#"{
  "name": "exports", "frames": 6, "substeps": 10, "backend": "cpu",
  "garments": [
    { "name": "sheet", "resolution": [12, 10], "size": [1, 0.8], "pins": [[0, 0], [-1, 0]],
      "colour": [0.2, 0.4, 0.7] },
    { "name": "rope", "kind": "rope", "resolution": [9], "size": [0.8], "position": [0, 1.5, 0.5],
      "pins": [[0]] }
  ],
  "output": { "pc2": true, "usd": true }
}"#;

/// Bakes SCENE into `dir/out` with extra arguments and returns the folder.
fn bake(dir: &Path, extra: &[&str]) -> PathBuf {
    common::write(dir, "scene.json", SCENE);
    let mut args = vec!["bake", "scene.json", "--out", "out"];
    args.extend_from_slice(extra);
    let out = common::drape(dir, &args);
    assert!(out.status.success(), "{}", common::stderr(&out));
    dir.join("out")
}

/// The `v` lines of an OBJ file in file order (grid order, as drape writes them; tobj renumbers
/// vertices in face order, and `tests/export_roundtrip.rs` checks OBJ frames with it face by face).
fn obj_positions(path: &Path) -> Vec<Vec3> {
    std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Vec3::new(v[0], v[1], v[2])
        })
        .collect()
}

/// Every frame of every mesh of a glTF, read with the `gltf` crate: base + morph target k − 1.
fn gltf_frames(path: &Path) -> Vec<(String, Vec<Vec<Vec3>>)> {
    let (doc, buffers, _) = gltf::import(path).expect("the gltf crate imports it");
    doc.nodes()
        .filter_map(|node| {
            let mesh = node.mesh()?;
            let primitive = mesh.primitives().next()?;
            let reader = primitive.reader(|b| Some(&buffers[b.index()]));
            let base: Vec<Vec3> = reader.read_positions()?.map(Vec3::from).collect();
            let mut frames = vec![base.clone()];
            for (positions, _, _) in reader.read_morph_targets() {
                let delta = positions.expect("positions");
                frames.push(
                    base.iter()
                        .zip(delta)
                        .map(|(b, d)| *b + Vec3::from(d))
                        .collect(),
                );
            }
            Some((node.name().unwrap_or("").to_string(), frames))
        })
        .collect()
}

#[test]
fn gltf_frames_equal_obj_frames_and_the_animation_plays_them_in_order() {
    let dir = common::temp_dir();
    let out = bake(dir.path(), &[]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["outputs"]["gltf"], "exports.glb");
    let meshes = gltf_frames(&out.join("exports.glb"));
    assert_eq!(meshes.len(), 2);
    for (name, frames) in &meshes {
        assert_eq!(frames.len(), 6, "{name}");
        for (k, frame) in frames.iter().enumerate() {
            let obj = obj_positions(&out.join(format!("obj/{name}_{:04}.obj", k + 1)));
            let worst = frame
                .iter()
                .zip(&obj)
                .map(|(a, b)| a.distance(*b))
                .fold(0.0, f32::max);
            // Base + (frame − base) in f32: at most a rounding of the delta apart.
            assert!(
                worst <= 1e-6,
                "{name} frame {}: {worst} m from the OBJ",
                k + 1
            );
        }
    }
    // The weights animation: key j at j/60 s gives target j − 1 the whole weight.
    let (doc, buffers, _) = gltf::import(out.join("exports.glb")).unwrap();
    let animation = doc.animations().next().expect("an animation");
    for channel in animation.channels() {
        let reader = channel.reader(|b| Some(&buffers[b.index()]));
        let times: Vec<f32> = reader.read_inputs().unwrap().collect();
        assert_eq!(times.len(), 6);
        for (j, t) in times.iter().enumerate() {
            assert!((t - j as f32 / 60.0).abs() < 1e-6);
        }
        let Some(gltf::animation::util::ReadOutputs::MorphTargetWeights(w)) = reader.read_outputs()
        else {
            panic!("weights")
        };
        let w: Vec<f32> = w.into_f32().collect();
        let targets = 5;
        for j in 0..6 {
            for t in 0..targets {
                let expected = if j > 0 && t == j - 1 { 1.0 } else { 0.0 };
                assert_eq!(w[j * targets + t], expected, "key {j} target {t}");
            }
        }
    }
    // Materials: the sheet's colour and an OBJ material library.
    let sheet = doc.materials().find(|m| m.name() == Some("sheet")).unwrap();
    assert_eq!(
        &sheet.pbr_metallic_roughness().base_color_factor()[..3],
        &[0.2, 0.4, 0.7]
    );
    let (_, materials) = tobj::load_obj(
        out.join("obj/sheet_0001.obj"),
        &tobj::LoadOptions::default(),
    )
    .unwrap();
    let materials = materials.expect("materials.mtl is read");
    assert_eq!(materials[0].diffuse, Some([0.2, 0.4, 0.7]));
}

#[test]
fn gltf_with_a_separate_buffer_reads_the_same() {
    let dir = common::temp_dir();
    let out = bake(dir.path(), &["--gltf", "gltf"]);
    assert!(out.join("exports.bin").is_file());
    let meshes = gltf_frames(&out.join("exports.gltf"));
    assert_eq!(meshes.len(), 2);
    assert_eq!(meshes[0].1.len(), 6);
}

/// PC2 from its spec: 12-byte signature, version, points, start frame, sample rate, samples,
/// then samples × points × 3 little-endian f32.
fn read_pc2(path: &Path) -> (i32, f32, f32, Vec<Vec<Vec3>>) {
    let bytes = std::fs::read(path).unwrap();
    assert_eq!(&bytes[..12], b"POINTCACHE2\0");
    let i32_at = |o: usize| i32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let f32_at = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap());
    let (version, points, start, rate, samples) =
        (i32_at(12), i32_at(16), f32_at(20), f32_at(24), i32_at(28));
    assert_eq!(bytes.len(), 32 + (points * samples * 12) as usize);
    let frames = (0..samples as usize)
        .map(|s| {
            (0..points as usize)
                .map(|p| {
                    let o = 32 + (s * points as usize + p) * 12;
                    Vec3::new(f32_at(o), f32_at(o + 4), f32_at(o + 8))
                })
                .collect()
        })
        .collect();
    (version, start, rate, frames)
}

#[test]
fn pc2_caches_hold_every_frame_in_the_rest_mesh_order() {
    let dir = common::temp_dir();
    let out = bake(dir.path(), &[]);
    for name in ["sheet", "rope"] {
        let (version, start, rate, frames) = read_pc2(&out.join(format!("pc2/{name}.pc2")));
        assert_eq!((version, start, rate, frames.len()), (1, 1.0, 1.0, 6));
        for (k, frame) in frames.iter().enumerate() {
            let obj = obj_positions(&out.join(format!("obj/{name}_{:04}.obj", k + 1)));
            assert_eq!(frame, &obj, "{name} frame {}", k + 1);
        }
        let rest = obj_positions(&out.join(format!("pc2/{name}_rest.obj")));
        assert_eq!(rest.len(), frames[0].len());
    }
}

#[test]
fn usd_layer_has_units_axis_and_a_time_sample_per_frame() {
    let dir = common::temp_dir();
    let out = bake(dir.path(), &[]);
    let text = std::fs::read_to_string(out.join("exports.usda")).unwrap();
    assert!(text.starts_with("#usda 1.0"));
    for line in [
        "metersPerUnit = 1",
        "upAxis = \"Y\"",
        "startTimeCode = 1",
        "endTimeCode = 6",
        "timeCodesPerSecond = 60",
    ] {
        assert!(text.contains(line), "missing {line}");
    }
    assert!(text.contains("def Mesh \"sheet\"") && text.contains("def BasisCurves \"rope\""));
    // Frame 3 of the sheet: the first point equals OBJ frame 3's first vertex.
    let sheet = &text[text.find("def Mesh \"sheet\"").unwrap()..];
    let samples = &sheet[sheet.find("points.timeSamples").unwrap()..];
    let line = samples
        .lines()
        .find(|l| l.trim_start().starts_with("3: ["))
        .expect("sample 3");
    let first: Vec<f32> = line[line.find("[(").unwrap() + 2..]
        .split(')')
        .next()
        .unwrap()
        .split(", ")
        .map(|v| v.parse().unwrap())
        .collect();
    let obj = obj_positions(&out.join("obj/sheet_0003.obj"));
    assert_eq!(Vec3::new(first[0], first[1], first[2]), obj[0]);
    // UVs and normals as vertex primvars: the OBJ's texture coordinates, and frame 3's normals
    // those of OBJ frame 3.
    let obj_text = std::fs::read_to_string(out.join("obj/sheet_0003.obj")).unwrap();
    let numbers = |line: &str| -> Vec<f32> {
        line.split(|c: char| "()[], ".contains(c))
            .filter_map(|v| v.parse().ok())
            .collect()
    };
    let st_line = sheet
        .lines()
        .find(|l| l.contains("texCoord2f[] primvars:st = ["))
        .expect("primvars:st");
    let st = numbers(st_line.split_once('=').unwrap().1);
    let obj_uvs: Vec<f32> = obj_text
        .lines()
        .filter_map(|l| l.strip_prefix("vt "))
        .flat_map(|l| l.split_whitespace().map(|v| v.parse::<f32>().unwrap()))
        .collect();
    assert_eq!(st, obj_uvs, "primvars:st are the OBJ's UVs");
    let normals = &sheet[sheet.find("primvars:normals.timeSamples").unwrap()..];
    let line = normals
        .lines()
        .find(|l| l.trim_start().starts_with("3: ["))
        .expect("normals sample 3");
    let usd_normals = numbers(line.trim_start().strip_prefix("3:").unwrap());
    let obj_normals: Vec<f32> = obj_text
        .lines()
        .filter_map(|l| l.strip_prefix("vn "))
        .flat_map(|l| l.split_whitespace().map(|v| v.parse::<f32>().unwrap()))
        .collect();
    assert_eq!(usd_normals.len(), obj_normals.len());
    for (a, b) in usd_normals.iter().zip(&obj_normals) {
        assert!((a - b).abs() < 1e-5, "normal {a} vs OBJ {b}");
    }
    assert_eq!(
        samples
            .lines()
            .take_while(|l| !l.trim().starts_with('}'))
            .filter(|l| l.contains(": ["))
            .count(),
        6
    );
}

/// The validator `.ci/deps` installs (npm `gltf-validator`), if it is there.
fn validator() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let module = root.join("target/gltf-validator/node_modules/gltf-validator");
    module
        .is_dir()
        .then(|| root.join("tests/validate_gltf.mjs"))
}

#[test]
fn the_khronos_validator_finds_no_errors() {
    let Some(script) = validator() else {
        eprintln!("skipped: run .ci/deps to install the Khronos glTF validator");
        return;
    };
    let dir = common::temp_dir();
    let sheet_and_rope = bake(dir.path(), &[]).join("exports.glb");
    // A second scene: a cloth on the mannequin, with the character in the file.
    let body = Path::new(env!("CARGO_MANIFEST_DIR")).join("characters/mannequin/raise_arms");
    let text = format!(
        r#"{{ "name": "mannequin", "frames": 4, "backend": "cpu",
              "garments": [{{ "name": "cloth", "resolution": [16, 16], "size": [1.2, 1.2], "position": [0, 1.9, 0] }}],
              "characters": [{{ "name": "body", "file": {:?}, "sequence_fps": 12 }}] }}"#,
        body.display().to_string()
    );
    common::write(dir.path(), "mannequin.json", &text);
    let out = common::drape(
        dir.path(),
        &["bake", "mannequin.json", "--out", "m", "--gltf", "gltf"],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let with_body = dir.path().join("m/mannequin.gltf");
    assert_eq!(gltf_frames(&with_body).len(), 2, "cloth and body");
    // A third: a cloth that tears (faces leave the mesh, some vertices end up in none).
    let tearing = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/tearing.json");
    let out = common::drape(
        dir.path(),
        &[
            "bake",
            tearing.to_str().unwrap(),
            "--out",
            "t",
            "--frames",
            "60",
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    let torn = dir.path().join("t/tearing.glb");
    // A fourth: a voxelized mesh garment (its own surface, embedded in the lattice).
    let cushion = bake_cushion(dir.path(), "c");
    for file in [sheet_and_rope, with_body, torn, cushion] {
        let run = std::process::Command::new("node")
            .arg(&script)
            .arg(&file)
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .expect("node runs");
        let text = String::from_utf8_lossy(&run.stdout);
        assert!(
            run.status.success(),
            "{}: {text}{}",
            file.display(),
            String::from_utf8_lossy(&run.stderr)
        );
        let result: serde_json::Value = serde_json::from_str(&text).expect("validator JSON");
        assert_eq!(
            result["issues"]["numErrors"],
            0,
            "{}: {text}",
            file.display()
        );
    }
}

/// Bakes `scenes/cushion.json` for 10 frames into `dir/name`; returns its glb.
fn bake_cushion(dir: &Path, name: &str) -> PathBuf {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/cushion.json");
    let out = common::drape(
        dir,
        &[
            "bake",
            scene.to_str().unwrap(),
            "--out",
            name,
            "--frames",
            "10",
        ],
    );
    assert!(out.status.success(), "{}", common::stderr(&out));
    dir.join(name).join("cushion.glb")
}

#[test]
fn a_mesh_garment_exports_its_own_surface_in_gltf_and_obj() {
    let dir = common::temp_dir();
    let glb = bake_cushion(dir.path(), "c");
    let mesh =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("garments/cushion.obj"))
            .unwrap();
    let vertices = mesh.lines().filter(|l| l.starts_with("v ")).count();
    let meshes = gltf_frames(&glb);
    let (name, frames) = meshes
        .iter()
        .find(|m| m.0 == "cushion")
        .expect("the cushion");
    assert_eq!(name, "cushion");
    assert_eq!(frames.len(), 10, "frames 1 to 10");
    assert!(
        frames.iter().all(|f| f.len() == vertices),
        "the mesh's {vertices} vertices"
    );
    let obj = obj_positions(&dir.path().join("c/obj/cushion_0010.obj"));
    let last = &frames[9];
    assert_eq!(obj.len(), vertices);
    let gap = obj
        .iter()
        .zip(last)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(gap < 1e-5, "OBJ and glTF frame 10 differ by {gap} m");
    // The cushion fell: frame 10 is lower than frame 1.
    let mean_y = |f: &[Vec3]| f.iter().map(|p| p.y).sum::<f32>() / f.len() as f32;
    assert!(mean_y(last) < mean_y(&frames[0]) - 0.01);
}

#[test]
fn an_output_folder_that_cannot_be_made_fails_clearly_and_leaves_nothing() {
    let dir = common::temp_dir();
    common::write(dir.path(), "scene.json", SCENE);
    common::write(dir.path(), "a_file", "not a folder");
    let out = common::drape(dir.path(), &["bake", "scene.json", "--out", "a_file/bake"]);
    assert_eq!(out.status.code(), Some(2), "{}", common::stderr(&out));
    assert!(
        common::stderr(&out).contains("--out"),
        "{}",
        common::stderr(&out)
    );
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left.len(), 2, "{left:?}");
}

#[test]
fn a_shot_starting_at_frame_1001_numbers_every_export_from_it() {
    // The same bake numbered from 1001: OBJ files, PC2 start frame, USD time codes, preview
    // images and the report carry the shot's frame numbers; the positions are those of a bake
    // numbered from 1 (equal frames hashes).
    let dir = common::temp_dir();
    let d = dir.path();
    common::write(
        d,
        "scene.json",
        r#"{ "name": "shot", "frames": 3, "backend": "cpu", "frame_start": 1001,
             "output": { "pc2": true, "usd": true, "preview": true, "preview_size": [64, 48] },
             "garments": [{ "name": "cloth", "resolution": [6, 5], "pins": [[0, 0], [-1, 0]] }] }"#,
    );
    let out = common::drape(d, &["bake", "scene.json", "--out", "shot"]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    let shot = d.join("shot");
    for k in 1001..=1003 {
        assert!(shot.join(format!("obj/cloth_{k}.obj")).is_file(), "obj {k}");
    }
    assert!(!shot.join("obj/cloth_0001.obj").exists());
    let pc2 = std::fs::read(shot.join("pc2/cloth.pc2")).unwrap();
    let start = f32::from_le_bytes(pc2[20..24].try_into().unwrap());
    assert_eq!(start, 1001.0, "PC2 start frame");
    let usda = std::fs::read_to_string(shot.join("shot.usda")).unwrap();
    assert!(usda.contains("startTimeCode = 1001") && usda.contains("endTimeCode = 1003"));
    assert!(usda.contains("            1001: [(") && usda.contains("            1003: [("));
    assert!(!usda.contains("            1: [("));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(shot.join("report.json")).unwrap()).unwrap();
    assert_eq!(report["frame_start"], 1001);
    assert_eq!(report["frames_baked"], 3);
    assert_eq!(report["last_frame"]["frame"], 1003);
    assert_eq!(report["penetrations_per_frame"][0]["frame"], 1001);
    if report["preview"].is_object() {
        for k in 1001..=1003 {
            assert!(
                shot.join(format!("preview/frame_{k}.png")).is_file(),
                "png {k}"
            );
        }
    }
    // The same bake from frame 1, and `--frame-start` overriding the scene.
    let from_one = common::drape(
        d,
        &[
            "bake",
            "scene.json",
            "--out",
            "one",
            "--frame-start",
            "1",
            "--gltf",
            "none",
        ],
    );
    assert!(from_one.status.success(), "{}", common::stderr(&from_one));
    let one: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("one/report.json")).unwrap()).unwrap();
    assert_eq!(one["frame_start"], 1);
    assert!(d.join("one/obj/cloth_0001.obj").is_file());
    assert_eq!(one["frames_hash"], report["frames_hash"]);
}

/// The Python of the USD virtual environment `.ci/deps` makes (usd-core from PyPI).
fn usd_python() -> PathBuf {
    let python = std::env::current_dir()
        .unwrap()
        .join("target/usd/bin/python");
    assert!(
        python.is_file(),
        "{} is missing: run .ci/deps (it installs usd-core from PyPI)",
        python.display()
    );
    python
}

#[test]
fn usd_core_reads_points_velocities_and_extents_that_match_the_obj_frames() {
    // usd-core (the official USD library) reads every sample back: points equal the OBJ
    // frames, velocities are their central differences in metres per second (one-sided at the
    // ends), extents their bounds.
    let dir = common::temp_dir();
    let out = bake(dir.path(), &[]);
    let script = r#"
import json, sys
from pxr import Usd, UsdGeom
stage = Usd.Stage.Open(sys.argv[1])
found = {}
for name in ("sheet", "rope"):
    prim = UsdGeom.PointBased(stage.GetPrimAtPath("/bake/" + name))
    times = prim.GetPointsAttr().GetTimeSamples()
    assert prim.GetVelocitiesAttr().GetTimeSamples() == times, name
    found[name] = [
        {"time": t,
         "points": [list(p) for p in prim.GetPointsAttr().Get(t)],
         "velocities": [list(v) for v in prim.GetVelocitiesAttr().Get(t)],
         "extent": [list(e) for e in prim.GetExtentAttr().Get(t)]}
        for t in times]
print(json.dumps(found))
"#;
    let run = std::process::Command::new(usd_python())
        .args(["-c", script])
        .arg(out.join("exports.usda"))
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", common::stderr(&run));
    let found: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let vec3 = |v: &serde_json::Value| {
        let c: Vec<f32> = v
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap() as f32)
            .collect();
        Vec3::new(c[0], c[1], c[2])
    };
    for name in ["sheet", "rope"] {
        let frames: Vec<Vec<Vec3>> = (1..=6)
            .map(|k| obj_positions(&out.join(format!("obj/{name}_{k:04}.obj"))))
            .collect();
        let samples = found[name].as_array().unwrap();
        assert_eq!(samples.len(), 6, "{name}");
        let mut fastest = 0.0f32;
        for (k, sample) in samples.iter().enumerate() {
            assert_eq!(sample["time"].as_f64(), Some(k as f64 + 1.0));
            let points: Vec<Vec3> = sample["points"]
                .as_array()
                .unwrap()
                .iter()
                .map(vec3)
                .collect();
            assert_eq!(points.len(), frames[k].len(), "{name} frame {k}");
            let (before, after) = (k.saturating_sub(1), (k + 1).min(5));
            let per = 60.0 / (after - before) as f32;
            for (i, p) in points.iter().enumerate() {
                assert!(
                    p.distance(frames[k][i]) < 1e-6,
                    "{name} frame {k} point {i}"
                );
                let v = vec3(&sample["velocities"][i]);
                let expected = (frames[after][i] - frames[before][i]) * per;
                // OBJ keeps 6 decimals: differences of two, over 1/60 s, within 1e-4 m/s.
                assert!(
                    v.distance(expected) < 1e-4,
                    "{name} frame {k} point {i}: velocity {v}, central difference {expected}"
                );
                fastest = fastest.max(v.length());
            }
            let (lo, hi) = points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| {
                (lo.min(*p), hi.max(*p))
            });
            let extent = sample["extent"].as_array().unwrap();
            assert!(vec3(&extent[0]).distance(lo) < 1e-6 && vec3(&extent[1]).distance(hi) < 1e-6);
        }
        assert!(
            fastest > 0.1,
            "{name} hardly moves ({fastest} m/s): the case tests nothing"
        );
    }
}
