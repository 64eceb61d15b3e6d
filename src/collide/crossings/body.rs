//! A character passing through itself ([`SelfCrossings`]), found through a tree of its
//! triangles built once on its rest pose and refitted every frame. Only pairs of triangles that
//! lay farther apart than [`APART`] at rest count, and two triangles' boxes lie no farther apart
//! than their centroids: so every part of the tree whose triangles' centroids lay within that
//! distance of each other at rest is left out of the search of itself, and two parts are
//! searched against each other only where their boxes overlap in the frame and their centroids
//! lay far enough apart at rest: a search over the places where one limb meets another, not
//! over every neighbouring pair of the mesh.

use super::intersect;
use crate::mesh::Weld;
use glam::Vec3;

/// A character passing through itself: the pairs of its own triangles that intersect in a
/// frame and lay farther apart than [`APART`] of its size in its rest pose. Cloth caught where
/// one part of a body sinks into another (a hand into a thigh) has no place outside the mesh,
/// so the bake reports these frames beside the mesh penetrations. Parts that overlap by
/// construction (a robot's rigid pieces at their joints) touch in the rest pose and are left
/// out, as are neighbouring triangles a bend folds through each other.
pub struct SelfCrossings {
    /// Each triangle's box in the rest pose.
    rest: Vec<Bounds>,
    /// How far apart two triangles' rest boxes must be for their crossing to count [m].
    apart: f32,
    tree: Tree,
}

/// The share of a character's size (its rest pose's largest extent) two of its triangles must
/// lie apart in the rest pose for their crossing to count: 5 %, 7.5 cm on a 1.5 m character
/// (his hand and thigh lie 45 cm apart in a T-pose, a robot's forearm and hand touch).
pub const APART: f32 = 0.05;

/// Triangles a leaf of the tree holds at most.
const LEAF: usize = 4;

type Bounds = (Vec3, Vec3);

/// The triangles split in halves along the longest side of their rest centroids' box, down to
/// leaves of [`LEAF`]: each node covers a contiguous run of `order`, its children follow it.
struct Tree {
    order: Vec<u32>,
    nodes: Vec<Node>,
}

struct Node {
    /// Its run of `order`.
    start: u32,
    end: u32,
    /// Its two children, or none for a leaf.
    children: Option<[u32; 2]>,
    /// The box of its triangles' rest centroids: two triangles' boxes lie no farther apart
    /// than their centroids, so no pair under two nodes lay farther apart at rest than the
    /// farthest points of these boxes.
    centres: Bounds,
}

fn union(a: Bounds, b: Bounds) -> Bounds {
    (a.0.min(b.0), a.1.max(b.1))
}

fn bounds_of(corners: [Vec3; 3]) -> Bounds {
    let [a, b, c] = corners;
    (a.min(b).min(c), a.max(b).max(c))
}

fn overlap(a: Bounds, b: Bounds) -> bool {
    !(a.0.max(b.0)).cmpgt(a.1.min(b.1)).any()
}

/// The farthest any point of box `a` lies from any point of box `b`.
fn farthest(a: Bounds, b: Bounds) -> f32 {
    (a.1 - b.0).max(b.1 - a.0).length()
}

/// The gap between boxes `a` and `b` (0 where they touch or overlap).
fn gap(a: Bounds, b: Bounds) -> f32 {
    (a.0 - b.1).max(b.0 - a.1).max(Vec3::ZERO).length()
}

impl Tree {
    /// Over triangles whose rest centroids are `centres`.
    fn new(centres: &[Vec3]) -> Tree {
        let mut tree = Tree {
            order: (0..centres.len() as u32).collect(),
            nodes: Vec::new(),
        };
        if !centres.is_empty() {
            tree.split(centres, 0, centres.len());
        }
        tree
    }

