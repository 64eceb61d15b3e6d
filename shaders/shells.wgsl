// Characters' shells on the GPU, mirroring `src/collide/shell/` step for step
// (ShellCollider::resolve, push_out, first_contact and the nearby lists of collision passes).
// Included before `finish.wgsl` (see `gpu::kernels::source`).

const SHELL_FOUND: u32 = 512u;
// The longest path a swept test traces, in grid cells (shell::SWEPT_PATH_CELLS).
const SWEPT_PATH_CELLS: f32 = 64.0;
// Length of a nearby list (shell::NEARBY), an empty entry, and "keep no list".
const NEARBY: u32 = 16u;
const NO_ENTRY: u32 = 0xffffffffu;
const NO_LIST: u32 = 0xffffffffu;
// Two pushes whose sides of the skin have a cosine below this pinch the particle (PINCH in
// src/collide/shell/contact.rs).
const PINCH: f32 = -0.5;
// ShellInfo.flags bits (gpu::layout::shell_flags).
const SHELL_SWEPT: u32 = 1u;
const SHELL_NORMALS: u32 = 2u;
const SHELL_STATIC: u32 = 4u;

fn shell_bucket(c: vec3<i32>, table: u32) -> u32 {
    return hash_cell(c) & (table - 1u);
}

// Where substep `substep`'s data of shell `sh` starts: particles, grid (a shell that never
// moves has its data in substep 0's share only).
struct ShellAt {
    info: ShellInfo,
    particles: u32,
    grid: u32,
}

fn shell_at(s: u32, substep: u32) -> ShellAt {
    let info = shell_info[s];
    let k = select(substep, 0u, (info.flags & SHELL_STATIC) != 0u);
    return ShellAt(
        info,
        k * contacts.shell_stride + info.first,
        k * contacts.grid_stride + info.grid,
    );
}

struct FirstHit {
    t: f32,
    off: f32,
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
    // Ties: nearest the particle's centre, then the lowest index (as the CPU).
    let off = dot(crossing, crossing);
    let b = *best;
    if (!b.found || t < b.t || (t == b.t && (off < b.off || (off == b.off && j < b.j)))) {
        *best = FirstHit(t, off, j, true);
    }
}

struct PushOut {
    p: vec3<f32>,
    total: vec3<f32>,
    skin: vec3<f32>,
    contacts: u32,
    // The first push's side of the skin, whether a later one opposed it, where the particle
    // was before the pushes and the pushes' lengths summed (Contact on the CPU).
    first: vec3<f32>,
    pinched: bool,
    start: vec3<f32>,
    pressed: f32,
    // The nearest candidates within two reaches of where the gathering looked, sorted by
    // squared distance, then index (Nearest in src/collide/shell/contact.rs).
    listed: u32,
    near: array<u32, 16>,
    far: array<f32, 16>,
}

fn push_out_at(p: vec3<f32>) -> PushOut {
    var acc: PushOut;
    acc.p = p;
    acc.total = vec3<f32>(0.0);
    acc.skin = vec3<f32>(0.0);
    acc.contacts = 0u;
    acc.first = vec3<f32>(0.0);
    acc.pinched = false;
    acc.start = p;
    acc.pressed = 0.0;
    acc.listed = 0u;
    return acc;
}

// Writes the gathered list to `shell_nearby` at `at_list` (NO_ENTRY past its end), unless
// that is NO_LIST.
fn write_nearby(acc: PushOut, at_list: u32) {
    if (at_list == NO_LIST) {
        return;
    }
    for (var k = 0u; k < NEARBY; k++) {
        shell_nearby[at_list + k] = select(NO_ENTRY, acc.near[k], k < acc.listed);
    }
}

// (d2, j) before entry k of the list.
fn shell_before(acc: ptr<function, PushOut>, k: u32, d2: f32, j: u32) -> bool {
    let f = (*acc).far[k];
    return d2 < f || (d2 == f && j < (*acc).near[k]);
}

