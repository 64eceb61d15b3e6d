//! Contract: any triangle mesh becomes a garment. A closed mesh is filled (and only its inside),
//! a flat sheet gives one layer, a tilted one stays one piece held by axis springs, the lattice
//! colours alternate so no spring joins two particles of one colour, and the exported surface
//! is the mesh itself carried by the particles; torn, it loses the faces over the cut. Bad mesh
//! garments are input errors (exit 2).

mod common;

use drape::garment::{Garment, SpringFamily};
use drape::scene::Scene;
use drape::sim::Simulation;
use glam::Vec3;
use std::path::Path;

/// Radii and spacing of `garments/cushion.obj` (a 32 × 16 polygon ellipsoid) as the tests place it.
const RADII: Vec3 = Vec3::new(0.25, 0.08, 0.25);
const SPACING: f32 = 0.025;

/// A scene with one mesh garment read from the repository's `garments/` folder.
fn mesh_scene(extra: &str) -> Scene {
    let text = format!(
        r#"{{ "frames": 1, "garments": [{{ "kind": "mesh", "mesh": "cushion.obj",
              "spacing": {SPACING}, "position": [0, 1, 0] {extra} }}] }}"#
    );
    Scene::parse_in(
        &text,
        "<test scene>",
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("garments")
            .as_path(),
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

fn garment(scene: &Scene) -> Garment {
    drape::garment::build_all(scene, "<test scene>")
        .unwrap_or_else(|e| panic!("{e}"))
        .remove(0)
}

/// (x/a)² + (y/b)² + (z/c)² of a point relative to the cushion's centre, for radii grown by `by`.
fn ellipsoid(p: Vec3, by: f32) -> f32 {
    let q = (p - Vec3::new(0.0, 1.0, 0.0)) / (RADII + Vec3::splat(by));
    q.length_squared()
}

#[test]
fn a_closed_mesh_is_filled_and_only_its_inside() {
    let scene = mesh_scene("");
    let placed = garment(&scene).source.expect("placed");
    assert!(placed.closed, "the ellipsoid is a closed mesh");
    let v = &placed.voxels;
    assert!(v.interior_cells > 0 && v.surface_cells > 0);
    let g = garment(&scene);
    assert_eq!(g.particle_count(), v.surface_cells + v.interior_cells);
    // Every lattice point well inside is a particle; every particle lies near or inside.
    let mut expected_inside = 0;
    for k in 0..v.occupied.len() as u32 {
        let c = drape::garment::cell_of(v.dims, k);
        let p = v.centre(c);
        if ellipsoid(p, -SPACING) < 1.0 {
            expected_inside += 1;
            assert!(
                v.occupied[k as usize],
                "cell {c:?} at {p} is inside but empty"
            );
        }
    }
    assert!(expected_inside > 100, "the test lattice is too coarse");
    for p in &g.positions {
        assert!(
            ellipsoid(*p, SPACING) <= 1.0,
            "particle at {p} is outside the cushion"
        );
    }
    eprintln!(
        "cushion: {} surface + {} interior cells, {} lattice points deep inside",
        v.surface_cells, v.interior_cells, expected_inside
    );

    // The same mesh as a surface only: hollow.
    let hollow = mesh_scene(r#", "fill": "surface""#);
    let hollow_mesh = garment(&hollow).source.unwrap();
    let h = &hollow_mesh.voxels;
    assert_eq!(h.interior_cells, 0);
    assert_eq!(garment(&hollow).particle_count(), h.surface_cells);
    let middle = drape::garment::index_of(h.dims, h.dims.map(|n| n / 2)) as usize;
    assert!(
        v.occupied[middle] && !h.occupied[middle],
        "the hollow cushion's middle is empty"
    );
}

/// A flat grid of `n` × `m` vertices, `w` × `d` metres, in its XZ plane.
fn sheet_obj(n: u32, m: u32, w: f32, d: f32) -> String {
    let mut s = String::new();
    for j in 0..m {
        for i in 0..n {
            let (x, z) = (i as f32 / (n - 1) as f32 * w, j as f32 / (m - 1) as f32 * d);
            s += &format!("v {x} 0 {z}\n");
        }
    }
    for j in 0..m - 1 {
        for i in 0..n - 1 {
            let a = j * n + i + 1;
            let (b, c, e) = (a + 1, a + n, a + n + 1);
            s += &format!("f {a} {c} {b}\nf {b} {c} {e}\n");
        }
    }
    s
}

fn sheet_scene(dir: &Path, rotation: [f32; 3]) -> Scene {
    common::write(dir, "sheet.obj", &sheet_obj(5, 4, 1.0, 0.6));
    let text = format!(
        r#"{{ "garments": [{{ "kind": "mesh", "mesh": "sheet.obj", "spacing": 0.1,
              "rotation": {rotation:?} }}] }}"#
    );
    Scene::parse_in(&text, "<test scene>", dir).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn a_flat_sheet_gives_one_layer_and_a_tilted_one_stays_one_piece() {
    let dir = common::temp_dir();
    let flat = garment(&sheet_scene(dir.path(), [0.0; 3]));
    assert_eq!(flat.dims, [11, 1, 7], "a 1 × 0.6 m sheet at 0.1 m");
    assert_eq!(
        flat.particle_count(),
        77,
        "every lattice point of the sheet, one layer"
    );
    assert_eq!(flat.spring_count(SpringFamily::Stretch), 10 * 7 + 11 * 6);

    let tilted = garment(&sheet_scene(dir.path(), [0.0, 0.0, 30.0]));
    // Each lattice column across the sheet holds one or two particles (a 6-connected surface).
    let mut column = std::collections::HashMap::new();
    for c in &tilted.cells {
        *column.entry((c[0], c[2])).or_insert(0) += 1;
    }
    assert!(column.values().all(|&n| (1..=2).contains(&n)), "{column:?}");
    // Axis springs alone join every particle to every other.
    let n = tilted.particle_count();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(p: &mut [usize], i: usize) -> usize {
        let mut r = i;
        while p[r] != r {
            r = p[r];
        }
        p[i] = r;
        r
    }
    for s in &tilted.springs {
        let (a, b) = (
            root(&mut parent, s.a as usize),
            root(&mut parent, s.b as usize),
        );
        parent[a] = b;
    }
    let pieces = (0..n).filter(|&i| root(&mut parent, i) == i).count();
    assert_eq!(
        pieces, 1,
        "the tilted sheet falls apart into {pieces} pieces"
    );
}

