//! Cell shear, the lattice's |90° − angle| that structural strain does not see: the report's
//! figure equals one computed here from the OBJ frames, cell by cell; shear springs hold a
//! hanging sheet's cells squarer; `accuracy.max_shear` is met by the budget where shear springs
//! can meet it and refused where the garment has none.

mod common;

use glam::Vec3;
use std::path::Path;

/// A level sheet of `nx` × `ny` particles that falls from `pins` and swings, with `extra`
/// garment fields.
fn sheet(nx: u32, ny: u32, pins: &str, extra: &str) -> String {
    format!(
        r#"{{ "name": "s", "frames": 30, "backend": "cpu", "output": {{ "gltf": "none" }},
              "garments": [{{ "name": "sheet", "resolution": [{nx}, {ny}], "size": [1.2, 0.8],
                              "pins": {pins}{extra} }}] }}"#
    )
}

/// Mean and largest |90° − angle| over every corner of every cell of the `nx` × `ny` grid in
/// the OBJ frame at `path` (vertices in grid order, row after row).
fn obj_shear(path: &Path, nx: usize, ny: usize) -> (f64, f64) {
    let v: Vec<Vec3> = std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Vec3::new(c[0], c[1], c[2])
        })
        .collect();
    assert_eq!(v.len(), nx * ny);
    let at = |i: usize, j: usize| v[j * nx + i].as_dvec3();
    let (mut sum, mut max, mut n) = (0.0f64, 0.0f64, 0);
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            // The cell's four corners, each with its two edges.
            let corners = [
                ((i, j), (i + 1, j), (i, j + 1)),
                ((i + 1, j), (i, j), (i + 1, j + 1)),
                ((i, j + 1), (i + 1, j + 1), (i, j)),
                ((i + 1, j + 1), (i, j + 1), (i + 1, j)),
            ];
            for (c, a, b) in corners {
                let (u, w) = (at(a.0, a.1) - at(c.0, c.1), at(b.0, b.1) - at(c.0, c.1));
                let angle = u.angle_between(w).to_degrees();
                let d = (90.0 - angle).abs();
                sum += d;
                max = max.max(d);
                n += 1;
            }
        }
    }
    (sum / n as f64, max)
}

fn bake(d: &Path, scene: &str) -> serde_json::Value {
    common::write(d, "scene.json", scene);
    common::bake_report(d)
}

#[test]
fn the_reports_cell_shear_is_the_obj_frames_cell_by_cell() {
    let dir = common::temp_dir();
    let d = dir.path();
    let report = bake(d, &sheet(12, 8, "[[0, 0], [-1, 0]]", ""));
    let last = &report["last_frame"];
    let (mean, max) = obj_shear(&d.join("out/obj/sheet_0030.obj"), 12, 8);
    let (r_mean, r_max) = (
        last["mean_shear_deg"].as_f64().unwrap(),
        last["max_shear_deg"].as_f64().unwrap(),
    );
    // OBJ keeps positions to f32 printing: a few thousandths of a degree.
    assert!(
        (r_mean - mean).abs() < 1e-3,
        "report {r_mean}°, OBJ {mean}°"
    );
    assert!((r_max - max).abs() < 1e-3, "report {r_max}°, OBJ {max}°");
    assert!(
        mean > 2.0,
        "a sheet hanging from two corners shears ({mean}°): the case tests nothing"
    );
}

#[test]
fn shear_springs_hold_a_hanging_sheets_cells_squarer() {
    let dir = common::temp_dir();
    let without = bake(dir.path(), &sheet(12, 8, "[[0, 0], [-1, 0]]", ""));
    let with = bake(
        dir.path(),
        &sheet(
            12,
            8,
            "[[0, 0], [-1, 0]]",
            r#", "stiffness": { "stretch": 10000, "shear": 10000 }"#,
        ),
    );
    let shear = |r: &serde_json::Value| r["last_frame"]["mean_shear_deg"].as_f64().unwrap();
    eprintln!(
        "mean cell shear {:.2}° without, {:.2}° with shear springs",
        shear(&without),
        shear(&with)
    );
    assert!(
        shear(&with) < 0.5 * shear(&without),
        "{} with against {} without",
        shear(&with),
        shear(&without)
    );
}

#[test]
fn a_shear_target_is_met_with_shear_springs_and_refused_without() {
    let dir = common::temp_dir();
    let d = dir.path();
    let top: Vec<String> = (0..12).map(|i| format!("[{i}, 0]")).collect();
    let pins = format!("[{}]", top.join(", "));
    let springs = r#", "stiffness": { "stretch": 10000, "shear": 10000 }"#;
    let scene = sheet(12, 8, &pins, springs).replace(
        r#""output""#,
        r#""accuracy": { "max_shear": 2.0 }, "output""#,
    );
    let report = bake(d, &scene);
    let budget = &report["budget"];
    assert_eq!(budget["met"], true, "{budget}");
    assert_eq!(budget["max_shear"], 2.0);
    let reached = budget["max_shear_reached"].as_f64().unwrap();
    assert!(reached > 0.0 && reached <= 2.0, "{reached}°");
    let refused = sheet(12, 8, &pins, "").replace(
        r#""output""#,
        r#""accuracy": { "max_shear": 2.0 }, "output""#,
    );
    common::write(d, "scene.json", &refused);
    let out = common::drape(d, &["bake", "scene.json", "--out", "refused"]);
    assert_eq!(out.status.code(), Some(2));
    let err = common::stderr(&out);
    assert!(
        err.contains("accuracy.max_shear") && err.contains("shear springs"),
        "{err}"
    );
    assert!(!d.join("refused").exists());
}
