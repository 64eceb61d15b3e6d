// Shared by every drape kernel: the only definition of the GPU structs. Each mirrors a Rust
// `#[repr(C)]` Pod struct in src/gpu/layout.rs (sizes checked by tests/wgsl_layout.rs), and each
// function mirrors, by name, a pure function of src/sim/constraint.rs.

// Per-dispatch constants (uniform, one 256-byte slot per dispatch kind, dynamic offset).
struct Params {
    gravity_step: vec4<f32>,   // g·h [m/s]
    particles: u32,
    springs: u32,
    structural: u32,           // structural springs at the head of `springs`
    colliders: u32,
    range_start: u32,          // colour range of a sweep; a substep's targets for `attach`
    range_end: u32,
    predict_next: u32,         // finish: also predict the next substep
    collider_base: u32,        // finish: this substep's first collider
    step: f32,                 // h [s]
    inv_step: f32,             // 1/h
    keep: f32,                 // velocity kept per step, exp(-damping h)
    omega: f32,                // over-relaxation
    range2_start: u32,         // a sweep's colour in a small model: its high side, after the low
    range2_end: u32,           // side's range_start..range_end; empty otherwise
    separator_colours: u32,    // a small model's separator: its colours, and where each starts
    separator_start: array<vec4<u32>, 4>, // (and the last ends), four to a vector
}

// Static per-particle data.
struct Particle {
    inv_mass: f32,             // 0 for pinned particles
    inertia: f32,              // a = m/h² (0 without integration)
    diag_inv: f32,             // 1/(a + Σ w), 0 for particles that never move
    contact_radius: f32,       // [m]
}

// One spring seen from one of its particles (12 bytes).
struct Slot {
    neighbour: u32,
    spring: u32,               // spring index; bit 31 set at the spring's b end
    weight: f32,
}

// A spring (12 bytes).
struct Spring {
    a: u32,
    b: u32,
    rest: f32,
}

// A long-range attachment (12 bytes).
struct Tether {
    particle: u32,
    pin: u32,
    rest: f32,
}

// An analytic collider (80 bytes): kind 0 plane (normal, offset), 1 sphere (centre, radius),
// 2 axis-aligned box (centre, half extents), 3 capsule (start, end, radius), 4 upright funnel
// (spout centre, radius, top radius in offset, second = (height, half thickness)), 5 wedge
// (centre, half extents; blade down along Z).
struct Collider {
    kind: u32,
    friction: f32,
    radius: f32,
    offset: f32,
    vector: vec4<f32>,         // plane normal, sphere or box centre, capsule start
    second: vec4<f32>,         // box half extents, capsule end; w = 1: swept test on
    rotation: vec4<f32>,       // box, wedge: orientation (unit quaternion x, y, z, w)
    moved: vec4<f32>,          // motion over the substep (xyz)
}

// `v` turned by the unit quaternion `q`.
fn quat_rotate(q: vec4<f32>, v: vec3<f32>) -> vec3<f32> {
    let t = 2.0 * cross(q.xyz, v);
    return v + q.w * t + cross(q.xyz, t);
}

// Particle–particle collisions: constants (uniform) of the hash grid.
struct Contacts {
    inv_cell: f32,             // 1 / cell width = 0.25 / particle radius
    diameter: f32,             // particles keep this far apart [m]
    table: u32,                // hash buckets (a power of two)
    enabled: u32,              // 0: no particle collisions (the buffers are placeholders)
    shells: u32,               // characters' shells
    shell_stride: u32,         // shell particles of all shells (one substep's worth)
    grid_stride: u32,          // shell grid entries of all shells (one substep's worth)
    nearby: u32,               // 1: `finish` lists each particle's nearby shell particles
}

// A character's shell (src/collide/shell/): where its particles and grid sit in one
// substep's share of `shell_particle` and `shell_grid`, and its constants.
struct ShellInfo {
    first: u32,                // first particle
    count: u32,                // particles
    grid: u32,                 // first grid entry: table + 1 bucket starts, then count items
    table: u32,                // hash buckets (a power of two)
    radius: f32,               // shell particle radius [m]
    friction: f32,
    cell: f32,                 // grid cell width [m]
    flags: u32,                // bit 0: swept test on; bit 1: normals present; bit 2: never moves
}

// A shell particle at the end of a substep: position, motion over it, skin normal.
struct ShellParticle {
    position: vec4<f32>,
    motion: vec4<f32>,
    normal: vec4<f32>,
}

