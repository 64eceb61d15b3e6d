//! Two domains and a separator for a small garment's red-black Gauss-Seidel.
//!
//! A team sweeps a colour at a time, every thread its share, a barrier after each colour. On a
//! garment of a few hundred particles a colour is about a microsecond of work a thread, and each
//! colour ends by moving the seam between the threads' shares from one core to the other: the
//! second core made a 440-particle cape's solve only 1.1–1.4 × faster (docs/benchmarks.md, stops
//! 58–64). So a small garment is cut across one lattice axis into a *low* and a *high* side, and
//! the low side's layers within a spring's reach of the cut become the *separator*: no spring
//! joins the two sides' other particles. The separator's particles get colours of their own,
//! swept after every other colour. Then the low side's interior colours read only low and
//! separator particles, the high side's only high and separator ones, so one thread can sweep
//! the low side through every interior colour while another sweeps the high side, with no
//! barrier between, and the separator follows on one thread: two barriers a sweep instead of one
//! a colour. That is the same multi-colour Gauss-Seidel, colour by colour, as any team size or
//! the GPU sweeps it (each colour's particles read only other colours), so the frames do not
//! depend on who sweeps. Each side is stored apart ([`super::model::Domains`]): with the two
//! sides of each colour side by side, the cores still shared a cache line at every colour and
//! each thread's half of the sweep took 1.5 × its time alone (docs/benchmarks.md, stop 65).
//!
//! The cut is chosen from the lattice alone (the garment's cells and stencil), not from its
//! springs, so tearing, which only removes springs, keeps the layout.

use crate::garment::Garment;

/// Which part of its garment's cut a particle lies in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    Low,
    Separator,
    High,
}

/// Models with more particles than this keep one range per colour. Above it a colour's share
/// is long enough that the seam costs little against the work (H's 10 000 particles scale 1.6–1.8 ×
/// on two threads; cut in two, garments of 1 600–3 012 particles were no faster), a team of more
/// than two threads keeps every thread busy, and the GPU is spared the separator's dispatch.
pub const SMALL_MODEL: usize = 1024;

/// Models of more colours keep one range per colour: the GPU sweeps a separator's colours in
/// one dispatch, their starts in its uniform (`gpu::layout::SEPARATOR_STARTS`). drape's stencils
/// need at most 7.
pub const MAX_COLOURS: usize = 15;

/// The side of each of `garment`'s particles (grid order): the cut across one axis that
/// minimises the larger side's particles plus the separator's (what two threads take), or every
/// particle on the low side when no cut does better than one thread alone.
pub fn sides(garment: &Garment) -> Vec<Side> {
    let Some((axis, cut)) = best_cut(garment) else {
        return vec![Side::Low; garment.cells.len()];
    };
    let reach = reach(garment, axis) as u32;
    (garment.cells.iter())
        .map(|c| match c[axis] {
            v if v >= cut => Side::High,
            v if v + reach >= cut => Side::Separator,
            _ => Side::Low,
        })
        .collect()
}

/// The axis and the first high layer of the best cut, if any.
fn best_cut(garment: &Garment) -> Option<(usize, u32)> {
    let n = garment.cells.len();
    let mut best: Option<(usize, usize, u32)> = None; // (cost, axis, cut)
    let mut best_cost = n;
    for axis in 0..3 {
        let reach = reach(garment, axis);
        let layers = garment.dims[axis] as usize;
        let mut count = vec![0usize; layers];
        for c in &garment.cells {
            count[c[axis] as usize] += 1;
        }
        // Separator: layers cut − reach .. cut; low: below it; high: from the cut on.
        for cut in reach..layers {
            let low: usize = count[..cut - reach].iter().sum();
            let separator: usize = count[cut - reach..cut].iter().sum();
            let high = n - low - separator;
            let cost = low.max(high) + separator;
            if low > 0 && high > 0 && cost < best_cost {
                best_cost = cost;
                best = Some((cost, axis, cut as u32));
            }
        }
    }
    best.map(|(_, axis, cut)| (axis, cut))
}

/// How many layers along `axis` the garment's springs reach (its stencil's largest offset there).
fn reach(garment: &Garment, axis: usize) -> usize {
    (garment.stencil.offsets.iter())
        .map(|(d, _)| d[axis].unsigned_abs() as usize)
        .max()
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::garment::test_sheet as garment;

    /// No spring joins the low and high sides, the separator is as thin as the stencil's reach
    /// across the cut, and the sides balance.
    #[test]
    fn no_spring_crosses_the_separator() {
        for (stiffness, thickness) in [
            (r#"{ "stretch": 100 }"#, 1),
            (r#"{ "stretch": 100, "shear": 10 }"#, 1),
            (r#"{ "stretch": 100, "shear": 10, "bend": 1 }"#, 2),
        ] {
            let g = garment([20, 13], stiffness);
            let sides = sides(&g);
            for s in &g.springs {
                let pair = (sides[s.a as usize], sides[s.b as usize]);
                assert!(
                    pair != (Side::Low, Side::High) && pair != (Side::High, Side::Low),
                    "{stiffness}: spring {s:?} crosses"
                );
            }
            let count = |side| sides.iter().filter(|&&s| s == side).count();
            // Cut across one axis: the separator is `thickness` rows of the other (20 or 13).
            let separator = count(Side::Separator);
            assert!(
                separator == 13 * thickness || separator == 20 * thickness,
                "{stiffness}: {separator}"
            );
            // Whole rows each side, as even as rows allow.
            let (low, high) = (count(Side::Low), count(Side::High));
            assert!(
                low.abs_diff(high) <= 20,
                "{stiffness}: {low} against {high}"
            );
        }
    }

    /// Tearing only removes springs, and the layout of a small model (its sides, separator and
    /// storage order) stays what it was: a torn model's state is the untorn one's.
    #[test]
    fn tearing_keeps_the_layout() {
        use crate::sim::model::Model;
        let mut g = garment([20, 13], r#"{ "stretch": 100, "shear": 10, "bend": 1 }"#);
        let whole = Model::new(std::slice::from_ref(&g));
        assert!(whole.domains.is_some());
        // Every spring across the middle row torn, and every third one elsewhere.
        let mut k = 0;
        g.springs.retain(|s| {
            k += 1;
            k % 3 != 0 && g.cells[s.a as usize][1] != 6
        });
        let torn = Model::new(std::slice::from_ref(&g));
        assert!(torn.springs.len() < whole.springs.len());
        assert_eq!(torn.storage_of, whole.storage_of);
        assert_eq!(torn.colour_ranges, whole.colour_ranges);
        assert_eq!(torn.domains, whole.domains);
    }

    /// A garment too thin to cut (every cut leaves a side empty) stays whole on the low side.
    #[test]
    fn a_garment_too_small_to_cut_stays_whole() {
        let g = garment([3, 2], r#"{ "stretch": 100, "shear": 10, "bend": 1 }"#);
        assert!(sides(&g).iter().all(|&s| s == Side::Low));
    }
}
