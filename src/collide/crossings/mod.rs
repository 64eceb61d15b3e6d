//! Cloth passing through itself, counted: the pairs of garment triangles that share no vertex
//! and intersect (an edge of one passes through the other), within a garment and between
//! garments. `report.json` gives the count per frame beside strain (`crossings`), so a user
//! sees cloth passing through itself, which no strain or penetration figure shows.
//!
//! Triangles that share a vertex (or a vertex's place: a mesh split at its seams or flat-shaded
//! is welded first) touch by construction and are left out; two layers lying
//! flat on each other without passing through do not count, however close, nor does an edge
//! that reaches less than [`TOUCH`] (1 µm) beyond the other's plane or meets it within
//! [`RIM`] of its edges (a touch: in f32, the rows of a flat sheet are coplanar only up to
//! rounding, where an edge's crossing with a neighbour's plane is noise). The pairs are
//! found through a uniform grid over the triangles' bounding boxes (a cell two mean edges
//! long), each pair tested once, in the cell holding the low corner of the two boxes' overlap.

mod body;

use crate::mesh::Weld;
pub use body::{SelfCrossings, APART};
use glam::{DVec3, Vec3};
use rayon::prelude::*;

/// The number of pairs of `triangles` (over `positions`) that share no vertex and intersect.
/// Vertices at one place count as one ([`Weld`]): a surface split at its seams (texture seams,
/// flat shading) touches across them, which is no crossing.
pub fn count(positions: &[Vec3], triangles: &[[u32; 3]]) -> usize {
    pairs(positions, triangles).len()
}

/// A warning for each garment whose surface passes through itself before any simulation: the
/// bake counts those pairs as crossings from its first frame, and nothing in it undoes them.
/// Either the mesh does as modelled (a surface pushed out along a body's normals crosses
/// itself where they converge: a top pushed 2.5 cm off CesiumMan's armpits had 44 pairs), or
/// the lattice that carries it does (parts of it closer than the lattice spacing are carried
/// by the same particles, and the surface they interpolate may pass through itself there).
pub fn modelled_warnings(garments: &[crate::garment::Garment]) -> Vec<String> {
    let mut out = Vec::new();
    for g in garments {
        let modelled = (g.source.as_ref()).map(|m| (m, pairs(&m.vertices, &m.triangles)));
        let rest;
        let (vertices, triangles, found, how) = match modelled {
            Some((mesh, found)) if !found.is_empty() => (
                &mesh.vertices,
                &mesh.triangles,
                found,
                "as modelled (fix the mesh: a surface pushed out along a body's normals crosses itself where they converge)",
            ),
            _ => {
                rest = rest_surface(g);
                let how = match g.source {
                    Some(_) => "as its lattice carries it (the mesh itself does not: parts of it lie closer than the lattice spacing, and the particles that carry them make it pass through itself; a finer spacing keeps them apart)",
                    None => "as built",
                };
                (&rest, &g.triangles, pairs(&rest, &g.triangles), how)
            }
        };
        let Some(&(a, b)) = found.first() else {
            continue;
        };
        let centre = |t: u32| triangles[t as usize].map(|i| vertices[i as usize]);
        let [p, q] = [a, b].map(|t| centre(t).iter().sum::<Vec3>() / 3.0);
        let at = (p + q) * 0.5;
        out.push(format!(
            "garment {}: its surface passes through itself before any simulation, in {} pairs of triangles (one around ({:.3}, {:.3}, {:.3}) m), {how}; the bake counts them as crossings from the first frame, and no collision undoes them",
            g.name,
            found.len(),
            at.x,
            at.y,
            at.z
        ));
    }
    out
}

/// A garment's surface at rest where the bake starts it: its mesh as the lattice carries it,
/// or its particles' own triangles.
fn rest_surface(g: &crate::garment::Garment) -> Vec<Vec3> {
    match &g.embedding {
        Some(e) => e.apply(&g.positions),
        None => g.positions.clone(),
    }
}

