//! Cloth inside a character's own mesh, measured against its triangles rather than against the
//! shell of particles that collides with the cloth: the check that the shell kept every particle
//! out of the body the user sees.
//!
//! The mesh is first welded by position ([`Surface::new`]): exported meshes split vertices
//! wherever normals or UVs change, and a flat-shaded one has three vertices of its own per
//! triangle, so without welding neighbouring triangles do not know they share an edge (and the
//! mesh does not know it is closed).
//!
//! On a closed welded mesh (every edge shared by an even number of triangles) a point is inside
//! when the winding number along a ray from it (+X, through a grid of the triangles' Y–Z boxes)
//! is not zero: exact in concave places, whatever the shading, and right where a pose sinks one
//! part into another (a hand into a thigh: winding 2), where a nearest-surface test calls cloth
//! between the two parts inside. On an open mesh (a hole at the neck, a single-sided plane) a
//! ray can leave through the hole, so there a point within [`REACH`] of the surface is decided
//! at its nearest surface point by the angle-weighted pseudonormal (Bærentzen and Aanæs 2005:
//! the face normal in a face, the sum of the two faces' normals on an edge, the angle-weighted
//! sum on a vertex), and a point farther away counts outside.
//!
//! Depth is the distance to the nearest triangle: within `REACH` through a uniform grid of the
//! triangles' boxes, beyond it over all triangles (cloth deep in a body is rare, but must not
//! read as shallow).

use super::Penetration;
use glam::{IVec3, Vec2, Vec3};
use rayon::prelude::*;

/// How far from the surface a point is looked at through the grid [m].
pub const REACH: f32 = 0.05;

/// Vertices closer than this are one vertex of the welded surface [m].
pub const WELD: f32 = 1e-6;
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

/// How many of `points` lie inside the mesh (`vertices`, `triangles`, wound counter-clockwise
/// seen from outside) and the deepest of them [m].
pub fn penetration(vertices: &[Vec3], triangles: &[[u32; 3]], points: &[Vec3]) -> Penetration {
    Surface::new(vertices, triangles).penetration(points)
}

/// Feature of a triangle that a nearest point lies on.
enum Feature {
    Face,
    Edge(u32, u32),
    Vertex(u32),
}

/// What of a character's mesh stays the same from frame to frame: which vertices weld
/// together, the welded triangles, their edges, and whether the mesh is closed.
#[derive(Clone, Debug)]
pub struct Topology {
    /// Per welded vertex, the input vertex that stands for it.
    kept: Vec<u32>,
    /// Welded triangles, degenerate ones (two corners welded together) left out.
    triangles: Vec<[u32; 3]>,
    /// Every edge (lower index first) with its triangle, sorted: runs of one edge.
    edges: Vec<((u32, u32), u32)>,
    /// Every edge is shared by an even number of triangles.
    closed: bool,
}

impl Topology {
    /// Welds the vertices of `frame` closer than [`WELD`] (vertices that ride the same skin
    /// stay together in the other frames) and finds the welded mesh's edges.
    pub fn new(frame: &[Vec3], triangles: &[[u32; 3]]) -> Topology {
        let (kept, map) = weld(frame);
        let triangles: Vec<[u32; 3]> = triangles
            .iter()
            .map(|t| t.map(|i| map[i as usize]))
            .filter(|[a, b, c]| a != b && b != c && a != c)
            .collect();
        let mut edges: Vec<((u32, u32), u32)> = triangles
            .iter()
            .enumerate()
            .flat_map(|(n, t)| {
                (0..3).map(move |k| {
                    let (i, j) = (t[k], t[(k + 1) % 3]);
                    ((i.min(j), i.max(j)), n as u32)
                })
            })
            .collect();
        edges.sort_unstable();
        let closed = !edges.is_empty()
            && edges
                .chunk_by(|a, b| a.0 == b.0)
                .all(|run| run.len() % 2 == 0);
        Topology {
            kept,
            triangles,
            edges,
            closed,
        }
    }
}

