// The total squared error Σ (|q_a - q_b| - L)² over structural springs, reduced on the GPU so
// per-iteration residuals are recorded without reading positions back: each workgroup sums 256
// springs into `partial`, then one workgroup sums the partials into the next slot of `residuals`.

@group(1) @binding(0) var<storage, read_write> partial: array<f32>;
@group(1) @binding(1) var<storage, read_write> residuals: array<f32>;
@group(1) @binding(2) var<storage, read_write> residual_count: atomic<u32>;

var<workgroup> sums: array<f32, 256>;

// Sum of `value` over the workgroup's 256 threads (a tree in shared memory); valid on thread 0.
fn workgroup_sum(local: u32, value: f32) -> f32 {
    sums[local] = value;
    workgroupBarrier();
    for (var stride = 128u; stride > 0u; stride = stride / 2u) {
        if (local < stride) {
            sums[local] = sums[local] + sums[local + stride];
        }
        workgroupBarrier();
    }
    return sums[0];
}

@compute @workgroup_size(256)
fn residual_partial(@builtin(global_invocation_id) id: vec3<u32>,
                    @builtin(local_invocation_id) local: vec3<u32>,
                    @builtin(workgroup_id) group: vec3<u32>) {
    var e = 0.0;
    let c = id.x;
    if (c < params.structural) {
        let s = springs[c];
        let q = (x[s.a] + delta[s.a]) - (x[s.b] + delta[s.b]);
        let err = length(q) - s.rest;
        e = err * err;
    }
    let total = workgroup_sum(local.x, e);
    if (local.x == 0u) {
        partial[group.x] = total;
    }
}

@compute @workgroup_size(256)
fn residual_total(@builtin(local_invocation_id) local: vec3<u32>) {
    let groups = (params.structural + 255u) / 256u;
    var e = 0.0;
    for (var g = local.x; g < groups; g = g + 256u) {
        e = e + partial[g];
    }
    let total = workgroup_sum(local.x, e);
    if (local.x == 0u) {
        let k = atomicAdd(&residual_count, 1u);
        residuals[k] = total;
    }
}
