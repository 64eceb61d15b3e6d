// Stage 2a, the local step: each spring's projection onto its rest length, relative to its
// start-of-step edge, g = L e / |e| - (x_a - x_b) with e = (x_a - x_b) + (Δ_a - Δ_b).
@compute @workgroup_size(64)
fn project(@builtin(global_invocation_id) id: vec3<u32>) {
    let c = id.x;
    if (c >= params.springs) {
        return;
    }
    let s = springs[c];
    let rest_edge = x[s.a] - x[s.b];
    let edge = rest_edge + (delta[s.a] - delta[s.b]);
    projection[c] = edge * spring_projection_scale(dot(edge, edge), s.rest) - rest_edge;
}
