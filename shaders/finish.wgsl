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

// A particle the shells push deeper into a collider than this share of its contact radius is
// pressed between the skin and the collider (INTO_COLLIDER in src/collide/mod.rs): the collider
// keeps it as far from its surface as its own push left it, and along the surface the skin
// carries it by friction.
const INTO_COLLIDER: f32 = 0.05;

// The deepest any collider holds p within radius of its surface (w: radius less the distance;
// -1e30 without colliders), with that collider's normal in xyz (the first one's on a tie), as
// collide::deepest.
fn deepest(p: vec3<f32>, radius: f32) -> vec4<f32> {
    var best = vec4<f32>(0.0, 1.0, 0.0, -1e30);
    for (var c = 0u; c < params.colliders; c = c + 1u) {
        let hit = collider_distance(colliders[params.collider_base + c], p);
        if (radius - hit.w > best.w) {
            best = vec4<f32>(hit.xyz, radius - hit.w);
        }
    }
    return best;
}

// collide::pressed_into: the shells moved the particle from `before` to `after`, deeper into a
// collider than INTO_COLLIDER of its contact radius; that collider's normal in xyz, w = 1 (w = 0
// when not).
fn pressed_into(xi: vec4<f32>, before: vec4<f32>, after: vec4<f32>, radius: f32) -> vec4<f32> {
    let allowed = INTO_COLLIDER * radius;
    let moved = after - before;
    if (params.colliders == 0u || dot(moved, moved) <= allowed * allowed) {
        return vec4<f32>(0.0);
    }
    let now = deepest((xi + after).xyz, radius);
    let was = deepest((xi + before).xyz, radius);
    if (now.w > max(was.w, 0.0) + allowed) {
        return vec4<f32>(now.xyz, 1.0);
    }
    return vec4<f32>(0.0);
}

// The displacement of a particle pressed between a shell and a collider of normal n, from
// `before` (Stages::pressed with collide::pressed_motion): carried along the surface by the
// first shell that presses it there, as far as friction on the squeeze holds it.
fn pressed(xi: vec4<f32>, before: vec4<f32>, radius: f32, n: vec3<f32>) -> vec4<f32> {
    let p = (xi + before).xyz;
    for (var s = 0u; s < contacts.shells; s = s + 1u) {
        let skin = shell_pressing(s, params.range_start, p, radius);
        if (skin.w >= 0.0) {
            let friction = shell_at(s, params.range_start).info.friction;
            let relative = before.xyz - skin.xyz;
            return before - vec4<f32>(friction_removed(relative, n, friction * skin.w), 0.0);
        }
    }
    return before;
}

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
    let by_colliders = d;
    for (var s = 0u; SHELLS && s < contacts.shells; s = s + 1u) {
        // With collision passes, list the shell particles near i for the next ones.
        let list = select(NO_LIST, (s * params.particles + i) * NEARBY, contacts.nearby != 0u);
        d = shell_resolve(s, params.range_start, xi, d, particle[i].contact_radius, list);
    }
    if (COLLIDERS && SHELLS && contacts.shells > 0u) {
        let into = pressed_into(xi, by_colliders, d, particle[i].contact_radius);
        if (into.w > 0.0) {
            d = pressed(xi, by_colliders, particle[i].contact_radius, into.xyz);
        }
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