/// A character's mesh welded by position in one frame, ready to say which points are inside.
pub struct Surface<'t> {
    topology: std::borrow::Cow<'t, Topology>,
    /// The welded vertices.
    vertices: Vec<Vec3>,
    /// The pseudonormals of an open mesh; None for a closed one (every edge shared by an even
    /// number of triangles), which the winding number decides.
    open: Option<Pseudonormals>,
}

/// The nearest point of a surface to a point ([`Surface::nearest_signed`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Nearest {
    /// Distance to the surface [m], below zero inside.
    pub distance: f32,
    /// The nearest point of the surface.
    pub point: Vec3,
    /// Unit normal there, pointing out of the body.
    pub normal: Vec3,
}

/// Angle-weighted pseudonormals (Bærentzen and Aanæs 2005), for open meshes.
struct Pseudonormals {
    /// Unit normal of each triangle.
    faces: Vec<Vec3>,
    /// Angle-weighted sum of the unit normals of each vertex's triangles.
    corners: Vec<Vec3>,
    /// Each edge (lower index first), sorted, with the sum of its triangles' unit normals.
    edges: Vec<((u32, u32), Vec3)>,
}

impl Surface<'static> {
    /// Welds `vertices` closer than [`WELD`]; on an open mesh, computes the pseudonormals.
    pub fn new(vertices: &[Vec3], triangles: &[[u32; 3]]) -> Surface<'static> {
        let topology = Topology::new(vertices, triangles);
        Surface::build(std::borrow::Cow::Owned(topology), vertices)
    }
}