    /// Adds the node over `order[start..end]` and its subtree; returns its index.
    fn split(&mut self, centres: &[Vec3], start: usize, end: usize) -> u32 {
        let run = &mut self.order[start..end];
        let centre = |t: u32| centres[t as usize];
        let (lo, hi) = (run.iter()).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), &t| {
            (lo.min(centre(t)), hi.max(centre(t)))
        });
        let index = self.nodes.len() as u32;
        self.nodes.push(Node {
            start: start as u32,
            end: end as u32,
            children: None,
            centres: (lo, hi),
        });
        if end - start <= LEAF {
            return index;
        }
        let axis = (hi - lo).max_position();
        let middle = run.len() / 2;
        run.select_nth_unstable_by(middle, |&a, &b| {
            centre(a)[axis].total_cmp(&centre(b)[axis]).then(a.cmp(&b))
        });
        let left = self.split(centres, start, start + middle);
        let right = self.split(centres, start + middle, end);
        self.nodes[index as usize].children = Some([left, right]);
        index
    }

    /// Every node's box over the triangles' boxes `boxes` of a frame (children after their
    /// parent: filled from the last node back).
    fn refit(&self, boxes: &[Bounds]) -> Vec<Bounds> {
        let mut fitted = vec![(Vec3::ZERO, Vec3::ZERO); self.nodes.len()];
        for (k, node) in self.nodes.iter().enumerate().rev() {
            fitted[k] = match node.children {
                Some([l, r]) => union(fitted[l as usize], fitted[r as usize]),
                None => (self.order[node.start as usize..node.end as usize].iter())
                    .map(|&t| boxes[t as usize])
                    .reduce(union)
                    .expect("a leaf holds a triangle"),
            };
        }
        fitted
    }

    fn triangles(&self, node: u32) -> &[u32] {
        let n = &self.nodes[node as usize];
        &self.order[n.start as usize..n.end as usize]
    }
}

