// Force fields on the GPU, the same steps as src/sim/forces.rs: each face's wind force (drag and
// lift along its normal, skin friction along it, from the air's velocity relative to the face),
// then each particle's acceleration (its faces' forces, a third each, and the attractors) and
// with it the substep's prediction t = h (f v + g h) + a h². After `finish`, the work the fields
// did over the substep, per particle, for the stability rule. The parameters' `range_start` is
// the substep of the frame (the `finish` slots').

struct FieldCounts {
    faces: u32,
    winds: u32,
    attractors: u32,
    rows: u32,                 // particles + 1: where the faces' indices start in `field_rows`
}

struct FieldWind {
    density: f32,
    drag: f32,
    friction: f32,
    waves: u32,
}

struct FieldWave {
    amplitude_phase: vec4<f32>,
    k_omega: vec4<f32>,
}

const GUST_WAVES: u32 = 4u;

@group(3) @binding(0) var<uniform> field: FieldCounts;
@group(3) @binding(1) var<storage, read> field_faces: array<vec4<u32>>;
@group(3) @binding(2) var<storage, read> field_rows: array<u32>;
@group(3) @binding(3) var<storage, read> field_winds: array<FieldWind>;
@group(3) @binding(4) var<storage, read> field_waves: array<FieldWave>;
@group(3) @binding(5) var<storage, read> field_attractors: array<vec4<f32>>;
// Per substep and wind: the steady velocity (xyz) and the substep's start time (w).
@group(3) @binding(6) var<storage, read> field_time: array<vec4<f32>>;
@group(3) @binding(7) var<storage, read_write> face_force: array<vec4<f32>>;
@group(3) @binding(8) var<storage, read_write> field_accel: array<vec4<f32>>;
@group(3) @binding(9) var<storage, read_write> field_work: array<f32>;

// The air's velocity at `x` (Wind::at).
fn wind_at(w: u32, steady: vec4<f32>, x: vec3<f32>) -> vec3<f32> {
    var v = steady.xyz;
    for (var k = 0u; k < field_winds[w].waves; k++) {
        let wave = field_waves[w * GUST_WAVES + k];
        v = v + wave.amplitude_phase.xyz
            * sin(dot(wave.k_omega.xyz, x) - wave.k_omega.w * steady.w + wave.amplitude_phase.w);
    }
    return v;
}

// Each face's wind force [N].
@compute @workgroup_size(64)
fn wind_faces(@builtin(global_invocation_id) id: vec3<u32>) {
    let f = id.x;
    if (f >= field.faces) {
        return;
    }
    let corners = field_faces[f];
    let a = x[corners.x].xyz;
    let b = x[corners.y].xyz;
    let c = x[corners.z].xyz;
    let normal_area = cross(b - a, c - a);
    let twice_area = length(normal_area);
    var force = vec3<f32>(0.0);
    if (twice_area > 0.0) {
        let n = normal_area / twice_area;
        let centre = (a + b + c) / 3.0;
        let motion = (velocity[corners.x].xyz + velocity[corners.y].xyz + velocity[corners.z].xyz) / 3.0;
        for (var w = 0u; w < field.winds; w++) {
            let steady = field_time[params.range_start * field.winds + w];
            let rel = wind_at(w, steady, centre) - motion;
            let along = dot(rel, n);
            let tangential = rel - along * n;
            let wind = field_winds[w];
            let scale = 0.25 * wind.density * twice_area * length(rel);
            force = force + scale * (wind.drag * along * n + wind.friction * tangential);
        }
    }
    face_force[f] = vec4<f32>(force, 0.0);
}

// Each free particle's acceleration [m/s²] and the substep's prediction.
@compute @workgroup_size(64)
fn field_accelerate(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles) {
        return;
    }
    let w = particle[i].inv_mass;
    if (w == 0.0) {
        field_accel[i] = vec4<f32>(0.0);
        return;
    }
    var push = vec3<f32>(0.0);
    for (var k = field_rows[i]; k < field_rows[i + 1u]; k++) {
        push = push + face_force[field_rows[field.rows + k]].xyz;
    }
    var acc = push * (w / 3.0);
    let p = x[i].xyz;
    for (var k = 0u; k < field.attractors; k++) {
        let at = field_attractors[2u * k];
        let radius = field_attractors[2u * k + 1u].x;
        let to = at.xyz - p;
        let d2 = dot(to, to) / (radius * radius);
        if (d2 < 1.0 && d2 > 0.0) {
            let fade = (1.0 - d2) * (1.0 - d2);
            acc = acc + normalize(to) * (at.w * fade);
        }
    }
    field_accel[i] = vec4<f32>(acc, 0.0);
    let t = (velocity[i] * params.keep + params.gravity_step) * params.step
        + vec4<f32>(acc, 0.0) * (params.step * params.step);
    delta[i] = t;
    target_delta[i] = t;
}

// The work of the substep's accelerations over its motion, m a·v h, added per particle.
@compute @workgroup_size(64)
fn field_work_done(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= params.particles || particle[i].inv_mass == 0.0) {
        return;
    }
    let m = 1.0 / particle[i].inv_mass;
    field_work[i] = field_work[i] + m * dot(field_accel[i].xyz, velocity[i].xyz) * params.step;
}
