//! Grid colouring for parallel Gauss-Seidel: particles of one colour share no spring, so a whole
//! colour can be updated at once (red-black Gauss-Seidel is the two-colour case).
//!
//! The colouring is derived from the stencil, not hard-coded: drape searches the smallest modulus
//! K and coefficients (a, b, c) such that colour(x, y, z) = (a·x + b·y + c·z) mod K differs across
//! every offset of the stencil, i.e. (a·dx + b·dy + c·dz) mod K ≠ 0 for every spring offset. For the
//! axis stencil this gives the classic (x + y + z) mod 2; with shear springs in a sheet 4 colours;
//! with shear and bend springs 5 (fewer than the 9 of a 3 × 3 product colouring, so fewer passes).

use super::stencil::Stencil;

/// colour(x, y, z) = (a·x + b·y + c·z) mod `modulus`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub struct Colouring {
    pub modulus: u32,
    pub coefficients: [u32; 3],
}

impl Colouring {
    /// The smallest linear colouring that separates every offset of `stencil`.
    pub fn derive(stencil: &Stencil) -> Colouring {
        // A stencil of at most 27 offsets is always separated by K = 27 with (1, 3, 9) on a
        // 3×3×3 neighbourhood; drape's stencils need far fewer colours, found in microseconds.
        for modulus in 1..=64u32 {
            let k = modulus as i64;
            for a in 0..modulus {
                for b in 0..modulus {
                    for c in 0..modulus {
                        let separates = stencil.offsets.iter().all(|(d, _)| {
                            let s = a as i64 * d[0] as i64
                                + b as i64 * d[1] as i64
                                + c as i64 * d[2] as i64;
                            s.rem_euclid(k) != 0
                        });
                        if separates {
                            return Colouring {
                                modulus,
                                coefficients: [a, b, c],
                            };
                        }
                    }
                }
            }
        }
        unreachable!("every stencil of offsets below 3 is separated by modulus 64")
    }

    /// The colour of the particle at lattice coordinates `cell`.
    pub fn colour(&self, cell: [u32; 3]) -> u32 {
        let s: u64 = (0..3)
            .map(|a| self.coefficients[a] as u64 * cell[a] as u64)
            .sum();
        (s % self.modulus as u64) as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axis_stencil_is_red_black() {
        let c = Colouring::derive(&Stencil::new([100, 100, 1], false, false));
        assert_eq!(c.modulus, 2);
        assert_eq!(c.colour([3, 4, 0]), 1);
        assert_eq!(c.colour([3, 5, 0]), 0);
    }

    #[test]
    fn shear_and_bend_need_more_colours() {
        assert_eq!(
            Colouring::derive(&Stencil::new([9, 9, 1], true, false)).modulus,
            4
        );
        assert_eq!(
            Colouring::derive(&Stencil::new([9, 9, 1], true, true)).modulus,
            5
        );
        assert_eq!(
            Colouring::derive(&Stencil::new([9, 1, 1], false, true)).modulus,
            3
        );
    }
}
