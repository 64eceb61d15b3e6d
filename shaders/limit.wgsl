// Strain limiting on the GPU (src/gpu/limit.rs; `sim::limit` on the CPU): after a substep's
// `finish`, the structural springs stretched past the limit are pulled back to it, colour by
// colour (no two springs of a colour share a particle), forward then backward, sweep after sweep
// until a sweep finds none past it or `sweeps` have run; velocities take the same correction.
// One workgroup does it all in one dispatch: its threads share each colour, a storage barrier
// between colours, and the sweep's count decides, the same for every thread, whether to go on.
// So a substep costs one dispatch however many sweeps it needs, and the CPU's order and
// arithmetic (`limit::pull_back`), spring by spring. Compiled after common.wgsl (x, velocity,
// particle, springs and params of group 0); its own bindings are in group 3.

struct Limit {
    strain: f32,           // the limit: 0.2 is 20 % longer than at rest
    colours: u32,
    sweeps: u32,           // at the most
    pad: u32,
}

@group(3) @binding(0) var<uniform> limit: Limit;
// Where each colour starts in `limit_order`, and its end.
@group(3) @binding(1) var<storage, read> limit_colour_start: array<u32>;
// Structural spring indices, colour by colour.
@group(3) @binding(2) var<storage, read> limit_order: array<u32>;
// Springs the first sweep of each substep found past the limit, summed over the frame.
@group(3) @binding(3) var<storage, read_write> limit_pulled: array<atomic<u32>>;

const LIMIT_GROUP: u32 = 256u;

var<workgroup> pulled_now: atomic<u32>;
var<workgroup> pulled_sweep: u32;

// Pulls spring `s` back to the limit if it is past it; whether it was.
fn pull_back(s: Spring) -> bool {
    let wa = particle[s.a].inv_mass;
    let wb = particle[s.b].inv_mass;
    let longest = s.rest * (1.0 + limit.strain);
    let d = x[s.b].xyz - x[s.a].xyz;
    let length = sqrt(dot(d, d));
    if (length <= longest || wa + wb == 0.0) {
        return false;
    }
    let c = d * ((length - longest) / (length * (wa + wb)));
    let da = vec4<f32>(c * wa, 0.0);
    let db = vec4<f32>(-c * wb, 0.0);
    x[s.a] = x[s.a] + da;
    x[s.b] = x[s.b] + db;
    velocity[s.a] = velocity[s.a] + da / params.step;
    velocity[s.b] = velocity[s.b] + db / params.step;
    return true;
}

@compute @workgroup_size(256)
fn limit_strain(@builtin(local_invocation_index) thread: u32) {
    for (var sweep = 0u; sweep < limit.sweeps; sweep = sweep + 1u) {
        if (thread == 0u) {
            atomicStore(&pulled_now, 0u);
        }
        workgroupBarrier();
        var mine = 0u;
        for (var k = 0u; k < limit.colours; k = k + 1u) {
            let c = select(k, limit.colours - 1u - k, sweep % 2u == 1u);
            let end = limit_colour_start[c + 1u];
            for (var j = limit_colour_start[c] + thread; j < end; j = j + LIMIT_GROUP) {
                if (pull_back(springs[limit_order[j]])) {
                    mine = mine + 1u;
                }
            }
            // The colour's moves seen by every thread before the next colour reads them.
            storageBarrier();
        }
        if (mine > 0u) {
            atomicAdd(&pulled_now, mine);
        }
        workgroupBarrier();
        if (thread == 0u) {
            pulled_sweep = atomicLoad(&pulled_now);
        }
        let pulled = workgroupUniformLoad(&pulled_sweep);
        if (sweep == 0u && thread == 0u) {
            atomicAdd(&limit_pulled[0], pulled);
        }
        if (pulled == 0u) {
            break;
        }
    }
}
