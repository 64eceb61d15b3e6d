// Analytic colliders on the GPU, mirroring `src/collide/mod.rs` function for function: signed
// distances of each shape, the swept first-contact test, and the push-out with Coulomb friction.
// Included before `finish.wgsl` (see `gpu::kernels::source`).

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

// Closest point to `q` on the segment `a`–`b` (2-D).
fn closest_on_segment(q: vec2<f32>, a: vec2<f32>, b: vec2<f32>) -> vec2<f32> {
    let ab = b - a;
    let t = clamp(dot(q - a, ab) / max(dot(ab, ab), 1e-12), 0.0, 1.0);
    return a + ab * t;
}

// Signed distance from an upright funnel wall at the origin (as funnel_distance on the CPU).
fn funnel_distance(p: vec3<f32>, radius: f32, top_radius: f32, height: f32, half_t: f32) -> vec4<f32> {
    let r = sqrt(p.x * p.x + p.z * p.z);
    var radial = vec3<f32>(1.0, 0.0, 0.0);
    if (r > 1e-9) {
        radial = vec3<f32>(p.x / r, 0.0, p.z / r);
    }
    let a = vec2<f32>(radius, 0.0);
    let b = vec2<f32>(top_radius, height);
    let q = vec2<f32>(r, p.y);
    let off = q - closest_on_segment(q, a, b);
    let len = length(off);
    var n2: vec2<f32>;
    if (len > 1e-9) {
        n2 = off / len;
    } else {
        let e = normalize(b - a);
        n2 = vec2<f32>(e.y, -e.x);
    }
    return vec4<f32>(radial * n2.x + vec3<f32>(0.0, 1.0, 0.0) * n2.y, len - half_t);
}

// Signed distance from a wedge of half extents `half` at the origin (as wedge_distance).
fn wedge_distance(p: vec3<f32>, half: vec3<f32>) -> vec4<f32> {
    var corners = array<vec2<f32>, 3>(
        vec2<f32>(0.0, -half.y),
        vec2<f32>(half.x, half.y),
        vec2<f32>(-half.x, half.y),
    );
    let q = p.xy;
    var best = 3.4e38;
    var c = vec2<f32>(0.0);
    var edge_normal = vec2<f32>(0.0, 1.0);
    var inside = true;
    for (var k = 0u; k < 3u; k = k + 1u) {
        let a = corners[k];
        let b = corners[(k + 1u) % 3u];
        let e = b - a;
        let outward = normalize(vec2<f32>(e.y, -e.x));
        inside = inside && dot(q - a, outward) <= 0.0;
        let cc = closest_on_segment(q, a, b);
        let d = dot(q - cc, q - cc);
        if (d < best) {
            best = d;
            c = cc;
            edge_normal = outward;
        }
    }
    let d2 = sqrt(best);
    var n2 = edge_normal;
    if (d2 > 1e-9) {
        n2 = select((q - c) / d2, (c - q) / d2, inside);
    }
    let flat = select(d2, -d2, inside);
    let along = abs(p.z) - half.z;
    let z = vec3<f32>(0.0, 0.0, select(-1.0, 1.0, p.z >= 0.0));
    if (flat <= 0.0 && along <= 0.0) {
        if (flat >= along) {
            return vec4<f32>(n2, 0.0, flat);
        }
        return vec4<f32>(z, along);
    }
    let u = max(flat, 0.0);
    let v = max(along, 0.0);
    let d = sqrt(u * u + v * v);
    return vec4<f32>((vec3<f32>(n2, 0.0) * u + z * v) / d, d);
}

// Signed distance to a collider's surface (xyz: outward normal, w: distance).
fn collider_distance(c: Collider, p: vec3<f32>) -> vec4<f32> {
    switch c.kind {
        case KIND_PLANE: {
            return vec4<f32>(c.vector.xyz, dot(c.vector.xyz, p) - c.offset);
        }
        case KIND_BOX: {
            let inverse = vec4<f32>(-c.rotation.xyz, c.rotation.w);
            let d = box_distance(quat_rotate(inverse, p - c.vector.xyz), c.second.xyz);
            return vec4<f32>(quat_rotate(c.rotation, d.xyz), d.w);
        }
        case KIND_FUNNEL: {
            return funnel_distance(p - c.vector.xyz, c.radius, c.offset, c.second.x, c.second.y);
        }
        case KIND_WEDGE: {
            let inverse = vec4<f32>(-c.rotation.xyz, c.rotation.w);
            let d = wedge_distance(quat_rotate(inverse, p - c.vector.xyz), c.second.xyz);
            return vec4<f32>(quat_rotate(c.rotation, d.xyz), d.w);
        }
        case KIND_CAPSULE: {
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
// `radius` of a collider, following its path relative to the collider, when its end point has
// passed back out; 2 when it does not (sphere tracing, as Collider::first_contact on the CPU).
fn first_contact(c: Collider, x: vec3<f32>, d: vec3<f32>, radius: f32) -> f32 {
    // Relative to the collider's pose at the end of the step: from x + moved to x + d.
    let moved = c.moved.xyz;
    let length = length(d - moved);
    let begin = collider_distance(c, x + moved);
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
        let dist = collider_distance(c, x + d * s + moved * (1.0 - s)).w;
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
            // Stop at the touching point of the path, carried along with the collider.
            d = vec4<f32>(d.xyz * s + c.moved.xyz * (1.0 - s), 0.0);
        }
    }
    let hit = collider_distance(c, (xi + d).xyz);
    let push = radius - hit.w;
    if (push <= 0.0) {
        return d;
    }
    let n = hit.xyz;
    let motion = d.xyz + n * push;
    return vec4<f32>(motion - friction_removed(motion, n, c.friction * push), 0.0);
}
