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