impl SelfCrossings {
    /// A character whose `triangles` rest at `rest` (its bake's first frame).
    pub fn new(rest: &[Vec3], triangles: &[[u32; 3]]) -> SelfCrossings {
        let (lo, hi) = (rest.iter()).fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(*p), hi.max(*p))
        });
        let size = (hi - lo).max_element().max(0.0);
        let boxes: Vec<Bounds> = (triangles.iter())
            .map(|t| bounds_of(t.map(|i| rest[i as usize])))
            .collect();
        let centres: Vec<Vec3> = (triangles.iter())
            .map(|t| t.iter().map(|&i| rest[i as usize]).sum::<Vec3>() / 3.0)
            .collect();
        SelfCrossings {
            tree: Tree::new(&centres),
            rest: boxes,
            apart: APART * size,
        }
    }

    /// How many pairs of `triangles` (over `positions`) pass through each other and lay apart
    /// in the rest pose.
    pub fn count(&self, positions: &[Vec3], triangles: &[[u32; 3]]) -> usize {
        self.pairs(positions, triangles).len()
    }

    /// Those pairs, as indices into `triangles` (the lower first), sorted: the pairs
    /// [`super::pairs`] finds whose rest boxes lie more than the rest distance apart.
    pub fn pairs(&self, positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<(u32, u32)> {
        let tree = &self.tree;
        if tree.nodes.is_empty() {
            return Vec::new();
        }
        let corners = |t: u32| triangles[t as usize].map(|i| positions[i as usize]);
        let boxes: Vec<Bounds> = (0..triangles.len() as u32)
            .map(|t| bounds_of(corners(t)))
            .collect();
        let now = tree.refit(&boxes);
        let mut found = Vec::new();
        let mut test = |i: u32, j: u32| {
            let (i, j) = (i.min(j), i.max(j));
            let (a, b) = (i as usize, j as usize);
            if !overlap(boxes[a], boxes[b]) || gap(self.rest[a], self.rest[b]) <= self.apart {
                return;
            }
            // Triangles at one place share a vertex (a seam, flat shading): a touch.
            let places = |t: usize| triangles[t].map(|v| Weld::place(positions[v as usize]));
            let (s, u) = (places(a), places(b));
            if s.iter().any(|v| u.contains(v)) {
                return;
            }
            if intersect(corners(i), corners(j)) {
                found.push((i, j));
            }
        };
        let mut stack = vec![(0u32, 0u32)];
        while let Some((a, b)) = stack.pop() {
            let (na, nb) = (&tree.nodes[a as usize], &tree.nodes[b as usize]);
            // No pair under these two lay more than `apart` apart at rest, or none meets now.
            if farthest(na.centres, nb.centres) <= self.apart
                || !overlap(now[a as usize], now[b as usize])
            {
                continue;
            }
            match (a == b, na.children, nb.children) {
                (true, Some([l, r]), _) => stack.extend([(l, l), (r, r), (l, r)]),
                (true, None, _) => {
                    let run = tree.triangles(a);
                    for (k, &i) in run.iter().enumerate() {
                        run[k + 1..].iter().for_each(|&j| test(i, j));
                    }
                }
                (false, Some([l, r]), Some(_)) if na.end - na.start >= nb.end - nb.start => {
                    stack.extend([(l, b), (r, b)])
                }
                (false, _, Some([l, r])) => stack.extend([(a, l), (a, r)]),
                (false, Some([l, r]), None) => stack.extend([(l, b), (r, b)]),
                (false, None, None) => {
                    for &i in tree.triangles(a) {
                        tree.triangles(b).iter().for_each(|&j| test(i, j));
                    }
                }
            }
        }
        found.sort_unstable();
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed tube around `axis` through `base`, `rings` rings of `around` vertices, radius
    /// `r`, length `length`, its vertices numbered from `first`.
    fn tube(
        base: Vec3,
        axis: Vec3,
        (r, length): (f32, f32),
        (rings, around): (u32, u32),
        first: u32,
    ) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let side = axis.any_orthonormal_vector();
        let other = axis.cross(side);
        let mut p = Vec::new();
        for k in 0..rings {
            for j in 0..around {
                let a = j as f32 / around as f32 * std::f32::consts::TAU;
                let along = length * k as f32 / (rings - 1) as f32;
                p.push(base + axis * along + (side * a.cos() + other * a.sin()) * r);
            }
        }
        let at = |k: u32, j: u32| first + k * around + j % around;
        let mut t = Vec::new();
        for k in 0..rings - 1 {
            for j in 0..around {
                t.push([at(k, j), at(k + 1, j), at(k + 1, j + 1)]);
                t.push([at(k, j), at(k + 1, j + 1), at(k, j + 1)]);
            }
        }
        (p, t)
    }

    /// The reference: every crossing pair of the mesh ([`super::super::pairs`]), kept where
    /// their rest boxes lie more than `apart` apart.
    fn reference(
        rest: &[Vec3],
        now: &[Vec3],
        triangles: &[[u32; 3]],
        apart: f32,
    ) -> Vec<(u32, u32)> {
        let box_of = |p: &[Vec3], t: usize| bounds_of(triangles[t].map(|i| p[i as usize]));
        let mut found = super::super::pairs(now, triangles);
        found.retain(|&(i, j)| gap(box_of(rest, i as usize), box_of(rest, j as usize)) > apart);
        found
    }

    #[test]
    fn an_arm_swung_into_a_body_crosses_it_as_every_pair_tested_says() {
        // A torso (a tube 1 m long, 15 cm radius) and an arm (a tube 60 cm long, 4 cm radius)
        // hung from beside its top, swung in steps towards and through the torso's side.
        let (body, body_triangles) = tube(Vec3::ZERO, Vec3::Y, (0.15, 1.0), (21, 24), 0);
        let first = body.len() as u32;
        let shoulder = Vec3::new(0.25, 0.95, 0.0);
        let arm_at = |angle: f32| {
            let down = glam::Quat::from_rotation_z(angle) * -Vec3::Y;
            tube(shoulder, down, (0.04, 0.6), (13, 12), first)
        };
        let (rest_arm, arm_triangles) = arm_at(0.0);
        let triangles = [body_triangles, arm_triangles].concat();
        let rest = [body.clone(), rest_arm].concat();
        let crossings = SelfCrossings::new(&rest, &triangles);
        let mut crossed = 0;
        for step in 0..12 {
            // From hanging clear beside it to 33° into it (its shoulder outside, its hand in).
            let angle = -0.05 * step as f32;
            let now = [body.clone(), arm_at(angle).0].concat();
            let expected = reference(&rest, &now, &triangles, crossings.apart);
            assert_eq!(crossings.pairs(&now, &triangles), expected, "step {step}");
            crossed += (!expected.is_empty()) as usize;
        }
        assert!((3..12).contains(&crossed), "{crossed}");
    }

    #[test]
    fn a_body_at_rest_or_squashed_flat_agrees_with_every_pair_tested() {
        // A tube at rest crosses nothing; squashed flat, its sides meet, 20 cm apart at rest.
        let (p, t) = tube(Vec3::ZERO, Vec3::Y, (0.1, 1.0), (11, 16), 0);
        let crossings = SelfCrossings::new(&p, &t);
        assert_eq!(crossings.count(&p, &t), 0);
        let squashed: Vec<Vec3> = p.iter().map(|v| v * Vec3::new(0.01, 1.0, 1.0)).collect();
        assert_eq!(
            crossings.pairs(&squashed, &t),
            reference(&p, &squashed, &t, crossings.apart)
        );
    }
}