impl<'t> Surface<'t> {
    /// The mesh of `topology` with the vertices of one frame (the frame's own vertices, in the
    /// order `topology` was made from).
    pub fn posed(topology: &'t Topology, vertices: &[Vec3]) -> Surface<'t> {
        Surface::build(std::borrow::Cow::Borrowed(topology), vertices)
    }

    fn build(topology: std::borrow::Cow<'t, Topology>, vertices: &[Vec3]) -> Surface<'t> {
        let welded: Vec<Vec3> = topology
            .kept
            .iter()
            .map(|&v| vertices[v as usize])
            .collect();
        let open = (!topology.closed).then(|| Pseudonormals::new(&welded, &topology));
        Surface {
            topology,
            vertices: welded,
            open,
        }
    }

    /// Every edge is shared by an even number of triangles.
    pub fn closed(&self) -> bool {
        self.topology.closed
    }

    /// The welded vertex count.
    pub fn welded_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// How many of `points` lie inside and the deepest of them [m].
    pub fn penetration(&self, points: &[Vec3]) -> Penetration {
        self.penetrations(&[points])[0]
    }

    /// [`Self::penetration`] of each of `sets` (a closed surface's rays are bucketed once for
    /// them all).
    pub fn penetrations(&self, sets: &[&[Vec3]]) -> Vec<Penetration> {
        let columns = self.open.is_none().then(|| Columns::new(self));
        (sets.iter())
            .map(|points| match &columns {
                _ if points.is_empty() => Penetration::default(),
                Some(columns) => self.closed_penetration(columns, points),
                None => self.open_penetration(points),
            })
            .collect()
    }

    /// [`Self::penetration`] of a closed surface: the winding number picks the points inside
    /// (few, usually none), and only those are measured.
    fn closed_penetration(&self, columns: &Columns, points: &[Vec3]) -> Penetration {
        let inside: Vec<Vec3> = points
            .par_iter()
            .with_min_len(1024)
            .filter(|&&p| columns.inside(self, p))
            .copied()
            .collect();
        let near = NearGrid::new(self, &inside);
        inside
            .par_iter()
            .map(|&p| {
                let depth = match near.nearest(self, p) {
                    Some((d2, ..)) => d2.sqrt(),
                    None => self.distance(p),
                };
                // At least a hair deep, so a point on the surface counts.
                Penetration::of_depth(depth.max(f32::MIN_POSITIVE))
            })
            .reduce(Penetration::default, Penetration::merge)
    }

    /// [`Self::penetration`] of an open surface: the nearest point's pseudonormal says which
    /// side a point is on.
    fn open_penetration(&self, points: &[Vec3]) -> Penetration {
        let normals = self.open.as_ref().expect("an open surface");
        let near = NearGrid::new(self, points);
        // A count and a maximum: the same on any number of threads.
        points
            .par_iter()
            .with_min_len(1024)
            .map(|&p| match near.nearest(self, p) {
                Some((d2, q, t, w))
                    if (p - q).dot(normals.at(&self.topology.triangles, t, w)) < 0.0 =>
                {
                    Penetration::of_depth(d2.sqrt().max(f32::MIN_POSITIVE))
                }
                _ => Penetration::default(),
            })
            .reduce(Penetration::default, Penetration::merge)
    }

    /// For each of `points`, the nearest point of the surface with the signed distance to it
    /// (below zero inside: by the winding number on a closed mesh, by the pseudonormals on an
    /// open one) and the unit normal there, pointing out. Exact at any distance (triangles
    /// beyond [`REACH`] are searched one by one), so for setting up a bake or inspecting one,
    /// not for every frame.
    pub fn nearest_signed(&self, points: &[Vec3]) -> Vec<Nearest> {
        let columns = self.open.is_none().then(|| Columns::new(self));
        let near = NearGrid::new(self, points);
        points
            .par_iter()
            .with_min_len(256)
            .map(|&p| {
                let (d2, q, t, w) = near
                    .nearest(self, p)
                    .unwrap_or_else(|| self.nearest_of_all(p));
                let [a, b, c] = self.triangles()[t].map(|i| self.vertices[i as usize]);
                let face = (b - a).cross(c - a).normalize_or(Vec3::Y);
                let inside = match (&columns, &self.open) {
                    (Some(columns), _) => columns.inside(self, p),
                    (None, Some(normals)) => {
                        (p - q).dot(normals.at(&self.topology.triangles, t, w)) < 0.0
                    }
                    (None, None) => false,
                };
                let distance = d2.sqrt();
                // Out of the surface: from the point through the surface when it is clear of
                // it, else the face's normal turned to agree with inside or outside.
                let towards = if inside { q - p } else { p - q };
                let normal = if distance > 1e-6 {
                    towards / distance
                } else if face.dot(towards) < 0.0 {
                    -face
                } else {
                    face
                };
                Nearest {
                    distance: if inside { -distance } else { distance },
                    point: q,
                    normal,
                }
            })
            .collect()
    }

    /// The nearest point of every triangle to `p`: squared distance, point, triangle, weights.
    fn nearest_of_all(&self, p: Vec3) -> (f32, Vec3, usize, Vec3) {
        let mut best = (f32::INFINITY, p, 0, Vec3::X);
        for (t, tri) in self.triangles().iter().enumerate() {
            let [a, b, c] = tri.map(|i| self.vertices[i as usize]);
            let w = closest_barycentric(p, a, b, c);
            let q = a * w.x + b * w.y + c * w.z;
            let d2 = p.distance_squared(q);
            if d2 < best.0 {
                best = (d2, q, t, w);
            }
        }
        best
    }

    /// The welded triangles.
    fn triangles(&self) -> &[[u32; 3]] {
        &self.topology.triangles
    }

    /// Distance from `p` to the nearest triangle, over all of them.
    fn distance(&self, p: Vec3) -> f32 {
        self.triangles()
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                let w = closest_barycentric(p, a, b, c);
                p.distance_squared(a * w.x + b * w.y + c * w.z)
            })
            .fold(f32::INFINITY, f32::min)
            .sqrt()
    }
}

