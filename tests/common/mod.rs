//! Helpers shared by the integration tests: scenes from JSON text, bakes in temporary folders,
//! and running the `drape` binary.
#![allow(dead_code)]

use drape::scene::Scene;
use std::path::{Path, PathBuf};
use std::process::Output;

/// Parses a scene written in the test (panics with the parse error if it is invalid).
pub fn scene(json: &str) -> Scene {
    Scene::parse(json, "<test scene>").unwrap_or_else(|e| panic!("test scene invalid: {e}"))
}

/// Scene P (the embedded default: the poncho on the mannequin, its frames written under
/// `dir`) for `frames` frames on the CPU, writing no frame files.
pub fn scene_p(dir: &Path, frames: u32) -> Scene {
    let mut scene = Scene::default_scene(&dir.join("mannequin")).expect("scene P");
    scene.frames = frames;
    scene.backend = drape::scene::BackendKind::Cpu;
    scene.output.obj = false;
    scene.output.gltf = drape::scene::GltfOutput::None;
    scene
}

/// `scene`'s simulation as the bake builds it, its characters' shells cached under `dir`.
pub fn simulation(scene: &Scene, dir: &Path) -> drape::sim::Simulation {
    let mut warnings = Vec::new();
    let characters =
        drape::bake::load_characters(scene, &dir.join("cache"), &mut warnings).unwrap();
    drape::bake::simulation(scene, characters, "<test scene>")
        .unwrap()
        .sim
}

/// A fresh temporary folder, removed when dropped.
pub fn temp_dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temporary folder")
}

/// Runs the drape binary with `args` in `dir`.
pub fn drape(dir: &Path, args: &[&str]) -> Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_drape"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("drape runs")
}

/// Writes `text` to `dir/name` and returns the path.
pub fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).expect("write test file");
    path
}

/// stderr of a finished command as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Largest distance any vertex of a character moves between consecutive frames [m].
pub fn largest_step(c: &drape::character::Character) -> f32 {
    c.frames
        .windows(2)
        .map(|w| {
            w[0].iter()
                .zip(&w[1])
                .map(|(p, q)| p.distance(*q))
                .fold(0.0, f32::max)
        })
        .fold(0.0, f32::max)
}

/// A GPU context on any adapter (lavapipe here and in CI), or None after printing "skipped" when
/// the machine has none.
pub fn gpu_context() -> Option<drape::gpu::GpuContext> {
    match drape::gpu::GpuContext::new(false) {
        Ok(c) => Some(c),
        Err(e) => {
            eprintln!("skipped: {e}");
            None
        }
    }
}

/// Two simulations of `scene` as the bake builds it (see [`simulation`]), to be told apart by how
/// they compute it and stepped with [`step_alike`].
pub fn two_simulations(
    scene: &Scene,
    dir: &Path,
) -> (drape::sim::Simulation, drape::sim::Simulation) {
    (simulation(scene, dir), simulation(scene, dir))
}

/// Steps `a` and `b` (two simulations of one scene that differ only in how they compute it)
/// through `frames` frames, asserting after each that their states are equal bit for bit
/// (`what`: the difference, for the message), then calls `after(a, b)`.
pub fn step_alike(
    (a, b): (&mut drape::sim::Simulation, &mut drape::sim::Simulation),
    frames: u32,
    what: &str,
    mut after: impl FnMut(&drape::sim::Simulation, &drape::sim::Simulation),
) {
    for frame in 0..frames {
        a.step_frame();
        b.step_frame();
        assert_eq!(a.state, b.state, "frame {frame}: {what} changed the cloth");
        after(a, b);
    }
}

/// Largest distance between the particles of two simulations of one scene [m].
pub fn largest_gap(a: &drape::sim::Simulation, b: &drape::sim::Simulation) -> f32 {
    a.state
        .positions
        .iter()
        .zip(&b.state.positions)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f32::max)
}

/// A character whose topology changes: `dir` gets a frame sequence of a horizontal 2 m square
/// at height 0.5 m (two triangles) for `big_frames` frames, then a 1 m square of four triangles
/// (a quarter of the area, so its re-sampled shell has about a quarter of the particles).
pub fn shrinking_floor(dir: &Path, big_frames: usize) {
    let big = "v -1 0.5 -1\nv 1 0.5 -1\nv 1 0.5 1\nv -1 0.5 1\nf 1 3 2\nf 1 4 3\n";
    let small = "v -0.5 0.5 -0.5\nv 0.5 0.5 -0.5\nv 0.5 0.5 0.5\nv -0.5 0.5 0.5\nv 0 0.5 0\n\
                 f 1 5 2\nf 2 5 3\nf 3 5 4\nf 4 5 1\n";
    for k in 1..=big_frames {
        write(dir, &format!("floor_{k:04}.obj"), big);
    }
    write(dir, &format!("floor_{:04}.obj", big_frames + 1), small);
}

