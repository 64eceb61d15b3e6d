//! Spring stencils: which lattice neighbours a particle is joined to (Provot's mass-spring model).
//!
//! Each family is a half-stencil of lattice offsets, so every undirected pair appears once:
//! structural springs join axis neighbours (up to 6 per particle), shear springs join face
//! diagonals, bend springs join particles two apart along an axis. Only offsets that fit in the
//! grid are active, so a 2-D sheet never carries the z offsets of a voxel block.

/// The family of a spring, each with its own stiffness.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SpringFamily {
    /// Axis neighbours: resists stretch. Always present.
    Stretch,
    /// Face diagonals: resists shear.
    Shear,
    /// Two apart along an axis: resists bending.
    Bend,
}

/// A half-stencil: lattice offsets with the family of the spring each one makes.
#[derive(Clone, Debug, PartialEq)]
pub struct Stencil {
    pub offsets: Vec<([i32; 3], SpringFamily)>,
}

impl Stencil {
    /// The stencil for a grid of `dims` particles per axis with the given families switched on.
    pub fn new(dims: [u32; 3], shear: bool, bend: bool) -> Stencil {
        let mut offsets: Vec<([i32; 3], SpringFamily)> = vec![
            ([1, 0, 0], SpringFamily::Stretch),
            ([0, 1, 0], SpringFamily::Stretch),
            ([0, 0, 1], SpringFamily::Stretch),
        ];
        if shear {
            for d in [
                [1, 1, 0],
                [1, -1, 0],
                [1, 0, 1],
                [1, 0, -1],
                [0, 1, 1],
                [0, 1, -1],
            ] {
                offsets.push((d, SpringFamily::Shear));
            }
        }
        if bend {
            for d in [[2, 0, 0], [0, 2, 0], [0, 0, 2]] {
                offsets.push((d, SpringFamily::Bend));
            }
        }
        offsets.retain(|(d, _)| (0..3).all(|a| d[a].unsigned_abs() < dims[a]));
        Stencil { offsets }
    }
}