impl Pseudonormals {
    /// From the welded vertices of a frame and the mesh's topology.
    fn new(vertices: &[Vec3], topology: &Topology) -> Pseudonormals {
        let (triangles, edges) = (&topology.triangles, &topology.edges);
        let faces: Vec<Vec3> = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| vertices[i as usize]);
                (b - a).cross(c - a).normalize_or_zero()
            })
            .collect();
        let mut corners = vec![Vec3::ZERO; vertices.len()];
        for (t, n) in triangles.iter().zip(&faces) {
            for k in 0..3 {
                let (i, j, l) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                let [p, q, r] = [i, j, l].map(|v| vertices[v as usize]);
                corners[i as usize] += (q - p).angle_between(r - p) * *n;
            }
        }
        let edges = edges
            .chunk_by(|a, b| a.0 == b.0)
            .map(|run| (run[0].0, run.iter().map(|e| faces[e.1 as usize]).sum()))
            .collect();
        Pseudonormals {
            faces,
            corners,
            edges,
        }
    }

    /// The pseudonormal at barycentric weights `w` of triangle `t` (unnormalised; its sign
    /// against p − q is what counts).
    fn at(&self, triangles: &[[u32; 3]], t: usize, w: Vec3) -> Vec3 {
        let [a, b, c] = triangles[t];
        let feature = match (w.x == 0.0, w.y == 0.0, w.z == 0.0) {
            (false, true, true) => Feature::Vertex(a),
            (true, false, true) => Feature::Vertex(b),
            (true, true, false) => Feature::Vertex(c),
            (false, false, true) => Feature::Edge(a, b),
            (true, false, false) => Feature::Edge(b, c),
            (false, true, false) => Feature::Edge(c, a),
            _ => Feature::Face,
        };
        match feature {
            Feature::Face => self.faces[t],
            Feature::Edge(i, j) => {
                let key = (i.min(j), i.max(j));
                let at = self.edges.binary_search_by_key(&key, |e| e.0);
                at.map_or(self.faces[t], |k| self.edges[k].1)
            }
            Feature::Vertex(i) => self.corners[i as usize],
        }
    }
}

/// Welds positions closer than [`WELD`]: the vertex that stands for each welded one, and each
/// vertex's welded index. Vertices are swept in order of X; each one not yet welded stands for
/// those after it within `WELD`.
fn weld(vertices: &[Vec3]) -> (Vec<u32>, Vec<u32>) {
    let mut order: Vec<u32> = (0..vertices.len() as u32).collect();
    order.sort_unstable_by(|&a, &b| {
        vertices[a as usize]
            .x
            .total_cmp(&vertices[b as usize].x)
            .then(a.cmp(&b))
    });
    let mut map = vec![u32::MAX; vertices.len()];
    let mut welded = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        if map[i as usize] != u32::MAX {
            continue;
        }
        let v = vertices[i as usize];
        let at = welded.len() as u32;
        welded.push(i);
        map[i as usize] = at;
        for &j in order[k + 1..]
            .iter()
            .take_while(|&&j| vertices[j as usize].x - v.x <= WELD)
        {
            if map[j as usize] == u32::MAX
                && vertices[j as usize].distance_squared(v) <= WELD * WELD
            {
                map[j as usize] = at;
            }
        }
    }
    (welded, map)
}

/// The triangles within [`REACH`] of each point's grid cell, for the points asked about.
struct NearGrid {
    grid: crate::character::shell::CellMap<Vec<u32>>,
    boxes: Vec<(Vec3, Vec3)>,
}

impl NearGrid {
    fn cell_of(p: Vec3) -> IVec3 {
        (p / REACH).floor().as_ivec3()
    }