/// A scene of a 0.4 m cloth 6 cm above the floor `shrinking_floor` wrote in `dir` (one file
/// per frame, shell radius 2 cm), with `passes` collision passes.
pub fn cloth_on_shrinking_floor(dir: &Path, frames: u32, passes: u32) -> Scene {
    scene(&format!(
        r#"{{ "fps": 60, "frames": {frames}, "substeps": 4, "backend": "cpu",
              "solver": {{ "iterations": 6, "contact_passes": {passes} }},
              "garments": [{{ "name": "cloth", "resolution": [12, 12], "size": [0.4, 0.4],
                             "position": [0, 0.56, 0] }}],
              "characters": [{{ "name": "floor", "file": {:?}, "sequence_fps": 60, "radius": 0.02 }}] }}"#,
        dir.display().to_string()
    ))
}

/// Bakes `dir/scene.json` into `dir/out` with the drape binary (it must succeed) and returns
/// the parsed report.json.
pub fn bake_report(dir: &Path) -> serde_json::Value {
    let out = drape(dir, &["bake", "scene.json", "--out", "out"]);
    assert!(out.status.success(), "{}", stderr(&out));
    serde_json::from_str(&std::fs::read_to_string(dir.join("out/report.json")).unwrap()).unwrap()
}

/// Options for a library bake into `out` on 2 threads, no progress bar, from the first frame.
pub fn bake_options(out: &Path) -> drape::bake::BakeOptions {
    drape::bake::BakeOptions {
        out: out.to_path_buf(),
        scene_file: "<test scene>".into(),
        threads: Some(2),
        progress: drape::bake::ProgressView::Hidden,
        shell_cache: Some(out.with_file_name("cache")),
        resume: drape::bake::Resume::No,
        until: None,
        fixed_team: false,
    }
}

/// Independent reference: inside by the parity of a ray's crossings over every triangle (f64
/// Möller–Trumbore along a fixed oblique direction).
pub fn parity_inside(v: &[glam::Vec3], t: &[[u32; 3]], p: glam::Vec3) -> bool {
    let d = glam::DVec3::new(0.5727, 0.6163, 0.5402).normalize();
    let o = p.as_dvec3();
    let mut hits = 0;
    for tri in t {
        let [a, b, c] = tri.map(|i| v[i as usize].as_dvec3());
        let (e1, e2) = (b - a, c - a);
        let h = d.cross(e2);
        let det = e1.dot(h);
        if det.abs() < 1e-15 {
            continue;
        }
        let s = o - a;
        let u = s.dot(h) / det;
        let q = s.cross(e1);
        let w = d.dot(q) / det;
        if u >= 0.0 && w >= 0.0 && u + w <= 1.0 && e2.dot(q) / det > 0.0 {
            hits += 1;
        }
    }
    hits % 2 == 1
}

/// A prism over the counter-clockwise polygon `outline` (triangulated as `caps`), from z = 0
/// to z = `height`, wound counter-clockwise seen from outside.
pub fn prism(
    outline: &[[f32; 2]],
    caps: &[[u32; 3]],
    height: f32,
) -> (Vec<glam::Vec3>, Vec<[u32; 3]>) {
    let n = outline.len() as u32;
    let mut v: Vec<glam::Vec3> = outline
        .iter()
        .map(|p| glam::Vec3::new(p[0], p[1], 0.0))
        .collect();
    v.extend(outline.iter().map(|p| glam::Vec3::new(p[0], p[1], height)));
    let mut t = Vec::new();
    for &[a, b, c] in caps {
        t.push([a, c, b]); // bottom, seen from below
        t.push([a + n, b + n, c + n]); // top
    }
    for i in 0..n {
        let j = (i + 1) % n;
        t.push([i, j, j + n]);
        t.push([i, j + n, i + n]);
    }
    (v, t)
}

/// An axis-aligned box from `lo` to `hi`.
pub fn cuboid(lo: glam::Vec3, hi: glam::Vec3) -> (Vec<glam::Vec3>, Vec<[u32; 3]>) {
    let (v, t) = prism(
        &[[lo.x, lo.y], [hi.x, lo.y], [hi.x, hi.y], [lo.x, hi.y]],
        &[[0, 1, 2], [0, 2, 3]],
        hi.z - lo.z,
    );
    (v.into_iter().map(|p| p + glam::Vec3::Z * lo.z).collect(), t)
}

