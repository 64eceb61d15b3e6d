// Driven motion on the GPU (src/gpu/drive.rs): before a frame's simulation pass, one dispatch
// evaluates every keyframed track at the end of every substep of the frame and writes where the
// keyframed attachments go and where the attachments that ride a character's skin go
// (`attach_target`, read by `attach`) and where the keyframed colliders are (`colliders`, read
// by `finish` and `contact_pass`), with the fastest of their motions for the stability rule:
// the arithmetic of `sim::attach::Track`, `sim::attach::Skin::surface` and
// `collide::Shape::moved` on the CPU. The CPU uploads the tracks and bindings once and, per
// frame, the substep it starts at, the skins' ridden vertices of the character frames the frame
// spans, and where each substep falls between them: no CPU work per substep beyond those few
// words. Compiled after common.wgsl (its Collider and quat_rotate); its own bindings are in
// group 3, where it writes buffers the other kernels read.

struct DriveFrame {
    first: u32,            // the frame's first substep, counted from the bake's start
    substeps: u32,         // substeps per frame
    attached: u32,         // attached particles (attach_target's stride per substep)
    keyed: u32,            // keyframed attachments (at the head of each substep's targets)
    colliders: u32,        // colliders (the colliders' stride per substep)
    moving: u32,           // keyframed colliders
    per_second: f32,       // substeps per second
    step: f32,             // h [s]
    riding: u32,           // attachments that ride skins (after the keyframed ones)
    skins: u32,            // skins they ride (ride_times' stride per substep)
    pad0: u32,
    pad1: u32,
}

// A rigid motion: its keys (`first`, `count` in `drive_keys`) about `pivot`.
struct Track {
    first: u32,
    count: u32,
    pad0: u32,
    pad1: u32,
    pivot: vec4<f32>,
}

// A key: translation (xyz) at time w [s], and the rotation there (unit quaternion x, y, z, w).
struct Key {
    translation: vec4<f32>,
    rotation: vec4<f32>,
}

// A keyframed attachment: the particle (storage index), its track, its rest position (xyz).
struct Keyed {
    particle: u32,
    track: u32,
    pad0: u32,
    pad1: u32,
    rest: vec4<f32>,
}

// A keyframed collider: its index among the colliders, its track, and its shape at rest.
struct Moving {
    index: u32,
    track: u32,
    pad0: u32,
    pad1: u32,
    rest: Collider,
}

// An attachment that rides a skin (`sim::attach::Riding`): its particle, its skin, its
// triangle's corners as indices into the skin's ridden vertices, the barycentric point (xyz)
// and the offset in the skin's frame there (xyz: tangent, bitangent, normal).
struct Riding {
    particle: u32,
    skin: u32,
    pad0: u32,
    pad1: u32,
    corners: vec4<u32>,
    bary: vec4<f32>,
    offset: vec4<f32>,
}

// A skin's place in `ride_window`: its first entry, and how many vertices it rides (each
// window slot holds that many, a position then a normal each).
struct RiddenSkin {
    window: u32,
    ridden: u32,
    pad0: u32,
    pad1: u32,
}

// Where the end of a substep falls in a skin's window: the slots of the character frames
// before and after it and the weight of the later (`Skin::span`).
struct RideTime {
    before: u32,
    after: u32,
    weight: f32,
    pad: u32,
}

@group(3) @binding(0) var<uniform> drive: DriveFrame;
@group(3) @binding(1) var<storage, read> drive_tracks: array<Track>;
@group(3) @binding(2) var<storage, read> drive_keys: array<Key>;
@group(3) @binding(3) var<storage, read> drive_keyed: array<Keyed>;
@group(3) @binding(4) var<storage, read> drive_moving: array<Moving>;
@group(3) @binding(5) var<storage, read> ride_bound: array<Riding>;
@group(3) @binding(6) var<storage, read> ride_skins: array<RiddenSkin>;
@group(3) @binding(7) var<storage, read> ride_times: array<RideTime>;
@group(3) @binding(8) var<storage, read> ride_window: array<vec4<f32>>;
@group(3) @binding(9) var<storage, read> drive_start: array<vec4<f32>>;
@group(3) @binding(10) var<storage, read_write> drive_targets: array<vec4<f32>>;
@group(3) @binding(11) var<storage, read_write> drive_posed: array<Collider>;
@group(3) @binding(12) var<storage, read_write> drive_speed: atomic<u32>;

// Hamilton product q·r of unit quaternions (glam's `Quat * Quat`).
fn quat_mul(q: vec4<f32>, r: vec4<f32>) -> vec4<f32> {
    return vec4<f32>(
        q.w * r.xyz + r.w * q.xyz + cross(q.xyz, r.xyz),
        q.w * r.w - dot(q.xyz, r.xyz),
    );
}