    /// Each triangle in every cell its box, grown by REACH, touches: a point's own cell then
    /// holds every triangle within REACH of it. Only the points' cells are kept (a body's
    /// triangles far from the cloth are never looked at).
    fn new(surface: &Surface, points: &[Vec3]) -> NearGrid {
        let mut grid: crate::character::shell::CellMap<Vec<u32>> = points
            .iter()
            .map(|&p| (Self::cell_of(p), Vec::new()))
            .collect();
        let (near_lo, near_hi) = points.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
        // Each triangle's box: a point farther from it than from the nearest triangle found so
        // far cannot be nearer that triangle (most candidates are passed over on the box alone).
        let boxes: Vec<(Vec3, Vec3)> = surface
            .triangles()
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|i| surface.vertices[i as usize]);
                (a.min(b).min(c), a.max(b).max(c))
            })
            .collect();
        for (t, &(lo, hi)) in boxes.iter().enumerate() {
            let (lo, hi) = (lo - REACH, hi + REACH);
            if lo.cmpgt(near_hi).any() || hi.cmplt(near_lo).any() {
                continue;
            }
            let (lo, hi) = (Self::cell_of(lo), Self::cell_of(hi));
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
        NearGrid { grid, boxes }
    }

    /// The nearest point of the surface within REACH of `p`: its squared distance, the point,
    /// the triangle and the barycentric weights there.
    fn nearest(&self, surface: &Surface, p: Vec3) -> Option<(f32, Vec3, usize, Vec3)> {
        let candidates = self.grid.get(&Self::cell_of(p))?;
        let mut best = (REACH * REACH, None);
        for &t in candidates {
            let (lo, hi) = self.boxes[t as usize];
            let outside = (lo - p).max(p - hi).max(Vec3::ZERO);
            if outside.length_squared() >= best.0 {
                continue;
            }
            let [a, b, c] = surface.triangles()[t as usize].map(|v| surface.vertices[v as usize]);
            let w = closest_barycentric(p, a, b, c);
            let q = a * w.x + b * w.y + c * w.z;
            let d2 = p.distance_squared(q);
            if d2 < best.0 {
                best = (d2, Some((q, t as usize, w)));
            }
        }
        best.1.map(|(q, t, w)| (best.0, q, t, w))
    }
}

/// The triangles of a closed surface bucketed by their boxes in the Y–Z plane, for rays cast
/// along +X.
struct Columns {
    cell: f32,
    lo: Vec2,
    /// The surface's largest X: a ray from beyond it crosses nothing.
    x_max: f32,
    size: [usize; 2],
    /// Each column's triangles, in compressed rows: `triangles[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    triangles: Vec<u32>,
}

/// Columns per side at most (a 64 × 64 grid over the body's Y–Z extent).
const COLUMNS: usize = 64;

impl Columns {
    fn new(surface: &Surface) -> Columns {
        let yz = |v: Vec3| Vec2::new(v.y, v.z);
        let (lo, hi) = surface
            .vertices
            .iter()
            .fold((Vec2::MAX, Vec2::MIN), |(lo, hi), &v| {
                (lo.min(yz(v)), hi.max(yz(v)))
            });
        let cell = ((hi - lo).max_element() / COLUMNS as f32).max(1e-4);
        let size = [
            ((hi.x - lo.x) / cell) as usize + 1,
            ((hi.y - lo.y) / cell) as usize + 1,
        ];
        // Each triangle's columns, as (first, last) in each direction.
        let spans: Vec<[glam::UVec2; 2]> = (surface.triangles().iter())
            .map(|tri| {
                let [a, b, c] = tri.map(|i| yz(surface.vertices[i as usize]));
                let (tlo, thi) = (a.min(b).min(c), a.max(b).max(c));
                let last = glam::UVec2::new(size[0] as u32 - 1, size[1] as u32 - 1);
                [
                    ((tlo - lo) / cell).as_uvec2(),
                    ((thi - lo) / cell).as_uvec2().min(last),
                ]
            })
            .collect();
        // Calls `visit` with each (column, triangle) a triangle's span covers.
        fn each(spans: &[[glam::UVec2; 2]], rows: usize, mut visit: impl FnMut(usize, u32)) {
            for (t, [i0, i1]) in spans.iter().enumerate() {
                for i in i0.x..=i1.x {
                    for j in i0.y..=i1.y {
                        visit(i as usize * rows + j as usize, t as u32);
                    }
                }
            }
        }
        // A counting sort: the columns' sizes, their starts, then the triangles in place.
        let mut start = vec![0u32; size[0] * size[1] + 1];
        each(&spans, size[1], |c, _| start[c + 1] += 1);
        for c in 1..start.len() {
            start[c] += start[c - 1];
        }
        let mut next = start.clone();
        let mut triangles = vec![0u32; start[start.len() - 1] as usize];
        each(&spans, size[1], |c, t| {
            triangles[next[c] as usize] = t;
            next[c] += 1;
        });
        Columns {
            cell,
            lo,
            x_max: surface.vertices.iter().fold(f32::MIN, |m, v| m.max(v.x)),
            size,
            start,
            triangles,
        }
    }

