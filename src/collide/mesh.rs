//! Cloth inside a character's own mesh, measured against its triangles rather than against the
//! shell of particles that collides with the cloth: the check that the shell kept every particle
//! out of the body the user sees.
//!
//! Each point's nearest triangle within [`REACH`] is found through a uniform grid of the
//! triangles' boxes; the point is inside when it lies behind the surface there, judged by the
//! vertex normals interpolated at the nearest point (smooth across edges and corners, where a face
//! normal would misjudge). A point farther than `REACH` from every triangle is counted outside:
//! cloth deeper than 5 cm in a body is a failure the shell metric reports anyway.

use super::Penetration;
use glam::{IVec3, Vec3};
use rayon::prelude::*;

/// How far from the surface a point is looked at [m].
pub const REACH: f32 = 0.05;

/// The point of triangle `abc` nearest `p`, as barycentric weights (Ericson, Real-Time Collision
/// Detection, 5.1.5). Attachments to a skin bind with it too.
pub fn closest_barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return Vec3::X;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return Vec3::Y;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return Vec3::new(1.0 - v, v, 0.0);
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return Vec3::Z;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return Vec3::new(1.0 - w, 0.0, w);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return Vec3::new(0.0, 1.0 - w, w);
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    Vec3::new(1.0 - v - w, v, w)
}

/// How many of `points` lie inside the mesh (`vertices`, `triangles`, unit vertex `normals`
/// pointing out) and the deepest of them [m].
pub fn penetration(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    normals: &[Vec3],
    points: &[Vec3],
) -> Penetration {
    let cell_of = |p: Vec3| (p / REACH).floor().as_ivec3();
    // Each triangle in every cell its box, grown by REACH, touches: a point's own cell then
    // holds every triangle within REACH of it. Only the points' cells are kept (a body's
    // triangles far from the cloth are never looked at).
    let mut grid: crate::character::shell::CellMap<Vec<u32>> =
        points.iter().map(|&p| (cell_of(p), Vec::new())).collect();
    let (near_lo, near_hi) = points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| {
        (lo.min(p), hi.max(p))
    });
    // Each triangle's box: a point farther from it than from the nearest triangle found so far
    // cannot be nearer that triangle (most candidates are passed over on the box alone).
    let boxes: Vec<(Vec3, Vec3)> = triangles
        .iter()
        .map(|tri| {
            let [a, b, c] = tri.map(|i| vertices[i as usize]);
            (a.min(b).min(c), a.max(b).max(c))
        })
        .collect();
    for (t, &(lo, hi)) in boxes.iter().enumerate() {
        let (lo, hi) = (lo - REACH, hi + REACH);
        if lo.cmpgt(near_hi).any() || hi.cmplt(near_lo).any() {
            continue;
        }
        let (lo, hi) = (cell_of(lo), cell_of(hi));
        for x in lo.x..=hi.x {
            for y in lo.y..=hi.y {
                for z in lo.z..=hi.z {
                    if let Some(list) = grid.get_mut(&IVec3::new(x, y, z)) {
                        list.push(t as u32);
                    }
                }
            }
        }
    }
    let depth = |p: Vec3| -> f32 {
        let Some(candidates) = grid.get(&cell_of(p)) else {
            return 0.0;
        };
        let mut best = (REACH * REACH, None);
        for &t in candidates {
            let (lo, hi) = boxes[t as usize];
            let outside = (lo - p).max(p - hi).max(Vec3::ZERO);
            if outside.length_squared() >= best.0 {
                continue;
            }
            let [i, j, k] = triangles[t as usize];
            let [a, b, c] = [i, j, k].map(|v| vertices[v as usize]);
            let w = closest_barycentric(p, a, b, c);
            let q = a * w.x + b * w.y + c * w.z;
            let d2 = p.distance_squared(q);
            if d2 < best.0 {
                best = (d2, Some((q, w, [i, j, k])));
            }
        }
        let Some((q, w, [i, j, k])) = best.1 else {
            return 0.0;
        };
        let n = normals[i as usize] * w.x + normals[j as usize] * w.y + normals[k as usize] * w.z;
        if (p - q).dot(n) < 0.0 {
            // At least a hair deep, so a point exactly on the surface behind it still counts.
            best.0.sqrt().max(f32::MIN_POSITIVE)
        } else {
            0.0
        }
    };
    // A count and a maximum: the same on any number of threads.
    points
        .par_iter()
        .with_min_len(1024)
        .map(|&p| Penetration::of_depth(depth(p)))
        .reduce(Penetration::default, Penetration::merge)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed unit cube centred at the origin, outward normals.
    fn cube() -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<Vec3>) {
        let v: Vec<Vec3> = (0..8)
            .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
            .map(|p| p - Vec3::splat(0.5))
            .collect();
        let faces = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let t: Vec<[u32; 3]> = faces
            .iter()
            .flat_map(|[a, b, c, d]| [[*a, *b, *c], [*a, *c, *d]])
            .collect();
        let n = crate::export::obj::vertex_normals(&t, &v);
        (v, t, n)
    }

    #[test]
    fn points_just_inside_a_cube_are_counted_with_their_depth() {
        let (v, t, n) = cube();
        // Inside by 1 cm and 3 cm under the top face, outside by 2 cm, and at the centre (0.5 m
        // deep: past REACH, so counted outside as documented).
        let points = [
            Vec3::new(0.1, 0.49, 0.0),
            Vec3::new(-0.2, 0.47, 0.1),
            Vec3::new(0.0, 0.52, 0.0),
            Vec3::ZERO,
        ];
        let p = penetration(&v, &t, &n, &points);
        assert_eq!(p.inside, 2);
        assert!((p.deepest - 0.03).abs() < 1e-5, "{}", p.deepest);
        // Near an edge and a corner, inside and out, the interpolated normal decides right.
        let edge_in = Vec3::new(0.49, 0.49, 0.0);
        let corner_out = Vec3::new(0.51, 0.51, 0.51);
        let q = penetration(&v, &t, &n, &[edge_in, corner_out]);
        assert_eq!(q.inside, 1);
    }

    #[test]
    fn the_nearest_point_is_on_the_triangle() {
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        for (p, expected) in [
            (Vec3::new(0.2, 0.2, 1.0), Vec3::new(0.2, 0.2, 0.0)),
            (Vec3::new(-1.0, -1.0, 0.0), a),
            (Vec3::new(2.0, -0.5, 0.0), b),
            (Vec3::new(1.0, 1.0, 0.0), Vec3::new(0.5, 0.5, 0.0)),
        ] {
            let w = closest_barycentric(p, a, b, c);
            let q = a * w.x + b * w.y + c * w.z;
            assert!(
                q.distance(expected) < 1e-6,
                "{p} → {q}, expected {expected}"
            );
        }
    }
}
