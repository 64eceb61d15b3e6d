// Particle–particle collisions on the GPU, the pushes of src/collide/particles/: after the
// solve, the predicted positions q = x + Δ are sorted into a hash grid of cells two particle
// diameters wide, every substep (a counting sort: count, one-workgroup scan, scatter; the CPU
// keeps neighbour lists between substeps instead), each bucket's particles are put in ascending
// order (the scatter's atomics leave them in any order, and the order sets the order of the sums
// below: with it, runs are repeatable; the CPU sums in ascending order over all buckets, so the
// two agree to rounding), and every particle moves by the mean of its pushes out of the
// particles it overlaps, all from the same q (Jacobi).
// `finish` adds the push to Δ.

const SKIP_STEPS: i32 = 1;

fn pc_cell_of(q: vec4<f32>) -> vec3<i32> {
    return vec3<i32>(floor(q.xyz * contacts.inv_cell));
}

fn pc_bucket_of(c: vec3<i32>) -> u32 {
    return hash_cell(c) & (contacts.table - 1u);
}

// Buckets' counts and cursors to zero (table + 1 entries).
@compute @workgroup_size(64)
fn pc_clear(@builtin(global_invocation_id) id: vec3<u32>) {
    let b = id.x;
    if (b <= contacts.table) {
        atomicStore(&pc_start[b], 0u);
        atomicStore(&pc_cursor[b], 0u);
    }
}

// Each particle's bucket, counted into pc_start[bucket + 1].
@compute @workgroup_size(64)
fn pc_count(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles) {
        return;
    }
    let b = pc_bucket_of(pc_cell_of(x[i] + delta[i]));
    pc_bucket[i] = b;
    atomicAdd(&pc_start[b + 1u], 1u);
}

const SCAN_THREADS: u32 = 256u;
var<workgroup> scan_partial: array<u32, 256>;

// Inclusive prefix sum of pc_start[1..=table] in one workgroup: each thread scans a run of
// buckets, thread 0 scans the runs' totals, each thread adds its run's offset. The cursors start
// at each bucket's start.
@compute @workgroup_size(256)
fn pc_scan(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    let per = max(contacts.table / SCAN_THREADS, 1u);
    let first = 1u + t * per;
    let last = min(first + per, contacts.table + 1u);
    var sum = 0u;
    for (var b = first; b < last; b = b + 1u) {
        sum = sum + atomicLoad(&pc_start[b]);
    }
    scan_partial[t] = sum;
    workgroupBarrier();
    if (t == 0u) {
        var running = 0u;
        for (var k = 0u; k < SCAN_THREADS; k = k + 1u) {
            let v = scan_partial[k];
            scan_partial[k] = running;
            running = running + v;
        }
    }
    workgroupBarrier();
    var running = scan_partial[t];
    for (var b = first; b < last; b = b + 1u) {
        running = running + atomicLoad(&pc_start[b]);
        atomicStore(&pc_start[b], running);
    }
    storageBarrier();
    workgroupBarrier();
    for (var b = first - 1u; b + 1u < last; b = b + 1u) {
        atomicStore(&pc_cursor[b], atomicLoad(&pc_start[b]));
    }
}

// Each particle into its bucket (in any order).
@compute @workgroup_size(64)
fn pc_scatter(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles) {
        return;
    }
    let slot = atomicAdd(&pc_cursor[pc_bucket[i]], 1u);
    pc_items[slot] = i;
}

// Each bucket's particles in ascending order (insertion sort: buckets hold a few particles).
@compute @workgroup_size(64)
fn pc_order(@builtin(global_invocation_id) id: vec3<u32>) {
    let b = id.x;
    if (b >= contacts.table) {
        return;
    }
    let begin = atomicLoad(&pc_start[b]);
    let end = atomicLoad(&pc_start[b + 1u]);
    for (var k = begin + 1u; k < end; k = k + 1u) {
        let v = pc_items[k];
        var j = k;
        while (j > begin && pc_items[j - 1u] > v) {
            pc_items[j] = pc_items[j - 1u];
            j = j - 1u;
        }
        pc_items[j] = v;
    }
}

fn pc_joined(i: u32, j: u32) -> bool {
    let a = pc_cell[i];
    let b = pc_cell[j];
    let d = abs(a.xyz - b.xyz);
    return a.w == b.w && d.x <= SKIP_STEPS && d.y <= SKIP_STEPS && d.z <= SKIP_STEPS;
}

// The direction two overlapping particles are pushed apart along: their separation at the
// substep's start (`before`, when they did not overlap in the same place), so a particle the
// solve carried through another goes back to the side it came from; else the separation now.
fn pc_apart(before: vec4<f32>, now: vec4<f32>, distance: f32) -> vec4<f32> {
    let start = length(before);
    return select(now / distance, before / start, start > 1e-9);
}

// The push of particle i out of the particles it overlaps (ParticleCollisions::push_out).
@compute @workgroup_size(64)
fn pc_push_out(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles) {
        return;
    }
    let wi = particle[i].inv_mass;
    if (wi == 0.0) {
        pc_push[i] = vec4<f32>(0.0);
        return;
    }
    let qi = x[i] + delta[i];
    // Cells are two diameters wide, so every particle closer than a diameter lies in the
    // 2 × 2 × 2 cells on the sides of the cell corner `qi` is nearest to.
    let scaled = qi.xyz * contacts.inv_cell;
    let c = vec3<i32>(floor(scaled));
    let side = select(vec3<i32>(-1), vec3<i32>(1), scaled - vec3<f32>(c) >= vec3<f32>(0.5));
    var seen: array<u32, 8>;
    var count = 0u;
    var push = vec4<f32>(0.0);
    var touching = 0u;
    for (var corner = 0u; corner < 8u; corner = corner + 1u) {
        let pick = vec3<i32>(vec3<u32>(corner, corner >> 1u, corner >> 2u) & vec3<u32>(1u));
        let b = pc_bucket_of(c + side * pick);
        var again = false;
        for (var k = 0u; k < count; k = k + 1u) {
            again = again || seen[k] == b;
        }
        if (again) {
            continue;
        }
        seen[count] = b;
        count = count + 1u;
        let end = atomicLoad(&pc_start[b + 1u]);
        for (var k = atomicLoad(&pc_start[b]); k < end; k = k + 1u) {
            let j = pc_items[k];
            if (j == i || pc_joined(i, j)) {
                continue;
            }
            let d = qi - (x[j] + delta[j]);
            let distance = length(d);
            if (distance >= contacts.diameter || distance < 1e-9) {
                continue;
            }
            // Pushed apart along their separation at the substep's start (pc_apart says why) until
            // a diameter apart along it (never less than the overlap: the projection is shorter).
            let along = pc_apart(x[i] - x[j], d, distance);
            let wj = particle[j].inv_mass;
            push = push + along * ((contacts.diameter - dot(d, along)) * wi / (wi + wj));
            touching = touching + 1u;
        }
    }
    // Averaged over the contacts (ParticleCollisions::push_out says why).
    pc_push[i] = push / f32(max(touching, 1u));
}