/// A warning for each two garments whose surfaces pass through each other before any
/// simulation (a top and a skirt modelled apart, each on the body, whose hem and waistband
/// cross): the particle collisions keep each particle on the side of the other cloth it starts
/// on, so only the clean start can undo them, and it does only for garments modelled on one
/// character (it lays each over the ones before it in the scene's order,
/// `bake::dress::clean_start`).
pub fn between_warnings(garments: &[crate::garment::Garment]) -> Vec<String> {
    let surfaces: Vec<Vec<Vec3>> = garments.iter().map(rest_surface).collect();
    let bounds = |points: &[Vec3]| {
        (points.iter()).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        })
    };
    let mut out = Vec::new();
    for (a, first) in garments.iter().enumerate() {
        for (b, second) in garments.iter().enumerate().skip(a + 1) {
            let ((a_lo, a_hi), (b_lo, b_hi)) = (bounds(&surfaces[a]), bounds(&surfaces[b]));
            if a_lo.cmpgt(b_hi).any() || b_lo.cmpgt(a_hi).any() {
                continue;
            }
            let offset = surfaces[a].len() as u32;
            let positions: Vec<Vec3> = surfaces[a].iter().chain(&surfaces[b]).copied().collect();
            let triangles: Vec<[u32; 3]> = (first.triangles.iter().copied())
                .chain(second.triangles.iter().map(|t| t.map(|i| i + offset)))
                .collect();
            let split = first.triangles.len() as u32;
            let found: Vec<(u32, u32)> = pairs(&positions, &triangles)
                .into_iter()
                .filter(|&(i, j)| (i < split) != (j < split))
                .collect();
            let Some(&(i, j)) = found.first() else {
                continue;
            };
            let centre = |t: u32| {
                triangles[t as usize]
                    .map(|k| positions[k as usize])
                    .iter()
                    .sum::<Vec3>()
                    / 3.0
            };
            let at = (centre(i) + centre(j)) * 0.5;
            out.push(format!(
                "garments {} and {}: their surfaces pass through each other before any simulation, in {} pairs of triangles (one around ({:.3}, {:.3}, {:.3}) m); the particle collisions keep each particle on the side of the other cloth it starts on, so only the clean start undoes it: for garments modelled on one character (`on`) it moves the later one's particles out over the earlier one (the scene's order is the order they are put on), elsewhere nothing does; model the outer garment clear of the inner one (two particle radii apart) where they overlap, or list the inner one first",
                first.name,
                second.name,
                found.len(),
                at.x,
                at.y,
                at.z
            ));
        }
    }
    out
}

/// The pairs [`count`] counts, as indices into `triangles` (the lower first), sorted.
pub fn pairs(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<(u32, u32)> {
    if triangles.len() < 2 {
        return Vec::new();
    }
    let weld = Weld::of(positions);
    let welded: Vec<[u32; 3]> = (triangles.iter())
        .map(|t| t.map(|i| weld.slot[i as usize]))
        .collect();
    let corners = |t: &[u32; 3]| t.map(|i| positions[i as usize]);
    let boxes: Vec<(Vec3, Vec3)> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = corners(t);
            (a.min(b).min(c), a.max(b).max(c))
        })
        .collect();
    let edges: f32 = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = corners(t);
            a.distance(b) + b.distance(c) + c.distance(a)
        })
        .sum();
    let cell = (2.0 * edges / (3 * triangles.len()) as f32).max(1e-6);
    let grid = |p: Vec3| (p / cell).floor().as_ivec3();
    // 21 bits a coordinate (a garment spans far fewer cells), packed so one integer sorts.
    let pack = |c: glam::IVec3| {
        let bits = |v: i32| (v as u64) & 0x1f_ffff;
        (bits(c.x) << 42) | (bits(c.y) << 21) | bits(c.z)
    };
    // Each box's low cell: the low corner of two boxes' overlap is in the larger of theirs.
    let low: Vec<glam::IVec3> = boxes.iter().map(|(lo, _)| grid(*lo)).collect();
    // Every (cell, triangle) its box covers, sorted by cell: each run is one cell's list.
    let mut entries: Vec<(u64, u32)> = Vec::with_capacity(4 * triangles.len());
    for (i, (_, hi)) in boxes.iter().enumerate() {
        let (a, b) = (low[i], grid(*hi));
        for x in a.x..=b.x {
            for y in a.y..=b.y {
                for z in a.z..=b.z {
                    entries.push((pack(glam::IVec3::new(x, y, z)), i as u32));
                }
            }
        }
    }
    entries.par_sort_unstable();
    let runs: Vec<&[(u64, u32)]> = entries.chunk_by(|a, b| a.0 == b.0).collect();
    let mut found: Vec<(u32, u32)> = runs
        .par_iter()
        .flat_map_iter(|run| {
            let at = run[0].0;
            let mut crossings = Vec::new();
            for (k, &(_, i)) in run.iter().enumerate() {
                for &(_, j) in &run[k + 1..] {
                    let (i, j) = (i as usize, j as usize);
                    let (lo, hi) = (boxes[i].0.max(boxes[j].0), boxes[i].1.min(boxes[j].1));
                    // Boxes apart, or the pair belongs to another cell they share.
                    if lo.cmpgt(hi).any() || pack(low[i].max(low[j])) != at {
                        continue;
                    }
                    let (s, t) = (welded[i], welded[j]);
                    if s.iter().any(|v| t.contains(v)) {
                        continue;
                    }
                    if intersect(corners(&triangles[i]), corners(&triangles[j])) {
                        crossings.push((i.min(j) as u32, i.max(j) as u32));
                    }
                }
            }
            crossings
        })
        .collect();
    found.sort_unstable();
    found
}

