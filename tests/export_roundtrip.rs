//! OBJ frames read back by a reader drape did not write (`tobj`) give exactly the simulated
//! positions, in grid order, with the grid's faces and UVs.

mod common;

use drape::bake::{bake, BakeOptions};

#[test]
fn obj_frames_read_back_with_the_simulated_positions() {
    let dir = common::temp_dir();
    let scene = common::scene(
        r#"{ "frames": 4, "garments": [
              { "name": "sheet", "resolution": [7, 5], "pins": [[0, 0], [-1, 0]] },
              { "name": "rope", "kind": "rope", "resolution": [9], "size": [0.5], "position": [0, 2, 0], "pins": [[0]] } ] }"#,
    );
    let out = dir.path().join("bake");
    let result = bake(
        &scene,
        &BakeOptions {
            out: out.clone(),
            scene_file: "test".into(),
            threads: Some(2),
            progress: drape::bake::ProgressView::Hidden,
            shell_cache: None,
            resume: Default::default(),
            until: None,
            fixed_team: false,
        },
    )
    .expect("bake");
    assert_eq!(result.report.frames_baked, 4);

    let (models, _) = tobj::load_obj(
        out.join("obj/sheet_0004.obj"),
        &tobj::LoadOptions::default(),
    )
    .expect("tobj reads the sheet");
    let mesh = &models[0].mesh;
    // tobj renumbers vertices in the order faces use them, so compare face by face: corner c of
    // face f must be grid vertex grid_triangles[f][c], derived here from the 7 × 5 grid.
    let mut grid_triangles = Vec::new();
    for y in 0..4u32 {
        for x in 0..6u32 {
            let i = y * 7 + x;
            grid_triangles.push([i, i + 7, i + 1]);
            grid_triangles.push([i + 1, i + 7, i + 8]);
        }
    }
    assert_eq!(
        mesh.indices.len(),
        3 * grid_triangles.len(),
        "two triangles per grid quad"
    );
    for (f, tri) in grid_triangles.iter().enumerate() {
        for (c, &v) in tri.iter().enumerate() {
            let k = mesh.indices[3 * f + c] as usize;
            let read = [
                mesh.positions[3 * k],
                mesh.positions[3 * k + 1],
                mesh.positions[3 * k + 2],
            ];
            assert_eq!(
                read,
                result.positions[v as usize].to_array(),
                "face {f} corner {c}: exact f32"
            );
        }
    }
    assert_eq!(mesh.positions.len(), 3 * 35);
    // And the file lists the vertices in grid (report) order.
    let sheet = std::fs::read_to_string(out.join("obj/sheet_0004.obj")).unwrap();
    let expected: Vec<[f32; 3]> = result.positions[..35]
        .iter()
        .map(|p| p.to_array())
        .collect();
    assert_eq!(vertex_lines(&sheet), expected);
    assert_eq!(mesh.texcoords.len(), 2 * 35);
    assert_eq!(mesh.normals.len(), 3 * 35);

    // The rope has no faces: it is written as a polyline, its vertices still in order.
    let text = std::fs::read_to_string(out.join("obj/rope_0004.obj")).unwrap();
    let expected: Vec<[f32; 3]> = result.positions[35..]
        .iter()
        .map(|p| p.to_array())
        .collect();
    assert_eq!(vertex_lines(&text), expected);
    assert!(text.lines().any(|l| l.starts_with("l 1/1 2/2")));
}

/// The `v x y z` lines of an OBJ file, in file order.
fn vertex_lines(text: &str) -> Vec<[f32; 3]> {
    text.lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f32> = l.split(' ').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2]]
        })
        .collect()
}
