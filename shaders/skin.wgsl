// Characters' shells placed on the GPU from their skins (src/gpu/skin.rs): each shell particle
// sits at barycentric coordinates on a triangle of the character's mesh, whose vertices the CPU
// uploads once per character frame. First the smooth normals of the frames in the window (each
// welded vertex's triangles' normals summed in triangle order, as
// `character::shell::welded_normals` sums them); then for every substep of a frame at once:
// each particle's position, motion and normal where `ShellCollider::advance` puts them on the
// CPU (the same arithmetic: positions per frame, then linear between frames), then each
// substep's hash grid by a counting sort (clear, count, one-workgroup scan per substep and shell,
// scatter, each bucket in ascending order, as the CPU's sort leaves it). Compiled on its own
// (not with common.wgsl): its buffers are bound as read-write and atomic here.
//
// Dispatches are (x, substep, shell): x loops over particles or buckets in steps of the whole
// dispatch's width, so a large shell needs no more than 65 535 workgroups along x.

struct SkinFrame {
    shell_stride: u32,     // shell particles of one substep (all shells), as ContactGroup lays them
    grid_stride: u32,      // shell grid words of one substep
    resident: u32,         // shells placed here
    bound: u32,            // bound shell particles of all resident shells
    cursor_stride: u32,    // cursor words of one substep
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// A shell placed here: its share of the shell buffers (ShellInfo's), of the binding, of the
// vertex window (two frames of `vertices` positions), of the cursors, of its mesh's triangles,
// of the vertices' weld slots, of the slots' triangle lists and of the slots' normals (two
// frames of `slots`).
struct SkinInfo {
    first: u32,
    count: u32,
    grid: u32,
    table: u32,
    cell: f32,
    bound: u32,
    window: u32,
    vertices: u32,
    cursor: u32,
    triangles: u32,
    vertex: u32,
    weld: u32,
    slots: u32,
    faces: u32,
    normals: u32,
    pad0: u32,
}

// Where a substep starts and ends, per shell: the window slots of the frames before and after
// each end and the weight between them (frame_weight on the CPU).
struct SkinTime {
    to_a: u32,
    to_b: u32,
    to_w: f32,
    from_a: u32,
    from_b: u32,
    from_w: f32,
    pad0: u32,
    pad1: u32,
}

@group(0) @binding(0) var<uniform> skin: SkinFrame;
@group(0) @binding(1) var<storage, read> skin_info: array<SkinInfo>;
@group(0) @binding(2) var<storage, read> skin_time: array<SkinTime>;
@group(0) @binding(3) var<storage, read> corners: array<vec4<u32>>;
@group(0) @binding(4) var<storage, read> barycentric: array<vec2<f32>>;
@group(0) @binding(5) var<storage, read> window: array<vec4<f32>>;
@group(0) @binding(6) var<storage, read> mesh_triangles: array<vec4<u32>>;
@group(0) @binding(7) var<storage, read> vertex_slot: array<u32>;
// Each weld slot's first entry in `slot_faces` (slots + 1 per shell), and the entries.
@group(0) @binding(8) var<storage, read> slot_start: array<u32>;
@group(0) @binding(9) var<storage, read> slot_faces: array<u32>;
// ShellParticle (position, motion, normal) as three vec4s.
@group(0) @binding(10) var<storage, read_write> shell_particle: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> shell_grid: array<atomic<u32>>;
@group(0) @binding(12) var<storage, read_write> keys: array<u32>;
@group(0) @binding(13) var<storage, read_write> cursor: array<atomic<u32>>;
@group(0) @binding(14) var<storage, read_write> slot_normal: array<vec4<f32>>;

const GROUP: u32 = 64u;

fn grid_at(info: SkinInfo, substep: u32) -> u32 {
    return substep * skin.grid_stride + info.grid;
}

fn cursor_at(info: SkinInfo, substep: u32) -> u32 {
    return substep * skin.cursor_stride + info.cursor;
}

// The shell grid's bucket of a point (shell_bucket and the cell in shells.wgsl).
fn skin_bucket(p: vec3<f32>, info: SkinInfo) -> u32 {
    let c = vec3<i32>(floor(p / info.cell));
    return hash_cell(c) & (info.table - 1u);
}

// glam's try_normalize: v / |v| when that is finite and not zero, else (0, 0, 0) and false.
fn unit(v: vec3<f32>) -> vec4<f32> {
    let rcp = 1.0 / length(v);
    if (rcp > 0.0 && rcp <= 3.4028235e38) {
        return vec4<f32>(v * rcp, 1.0);
    }
    return vec4<f32>(0.0);
}

// A particle's position on the frame in window slot `slot` (Shell::positions).
fn slot_position(info: SkinInfo, slot: u32, c: vec4<u32>, uv: vec2<f32>) -> vec3<f32> {
    let base = info.window + slot * info.vertices;
    let a = window[base + c.x].xyz;
    let b = window[base + c.y].xyz;
    let d = window[base + c.z].xyz;
    return a + (b - a) * uv.x + (d - a) * uv.y;
}

// A particle's normal on that frame (character::shell::particle_normal).
fn particle_normal(info: SkinInfo, slot: u32, c: vec4<u32>, uv: vec2<f32>) -> vec3<f32> {
    let base = info.window + slot * info.vertices;
    let normals = info.normals + slot * info.slots;
    let na = slot_normal[normals + vertex_slot[info.vertex + c.x]].xyz;
    let nb = slot_normal[normals + vertex_slot[info.vertex + c.y]].xyz;
    let nc = slot_normal[normals + vertex_slot[info.vertex + c.z]].xyz;
    let mixed = na * (1.0 - uv.x - uv.y) + nb * uv.x + nc * uv.y;
    let n = unit(mixed);
    if (n.w > 0.0) {
        return n.xyz;
    }
    let a = window[base + c.x].xyz;
    let face = unit(cross(window[base + c.y].xyz - a, window[base + c.z].xyz - a));
    if (face.w > 0.0) {
        return face.xyz;
    }
    return vec3<f32>(0.0, 1.0, 0.0);
}

// glam's lerp (a·(1 − w) + b·w), exactly `a` at w = 0.
fn blend(a: vec3<f32>, b: vec3<f32>, w: f32) -> vec3<f32> {
    if (w == 0.0) {
        return a;
    }
    return a * (1.0 - w) + b * w;
}

// Each weld slot's smooth normal on each frame of the window (welded_normals): the normals of
// its triangles, (b − a) × (c − a), summed in triangle order, made unit (zero where they
// cancel). Dispatched as (x, window slot, shell).
@compute @workgroup_size(64)
fn skin_normals(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let info = skin_info[id.z];
    let base = info.window + id.y * info.vertices;
    for (var s = id.x; s < info.slots; s += groups.x * GROUP) {
        var sum = vec3<f32>(0.0);
        for (var e = slot_start[info.weld + s]; e < slot_start[info.weld + s + 1u]; e++) {
            let t = mesh_triangles[info.triangles + slot_faces[info.faces + e]];
            let a = window[base + t.x].xyz;
            sum = sum + cross(window[base + t.y].xyz - a, window[base + t.z].xyz - a);
        }
        slot_normal[info.normals + id.y * info.slots + s] = vec4<f32>(unit(sum).xyz, 0.0);
    }
}

// Each resident shell's bucket starts (table + 1 words) of every substep to zero.
@compute @workgroup_size(64)
fn skin_clear(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let info = skin_info[id.z];
    let at = grid_at(info, id.y);
    for (var b = id.x; b <= info.table; b += groups.x * GROUP) {
        atomicStore(&shell_grid[at + b], 0u);
    }
}

// Each particle's position, motion and normal at the end of each substep, its bucket, counted.
@compute @workgroup_size(64)
fn skin_place(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let substep = id.y;
    let info = skin_info[id.z];
    let t = skin_time[substep * skin.resident + id.z];
    let at = grid_at(info, substep);
    for (var i = id.x; i < info.count; i += groups.x * GROUP) {
        let c = corners[info.bound + i];
        let uv = barycentric[info.bound + i];
        let p = blend(slot_position(info, t.to_a, c, uv), slot_position(info, t.to_b, c, uv), t.to_w);
        let q = blend(slot_position(info, t.from_a, c, uv), slot_position(info, t.from_b, c, uv), t.from_w);
        let n = unit(blend(particle_normal(info, t.to_a, c, uv), particle_normal(info, t.to_b, c, uv), t.to_w));
        let normal = select(vec3<f32>(0.0, 1.0, 0.0), n.xyz, n.w > 0.0);
        let out = 3u * (substep * skin.shell_stride + info.first + i);
        shell_particle[out] = vec4<f32>(p, 0.0);
        shell_particle[out + 1u] = vec4<f32>(p - q, 0.0);
        shell_particle[out + 2u] = vec4<f32>(normal, 0.0);
        let b = skin_bucket(p, info);
        keys[substep * skin.bound + info.bound + i] = b;
        atomicAdd(&shell_grid[at + b + 1u], 1u);
    }
}

const SCAN_THREADS: u32 = 256u;
var<workgroup> scan_partial: array<u32, 256>;

// Inclusive prefix sum of one substep's and shell's counts (pc_scan's method: each thread a run
// of buckets, thread 0 the runs' totals), then each bucket's cursor at its start.
@compute @workgroup_size(256)
fn skin_scan(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let info = skin_info[wid.z];
    let at = grid_at(info, wid.y);
    let cursors = cursor_at(info, wid.y);
    let t = lid.x;
    let per = info.table / SCAN_THREADS + 1u;
    let first = 1u + t * per;
    let last = min(first + per, info.table + 1u);
    var sum = 0u;
    for (var b = first; b < last; b++) {
        sum += atomicLoad(&shell_grid[at + b]);
    }
    scan_partial[t] = sum;
    workgroupBarrier();
    if (t == 0u) {
        var running = 0u;
        for (var k = 0u; k < SCAN_THREADS; k++) {
            let v = scan_partial[k];
            scan_partial[k] = running;
            running += v;
        }
    }
    workgroupBarrier();
    var running = scan_partial[t];
    for (var b = first; b < last; b++) {
        running += atomicLoad(&shell_grid[at + b]);
        atomicStore(&shell_grid[at + b], running);
    }
    storageBarrier();
    workgroupBarrier();
    for (var b = first - 1u; b + 1u < last; b++) {
        atomicStore(&cursor[cursors + b], atomicLoad(&shell_grid[at + b]));
    }
}

// Each particle into its bucket (in any order).
@compute @workgroup_size(64)
fn skin_scatter(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let substep = id.y;
    let info = skin_info[id.z];
    let items = grid_at(info, substep) + info.table + 1u;
    let cursors = cursor_at(info, substep);
    for (var i = id.x; i < info.count; i += groups.x * GROUP) {
        let b = keys[substep * skin.bound + info.bound + i];
        let slot = atomicAdd(&cursor[cursors + b], 1u);
        atomicStore(&shell_grid[items + slot], i);
    }
}

// Each bucket's particles in ascending order (insertion sort: buckets hold a few).
@compute @workgroup_size(64)
fn skin_order(@builtin(global_invocation_id) id: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let info = skin_info[id.z];
    let at = grid_at(info, id.y);
    let items = at + info.table + 1u;
    for (var b = id.x; b < info.table; b += groups.x * GROUP) {
        let begin = items + atomicLoad(&shell_grid[at + b]);
        let end = items + atomicLoad(&shell_grid[at + b + 1u]);
        for (var k = begin + 1u; k < end; k++) {
            let v = atomicLoad(&shell_grid[k]);
            var j = k;
            while (j > begin && atomicLoad(&shell_grid[j - 1u]) > v) {
                atomicStore(&shell_grid[j], atomicLoad(&shell_grid[j - 1u]));
                j--;
            }
            atomicStore(&shell_grid[j], v);
        }
    }
}
