// Stage 1, predict: the inertial displacement t = h (f v + g h) of every free particle becomes
// both the solver's target and its starting displacement.
@compute @workgroup_size(64)
fn predict(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles || particle[i].inv_mass == 0.0) {
        return;
    }
    let t = (velocity[i] * params.keep + params.gravity_step) * params.step;
    delta[i] = t;
    target_delta[i] = t;
}