    /// Whether `p` is inside, by the winding number along a +X ray (each crossing counts +1
    /// where the ray leaves the surface, −1 where it enters): 1 inside, 0 outside, 2 where a
    /// pose sinks one part into another (a hand into a thigh), which is inside too. A ray that
    /// grazes an edge or a vertex is cast again from a point a few micrometres aside.
    fn inside(&self, surface: &Surface, p: Vec3) -> bool {
        for nudge in [
            Vec2::ZERO,
            Vec2::new(3.1e-6, 1.7e-6),
            Vec2::new(-2.3e-6, 4.1e-6),
        ] {
            if let Some(winding) = self.winding(surface, p + Vec3::new(0.0, nudge.x, nudge.y)) {
                return winding != 0;
            }
        }
        false
    }

    /// The winding number along the ray, or None when it grazes an edge or a vertex.
    fn winding(&self, surface: &Surface, p: Vec3) -> Option<i32> {
        let at = (Vec2::new(p.y, p.z) - self.lo) / self.cell;
        if at.x < 0.0 || at.y < 0.0 || p.x > self.x_max {
            return Some(0);
        }
        let (i, j) = (at.x as usize, at.y as usize);
        if i >= self.size[0] || j >= self.size[1] {
            return Some(0);
        }
        let mut winding = 0;
        let c = i * self.size[1] + j;
        for &t in &self.triangles[self.start[c] as usize..self.start[c + 1] as usize] {
            let [a, b, c] = surface.triangles()[t as usize].map(|v| surface.vertices[v as usize]);
            winding += crossing(p, a, b, c)?;
        }
        Some(winding)
    }
}