#[test]
fn colours_alternate_on_a_voxel_block() {
    let g = garment(&mesh_scene(""));
    assert_eq!(g.colour_count(), 2);
    for (k, c) in g.cells.iter().enumerate() {
        assert_eq!(g.colour_of(k as u32), (c[0] + c[1] + c[2]) % 2);
    }
    // With shear springs the stencil needs more colours; still no spring inside one colour.
    let sheared = garment(&mesh_scene(
        r#", "stiffness": { "shear": 500, "bend": 50 }"#,
    ));
    assert!(sheared.colour_count() > 2);
    for s in &sheared.springs {
        assert_ne!(sheared.colour_of(s.a), sheared.colour_of(s.b), "{s:?}");
    }
}

#[test]
fn the_exported_surface_is_the_mesh_carried_by_the_particles() {
    let scene = mesh_scene("");
    let g = garment(&scene);
    let placed = g.source.clone().unwrap();
    let embedding = g
        .embedding
        .clone()
        .expect("a mesh garment embeds its surface");
    assert_eq!(embedding.vertex_count(), placed.vertices.len());
    // At rest the embedded surface lies within a cell of the mesh.
    let rest = embedding.apply(&g.positions);
    let worst = rest
        .iter()
        .zip(&placed.vertices)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(worst < SPACING, "embedded vertices {worst} m from the mesh");
    // Moved rigidly, the surface moves with it.
    let shift = Vec3::new(0.3, -0.2, 0.1);
    let moved: Vec<Vec3> = g.positions.iter().map(|p| *p + shift).collect();
    for (a, b) in embedding.apply(&moved).iter().zip(&rest) {
        assert!((*a - *b - shift).length() < 1e-5);
    }
}

#[test]
fn a_solid_cushion_lands_on_the_floor_and_keeps_its_shape() {
    let text = r#"{ "frames": 90, "colliders": [{ "kind": "plane" }],
        "garments": [{ "kind": "mesh", "mesh": "cushion.obj", "spacing": 0.025, "mass": 0.4,
                       "position": [0, 0.5, 0], "stiffness": { "stretch": 2000, "shear": 1000 } }] }"#;
    let garments = Path::new(env!("CARGO_MANIFEST_DIR")).join("garments");
    let scene = Scene::parse_in(text, "<test scene>", &garments).unwrap();
    let mut sim = Simulation::new(&scene).unwrap();
    let rest_height = 2.0 * RADII.y;
    for _ in 0..scene.frames {
        sim.step_frame();
    }
    let (lo, hi) = sim.export_positions().iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    assert!(lo.is_finite() && hi.is_finite());
    let height = hi.y - lo.y;
    eprintln!("cushion at rest on the floor: lowest {:.4} m, height {height:.3} m (rest {rest_height:.3})", lo.y);
    assert!(lo.y > 0.0, "a particle went through the floor ({} m)", lo.y);
    assert!(hi.y < 0.3, "the cushion has not landed");
    assert!(
        height > 0.7 * rest_height,
        "the solid collapsed to {height} m"
    );
    assert!(sim.energy().kinetic < 1e-3, "still moving after 1.5 s");
}

/// Vertices and faces of an OBJ file.
fn read_obj(path: &Path) -> (Vec<Vec3>, Vec<[usize; 3]>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut v = Vec::new();
    let mut f = Vec::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let c: Vec<f32> = words.take(3).map(|w| w.parse().unwrap()).collect();
                v.push(Vec3::new(c[0], c[1], c[2]));
            }
            Some("f") => {
                let c: Vec<usize> = words
                    .take(3)
                    .map(|w| w.split('/').next().unwrap().parse::<usize>().unwrap() - 1)
                    .collect();
                f.push([c[0], c[1], c[2]]);
            }
            _ => {}
        }
    }
    (v, f)
}

