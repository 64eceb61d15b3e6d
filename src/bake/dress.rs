//! Dressing a character before the first substep: a clean start. Garment particles that begin
//! inside a character (inside its mesh, or closer to it than its shell lets cloth come) are
//! moved out along the surface's normal to the shell's radius, so the first substep does not
//! fire them out of the body. Then garments modelled on one character are layered in the
//! scene's order (the first put on first): where a particle of a later garment lies under or
//! within two contact radii of an earlier one over the same skin, the later garment rises along
//! the skin's normal as a sheet until it lies two contact radii over it, so an outfit whose
//! pieces were modelled apart (a top's hem through a skirt's waistband) starts with each piece
//! on its own side. The report says how many moved and how far.

use crate::collide::mesh::Surface;
use crate::export::sequence::BakeMeshes;
use crate::report::CleanStart;
use crate::sim::Simulation;
use glam::Vec3;

/// Moves every free garment particle of `sim` that starts inside a character of `meshes` (on
/// its frame 0, where the bake starts) to `radius + thickness / 2` outside its surface, along
/// the normal at the nearest point: `radius` is the character's shell radius, `thickness /
/// 2` the particle's contact radius. Characters are taken in turn; a particle moved out of
/// one is then tested against the next. Then the garments of `garments` (the scene's, in its
/// order) modelled on one character are laid each over the ones before it ([`layer`]).
pub fn clean_start(
    sim: &mut Simulation,
    meshes: &BakeMeshes,
    garments: &[crate::scene::GarmentSpec],
) -> CleanStart {
    let mut report = out_of_bodies(sim, meshes);
    for (name, vertices, triangles) in meshes.characters_on(0) {
        let on: Vec<usize> = (garments.iter().enumerate())
            .filter(|(_, g)| g.on.as_deref() == Some(name))
            .map(|(k, _)| k)
            .collect();
        if on.len() > 1 {
            layer(sim, &Surface::new(vertices, triangles), &on, &mut report);
        }
    }
    report
}

/// The first part of [`clean_start`]: every free particle out of every character.
fn out_of_bodies(sim: &mut Simulation, meshes: &BakeMeshes) -> CleanStart {
    let mut report = CleanStart::default();
    let free: Vec<usize> = (0..sim.state.positions.len())
        .filter(|&i| sim.model().inv_mass[i] != 0.0)
        .collect();
    if free.is_empty() {
        return report;
    }
    for (name, vertices, triangles) in meshes.characters_on(0) {
        let Some(shell) = sim.drivers.shells.iter().find(|s| s.name == name) else {
            continue;
        };
        let radius = shell.radius;
        let surface = Surface::new(vertices, triangles);
        let points: Vec<glam::Vec3> = free
            .iter()
            .map(|&i| sim.state.positions[i].truncate())
            .collect();
        let nearest = surface.nearest_signed(&points);
        for (&i, n) in free.iter().zip(nearest) {
            let clearance = radius + sim.model().contact_radius[i];
            if n.distance >= clearance {
                continue;
            }
            let to = n.point + n.normal * clearance;
            let p = &mut sim.state.positions[i];
            let moved = p.truncate().distance(to);
            *p = to.extend(0.0);
            sim.state.velocities[i] = glam::Vec4::ZERO;
            report.moved += 1;
            report.inside_mesh += (n.distance < 0.0) as usize;
            report.largest_move_m = report.largest_move_m.max(moved);
        }
    }
    report
}

/// A garment particle placed against the skin for [`layer`]: its storage index, whether it is
/// held, its contact radius, its distance out of the skin, the nearest skin point and the
/// skin's normal there.
struct OnSkin {
    index: usize,
    /// Pinned or attached: it covers the skin for later garments but is not moved.
    held: bool,
    radius: f32,
    distance: f32,
    point: Vec3,
    normal: Vec3,
}

