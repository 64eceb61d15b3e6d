//! Dressing a character before the first substep: a clean start. Garment particles that begin
//! inside a character (inside its mesh, or closer to it than its shell lets cloth come) are
//! moved out along the surface's normal to the shell's radius, so the first substep does not
//! fire them out of the body. The report says how many moved and how far.

use crate::collide::mesh::Surface;
use crate::export::sequence::BakeMeshes;
use crate::report::CleanStart;
use crate::sim::Simulation;
use glam::Vec3;

/// Moves every free garment particle of `sim` that starts inside a character of `meshes` (on
/// its frame 0, where the bake starts) to `radius + thickness / 2` outside its surface, along
/// the normal at the nearest point: `radius` is the character's shell radius, `thickness /
/// 2` the particle's contact radius. Characters are taken in turn; a particle moved out of
/// one is then tested against the next.
pub fn clean_start(sim: &mut Simulation, meshes: &BakeMeshes) -> CleanStart {
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