/// How the ray from `p` along +X crosses triangle `abc`: +1 leaving the surface (the
/// triangle faces +X), −1 entering, 0 missing it; None when it passes within a rounding error
/// of an edge or a vertex, where the answer is not to be trusted.
fn crossing(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Option<i32> {
    // Edge functions in the Y–Z plane, in f64.
    let e = |u: Vec3, v: Vec3| {
        (v.y as f64 - u.y as f64) * (p.z as f64 - u.z as f64)
            - (v.z as f64 - u.z as f64) * (p.y as f64 - u.y as f64)
    };
    let (wa, wb, wc) = (e(b, c), e(c, a), e(a, b));
    let area = wa + wb + wc;
    if area.abs() < 1e-30 {
        return Some(0); // edge-on to the ray: crossed through its neighbours
    }
    let eps = 1e-9 * area.abs();
    if wa.abs() < eps || wb.abs() < eps || wc.abs() < eps {
        if (wa >= -eps && wb >= -eps && wc >= -eps) || (wa <= eps && wb <= eps && wc <= eps) {
            return None;
        }
        return Some(0);
    }
    let inside = (wa > 0.0 && wb > 0.0 && wc > 0.0) || (wa < 0.0 && wb < 0.0 && wc < 0.0);
    if !inside {
        return Some(0);
    }
    let x = (wa * a.x as f64 + wb * b.x as f64 + wc * c.x as f64) / area;
    // The projected area's sign is the sign of the normal's X.
    Some(match (x > p.x as f64, area > 0.0) {
        (false, _) => 0,
        (true, true) => 1,
        (true, false) => -1,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::mesh::cuboid;

    /// An L-shaped prism (concave: a reflex edge along Z at (0.1, 0.1)), smooth-shaded: one
    /// vertex per corner, shared by every triangle there. The L is the square 0..0.2 in X and
    /// Y less the quarter 0.1..0.2 × 0.1..0.2, 0.1 m deep in Z.
    fn l_prism() -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let outline = [
            [0.0, 0.0],
            [0.2, 0.0],
            [0.2, 0.1],
            [0.1, 0.1],
            [0.1, 0.2],
            [0.0, 0.2],
        ];
        let mut v: Vec<Vec3> = outline.iter().map(|p| Vec3::new(p[0], p[1], 0.0)).collect();
        v.extend(outline.iter().map(|p| Vec3::new(p[0], p[1], 0.1)));
        // Caps: the L as four triangles fanned from corner 3 (the reflex one), which sees
        // every other corner.
        let mut t = Vec::new();
        for k in [4u32, 5, 0, 1] {
            let next = (k + 1) % 6;
            t.push([3, next, k]); // bottom (z = 0), facing −Z
            t.push([9, k + 6, next + 6]); // top (z = 0.1), facing +Z
        }
        // Sides: the outline runs counter-clockwise seen from +Z, so (k, k+1, top) faces out.
        for k in 0..6u32 {
            let n = (k + 1) % 6;
            t.push([k, n, n + 6]);
            t.push([k, n + 6, k + 6]);
        }
        (v, t)
    }

    /// The same triangles with three vertices of their own each (flat-shaded as exported).
    fn flat(v: &[Vec3], t: &[[u32; 3]]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let vertices = t
            .iter()
            .flat_map(|tri| tri.map(|i| v[i as usize]))
            .collect();
        let triangles = (0..t.len() as u32)
            .map(|k| [3 * k, 3 * k + 1, 3 * k + 2])
            .collect();
        (vertices, triangles)
    }

    /// Independent reference: inside by the parity of a ray's crossings (Möller–Trumbore, in
    /// f64, along a direction no edge of the test meshes lies in), over every triangle.
    fn parity_inside(v: &[Vec3], t: &[[u32; 3]], p: Vec3) -> bool {
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
            if u < 0.0 || w < 0.0 || u + w > 1.0 {
                continue;
            }
            if e2.dot(q) / det > 0.0 {
                hits += 1;
            }
        }
        hits % 2 == 1
    }

    /// Points on a lattice through the L's box and a little around it, none on a face.
    fn probe_points() -> Vec<Vec3> {
        let mut points = Vec::new();
        for i in 0..27 {
            for j in 0..27 {
                for k in 0..15 {
                    points.push(Vec3::new(
                        -0.03 + i as f32 * 0.01 + 0.0013,
                        -0.03 + j as f32 * 0.01 + 0.0021,
                        -0.03 + k as f32 * 0.011 + 0.0017,
                    ));
                }
            }
        }
        points
    }

    #[test]
    fn flat_and_smooth_copies_of_a_concave_mesh_agree_with_ray_parity() {
        let (v, t) = l_prism();
        let (fv, ft) = flat(&v, &t);
        let smooth = Surface::new(&v, &t);
        let flat = Surface::new(&fv, &ft);
        assert!(smooth.closed() && flat.closed());
        assert_eq!(
            flat.welded_vertices(),
            12,
            "the flat copy welds back to 12 corners"
        );
        let mut inside = 0;
        for p in probe_points() {
            let expected = parity_inside(&v, &t, p);
            for (name, s) in [("smooth", &smooth), ("flat", &flat)] {
                let got = s.penetration(&[p]).inside == 1;
                assert_eq!(
                    got, expected,
                    "{name} copy at {p}: inside {got}, parity {expected}"
                );
            }
            inside += expected as usize;
        }
        // The L's volume is 3/4 of 0.2 × 0.2 × 0.1 m: about 3/4 × 20 × 20 × 9 lattice points.
        assert!((2600..2800).contains(&inside), "{inside} points inside");
    }

    #[test]
    fn points_by_a_concave_edge_and_corner_are_judged_right() {
        let (v, t) = l_prism();
        let (fv, ft) = flat(&v, &t);
        // The reflex edge runs along Z at (0.1, 0.1); the notch (x, y > 0.1) is outside.
        let cases = [
            (
                Vec3::new(0.102, 0.102, 0.05),
                false,
                "in the notch by the reflex edge",
            ),
            (
                Vec3::new(0.098, 0.098, 0.05),
                true,
                "in the body by the reflex edge",
            ),
            (
                Vec3::new(0.101, 0.13, 0.05),
                false,
                "beside the notch's wall, outside",
            ),
            (
                Vec3::new(0.099, 0.13, 0.05),
                true,
                "behind the notch's wall, inside",
            ),
            (
                Vec3::new(0.102, 0.102, 0.1005),
                false,
                "above the reflex edge's top corner",
            ),
            (
                Vec3::new(0.098, 0.098, 0.0995),
                true,
                "under the reflex edge's top corner",
            ),
            (Vec3::new(0.201, 0.05, 0.05), false, "outside a convex side"),
            (
                Vec3::new(0.201, 0.101, 0.101),
                false,
                "past a convex corner",
            ),
        ];
        for (p, expected, what) in cases {
            assert_eq!(parity_inside(&v, &t, p), expected, "reference: {what}");
            for (name, (vv, tt)) in [("smooth", (&v, &t)), ("flat", (&fv, &ft))] {
                let got = penetration(vv, tt, &[p]);
                assert_eq!(got.inside == 1, expected, "{name}: {what} at {p}");
            }
        }
    }

    #[test]
    fn depth_is_the_distance_to_the_surface_near_and_deep() {
        let (v, t) = cuboid(Vec3::splat(-0.5), Vec3::splat(0.5));
        let (fv, ft) = flat(&v, &t);
        // 1 cm and 3 cm under the top face, 2 cm over it, and the centre (0.5 m deep: past
        // REACH, decided by parity and measured over all triangles).
        let points = [
            Vec3::new(0.1, 0.49, 0.0),
            Vec3::new(-0.2, 0.47, 0.1),
            Vec3::new(0.0, 0.52, 0.0),
            Vec3::new(0.0, 0.0, 0.0),
        ];
        for (vv, tt) in [(&v, &t), (&fv, &ft)] {
            let p = penetration(vv, tt, &points);
            assert_eq!(p.inside, 3);
            assert!((p.deepest - 0.5).abs() < 1e-5, "{}", p.deepest);
            let q = penetration(vv, tt, &points[..3]);
            assert!((q.deepest - 0.03).abs() < 1e-5, "{}", q.deepest);
        }
    }

    #[test]
    fn a_part_sunk_into_another_is_inside_and_the_gap_beside_it_outside() {
        // A body (cube) with a limb (a thinner box) sunk 10 cm into its side, as a pose folds
        // a hand into a thigh: one mesh, both parts closed, the limb's end inside the body.
        let (mut v, mut t) = cuboid(Vec3::splat(-0.5), Vec3::splat(0.5));
        let (lv, lt) = cuboid(Vec3::new(0.4, -0.1, -0.1), Vec3::new(1.0, 0.1, 0.1));
        let base = v.len() as u32;
        v.extend(lv);
        t.extend(lt.iter().map(|tri| tri.map(|i| i + base)));
        let s = Surface::new(&v, &t);
        assert!(s.closed());
        let cases = [
            (Vec3::new(0.45, 0.0, 0.0), true, "in both parts (winding 2)"),
            (
                Vec3::new(0.45, 0.12, 0.0),
                true,
                "in the body beside the sunk limb",
            ),
            (
                Vec3::new(0.55, 0.12, 0.0),
                false,
                "outside both, by the limb's side",
            ),
            (Vec3::new(0.7, 0.0, 0.0), true, "in the limb"),
            (Vec3::new(0.52, 0.3, 0.0), false, "outside the body's face"),
        ];
        for (p, expected, what) in cases {
            assert_eq!(s.penetration(&[p]).inside == 1, expected, "{what} at {p}");
        }
    }

    #[test]
    fn an_open_mesh_counts_only_what_lies_behind_it_within_reach() {
        // The cube without its top face: a deep point cannot be decided and counts outside;
        // one just behind a remaining face counts inside.
        let (v, t) = cuboid(Vec3::splat(-0.5), Vec3::splat(0.5));
        let open: Vec<[u32; 3]> = t
            .into_iter()
            .filter(|tri| !tri.iter().all(|&i| v[i as usize].y > 0.0))
            .collect();
        let s = Surface::new(&v, &open);
        assert!(!s.closed());
        assert_eq!(s.penetration(&[Vec3::ZERO]).inside, 0);
        assert_eq!(s.penetration(&[Vec3::new(0.0, -0.49, 0.0)]).inside, 1);
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
