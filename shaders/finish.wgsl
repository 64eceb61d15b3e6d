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
        d = collider_resolve(colliders[params.collider_base + c], xi, d, particle[i].contact_radius);
    }
    for (var s = 0u; s < contacts.shells; s = s + 1u) {
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
    for (var c = 0u; c < params.colliders; c = c + 1u) {
        d = collider_resolve(colliders[params.collider_base + c], xi, d, radius);
    }
    for (var s = 0u; s < contacts.shells; s = s + 1u) {
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

// ---- Characters' shells: ShellCollider::resolve on the CPU, step for step. ----

const SHELL_FOUND: u32 = 512u;
// Length of a nearby list (shell::NEARBY), an empty entry, and "keep no list".
const NEARBY: u32 = 16u;
const NO_ENTRY: u32 = 0xffffffffu;
const NO_LIST: u32 = 0xffffffffu;

fn shell_bucket(c: vec3<i32>, table: u32) -> u32 {
    let h = (c.x * 73856093) ^ (c.y * 19349663) ^ (c.z * 83492791);
    return bitcast<u32>(h) & (table - 1u);
}

// Where substep `substep`'s data of shell `sh` starts: particles, grid.
struct ShellAt {
    info: ShellInfo,
    particles: u32,
    grid: u32,
}

fn shell_at(s: u32, substep: u32) -> ShellAt {
    let info = shell_info[s];
    return ShellAt(
        info,
        substep * contacts.shell_stride + info.first,
        substep * contacts.grid_stride + info.grid,
    );
}

struct FirstHit {
    t: f32,
    j: u32,
    found: bool,
}

// First-contact test of one candidate (ShellCollider::first_contact).
fn shell_first_visit(at: ShellAt, j: u32, x: vec3<f32>, d: vec3<f32>, reach: f32, best: ptr<function, FirstHit>) {
    let q = shell_particle[at.particles + j];
    let n = q.normal.xyz;
    let end = q.position.xyz;
    let r0 = x - (end - q.motion.xyz);
    let r1 = x + d - end;
    let h0 = dot(r0, n);
    let h1 = dot(r1, n);
    if (h0 < 0.0 || h1 >= 0.0 || dot(r1, r1) < reach * reach) {
        return;
    }
    let t = h0 / (h0 - h1);
    let crossing = r0 + (r1 - r0) * t;
    if (dot(crossing, crossing) >= reach * reach) {
        return;
    }
    if (!(*best).found || t < (*best).t) {
        *best = FirstHit(t, j, true);
    }
}

struct PushOut {
    p: vec3<f32>,
    total: vec3<f32>,
    skin: vec3<f32>,
    contacts: u32,
    // The nearest candidates within two reaches, sorted by squared distance (when listing).
    listing: bool,
    listed: u32,
    near: array<u32, 16>,
    far: array<f32, 16>,
}

fn push_out_at(p: vec3<f32>, listing: bool) -> PushOut {
    var acc: PushOut;
    acc.p = p;
    acc.total = vec3<f32>(0.0);
    acc.skin = vec3<f32>(0.0);
    acc.contacts = 0u;
    acc.listing = listing;
    acc.listed = 0u;
    return acc;
}

// Writes the list kept while pushing out to `shell_nearby` at `at_list` (NO_ENTRY past its end).
fn write_nearby(acc: PushOut, at_list: u32) {
    if (!acc.listing) {
        return;
    }
    for (var k = 0u; k < NEARBY; k++) {
        shell_nearby[at_list + k] = select(NO_ENTRY, acc.near[k], k < acc.listed);
    }
}

// Push-out from one candidate (ShellCollider::push_out).
fn shell_push_visit(at: ShellAt, j: u32, reach: f32, acc: ptr<function, PushOut>) {
    let q = shell_particle[at.particles + j];
    let d = (*acc).p - q.position.xyz;
    let dist2 = dot(d, d);
    if ((*acc).listing && dist2 < 4.0 * reach * reach
        && ((*acc).listed < NEARBY || dist2 < (*acc).far[NEARBY - 1u])) {
        var k = min((*acc).listed, NEARBY - 1u);
        while (k > 0u && (*acc).far[k - 1u] > dist2) {
            (*acc).far[k] = (*acc).far[k - 1u];
            (*acc).near[k] = (*acc).near[k - 1u];
            k = k - 1u;
        }
        (*acc).far[k] = dist2;
        (*acc).near[k] = j;
        (*acc).listed = min((*acc).listed + 1u, NEARBY);
    }
    if (dist2 >= reach * reach) {
        return;
    }
    var push: vec3<f32>;
    let normal = q.normal.xyz;
    if ((at.info.flags & 2u) != 0u && dot(d, normal) < 0.0) {
        let along = d - normal * dot(d, normal);
        let height = sqrt(max(reach * reach - dot(along, along), 0.0));
        push = normal * (height - dot(d, normal));
    } else {
        let dist = sqrt(dist2);
        var n = vec3<f32>(0.0, 1.0, 0.0);
        if (dist > 1e-9) {
            n = d / dist;
        }
        push = n * (reach - dist);
    }
    (*acc).p = (*acc).p + push;
    (*acc).total = (*acc).total + push;
    (*acc).skin = (*acc).skin + q.motion.xyz;
    (*acc).contacts = (*acc).contacts + 1u;
}

fn shell_items(at: ShellAt, b: u32) -> vec2<u32> {
    let items = at.grid + at.info.table + 1u;
    return vec2<u32>(items + shell_grid[at.grid + b], items + shell_grid[at.grid + b + 1u]);
}

// Push-out over the 27 cells around `p` (HashGrid::near: each bucket once).
fn shell_push_near(at: ShellAt, reach: f32, acc: ptr<function, PushOut>) {
    let c = vec3<i32>(floor((*acc).p / at.info.cell));
    var seen: array<u32, 27>;
    var n = 0u;
    for (var dx = -1; dx <= 1; dx++) {
        for (var dy = -1; dy <= 1; dy++) {
            for (var dz = -1; dz <= 1; dz++) {
                let b = shell_bucket(c + vec3<i32>(dx, dy, dz), at.info.table);
                var again = false;
                for (var k = 0u; k < n; k++) {
                    again = again || seen[k] == b;
                }
                if (again) {
                    continue;
                }
                seen[n] = b;
                n = n + 1u;
                let range = shell_items(at, b);
                for (var k = range.x; k < range.y; k++) {
                    shell_push_visit(at, shell_grid[k], reach, acc);
                }
            }
        }
    }
}

// Friction on the motion relative to the skin (as the CPU), the corrected displacement.
fn shell_finish(at: ShellAt, x3: vec3<f32>, acc: PushOut) -> vec4<f32> {
    var p = acc.p;
    if (acc.contacts == 0u) {
        return vec4<f32>(p - x3, 0.0);
    }
    let push_len = length(acc.total);
    var n = vec3<f32>(0.0, 1.0, 0.0);
    if (push_len > 1e-12) {
        n = acc.total / push_len;
    }
    let skin = acc.skin / f32(acc.contacts);
    let relative = (p - x3) - skin;
    let tangent = relative - n * dot(relative, n);
    let t_len = length(tangent);
    let limit = at.info.friction * push_len;
    if (t_len <= limit) {
        p = p - tangent;
    } else {
        p = p - tangent * (limit / t_len);
    }
    return vec4<f32>(p - x3, 0.0);
}

// A garment particle against shell `s` at substep `substep` (ShellCollider::resolve); lists its
// nearby shell particles at `list` unless that is NO_LIST.
fn shell_resolve(s: u32, substep: u32, x: vec4<f32>, delta: vec4<f32>, radius: f32, list: u32) -> vec4<f32> {
    let at = shell_at(s, substep);
    if (at.info.count == 0u) {
        return delta;
    }
    let reach = at.info.radius + radius;
    let x3 = x.xyz;
    let d = delta.xyz;
    var p = x3 + d;
    if ((at.info.flags & 3u) == 3u && length(d) <= 64.0 * at.info.cell) {
        // The cells around the path (HashGrid::near_segment), gathered once for both tests.
        var found: array<u32, 512>;
        var count = 0u;
        let lo = vec3<i32>(floor(min(x3, p) / at.info.cell)) - vec3<i32>(1);
        let hi = vec3<i32>(floor(max(x3, p) / at.info.cell)) + vec3<i32>(1);
        for (var cx = lo.x; cx <= hi.x; cx++) {
            for (var cy = lo.y; cy <= hi.y; cy++) {
                for (var cz = lo.z; cz <= hi.z; cz++) {
                    let range = shell_items(at, shell_bucket(vec3<i32>(cx, cy, cz), at.info.table));
                    for (var k = range.x; k < range.y; k++) {
                        if (count < SHELL_FOUND) {
                            found[count] = shell_grid[k];
                        }
                        count = count + 1u;
                    }
                }
            }
        }
        if (count <= SHELL_FOUND) {
            var best = FirstHit(0.0, 0u, false);
            for (var k = 0u; k < count; k++) {
                shell_first_visit(at, found[k], x3, d, reach, &best);
            }
            if (best.found) {
                p = x3 + d * best.t + shell_particle[at.particles + best.j].motion.xyz * (1.0 - best.t);
            }
            var acc = push_out_at(p, list != NO_LIST);
            for (var k = 0u; k < count; k++) {
                shell_push_visit(at, found[k], reach, &acc);
            }
            write_nearby(acc, list);
            return shell_finish(at, x3, acc);
        }
        // Too many candidates to keep: trace with a second walk over the same cells.
        var best = FirstHit(0.0, 0u, false);
        for (var cx = lo.x; cx <= hi.x; cx++) {
            for (var cy = lo.y; cy <= hi.y; cy++) {
                for (var cz = lo.z; cz <= hi.z; cz++) {
                    let range = shell_items(at, shell_bucket(vec3<i32>(cx, cy, cz), at.info.table));
                    for (var k = range.x; k < range.y; k++) {
                        shell_first_visit(at, shell_grid[k], x3, d, reach, &best);
                    }
                }
            }
        }
        if (best.found) {
            p = x3 + d * best.t + shell_particle[at.particles + best.j].motion.xyz * (1.0 - best.t);
        }
    }
    var acc = push_out_at(p, list != NO_LIST);
    shell_push_near(at, reach, &acc);
    write_nearby(acc, list);
    return shell_finish(at, x3, acc);
}

// A collision pass's test of a garment particle against shell `s`'s particles listed at `list`
// (ShellCollider::resolve_nearby): end point only, no listing.
fn shell_resolve_nearby(s: u32, substep: u32, x: vec4<f32>, delta: vec4<f32>, radius: f32, list: u32) -> vec4<f32> {
    if (shell_nearby[list] == NO_ENTRY) {
        return delta;
    }
    let at = shell_at(s, substep);
    let reach = at.info.radius + radius;
    var acc = push_out_at(x.xyz + delta.xyz, false);
    for (var k = 0u; k < NEARBY; k++) {
        let j = shell_nearby[list + k];
        if (j == NO_ENTRY) {
            break;
        }
        shell_push_visit(at, j, reach, &acc);
    }
    return shell_finish(at, x.xyz, acc);
}
