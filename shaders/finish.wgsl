// Stages 3 to 5 for each free particle: long-range attachments to the pins, collisions with
// friction, then x += Δ and v = Δ/h, and (when another substep follows) its prediction.

fn tether_correction(offset: vec4<f32>, rest: f32) -> vec4<f32> {
    let len2 = dot(offset, offset);
    if (len2 > rest * rest) {
        return offset * (rest / sqrt(len2) - 1.0);
    }
    return vec4<f32>(0.0);
}

// Signed distance to a collider's surface (xyz: outward normal, w: distance).
fn collider_distance(c: Collider, p: vec3<f32>) -> vec4<f32> {
    if (c.kind == 0u) {
        return vec4<f32>(c.vector.xyz, dot(c.vector.xyz, p) - c.offset);
    }
    let d = p - c.vector.xyz;
    let len = length(d);
    var n = vec3<f32>(0.0, 1.0, 0.0);
    if (len > TINY_LENGTH) {
        n = d / len;
    }
    return vec4<f32>(n, len - c.radius);
}

// Push out to `radius` from the surface and apply Coulomb friction to the step's motion.
fn collider_resolve(c: Collider, xi: vec4<f32>, d: vec4<f32>, radius: f32) -> vec4<f32> {
    let hit = collider_distance(c, (xi + d).xyz);
    let push = radius - hit.w;
    if (push <= 0.0) {
        return d;
    }
    let n = hit.xyz;
    var motion = d.xyz + n * push;
    let tangent = motion - n * dot(motion, n);
    let t_len = length(tangent);
    let limit = c.friction * push;
    if (t_len <= limit) {
        motion = motion - tangent;
    } else {
        motion = motion - tangent * (limit / t_len);
    }
    return vec4<f32>(motion, 0.0);
}

@compute @workgroup_size(64)
fn finish(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles || particle[i].inv_mass == 0.0) {
        return;
    }
    let xi = x[i];
    var d = delta[i];
    for (var k = tether_start[i]; k < tether_start[i + 1u]; k = k + 1u) {
        let t = tethers[k];
        d = d + tether_correction((xi - x[t.pin]) + (d - target_delta[t.pin]), t.rest);
    }
    for (var c = 0u; c < params.colliders; c = c + 1u) {
        d = collider_resolve(colliders[c], xi, d, particle[i].contact_radius);
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