/// How far both ends of an edge must lie from a triangle's plane, on either side [m], for the
/// edge to pass through it: nearer is a touch. A flat sheet's rows lie in one plane up to the
/// rounding of single-precision coordinates (6·10⁻⁸ m near 1 m), where an edge's crossing
/// point with a neighbour's plane is noise; 1 µm is well above that and far below any real
/// crossing of cloth.
pub const TOUCH: f64 = 1e-6;

/// How far inside the triangle the crossing point must be, in each barycentric coordinate: an
/// edge through another's edge or corner is a touch.
pub const RIM: f64 = 1e-6;

/// True when triangles `s` and `t` intersect: an edge of one passes through the other, its
/// ends more than [`TOUCH`] either side of the other's plane and its crossing point more than
/// [`RIM`] inside the other (in f64).
pub fn intersect(s: [Vec3; 3], t: [Vec3; 3]) -> bool {
    let (s, t) = (s.map(|p| p.as_dvec3()), t.map(|p| p.as_dvec3()));
    edges_through(s, t) || edges_through(t, s)
}

/// True when an edge of `s` passes through `t` (see [`intersect`]).
fn edges_through(s: [DVec3; 3], t: [DVec3; 3]) -> bool {
    let n = (t[1] - t[0]).cross(t[2] - t[0]).normalize_or_zero();
    if n == DVec3::ZERO {
        return false;
    }
    let d = s.map(|p| n.dot(p - t[0]));
    // Most pairs near each other have no corner beyond the other's plane on one side.
    if d.iter().all(|&d| d >= -TOUCH) || d.iter().all(|&d| d <= TOUCH) {
        return false;
    }
    (0..3).any(|k| {
        let (a, b) = (d[k], d[(k + 1) % 3]);
        let across = (a > TOUCH && b < -TOUCH) || (a < -TOUCH && b > TOUCH);
        across && inside(t, s[k] + (s[(k + 1) % 3] - s[k]) * (a / (a - b)))
    })
}