/// Lays the garments `on` (model garment indices, in the scene's order, all modelled on the
/// character whose skin is `surface`) each over the ones before it: a particle of a later
/// garment needs to rise along the skin's normal to two contact radii over the farthest
/// particle of an earlier garment that covers the same skin (its nearest skin point within
/// two contact diameters of the particle's, the normals within 60°), when it lies lower, and
/// the garment rises by [`lifts`].
fn layer(sim: &mut Simulation, surface: &Surface, on: &[usize], report: &mut CleanStart) {
    let model = sim.model();
    let mut placed: Vec<Vec<OnSkin>> = on
        .iter()
        .map(|&g| {
            let range = model.garments[g].export.clone();
            let all: Vec<usize> = range.map(|e| model.storage_of[e] as usize).collect();
            let points: Vec<Vec3> = (all.iter())
                .map(|&i| sim.state.positions[i].truncate())
                .collect();
            (all.iter().zip(surface.nearest_signed(&points)))
                .map(|(&index, n)| OnSkin {
                    index,
                    held: model.inv_mass[index] == 0.0,
                    radius: model.contact_radius[index],
                    distance: n.distance,
                    point: n.point,
                    normal: n.normal,
                })
                .collect()
        })
        .collect();
    for outer in 1..placed.len() {
        let (under, rest) = placed.split_at_mut(outer);
        let covering: Vec<&OnSkin> = under.iter().flatten().collect();
        let reach = 4.0
            * (covering.iter().map(|p| p.radius))
                .chain(rest[0].iter().map(|p| p.radius))
                .fold(0.0f32, f32::max);
        if reach <= 0.0 {
            continue;
        }
        let grid = SkinGrid::new(covering.iter().map(|p| p.point), reach);
        // How far each free particle must rise to lie over the garments put on before.
        let needed: Vec<f32> = (rest[0].iter())
            .map(|p| {
                let mut over = f32::NEG_INFINITY;
                grid.near(p.point, |k| {
                    let q = covering[k];
                    if q.point.distance(p.point) <= reach && q.normal.dot(p.normal) > 0.5 {
                        over = over.max(q.distance + q.radius + p.radius);
                    }
                });
                match p.held {
                    true => 0.0,
                    false => (over - p.distance).max(0.0),
                }
            })
            .collect();
        let most = needed.iter().copied().fold(0.0f32, f32::max);
        if most <= 0.0 {
            continue;
        }
        let lifts = lifts(&rest[0], &needed, most);
        for (p, lift) in rest[0]
            .iter_mut()
            .zip(lifts)
            .filter(|(p, l)| !p.held && *l > 0.0)
        {
            let x = &mut sim.state.positions[p.index];
            *x += (p.normal * lift).extend(0.0);
            sim.state.velocities[p.index] = glam::Vec4::ZERO;
            p.distance += lift;
            report.layered += 1;
            report.largest_layering_m = report.largest_layering_m.max(lift);
        }
    }
}

/// How far [`layer`] lifts each particle of a garment (`placed`) whose particles need to rise
/// `needed` (the most of them `most`): the garment rises as a sheet, each particle by the most
/// any particle facing its way needs less [`LIFT_SLOPE`] times their distance along the skin.
/// So the layers of its lattice over one patch of skin rise together (a particle that alone
/// rose to where the garment before it lets it would flatten the lattice's thickness there),
/// and the lift fades around the overlap instead of stepping.
fn lifts(placed: &[OnSkin], needed: &[f32], most: f32) -> Vec<f32> {
    let grid = SkinGrid::new(placed.iter().map(|p| p.point), most / LIFT_SLOPE);
    (placed.iter())
        .map(|p| {
            let mut lift = 0.0f32;
            grid.near(p.point, |j| {
                let q = &placed[j];
                if needed[j] > 0.0 && q.normal.dot(p.normal) > 0.5 {
                    lift = lift.max(needed[j] - LIFT_SLOPE * q.point.distance(p.point));
                }
            });
            lift
        })
        .collect()
}

/// How fast [`layer`]'s lift fades along the skin around the particles that need it: 1 in 2.
const LIFT_SLOPE: f32 = 0.5;

