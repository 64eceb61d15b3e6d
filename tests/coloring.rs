//! Contract: for every spring stencil, the derived colouring never gives two particles joined by
//! a spring the same colour (what parallel Gauss-Seidel relies on), and the validator catches a
//! colouring that does.

mod common;

use drape::garment::Garment;
use drape::sim::Model;

fn model(kind: &str, resolution: &str, shear: f32, bend: f32) -> (Garment, Model) {
    let scene = common::scene(&format!(
        r#"{{ "garments": [{{ "kind": "{kind}", "resolution": {resolution}, "size": {size},
             "stiffness": {{ "stretch": 100, "shear": {shear}, "bend": {bend} }} }}] }}"#,
        size = if kind == "rope" { "[1]" } else { "[1, 1]" }
    ));
    let g = Garment::build("g".into(), &scene.garments[0]);
    let m = Model::new(std::slice::from_ref(&g));
    (g, m)
}

#[test]
fn every_stencil_colouring_separates_its_springs() {
    let cases = [
        ("sheet", "[17, 13]", 0.0, 0.0, 2),
        ("sheet", "[17, 13]", 50.0, 0.0, 4),
        ("sheet", "[17, 13]", 0.0, 5.0, 3),
        ("sheet", "[17, 13]", 50.0, 5.0, 5),
        ("rope", "[40]", 0.0, 0.0, 2),
        ("rope", "[40]", 0.0, 5.0, 3),
    ];
    for (kind, res, shear, bend, colours) in cases {
        let (g, m) = model(kind, res, shear, bend);
        assert_eq!(
            g.colour_count(),
            colours,
            "{kind} {res} shear {shear} bend {bend}"
        );
        m.check_colouring().unwrap_or_else(|s| {
            panic!("{kind} {res} shear {shear} bend {bend}: spring {s:?} joins one colour")
        });
        // Every spring, checked directly on the garment's lattice colours too.
        for s in &g.springs {
            assert_ne!(g.colour_of(s.a), g.colour_of(s.b), "{kind}: spring {s:?}");
        }
        // Colour classes partition the particles.
        assert_eq!(
            m.colour_ranges.iter().map(|r| r.len()).sum::<usize>(),
            g.particle_count()
        );
    }
}

#[test]
fn axis_stencil_is_x_plus_y_mod_2() {
    let (g, _) = model("sheet", "[6, 5]", 0.0, 0.0);
    for k in 0..g.particle_count() as u32 {
        let (x, y) = (k % 6, k / 6);
        assert_eq!(g.colour_of(k), (x + y) % 2);
    }
}

#[test]
fn validator_rejects_a_colouring_that_joins_a_colour() {
    let (_, mut m) = model("sheet", "[8, 8]", 50.0, 0.0);
    // Merge the four colours into two: diagonal neighbours now share a colour.
    let n = m.particle_count();
    let half = m.colour_ranges[1].end;
    m.colour_ranges = vec![0..half, half..n];
    assert!(m.check_colouring().is_err());
}

#[test]
fn a_sheet_with_a_hole_loses_only_the_hole() {
    let scene = common::scene(
        r#"{ "garments": [{ "resolution": [21, 21], "size": [1, 1], "hole_radius": 0.2,
             "stiffness": { "stretch": 100, "shear": 10 } }] }"#,
    );
    let g = Garment::build("poncho".into(), &scene.garments[0]);
    let centre = glam::Vec3::new(0.0, 1.0, 0.0);
    // Every cell centred within 0.2 m of the middle is gone, every other one is there.
    let expected = (0..21 * 21)
        .filter(|k| {
            let (x, z) = ((k % 21) as f32 / 20.0 - 0.5, (k / 21) as f32 / 20.0 - 0.5);
            x.hypot(z) > 0.2
        })
        .count();
    assert_eq!(g.particle_count(), expected);
    assert!(g.positions.iter().all(|p| p.distance(centre) > 0.2 - 1e-6));
    let m = Model::new(std::slice::from_ref(&g));
    m.check_colouring()
        .expect("colouring still separates every spring");
    let n = g.particle_count() as u32;
    assert!(g.springs.iter().all(|s| s.a < n && s.b < n));
    assert!(g.triangles.iter().all(|t| t.iter().all(|&i| i < n)));
    // No spring or triangle spans the hole: none is longer than a diagonal of the grid.
    assert!(g
        .springs
        .iter()
        .all(|s| g.positions[s.a as usize].distance(g.positions[s.b as usize]) < 0.08));
    let err = drape::scene::Scene::parse(r#"{ "garments": [{ "kind": "rope", "resolution": [5], "size": [1], "hole_radius": 0.1 }] }"#, "x.json")
        .unwrap_err();
    assert!(err.to_string().contains("hole_radius"), "{err}");
}