// The part of `motion` along the surface (unit normal `n`) that Coulomb friction removes: all
// of it up to `limit`, `limit` of it beyond (collide::friction_removed).
fn friction_removed(motion: vec3<f32>, n: vec3<f32>, limit: f32) -> vec3<f32> {
    let tangent = motion - n * dot(motion, n);
    let t_len = length(tangent);
    if (t_len <= limit) {
        return tangent;
    }
    return tangent * (limit / t_len);
}

const B_END: u32 = 0x80000000u;
const TINY_LENGTH: f32 = 1e-12;

// Collider.kind (gpu::layout::collider_kind; tests/shaders.rs checks every shared constant).
const KIND_PLANE: u32 = 0u;
const KIND_SPHERE: u32 = 1u;
const KIND_BOX: u32 = 2u;
const KIND_CAPSULE: u32 = 3u;
const KIND_FUNNEL: u32 = 4u;
const KIND_WEDGE: u32 = 5u;

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read_write> x: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> velocity: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> delta: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read_write> target_delta: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read_write> projection: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read_write> scratch: array<vec4<f32>>;
@group(0) @binding(7) var<storage, read> particle: array<Particle>;
@group(0) @binding(8) var<storage, read> slot_start: array<u32>;
@group(0) @binding(9) var<storage, read> slots: array<Slot>;
@group(0) @binding(10) var<storage, read> springs: array<Spring>;
@group(0) @binding(11) var<storage, read> tether_start: array<u32>;
@group(0) @binding(12) var<storage, read> tethers: array<Tether>;
@group(0) @binding(13) var<storage, read> colliders: array<Collider>;

// Particle–particle collisions (src/collide/particles/): per particle (lattice cell xyz,
// garment w), its bucket, the buckets' starts, a scatter cursor, particles sorted by bucket, and
// each particle's push of the substep.
@group(2) @binding(0) var<uniform> contacts: Contacts;
@group(2) @binding(1) var<storage, read> pc_cell: array<vec4<i32>>;
@group(2) @binding(2) var<storage, read_write> pc_bucket: array<u32>;
@group(2) @binding(3) var<storage, read_write> pc_start: array<atomic<u32>>;
@group(2) @binding(4) var<storage, read_write> pc_cursor: array<atomic<u32>>;
@group(2) @binding(5) var<storage, read_write> pc_items: array<u32>;
@group(2) @binding(6) var<storage, read_write> pc_push: array<vec4<f32>>;

// Attachments: the attached particles (storage index) and, per substep of the frame, where each
// goes (uploaded by the CPU every frame).
@group(2) @binding(7) var<storage, read> attach_particle: array<u32>;
@group(2) @binding(8) var<storage, read> attach_target: array<vec4<f32>>;

// Characters' shells, every substep of the frame (uploaded by the CPU every frame).
@group(2) @binding(9) var<storage, read> shell_info: array<ShellInfo>;
@group(2) @binding(10) var<storage, read> shell_particle: array<ShellParticle>;
@group(2) @binding(11) var<storage, read> shell_grid: array<u32>;
// With collision passes: NEARBY shell particles per garment particle per shell (shell-major),
// listed by `finish` for the next substep's `contact_pass` (ShellCollider::resolve_nearby).
@group(2) @binding(12) var<storage, read_write> shell_nearby: array<u32>;

// L / |e| for an edge of squared length `length_squared` (0 when too short to have a direction).
fn spring_projection_scale(length_squared: f32, rest: f32) -> f32 {
    if (length_squared > TINY_LENGTH * TINY_LENGTH) {
        return rest / sqrt(length_squared);
    }
    return 0.0;
}

// Move from `old` past the Gauss-Seidel value `new` by factor ω.
fn over_relax(old: vec4<f32>, new_value: vec4<f32>, omega: f32) -> vec4<f32> {
    return old + (new_value - old) * omega;
}

// +1 at a spring's a end, -1 at its b end.
fn slot_sign(spring: u32) -> f32 {
    return select(1.0, -1.0, (spring & B_END) != 0u);
}

// The Gauss-Seidel row of particle i: (a t + Σ w (Δ_k ± g_k)) / (a + Σ w), reading Δ or scratch.
fn spring_row_solve(i: u32) -> vec4<f32> {
    let p = particle[i];
    var acc = target_delta[i] * p.inertia;
    for (var k = slot_start[i]; k < slot_start[i + 1u]; k = k + 1u) {
        let s = slots[k];
        let g = projection[s.spring & ~B_END] * slot_sign(s.spring);
        acc = acc + (delta[s.neighbour] + g) * s.weight;
    }
    return acc * p.diag_inv;
}