/// Points bucketed by cell (a hash map of cells `cell` wide): the points within `cell` of a
/// point are in the 27 cells around its own.
struct SkinGrid {
    cell: f32,
    cells: std::collections::HashMap<glam::IVec3, Vec<usize>>,
}

impl SkinGrid {
    fn new(points: impl Iterator<Item = Vec3>, cell: f32) -> SkinGrid {
        let mut cells: std::collections::HashMap<glam::IVec3, Vec<usize>> = Default::default();
        for (k, p) in points.enumerate() {
            cells
                .entry((p / cell).floor().as_ivec3())
                .or_default()
                .push(k);
        }
        SkinGrid { cell, cells }
    }

    /// Calls `each` with every point in the 27 cells around `p`'s, in ascending order per cell.
    fn near(&self, p: Vec3, mut each: impl FnMut(usize)) {
        let c = (p / self.cell).floor().as_ivec3();
        for x in -1..=1 {
            for y in -1..=1 {
                for z in -1..=1 {
                    if let Some(points) = self.cells.get(&(c + glam::IVec3::new(x, y, z))) {
                        points.iter().for_each(|&k| each(k));
                    }
                }
            }
        }
    }
}

/// How far a garment starts from the body it was modelled on ([`clearance`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Clearance {
    /// The nearest particle's signed distance to the body's surface [m] (below zero inside).
    pub min: f32,
    /// The 5th percentile of the particles' signed distances [m].
    pub p5: f32,
    /// Particles inside the body's mesh.
    pub inside: usize,
    /// Particles closer to the surface than `radius` (inside the shell, or the mesh).
    pub within: usize,
}

/// The clearance of `points` (a garment's particles) to the mesh `vertices` and `triangles`
/// (a character in its bind pose), counting those closer than `radius` to it.
pub fn clearance(
    vertices: &[Vec3],
    triangles: &[[u32; 3]],
    points: &[Vec3],
    radius: f32,
) -> Clearance {
    let surface = Surface::new(vertices, triangles);
    let mut distances: Vec<f32> = surface
        .nearest_signed(points)
        .iter()
        .map(|n| n.distance)
        .collect();
    distances.sort_by(f32::total_cmp);
    let at = |q: f32| distances[((distances.len() - 1) as f32 * q) as usize];
    Clearance {
        min: distances.first().copied().unwrap_or(f32::INFINITY),
        p5: if distances.is_empty() {
            f32::INFINITY
        } else {
            at(0.05)
        },
        inside: distances.iter().filter(|&&d| d < 0.0).count(),
        within: distances.iter().filter(|&&d| d < radius).count(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn on_skin(x: f32, distance: f32) -> OnSkin {
        OnSkin {
            index: 0,
            held: false,
            radius: 0.005,
            distance,
            point: Vec3::new(x, 0.0, 0.0),
            normal: Vec3::Y,
        }
    }

    #[test]
    fn a_lattice_rises_as_a_sheet_its_layers_together_and_fading_around_the_overlap() {
        // Two layers of a lattice over the skin at x = 0 (5 mm and 20 mm out), the inner one
        // 30 mm under where the garment before it lets it lie; neighbours along the skin 2 cm
        // and 10 cm away, and one facing the other way (the far side of a limb) at x = 0.
        let mut placed = vec![
            on_skin(0.0, 0.005),
            on_skin(0.0, 0.020),
            on_skin(0.02, 0.005),
            on_skin(0.10, 0.005),
            on_skin(0.0, 0.005),
        ];
        placed[4].normal = -Vec3::Y;
        let needed = [0.03, 0.0, 0.0, 0.0, 0.0];
        let lifts = lifts(&placed, &needed, 0.03);
        // Both layers by the same 30 mm: the lattice keeps its 15 mm thickness.
        assert_eq!(lifts[0], 0.03);
        assert_eq!(lifts[1], 0.03);
        // 2 cm along the skin, half that less; 10 cm away, beyond the fade; facing away, none.
        assert!((lifts[2] - 0.02).abs() < 1e-6, "{lifts:?}");
        assert_eq!(lifts[3], 0.0);
        assert_eq!(lifts[4], 0.0);
    }
}
