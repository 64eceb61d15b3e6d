//! The mesh penetration metric (`collide::mesh`) on hostile character geometry, each case
//! against an independent answer written here (analytic insides of boxes and prisms, or ray
//! parity): a concave L prism, smooth and flat-shaded, probed on a grid and just either side
//! of its reflex edge; a 1 cm plate; two cubes meeting along one edge (non-manifold); a box
//! with its top missing (open: decided by pseudonormals within `REACH` of the surface); and the
//! L prism moved far and turned between frames, measured with the first frame's topology as a
//! bake measures a fast character.

mod common;

use common::{cuboid, flat_shaded, parity_inside, prism};
use drape::collide::mesh::{Surface, Topology, REACH};
use glam::{Quat, Vec3};

/// The L: a 2 × 2 square without its upper right quarter; a fan from its outer corner.
fn l_prism() -> (Vec<Vec3>, Vec<[u32; 3]>) {
    prism(
        &[
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 1.0],
            [1.0, 1.0],
            [1.0, 2.0],
            [0.0, 2.0],
        ],
        &[[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]],
        0.5,
    )
}

fn in_l(p: Vec3) -> bool {
    (0.0..0.5).contains(&p.z)
        && ((0.0..2.0).contains(&p.x) && (0.0..1.0).contains(&p.y)
            || (0.0..1.0).contains(&p.x) && (0.0..2.0).contains(&p.y))
}

/// A grid of probes over `lo`..`hi`, `step` apart, off every face and edge of the cases.
fn probes(lo: Vec3, hi: Vec3, step: f32) -> Vec<Vec3> {
    let off = Vec3::new(0.0131, 0.0173, 0.0119);
    let n = ((hi - lo) / step).ceil().as_uvec3();
    let mut out = Vec::new();
    for i in 0..n.x {
        for j in 0..n.y {
            for k in 0..n.z {
                out.push(lo + off + Vec3::new(i as f32, j as f32, k as f32) * step);
            }
        }
    }
    out
}

#[test]
fn a_concave_prism_is_measured_alike_smooth_or_flat_shaded_and_as_parity_says() {
    let (v, t) = l_prism();
    let (fv, ft) = flat_shaded(&v, &t);
    let mut points = probes(Vec3::splat(-0.2), Vec3::new(2.2, 2.2, 0.7), 0.05);
    // Just either side of the reflex edge at x = y = 1, and of the outer faces near it.
    for z in [0.1f32, 0.25, 0.4] {
        for e in [1e-3f32, 5e-3, 2e-2] {
            points.push(Vec3::new(1.0 + e, 1.0 + e, z)); // outside, in the notch
            points.push(Vec3::new(1.0 - e, 1.0 - e, z)); // inside, at the corner
            points.push(Vec3::new(1.0 + e, 1.0 - e, z)); // inside, under the notch
            points.push(Vec3::new(1.0 - e, 1.0 + e, z)); // inside, beside it
        }
    }
    let expected = points.iter().filter(|&&p| in_l(p)).count();
    assert!(expected > 1000);
    let parity = points.iter().filter(|&&p| parity_inside(&v, &t, p)).count();
    assert_eq!(
        parity, expected,
        "the reference disagrees with the L's inside"
    );
    let smooth = Surface::new(&v, &t);
    let flat = Surface::new(&fv, &ft);
    assert!(smooth.closed() && flat.closed());
    assert_eq!(
        flat.welded_vertices(),
        12,
        "flat shading welds back to the prism's corners"
    );
    assert_eq!(smooth.penetration(&points).inside, expected);
    assert_eq!(flat.penetration(&points).inside, expected);
    // Point by point at the reflex edge.
    for &p in &points[points.len() - 36..] {
        assert_eq!(flat.penetration(&[p]).inside == 1, in_l(p), "{p}");
    }
}

#[test]
fn a_one_centimetre_plate_holds_what_is_inside_it_and_nothing_beside_it() {
    let (v, t) = cuboid(Vec3::ZERO, Vec3::new(1.0, 1.0, 0.01));
    let surface = Surface::new(&v, &t);
    let grid = |z: f32| -> Vec<Vec3> {
        probes(Vec3::new(-0.1, -0.1, 0.0), Vec3::new(1.1, 1.1, 0.001), 0.05)
            .into_iter()
            .map(|p| Vec3::new(p.x, p.y, z))
            .collect()
    };
    let mid = grid(0.005);
    let expected = mid
        .iter()
        .filter(|p| (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y))
        .count();
    let found = surface.penetration(&mid);
    assert_eq!(found.inside, expected);
    assert!(
        (found.deepest - 0.005).abs() < 1e-4,
        "{} m deep",
        found.deepest
    );
    for z in [0.011f32, 0.02, -0.001, -0.01] {
        assert_eq!(
            surface.penetration(&grid(z)).inside,
            0,
            "beside the plate at z = {z}"
        );
    }
}

