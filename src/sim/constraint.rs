//! Constraint maths as pure functions, shared by every CPU solver (and mirrored by name in the
//! WGSL kernels), so a disagreement between solvers points at one function.

use glam::Vec4;

/// Lengths below this [m] have no direction; their springs project to zero length.
pub const TINY_LENGTH: f32 = 1e-12;

/// Projective Dynamics local step for a distance spring (Bouaziz et al. 2014, §5.2; thesis eq. 3.9):
/// the closest point of the constraint set to the current edge is the edge rescaled to its rest
/// length, d = L · (q_i − q_j) / |q_i − q_j|. Returns d, the offset particle i wants from j.
#[inline(always)]
pub fn spring_projection(qi: Vec4, qj: Vec4, rest: f32) -> Vec4 {
    let d = qi - qj;
    d * spring_projection_scale(d.length_squared(), rest)
}

/// The factor L / |e| that scales an edge e with squared length `length_squared` onto rest length
/// L (0 for an edge too short to have a direction): `spring_projection` split so a batch of
/// springs can take its square roots and divisions together.
#[inline(always)]
pub fn spring_projection_scale(length_squared: f32, rest: f32) -> f32 {
    if length_squared > TINY_LENGTH * TINY_LENGTH {
        rest / length_squared.sqrt()
    } else {
        0.0
    }
}

/// Projective Dynamics global step for one particle (thesis algorithm 4, one Gauss-Seidel row):
/// minimising a_i/2 |q_i − s_i|² + Σ_k w_k/2 |q_i − q_k − d_k|² over q_i gives
/// q_i = (a_i s_i + Σ_k w_k (q_k + d_k)) / (a_i + Σ_k w_k). `rhs` holds a_i s_i + Σ_k w_k d_k,
/// `neighbours` yields (w_k, q_k), `diag_inv` is 1 / (a_i + Σ_k w_k).
#[inline(always)]
pub fn spring_row_solve(
    rhs: Vec4,
    neighbours: impl Iterator<Item = (f32, Vec4)>,
    diag_inv: f32,
) -> Vec4 {
    let mut acc = rhs;
    for (w, q) in neighbours {
        acc += q * w;
    }
    acc * diag_inv
}

/// Successive over-relaxation: move from `old` past the Gauss-Seidel value `new` by factor ω.
#[inline(always)]
pub fn over_relax(old: Vec4, new: Vec4, omega: f32) -> Vec4 {
    old + (new - old) * omega
}

/// Position Based Dynamics distance constraint (Müller et al. 2007, eq. 9): the correction of
/// particle i, with inverse masses `wi`, `wj`, that restores the rest length:
/// Δq_i = −w_i / (w_i + w_j) · (|q_i − q_j| − L) · (q_i − q_j) / |q_i − q_j|.
#[inline(always)]
pub fn pbd_distance_correction(qi: Vec4, wi: f32, qj: Vec4, wj: f32, rest: f32) -> Vec4 {
    let d = qi - qj;
    let len = d.length();
    let w = wi + wj;
    if len > TINY_LENGTH && w > 0.0 {
        d * (-(wi / w) * (len - rest) / len)
    } else {
        Vec4::ZERO
    }
}

/// Long-range attachment (Kim, Chentanez and Müller 2012): a unilateral distance constraint that
/// keeps a particle within `rest` of its pin. `offset` is the particle's position minus the pin's;
/// returns the correction to add to the particle (zero when it is close enough).
#[inline(always)]
pub fn tether_correction(offset: Vec4, rest: f32) -> Vec4 {
    // Most particles are slack: compare squared lengths and take the root only when pulled.
    let len2 = offset.length_squared();
    if len2 > rest * rest {
        offset * (rest / len2.sqrt() - 1.0)
    } else {
        Vec4::ZERO
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_has_rest_length_and_direction() {
        let d = spring_projection(Vec4::new(3.0, 4.0, 0.0, 0.0), Vec4::ZERO, 1.0);
        assert!((d.length() - 1.0).abs() < 1e-6);
        assert!((d.x - 0.6).abs() < 1e-6 && (d.y - 0.8).abs() < 1e-6);
    }

    #[test]
    fn pbd_correction_restores_length() {
        let (a, b) = (Vec4::new(2.0, 0.0, 0.0, 0.0), Vec4::ZERO);
        let da = pbd_distance_correction(a, 1.0, b, 1.0, 1.0);
        let db = pbd_distance_correction(b, 1.0, a, 1.0, 1.0);
        assert!((((a + da) - (b + db)).length() - 1.0).abs() < 1e-6);
    }
}