/// True when point `x` of triangle `t`'s plane lies more than [`RIM`] inside it in each
/// barycentric coordinate.
fn inside([a, b, c]: [DVec3; 3], x: DVec3) -> bool {
    let (e0, e1, e2) = (b - a, c - a, x - a);
    let (d00, d01, d11) = (e0.dot(e0), e0.dot(e1), e1.dot(e1));
    let (d20, d21) = (e2.dot(e0), e2.dot(e1));
    let denom = d00 * d11 - d01 * d01;
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    v > RIM && w > RIM && 1.0 - v - w > RIM
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An `n` × `n` grid of squares of side `1/n` from `origin` along `u` and `v`, each split
    /// along its rising diagonal.
    fn sheet(n: u32, origin: Vec3, u: Vec3, v: Vec3, first: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut p = Vec::new();
        for j in 0..=n {
            for i in 0..=n {
                p.push(origin + u * (i as f32 / n as f32) + v * (j as f32 / n as f32));
            }
        }
        let at = |i: u32, j: u32| first + j * (n + 1) + i;
        let mut t = Vec::new();
        for j in 0..n {
            for i in 0..n {
                t.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                t.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        (p, t)
    }

    #[test]
    fn a_flat_sheet_and_two_close_layers_do_not_cross() {
        let (p, t) = sheet(8, Vec3::ZERO, Vec3::X, Vec3::Z, 0);
        assert_eq!(count(&p, &t), 0);
        // A second layer 1 mm above: close, but not through.
        let (q, s) = sheet(8, Vec3::Y * 1e-3, Vec3::X, Vec3::Z, p.len() as u32);
        let (p, t) = ([p, q].concat(), [t, s].concat());
        assert_eq!(count(&p, &t), 0);
    }

    #[test]
    fn two_sheets_through_each_other_cross_where_their_pieces_of_the_line_overlap() {
        // Sheet A in the plane z = 0 (x, y in 0…1), sheet B in the plane y = 0.55 (x from 0.07,
        // z from −0.45): they cross along the line y = 0.55, z = 0. Each triangle meets that
        // line in an interval of x; two triangles intersect where their intervals overlap.
        let n = 5;
        let (pa, ta) = sheet(n, Vec3::ZERO, Vec3::X, Vec3::Y, 0);
        let first = pa.len() as u32;
        // B's columns are shifted from A's so no edge of one meets an edge of the other on the
        // line (a touch at a point, which the grid pieces of real cloth never line up for).
        let (pb, tb) = sheet(n, Vec3::new(0.07, 0.55, -0.45), Vec3::X, Vec3::Z, first);
        let positions = [pa, pb].concat();
        let triangles = [ta.clone(), tb.clone()].concat();
        // The interval of x a triangle covers on a line across it at `height` (its second
        // coordinate, y for A and z for B), by its edges' crossings of that height.
        let interval = |t: &[u32; 3], coordinate: fn(Vec3) -> f32, height: f32| {
            let c = t.map(|i| positions[i as usize]);
            let mut xs = Vec::new();
            for k in 0..3 {
                let (a, b) = (c[k], c[(k + 1) % 3]);
                let (ha, hb) = (coordinate(a) - height, coordinate(b) - height);
                if ha * hb < 0.0 {
                    xs.push(a.x + (b.x - a.x) * ha / (ha - hb));
                }
            }
            (xs.len() == 2).then(|| (xs[0].min(xs[1]), xs[0].max(xs[1])))
        };
        let a: Vec<(f32, f32)> = ta
            .iter()
            .filter_map(|t| interval(t, |p| p.y, 0.55))
            .collect();
        let b: Vec<(f32, f32)> = tb
            .iter()
            .filter_map(|t| interval(t, |p| p.z, 0.0))
            .collect();
        let expected = a
            .iter()
            .flat_map(|x| b.iter().map(move |y| (x, y)))
            .filter(|(x, y)| x.0.max(y.0) < x.1.min(y.1) - 1e-6)
            .count();
        // Two triangles of A's row and two of B's per column of cells meet the line.
        assert_eq!((a.len(), b.len()), (2 * n as usize, 2 * n as usize));
        assert!(expected >= 2 * n as usize, "{expected}");
        assert_eq!(count(&positions, &triangles), expected);
        // B moved half a metre along z no longer reaches A.
        let apart: Vec<Vec3> = (positions.iter().enumerate())
            .map(|(i, p)| {
                if i < first as usize {
                    *p
                } else {
                    *p + Vec3::Z * 0.5
                }
            })
            .collect();
        assert_eq!(count(&apart, &triangles), 0);
    }

    /// `triangles` over `positions` flat-shaded: every triangle with its own three vertices.
    fn unwelded(positions: &[Vec3], triangles: &[[u32; 3]]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p = triangles
            .iter()
            .flatten()
            .map(|&i| positions[i as usize])
            .collect();
        let t = (0..triangles.len() as u32)
            .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
            .collect();
        (p, t)
    }

    #[test]
    fn a_flat_shaded_copy_counts_as_the_indexed_mesh() {
        // Split at every edge, neighbours touch across the seams without sharing an index.
        let (p, t) = sheet(8, Vec3::ZERO, Vec3::X, Vec3::Z, 0);
        let (fp, ft) = unwelded(&p, &t);
        assert_eq!(count(&fp, &ft), 0);
        let (mut p, t) = sheet(6, Vec3::ZERO, Vec3::X, Vec3::Z, 0);
        for q in p.iter_mut().filter(|q| q.x > 0.5) {
            let x = q.x - 0.5;
            *q = Vec3::new(0.5 - 0.9 * x, -0.2 + 0.8 * x, q.z);
        }
        let (fp, ft) = unwelded(&p, &t);
        assert_eq!(count(&fp, &ft), count(&p, &t));
    }

    #[test]
    fn a_sheet_folded_through_itself_crosses_and_neighbours_never_count() {
        // A strip whose far half is turned up through its near half (an X seen from the side):
        // a garment passing through itself.
        let (mut p, t) = sheet(6, Vec3::ZERO, Vec3::X, Vec3::Z, 0);
        let flat = count(&p, &t);
        // The far half runs back under the near one and rises through it at x = 0.275.
        for q in p.iter_mut().filter(|q| q.x > 0.5) {
            let x = q.x - 0.5;
            *q = Vec3::new(0.5 - 0.9 * x, -0.2 + 0.8 * x, q.z);
        }
        assert_eq!(flat, 0);
        assert!(count(&p, &t) > 0);
    }
}