#[test]
fn two_cubes_meeting_along_an_edge_count_what_is_in_either() {
    // Non-manifold: the shared edge belongs to four triangles (still an even number: closed).
    let (mut v, mut t) = cuboid(Vec3::ZERO, Vec3::ONE);
    let (v2, t2) = cuboid(Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 2.0, 1.0));
    let base = v.len() as u32;
    v.extend(v2);
    t.extend(t2.iter().map(|tri| tri.map(|i| i + base)));
    let surface = Surface::new(&v, &t);
    assert!(surface.closed());
    let points = probes(Vec3::splat(-0.2), Vec3::new(2.2, 2.2, 1.2), 0.07);
    let inside = |p: &Vec3, lo: Vec3| (0..3).all(|k| (lo[k]..lo[k] + 1.0).contains(&p[k]));
    let expected = points
        .iter()
        .filter(|p| inside(p, Vec3::ZERO) || inside(p, Vec3::new(1.0, 1.0, 0.0)))
        .count();
    assert!(expected > 1000);
    assert_eq!(surface.penetration(&points).inside, expected);
    let parity = points.iter().filter(|&&p| parity_inside(&v, &t, p)).count();
    assert_eq!(parity, expected);
}

#[test]
fn an_open_box_counts_what_is_within_reach_of_its_walls() {
    // No top: a ray can leave through the hole, so points within REACH of the surface are
    // judged by its pseudonormals and points farther in count outside (the shell's business).
    let (v, t) = cuboid(Vec3::ZERO, Vec3::ONE);
    let (v, t): (Vec<Vec3>, Vec<[u32; 3]>) = (
        v.clone(),
        t.into_iter()
            .filter(|tri| !tri.iter().all(|&i| v[i as usize].z == 1.0))
            .collect(),
    );
    assert_eq!(t.len(), 10);
    let surface = Surface::new(&v, &t);
    assert!(!surface.closed());
    // Above the open top, next to a wall's rim, is ambiguous (the rim's face says inside):
    // probes stay out of that slab.
    let points: Vec<Vec3> = probes(Vec3::splat(-0.2), Vec3::splat(1.2), 0.031)
        .into_iter()
        .filter(|p| !(p.z > 1.0 && (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y)))
        .collect();
    let expected = points
        .iter()
        .filter(|p| {
            (0..3).all(|k| (0.0..1.0).contains(&p[k]))
                && [p.x, 1.0 - p.x, p.y, 1.0 - p.y, p.z]
                    .iter()
                    .any(|&d| d < REACH)
        })
        .count();
    let in_box = points
        .iter()
        .filter(|p| (0..3).all(|k| (0.0..1.0).contains(&p[k])))
        .count();
    assert!(
        expected > 500 && in_box - expected > 1000,
        "{expected} of {in_box}"
    );
    assert_eq!(surface.penetration(&points).inside, expected);
}

#[test]
fn a_character_moved_far_between_frames_is_measured_with_its_first_frames_topology() {
    // A bake welds a character's mesh once, on its first frame; a fast limb is far elsewhere
    // by a later frame. The same probes carried along give the same count.
    let (v, t) = flat_shaded(&l_prism().0, &l_prism().1);
    let topology = Topology::new(&v, &t);
    let turn = Quat::from_rotation_z(1.3) * Quat::from_rotation_x(0.4);
    let shift = Vec3::new(3.0, -1.0, 2.0);
    let moved: Vec<Vec3> = v.iter().map(|&p| turn * p + shift).collect();
    let points = probes(Vec3::splat(-0.2), Vec3::new(2.2, 2.2, 0.7), 0.06);
    let carried: Vec<Vec3> = points.iter().map(|&p| turn * p + shift).collect();
    let expected = points.iter().filter(|&&p| in_l(p)).count();
    let posed = Surface::posed(&topology, &moved);
    assert_eq!(posed.penetration(&carried).inside, expected);
}