/// Every triangle with three vertices of its own, as a flat-shaded export writes it.
pub fn flat_shaded(v: &[glam::Vec3], t: &[[u32; 3]]) -> (Vec<glam::Vec3>, Vec<[u32; 3]>) {
    let vertices: Vec<glam::Vec3> = t
        .iter()
        .flat_map(|tri| tri.map(|i| v[i as usize]))
        .collect();
    let triangles = (0..t.len() as u32)
        .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
        .collect();
    (vertices, triangles)
}

/// `v`, `t` as an OBJ file at `path`.
pub fn write_obj(path: &Path, v: &[glam::Vec3], t: &[[u32; 3]]) {
    let mut text = String::new();
    for p in v {
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for [a, b, c] in t {
        text += &format!("f {} {} {}\n", a + 1, b + 1, c + 1);
    }
    std::fs::write(path, text).unwrap();
}

/// The vertices and triangles of an OBJ file drape wrote.
pub fn read_obj(path: &Path) -> (Vec<glam::Vec3>, Vec<[u32; 3]>) {
    let (mut v, mut t) = (Vec::new(), Vec::new());
    for line in std::fs::read_to_string(path).unwrap().lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let c: Vec<f32> = words.map(|w| w.parse().unwrap()).collect();
                v.push(glam::Vec3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let i: Vec<u32> = words
                    .map(|w| w.split('/').next().unwrap().parse::<u32>().unwrap() - 1)
                    .collect();
                for k in 1..i.len() - 1 {
                    t.push([i[0], i[k], i[k + 1]]);
                }
            }
            _ => {}
        }
    }
    (v, t)
}

/// An OBJ of CesiumMan's bind pose, welded by position and pushed `offset` out along the
/// angle-weighted vertex normals: a garment that is the body's own skin.
pub fn pushed_skin(offset: f32, out: &Path) -> PathBuf {
    let cesium = std::env::current_dir()
        .unwrap()
        .join("characters/CesiumMan/CesiumMan.glb");
    let asset = drape::character::Asset::open(&cesium).unwrap();
    let vertices = asset.bind_pose();
    let triangles = asset.triangles();
    let mut index = std::collections::HashMap::new();
    let mut welded: Vec<glam::Vec3> = Vec::new();
    let remap: Vec<usize> = vertices
        .iter()
        .map(|v| {
            *index
                .entry(v.to_array().map(f32::to_bits))
                .or_insert_with(|| {
                    welded.push(*v);
                    welded.len() - 1
                })
        })
        .collect();
    let faces: Vec<[usize; 3]> = triangles
        .iter()
        .map(|t| t.map(|i| remap[i as usize]))
        .filter(|[a, b, c]| a != b && b != c && a != c)
        .collect();
    let mut normals = vec![glam::Vec3::ZERO; welded.len()];
    for f in &faces {
        let [a, b, c] = f.map(|i| welded[i]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        for k in 0..3 {
            let (p, q, r) = (welded[f[k]], welded[f[(k + 1) % 3]], welded[f[(k + 2) % 3]]);
            normals[f[k]] += (q - p).angle_between(r - p) * n;
        }
    }
    let mut text = String::new();
    for (v, n) in welded.iter().zip(&normals) {
        let p = *v + n.normalize_or_zero() * offset;
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for f in &faces {
        text += &format!("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    let path = out.join("skin.obj");
    std::fs::write(&path, text).unwrap();
    path
}

/// The largest distance between two characters' triangle corners over their frames, triangle
/// by triangle (formats split vertices differently: FBX and Collada keep one per corner).
pub fn worst_corner_distance(
    a: &drape::character::Character,
    b: &drape::character::Character,
) -> f32 {
    let (ta, tb) = (a.triangles_of(0), b.triangles_of(0));
    assert_eq!(ta.len(), tb.len(), "triangle counts");
    assert_eq!(a.frames.len(), b.frames.len(), "frame counts");
    let mut worst = 0.0f32;
    for (fa, fb) in a.frames.iter().zip(&b.frames) {
        for (x, y) in ta.iter().zip(tb) {
            for c in 0..3 {
                worst = worst.max(fa[x[c] as usize].distance(fb[y[c] as usize]));
            }
        }
    }
    worst
}

/// Writes a GLB of `root` (as `gltf-json` serialises it) with `blob` as its binary chunk.
pub fn write_glb(path: &Path, root: &gltf::json::Root, blob: &[u8]) {
    let mut json = gltf::json::serialize::to_vec(root).unwrap();
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    let mut bin = blob.to_vec();
    while bin.len() % 4 != 0 {
        bin.push(0);
    }
    let length = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(length);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(length as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    std::fs::write(path, out).unwrap();
}