// acos(x) for x in [0, 1] as glam computes it for slerp (DirectXMath's 7-degree minimax
// polynomial), so both backends turn keyframed shapes alike.
fn acos_approx(x: f32) -> f32 {
    let p = ((((((-0.0012624911 * x + 0.00667009) * x - 0.017088126) * x + 0.03089188) * x
        - 0.050174303) * x + 0.08897899) * x - 0.2145988) * x + 1.5707963;
    return p * sqrt(max(1.0 - x, 0.0));
}

// Spherical interpolation from `a` to `b` by `s`, the short way round (glam's `Quat::slerp`).
fn quat_slerp(a: vec4<f32>, b_in: vec4<f32>, s: f32) -> vec4<f32> {
    var b = b_in;
    var d = dot(a, b);
    if (d < 0.0) {
        b = -b;
        d = -d;
    }
    if (d > 1.0 - 1.1920929e-7) {
        return normalize(a * (1.0 - s) + b * s);
    }
    let theta = acos_approx(d);
    return (a * sin(theta * (1.0 - s)) + b * sin(theta * s)) / sin(theta);
}

// The pose of track `t` at time `time`: (rotation, translation), held before its first key and
// after its last, linear between (`Track::pose`).
struct Pose {
    rotation: vec4<f32>,
    translation: vec3<f32>,
}

fn track_pose(t: u32, time: f32) -> Pose {
    let track = drive_tracks[t];
    // Keys at or before `time` (`partition_point`).
    var i = 0u;
    while (i < track.count && drive_keys[track.first + i].translation.w <= time) {
        i = i + 1u;
    }
    if (i == 0u) {
        let k = drive_keys[track.first];
        return Pose(k.rotation, k.translation.xyz);
    }
    if (i == track.count) {
        let k = drive_keys[track.first + i - 1u];
        return Pose(k.rotation, k.translation.xyz);
    }
    let a = drive_keys[track.first + i - 1u];
    let b = drive_keys[track.first + i];
    let w = (time - a.translation.w) / (b.translation.w - a.translation.w);
    let translation = a.translation.xyz * (1.0 - w) + b.translation.xyz * w;
    return Pose(quat_slerp(a.rotation, b.rotation, w), translation);
}

// Where pose `pose` of track `t` takes point `p` (`Track::apply`).
fn posed_point(t: u32, pose: Pose, p: vec3<f32>) -> vec3<f32> {
    let pivot = drive_tracks[t].pivot.xyz;
    return pivot + quat_rotate(pose.rotation, p - pivot) + pose.translation;
}

// Collider `rest` moved by pose `pose` of track `t` (`Shape::moved`).
fn posed_collider(rest: Collider, t: u32, pose: Pose) -> Collider {
    var c = rest;
    switch rest.kind {
        case KIND_PLANE: {
            let n = quat_rotate(pose.rotation, rest.vector.xyz);
            c.vector = vec4<f32>(n, 0.0);
            c.offset = dot(n, posed_point(t, pose, rest.vector.xyz * rest.offset));
        }
        case KIND_BOX, KIND_WEDGE: {
            c.vector = vec4<f32>(posed_point(t, pose, rest.vector.xyz), 0.0);
            c.rotation = quat_mul(pose.rotation, rest.rotation);
        }
        case KIND_CAPSULE: {
            c.vector = vec4<f32>(posed_point(t, pose, rest.vector.xyz), 0.0);
            c.second = vec4<f32>(posed_point(t, pose, rest.second.xyz), rest.second.w);
        }
        default: {
            // Sphere and funnel: the centre (a funnel's keyframed rotation is rejected).
            c.vector = vec4<f32>(posed_point(t, pose, rest.vector.xyz), 0.0);
        }
    }
    return c;
}

// The centre a collider's motion is measured at (`Shape::centre`).
fn collider_centre(c: Collider) -> vec3<f32> {
    switch c.kind {
        case KIND_PLANE: {
            return c.vector.xyz * c.offset;
        }
        case KIND_CAPSULE: {
            return (c.vector.xyz + c.second.xyz) * 0.5;
        }
        default: {
            return c.vector.xyz;
        }
    }
}

// The end of substep `s` of the frame [s] (`Clock::next_time`); substep -1 is where the frame
// starts.
fn substep_end(s: u32) -> f32 {
    return f32(drive.first + s + 1u) / drive.per_second;
}

// `v` scaled to length 1, or `fallback` where it has none (glam's `normalize_or`).
fn normalize_or(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let l = length(v);
    if (l > 1e-37) {
        return v / l;
    }
    return fallback;
}