// Gathering: candidate j into the sorted list when within two reaches of `p` (Nearest::insert).
fn shell_gather_visit(at: ShellAt, j: u32, p: vec3<f32>, reach: f32, acc: ptr<function, PushOut>) {
    let d = p - shell_particle[at.particles + j].position.xyz;
    let dist2 = dot(d, d);
    if (dist2 >= 4.0 * reach * reach) {
        return;
    }
    if ((*acc).listed == NEARBY && !shell_before(acc, NEARBY - 1u, dist2, j)) {
        return;
    }
    var k = (*acc).listed;
    while (k > 0u && shell_before(acc, k - 1u, dist2, j)) {
        k = k - 1u;
    }
    if (k > 0u && (*acc).near[k - 1u] == j) {
        return;
    }
    var m = min((*acc).listed, NEARBY - 1u);
    while (m > k) {
        (*acc).far[m] = (*acc).far[m - 1u];
        (*acc).near[m] = (*acc).near[m - 1u];
        m = m - 1u;
    }
    (*acc).far[k] = dist2;
    (*acc).near[k] = j;
    (*acc).listed = min((*acc).listed + 1u, NEARBY);
}

// Push-out from one candidate (ShellCollider::push_from).
fn shell_push_visit(at: ShellAt, j: u32, reach: f32, acc: ptr<function, PushOut>) {
    let q = shell_particle[at.particles + j];
    let d = (*acc).p - q.position.xyz;
    let dist2 = dot(d, d);
    if (dist2 >= reach * reach) {
        return;
    }
    var push: vec3<f32>;
    let normal = q.normal.xyz;
    if ((at.info.flags & SHELL_NORMALS) != 0u && dot(d, normal) < 0.0) {
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
    // The side of the skin the push comes from (Contact::add): the skin's unit normal, or the
    // push's direction on a shell without normals.
    var side = normal;
    if ((at.info.flags & SHELL_NORMALS) == 0u) {
        let push_len = length(push);
        side = select(vec3<f32>(0.0), push * (1.0 / push_len), push_len > 1e-30);
    }
    if (any(side != vec3<f32>(0.0))) {
        if (all((*acc).first == vec3<f32>(0.0))) {
            (*acc).first = side;
        } else if (dot(side, (*acc).first) < PINCH) {
            (*acc).pinched = true;
        }
    }
    (*acc).p = (*acc).p + push;
    (*acc).total = (*acc).total + push;
    (*acc).pressed = (*acc).pressed + length(push);
    (*acc).skin = (*acc).skin + q.motion.xyz;
    (*acc).contacts = (*acc).contacts + 1u;
}

// Pushes out of the gathered list, nearest first.
fn shell_push_listed(at: ShellAt, reach: f32, acc: ptr<function, PushOut>) {
    if ((*acc).listed == 0u || (*acc).far[0] >= reach * reach) {
        return; // in reach of none
    }
    for (var k = 0u; k < (*acc).listed; k++) {
        shell_push_visit(at, (*acc).near[k], reach, acc);
    }
}

// A second round is due (ShellCollider::push_out): the list is full and the pushes moved the
// particle near candidates past its end; the list is cleared for it.
fn shell_again(acc: ptr<function, PushOut>, start: vec3<f32>, reach: f32) -> bool {
    let moved = distance((*acc).p, start);
    let again = (*acc).listed == NEARBY && (*acc).far[NEARBY - 1u] < (reach + moved) * (reach + moved);
    if (again) {
        (*acc).listed = 0u;
    }
    return again;
}

fn shell_items(at: ShellAt, b: u32) -> vec2<u32> {
    let items = at.grid + at.info.table + 1u;
    return vec2<u32>(items + shell_grid[at.grid + b], items + shell_grid[at.grid + b + 1u]);
}

// Gathering over the 27 cells around `centre` (HashGrid::near: each bucket once), from `p`.
fn shell_gather_near(at: ShellAt, centre: vec3<f32>, p: vec3<f32>, reach: f32, acc: ptr<function, PushOut>) {
    let c = vec3<i32>(floor(centre / at.info.cell));
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
                    shell_gather_visit(at, shell_grid[k], p, reach, acc);
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
    if (acc.pinched) {
        // Held across the gap, slipping along it past friction on the squeeze (the CPU's).
        let n = acc.first;
        let wanted = (acc.start - x3) - skin;
        let along = wanted - n * dot(wanted, n);
        let squeeze = acc.pressed / f32(acc.contacts);
        let held = friction_removed(along, n, at.info.friction * squeeze);
        return vec4<f32>(skin + along - held, 0.0);
    }
    let relative = (p - x3) - skin;
    p = p - friction_removed(relative, n, at.info.friction * push_len);
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
    if ((at.info.flags & (SHELL_SWEPT | SHELL_NORMALS)) == (SHELL_SWEPT | SHELL_NORMALS) && length(d) <= SWEPT_PATH_CELLS * at.info.cell) {
        // The cells around the path (HashGrid::near_segment), gathered once for both tests.
        var found: array<u32, SHELL_FOUND>;
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
            var best = FirstHit(0.0, 0.0, 0u, false);
            for (var k = 0u; k < count; k++) {
                shell_first_visit(at, found[k], x3, d, reach, &best);
            }
            if (best.found) {
                p = x3 + d * best.t + shell_particle[at.particles + best.j].motion.xyz * (1.0 - best.t);
            }
            var acc = push_out_at(p);
            for (var k = 0u; k < count; k++) {
                shell_gather_visit(at, found[k], p, reach, &acc);
            }
            write_nearby(acc, list);
            shell_push_listed(at, reach, &acc);
            if (shell_again(&acc, p, reach)) {
                let q = acc.p;
                for (var k = 0u; k < count; k++) {
                    shell_gather_visit(at, found[k], q, reach, &acc);
                }
                shell_push_listed(at, reach, &acc);
            }
            return shell_finish(at, x3, acc);
        }
        // Too many candidates to keep: trace with a second walk over the same cells.
        var best = FirstHit(0.0, 0.0, 0u, false);
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
    var acc = push_out_at(p);
    shell_gather_near(at, p, p, reach, &acc);
    write_nearby(acc, list);
    shell_push_listed(at, reach, &acc);
    if (shell_again(&acc, p, reach)) {
        shell_gather_near(at, p, acc.p, reach, &acc);
        shell_push_listed(at, reach, &acc);
    }
    return shell_finish(at, x3, acc);
}

// How shell `s` presses a garment particle at `p` of contact `radius` (ShellCollider::pressing):
// the mean motion of the shell particles it lies within reach of, nearest first, in xyz, and
// their mean overlap in w; w = -1 when it lies within reach of none.
fn shell_pressing(s: u32, substep: u32, p: vec3<f32>, radius: f32) -> vec4<f32> {
    let at = shell_at(s, substep);
    if (at.info.count == 0u) {
        return vec4<f32>(0.0, 0.0, 0.0, -1.0);
    }
    let reach = at.info.radius + radius;
    var acc = push_out_at(p);
    shell_gather_near(at, p, p, reach, &acc);
    var motion = vec3<f32>(0.0);
    var overlap = 0.0;
    var count = 0u;
    for (var k = 0u; k < acc.listed; k++) {
        let q = shell_particle[at.particles + acc.near[k]];
        let distance = length(p - q.position.xyz);
        if (distance < reach) {
            motion = motion + q.motion.xyz;
            overlap = overlap + (reach - distance);
            count = count + 1u;
        }
    }
    if (count == 0u) {
        return vec4<f32>(0.0, 0.0, 0.0, -1.0);
    }
    return vec4<f32>(motion / f32(count), overlap / f32(count));
}

// A collision pass's test of a garment particle against shell `s`'s particles listed at `list`
// (ShellCollider::resolve_nearby): end point only, no listing.
fn shell_resolve_nearby(s: u32, substep: u32, x: vec4<f32>, delta: vec4<f32>, radius: f32, list: u32) -> vec4<f32> {
    if (shell_nearby[list] == NO_ENTRY) {
        return delta;
    }
    let at = shell_at(s, substep);
    let reach = at.info.radius + radius;
    var acc = push_out_at(x.xyz + delta.xyz);
    for (var k = 0u; k < NEARBY; k++) {
        let j = shell_nearby[list + k];
        if (j == NO_ENTRY) {
            break;
        }
        shell_push_visit(at, j, reach, &acc);
    }
    return shell_finish(at, x.xyz, acc);
}
