// Stages 3 to 5 for each free particle: long-range attachments to the pins, collisions with
// friction, then x += Δ and v = Δ/h, and (when another substep follows) its prediction.

fn tether_correction(offset: vec4<f32>, rest: f32) -> vec4<f32> {
    let len2 = dot(offset, offset);
    if (len2 > rest * rest) {
        return offset * (rest / sqrt(len2) - 1.0);
    }
    return vec4<f32>(0.0);
}

// Distance from a ball of `radius` at the origin to `d` (xyz: outward normal, w: distance).
fn ball_distance(d: vec3<f32>, radius: f32) -> vec4<f32> {
    let len = length(d);
    var n = vec3<f32>(0.0, 1.0, 0.0);
    if (len > TINY_LENGTH) {
        n = d / len;
    }
    return vec4<f32>(n, len - radius);
}

// Signed distance from an axis-aligned box of half extents `half` at the origin to `p`.
fn box_distance(p: vec3<f32>, half: vec3<f32>) -> vec4<f32> {
    let q = abs(p) - half;
    let outside = max(q, vec3<f32>(0.0));
    let out_len = length(outside);
    if (out_len > 0.0) {
        return vec4<f32>(outside * sign(p) / out_len, out_len);
    }
    var n = vec3<f32>(0.0);
    var axis = 2u;
    if (q.x >= q.y && q.x >= q.z) {
        axis = 0u;
    } else if (q.y >= q.z) {
        axis = 1u;
    }
    n[axis] = select(-1.0, 1.0, p[axis] >= 0.0);
    return vec4<f32>(n, q[axis]);
}

// Signed distance to a collider's surface (xyz: outward normal, w: distance).
fn collider_distance(c: Collider, p: vec3<f32>) -> vec4<f32> {
    switch c.kind {
        case 0u: {
            return vec4<f32>(c.vector.xyz, dot(c.vector.xyz, p) - c.offset);
        }
        case 2u: {
            return box_distance(p - c.vector.xyz, c.second.xyz);
        }
        case 3u: {
            let axis = c.second.xyz - c.vector.xyz;
            let t = clamp(dot(p - c.vector.xyz, axis) / max(dot(axis, axis), 1e-12), 0.0, 1.0);
            return ball_distance(p - (c.vector.xyz + axis * t), c.radius);
        }
        default: {
            return ball_distance(p - c.vector.xyz, c.radius);
        }
    }
}

// The fraction of the step at which a particle leaving `x` (outside) by `d` first comes within
// `radius` of a static collider, when its end point has passed back out; 2 when it does not
// (sphere tracing along the path, as Collider::first_contact on the CPU).
fn first_contact(c: Collider, x: vec3<f32>, d: vec3<f32>, radius: f32) -> f32 {
    let length = length(d);
    let begin = collider_distance(c, x);
    let start = begin.w - radius;
    if (start >= length || length < 1e-9) {
        return 2.0;
    }
    let end = collider_distance(c, x + d);
    if (end.w < radius) {
        return 2.0;
    }
    if (start <= 0.0) {
        // Touching at the start, clear at the end: through the solid if the surface faces the
        // other way there.
        return select(2.0, 0.0, dot(begin.xyz, end.xyz) < 0.0);
    }
    // March to where the path first comes within `radius`, then on to see whether it enters the
    // solid itself (grazing the contact layer is left to the end-point test).
    var s = 0.0;
    var touch = 2.0;
    for (var k = 0; k < 64; k++) {
        let dist = collider_distance(c, x + d * s).w;
        if (touch > 1.0 && dist - radius <= 1e-6) {
            touch = s;
        } else if (touch <= 1.0 && dist <= 0.0) {
            return touch;
        }
        var gap = dist;
        if (touch > 1.0) {
            gap = dist - radius;
        }
        s = s + max(gap, 1e-4 * radius) / length;
        if (s >= 1.0) {
            return 2.0;
        }
    }
    return 2.0;
}

// Push out to `radius` from the surface and apply Coulomb friction to the step's motion; with
// the swept test on, stop first where the path touches the surface.
fn collider_resolve(c: Collider, xi: vec4<f32>, d_in: vec4<f32>, radius: f32) -> vec4<f32> {
    var d = d_in;
    if (c.second.w > 0.5) {
        let s = first_contact(c, xi.xyz, d.xyz, radius);
        if (s <= 1.0) {
            d = vec4<f32>(d.xyz * s, 0.0);
        }
    }
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
    if (contacts.enabled != 0u) {
        d = d + pc_push[i];
    }
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