// A unit vector perpendicular to unit `n` (glam's `any_orthonormal_vector`).
fn any_orthonormal(n: vec3<f32>) -> vec3<f32> {
    let sign = select(-1.0, 1.0, n.z >= 0.0);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    return vec3<f32>(b, sign + n.y * n.y * a, -n.y);
}

// Ridden vertex `v` of skin `skin` at the end of substep `s`: position and smooth normal,
// linear between the window's two character frames (`Skin::surface`).
struct Ridden {
    position: vec3<f32>,
    normal: vec3<f32>,
}

fn ridden_at(skin: u32, v: u32, s: u32) -> Ridden {
    let info = ride_skins[skin];
    let time = ride_times[s * drive.skins + skin];
    let a = info.window + 2u * (time.before * info.ridden + v);
    let b = info.window + 2u * (time.after * info.ridden + v);
    let w = time.weight;
    return Ridden(
        mix(ride_window[a].xyz, ride_window[b].xyz, w),
        mix(ride_window[a + 1u].xyz, ride_window[b + 1u].xyz, w),
    );
}

// Where riding attachment `r` goes at the end of substep `s`: the point at its barycentric
// coordinates plus its offset in the skin's frame there (`surface_frame`).
fn ride_target(r: Riding, s: u32) -> vec3<f32> {
    let p0 = ridden_at(r.skin, r.corners.x, s);
    let p1 = ridden_at(r.skin, r.corners.y, s);
    let p2 = ridden_at(r.skin, r.corners.z, s);
    let facet = normalize_or(cross(p1.position - p0.position, p2.position - p0.position),
        vec3<f32>(0.0, 1.0, 0.0));
    let bary = r.bary.xyz;
    let n = normalize_or(p0.normal * bary.x + p1.normal * bary.y + p2.normal * bary.z, facet);
    let edge = p1.position - p0.position;
    let e = normalize_or(edge - n * dot(edge, n), any_orthonormal(n));
    let point = p0.position * bary.x + p1.position * bary.y + p2.position * bary.z;
    let o = r.offset.xyz;
    return point + e * o.x + cross(n, e) * o.y + n * o.z;
}

// Speeds are not negative, so their bits order as the speeds do.
fn note_speed(speed: f32) {
    atomicMax(&drive_speed, bitcast<u32>(speed));
}

// One invocation per (substep, keyframed attachment, keyframed collider or riding attachment)
// of the frame, in rows of workgroups (x) as wide as a dispatch allows.
@compute @workgroup_size(64)
fn drive_frame(
    @builtin(global_invocation_id) id: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    let items = drive.keyed + drive.moving + drive.riding;
    let k = id.x + id.y * groups.x * 64u;
    if (k >= items * drive.substeps) {
        return;
    }
    let s = k / items;
    let item = k % items;
    let time = substep_end(s);
    if (item < drive.keyed) {
        let keyed = drive_keyed[item];
        let t = keyed.track;
        let goal = posed_point(t, track_pose(t, time), keyed.rest.xyz);
        // Where the particle was at the substep's start: at the frame's start, or the last
        // substep's target.
        var last = drive_start[keyed.particle].xyz;
        if (s > 0u) {
            last = posed_point(t, track_pose(t, substep_end(s - 1u)), keyed.rest.xyz);
        }
        drive_targets[s * drive.attached + item] = vec4<f32>(goal, 0.0);
        note_speed(distance(goal, last) / drive.step);
        return;
    }
    if (item >= drive.keyed + drive.moving) {
        let i = item - drive.keyed - drive.moving;
        let riding = ride_bound[i];
        let goal = ride_target(riding, s);
        var last = drive_start[riding.particle].xyz;
        if (s > 0u) {
            last = ride_target(riding, s - 1u);
        }
        drive_targets[s * drive.attached + drive.keyed + i] = vec4<f32>(goal, 0.0);
        note_speed(distance(goal, last) / drive.step);
        return;
    }
    let moving = drive_moving[item - drive.keyed];
    var posed = posed_collider(moving.rest, moving.track, track_pose(moving.track, time));
    // The pose before: the last substep's, or the shape at rest before the bake's first.
    var before = moving.rest;
    if (drive.first + s > 0u) {
        let earlier = f32(drive.first + s) / drive.per_second;
        before = posed_collider(moving.rest, moving.track, track_pose(moving.track, earlier));
    }
    let moved = collider_centre(posed) - collider_centre(before);
    posed.moved = vec4<f32>(moved, 0.0);
    drive_posed[s * drive.colliders + moving.index] = posed;
    note_speed(length(moved) / drive.step);
}
