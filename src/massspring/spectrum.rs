//! The highest natural frequency ω_max of a mass-spring model: ω_max² is the largest eigenvalue of
//! M⁻¹K (K the stiffness matrix, pinned particles held), found by power iteration. It bounds the
//! stable step of the explicit integrators (Verlet 2/ω_max, RK4 2√2/ω_max).

use super::forces::{apply_springs, spring_blocks};
use super::MassSpring;
use glam::DVec3;

/// ω_max [rad/s] at the model's current positions, and the power iterations it took.
pub fn highest_frequency(sys: &MassSpring) -> (f64, u32) {
    let n = sys.len();
    let mut blocks = Vec::new();
    // With h = 1 and no dashpots the blocks are exactly the stiffness blocks J.
    let undamped = MassSpring {
        env: super::Environment {
            spring_damping: 0.0,
            ..sys.env
        },
        ..sys.clone()
    };
    spring_blocks(&undamped, &sys.positions, 1.0, &mut blocks);
    // A fixed, irregular start vector so the result is deterministic and touches every mode.
    let mut v: Vec<DVec3> = (0..n)
        .map(|i| {
            let t = i as f64;
            DVec3::new(
                (t * 0.7548).sin(),
                (t * 1.3137 + 1.0).sin(),
                (t * 2.1).cos(),
            ) * sys.inv_mass[i].signum()
        })
        .collect();
    let mut y = vec![DVec3::ZERO; n];
    let mut lambda = 0.0;
    for iteration in 1..=5000u32 {
        y.fill(DVec3::ZERO);
        apply_springs(&undamped, &blocks, &v, &mut y);
        let mut norm = 0.0;
        let mut rayleigh = 0.0;
        for i in 0..n {
            y[i] *= sys.inv_mass[i];
            rayleigh += v[i].dot(y[i]);
            norm += y[i].length_squared();
        }
        let v_norm: f64 = v.iter().map(|v| v.length_squared()).sum();
        let next = rayleigh / v_norm;
        let norm = norm.sqrt();
        for i in 0..n {
            v[i] = y[i] / norm;
        }
        if iteration > 10 && (next - lambda).abs() <= 1e-7 * next {
            return (next.sqrt(), iteration);
        }
        lambda = next;
    }
    (lambda.sqrt(), 5000)
}

/// Gershgorin's upper bound on ω_max: ω_max² ≤ max over free particles of 2·Σ k / m.
pub fn gershgorin_bound(sys: &MassSpring) -> f64 {
    let mut sum = vec![0.0f64; sys.len()];
    for s in &sys.springs {
        sum[s.a as usize] += s.stiffness;
        sum[s.b as usize] += s.stiffness;
    }
    (0..sys.len())
        .map(|i| 2.0 * sum[i] * sys.inv_mass[i])
        .fold(0.0, f64::max)
        .sqrt()
}
