// Stage 2b, one colour of a red-black Gauss-Seidel sweep: particles of one colour are contiguous
// (colour-sorted storage; a small model's colour in two ranges, its low and high sides), share no
// spring, and update in place.
@compute @workgroup_size(64)
fn sweep(@builtin(global_invocation_id) id: vec3<u32>) {
    let low = params.range_end - params.range_start;
    var i = params.range_start + id.x;
    if (id.x >= low) {
        i = params.range2_start + (id.x - low);
        if (i >= params.range2_end) {
            return;
        }
    }
    if (particle[i].diag_inv == 0.0) {
        return;
    }
    delta[i] = over_relax(delta[i], spring_row_solve(i), params.omega);
}

// A small model's separator (src/sim/separator.rs), after both sides: every colour in one
// dispatch of one workgroup, its threads sharing each colour, a storage barrier between colours
// (a few dozen particles: one dispatch where a colour each would be several).
const SEPARATOR_GROUP: u32 = 64u;

@compute @workgroup_size(64)
fn sweep_separator(@builtin(local_invocation_index) thread: u32) {
    for (var c = 0u; c < params.separator_colours; c = c + 1u) {
        let start = params.separator_start[c / 4u][c % 4u];
        let end = params.separator_start[(c + 1u) / 4u][(c + 1u) % 4u];
        for (var i = start + thread; i < end; i = i + SEPARATOR_GROUP) {
            if (particle[i].diag_inv != 0.0) {
                delta[i] = over_relax(delta[i], spring_row_solve(i), params.omega);
            }
        }
        // The colour's moves seen by every thread before the next colour reads them.
        storageBarrier();
    }
}

// Jacobi: every particle from the previous iterate into `scratch` (no atomics) ...
@compute @workgroup_size(64)
fn jacobi(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles) {
        return;
    }
    if (particle[i].diag_inv == 0.0) {
        scratch[i] = delta[i];
        return;
    }
    scratch[i] = over_relax(delta[i], spring_row_solve(i), params.omega);
}

// ... then copied back.
@compute @workgroup_size(64)
fn copy_scratch(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i < params.particles) {
        delta[i] = scratch[i];
    }
}

// PBD distance correction of particle i across the edge e = q_i - q_j (Müller et al. 2007).
fn pbd_distance_correction(edge: vec4<f32>, wi: f32, wj: f32, rest: f32) -> vec4<f32> {
    let len = length(edge);
    let w = wi + wj;
    if (len > TINY_LENGTH && w > 0.0) {
        return edge * (-(wi / w) * (len - rest) / len);
    }
    return vec4<f32>(0.0);
}

// Position Based Dynamics, Jacobi with averaging, into `scratch`.
@compute @workgroup_size(64)
fn pbd(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles) {
        return;
    }
    let wi = particle[i].inv_mass;
    let first = slot_start[i];
    let last = slot_start[i + 1u];
    if (wi == 0.0 || first == last) {
        scratch[i] = delta[i];
        return;
    }
    var sum = vec4<f32>(0.0);
    for (var k = first; k < last; k = k + 1u) {
        let s = slots[k];
        let j = s.neighbour;
        let edge = (x[i] - x[j]) + (delta[i] - delta[j]);
        sum = sum + pbd_distance_correction(edge, wi, particle[j].inv_mass, springs[s.spring & ~B_END].rest);
    }
    scratch[i] = delta[i] + sum * (params.omega / f32(last - first));
}
