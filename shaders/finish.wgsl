// Stages 3 to 5 for each free particle: long-range attachments to the pins, collisions with
// friction, then x += Δ and v = Δ/h, and (when another substep follows) its prediction.
// The collision functions it calls are in `colliders.wgsl` and `shells.wgsl`, which mirror
// `src/collide/`; this file holds the stages of `src/sim/` that use them.

// False in the pipelines for scenes without characters (or without analytic colliders): that
// code is compiled out (`gpu::Kernels::new`). Unreached, it still cost: its large private
// arrays and loops made `finish` of scene H on lavapipe 2 869 ms per frame, 182 ms without
// (docs/benchmarks.md), and they are register pressure on any GPU.
override SHELLS: bool = true;
override COLLIDERS: bool = true;

fn tether_correction(offset: vec4<f32>, rest: f32) -> vec4<f32> {
    let len2 = dot(offset, offset);
    if (len2 > rest * rest) {
        return offset * (rest / sqrt(len2) - 1.0);
    }
    return vec4<f32>(0.0);
}


@compute @workgroup_size(64)
fn finish(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles || particle[i].inv_mass == 0.0) {
        return;
    }
    let xi = x[i];
    var d = delta[i];
    if (contacts.enabled != 0u) {
        d = d + pc_push[i];
    }
    for (var k = tether_start[i]; k < tether_start[i + 1u]; k = k + 1u) {
        let t = tethers[k];
        d = d + tether_correction((xi - x[t.pin]) + (d - target_delta[t.pin]), t.rest);
    }
    for (var c = 0u; COLLIDERS && c < params.colliders; c = c + 1u) {
        d = collider_resolve(colliders[params.collider_base + c], xi, d, particle[i].contact_radius);
    }
    for (var s = 0u; SHELLS && s < contacts.shells; s = s + 1u) {
        // With collision passes, list the shell particles near i for the next ones.
        let list = select(NO_LIST, (s * params.particles + i) * NEARBY, contacts.nearby != 0u);
        d = shell_resolve(s, params.range_start, xi, d, particle[i].contact_radius, list);
    }
    x[i] = xi + d;
    velocity[i] = d * params.inv_step;
    if (params.predict_next != 0u) {
        let t = (velocity[i] * params.keep + params.gravity_step) * params.step;
        delta[i] = t;
        target_delta[i] = t;
    } else {
        delta[i] = vec4<f32>(0.0);
    }
}

// A collision pass inside the solve (Stages::contact_pass on the CPU): collisions and friction on
// Δ as `finish` does them, each shell tested against the particle's nearby list only.
@compute @workgroup_size(64)
fn contact_pass(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles || particle[i].inv_mass == 0.0) {
        return;
    }
    let xi = x[i];
    var d = delta[i];
    let radius = particle[i].contact_radius;
    for (var c = 0u; COLLIDERS && c < params.colliders; c = c + 1u) {
        d = collider_resolve(colliders[params.collider_base + c], xi, d, radius);
    }
    for (var s = 0u; SHELLS && s < contacts.shells; s = s + 1u) {
        d = shell_resolve_nearby(s, params.range_start, xi, d, radius, (s * params.particles + i) * NEARBY);
    }
    delta[i] = d;
}

// Without time integration (scene E): positions take the displacement, nothing else moves.
@compute @workgroup_size(64)
fn finish_static(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles) {
        return;
    }
    x[i] = x[i] + delta[i];
    delta[i] = vec4<f32>(0.0);
}

// Attached particles to where their targets are at the end of the coming substep, with the
// velocity that took them there (Simulation::place_attachments on the CPU).
@compute @workgroup_size(64)
fn attach(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = params.range_start + id.x;
    if (k >= params.range_end) {
        return;
    }
    let p = attach_particle[id.x];
    let goal = attach_target[k];
    velocity[p] = (goal - x[p]) * params.inv_step;
    x[p] = goal;
}