#[test]
fn a_torn_mesh_garment_loses_the_faces_over_the_cut() {
    // A 1 m square mesh (10 × 10 quads) hung by its top edge, voxelized at 5 cm, its bottom-left
    // corner grabbed and pulled away: springs tear, and the surface triangles carried across
    // a torn spring leave the exported mesh, so no face is left stretched over the cut.
    let dir = common::temp_dir();
    common::write(dir.path(), "sheet.obj", &sheet_obj(11, 11, 1.0, 1.0));
    common::write(
        dir.path(),
        "scene.json",
        r#"{ "frames": 60, "substeps": 10, "solver": { "iterations": 2 },
             "garments": [{ "name": "sheet", "kind": "mesh", "mesh": "sheet.obj", "spacing": 0.05,
                            "rotation": [90, 0, 0], "position": [0, 1.2, 0], "tethers": false,
                            "tear_strain": 0.2,
                            "attachments": [
                              { "particles": "top_edge", "keyframes": [{ "time": 0 }] },
                              { "particles": { "near": [-0.45, 0.75, 0], "radius": 0.12 },
                                "keyframes": [{ "time": 0.1 },
                                              { "time": 0.9, "translation": [-0.3, -0.9, 0.4] }] }] }] }"#,
    );
    let report = common::bake_report(dir.path());
    let torn = report["torn_springs"].as_u64().unwrap();
    assert!(torn > 0, "nothing tore");
    let (rest, whole) = read_obj(&dir.path().join("out/obj/sheet_0001.obj"));
    let (last, kept) = read_obj(&dir.path().join("out/obj/sheet_0060.obj"));
    assert_eq!(whole.len(), 200, "frame 1 is the whole mesh");
    // Kept faces are the rest mesh's faces, so edges compare one to one.
    let stretch = |f: &[usize; 3]| {
        (0..3)
            .map(|k| {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                last[a].distance(last[b]) / rest[a].distance(rest[b])
            })
            .fold(0.0f32, f32::max)
    };
    let worst_kept = kept.iter().map(stretch).fold(0.0f32, f32::max);
    eprintln!(
        "{torn} springs tore; faces {} → {}; the most stretched kept face edge {worst_kept:.2} × its rest length",
        whole.len(),
        kept.len()
    );
    assert!(kept.len() < whole.len(), "torn faces must leave the mesh");
    assert!(
        worst_kept < 2.0,
        "a kept face is stretched {worst_kept} × over the cut"
    );
}

#[test]
fn bad_mesh_garments_are_input_errors() {
    let dir = common::temp_dir();
    let cushion = Path::new(env!("CARGO_MANIFEST_DIR")).join("garments/cushion.obj");
    std::fs::copy(&cushion, dir.path().join("cushion.obj")).unwrap();
    common::write(dir.path(), "broken.obj", "v 0 0 0\nv 1 0 0\n");
    for (garment, field, expect) in [
        (
            r#""kind": "mesh", "mesh": "nowhere.obj""#,
            "garments[0].mesh",
            "nowhere.obj",
        ),
        (r#""kind": "mesh""#, "garments[0].mesh", "needs a mesh file"),
        (
            r#""kind": "mesh", "mesh": "broken.obj""#,
            "garments[0].mesh",
            "broken.obj",
        ),
        (
            r#""mesh": "cushion.obj""#,
            "garments[0].mesh",
            "belong to mesh garments",
        ),
        (
            r#""kind": "mesh", "mesh": "cushion.obj", "spacing": 0"#,
            "garments[0].spacing",
            "above zero",
        ),
        (
            r#""kind": "mesh", "mesh": "cushion.obj", "spacing": 0.0001"#,
            "garments[0].spacing",
            "limit",
        ),
        (
            r#""kind": "mesh", "mesh": "cushion.obj", "spacing": 0.05, "pins": [[0, 0, 0]]"#,
            "garments[0].pins",
            "no particle",
        ),
        (
            r#""kind": "mesh", "mesh": "cushion.obj", "pins": [[0, 0]]"#,
            "garments[0].pins",
            "not in the",
        ),
        (
            r#""kind": "mesh", "mesh": "cushion.obj", "tear_strain": -0.5"#,
            "garments[0].tear_strain",
            "above zero",
        ),
        (
            r#""kind": "mesh", "mesh": "cushion.obj", "attachments": [{ "particles": "corners", "keyframes": [{ "time": 0 }] }]"#,
            "garments[0].attachments",
            "unknown region",
        ),
    ] {
        common::write(
            dir.path(),
            "scene.json",
            &format!(r#"{{ "garments": [{{ {garment} }}] }}"#),
        );
        let out = common::drape(
            dir.path(),
            &["bake", "scene.json", "--out", "out", "--frames", "1"],
        );
        let err = common::stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{garment}: {err}");
        assert!(
            err.contains(field) && err.contains(expect),
            "{garment}: {err}"
        );
        assert!(
            !dir.path().join("out").exists(),
            "{garment}: an output folder was left"
        );
    }
}
