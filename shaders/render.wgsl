// Preview renderer: Blinn-Phong shading with a shadowed key light and an unshadowed fill light,
// lit the same on both sides of the cloth, with percentage-closer filtered shadow mapping.
//
// Two-sided lighting: cloth is a single surface seen from both sides. The thesis's renderer lit
// back faces with the front face's normal, so the inside of a poncho came out dark; here the
// normal is flipped on back-facing fragments, so each side is lit as the side it is.

struct Globals {
    view_proj: mat4x4<f32>,
    light_view_proj: mat4x4<f32>,
    // Camera position (w unused).
    eye: vec4<f32>,
    // Unit vectors towards the key and the fill light (w: intensity).
    key: vec4<f32>,
    fill: vec4<f32>,
    // x: 1 / shadow map size, y: ambient level, z: depth bias.
    shadow: vec4<f32>,
};

struct Draw {
    // Base colour (linear RGB, alpha 1).
    colour: vec4<f32>,
    // x: specular strength, y: shininess.
    material: vec4<f32>,
};

@group(0) @binding(0) var<uniform> globals: Globals;
@group(0) @binding(1) var shadow_map: texture_depth_2d;
@group(0) @binding(2) var shadow_sampler: sampler_comparison;
@group(1) @binding(0) var<uniform> draw: Draw;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
};

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    return out;
}

// Fraction of the key light reaching `world` (3 × 3 PCF over the shadow map).
fn lit_fraction(world: vec3<f32>) -> f32 {
    let p = globals.light_view_proj * vec4<f32>(world, 1.0);
    let ndc = p.xyz / p.w;
    let uv = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    if (any(uv < vec2<f32>(0.0)) || any(uv > vec2<f32>(1.0)) || ndc.z > 1.0) {
        return 1.0;
    }
    let texel = globals.shadow.x;
    var sum = 0.0;
    for (var y = -1; y <= 1; y++) {
        for (var x = -1; x <= 1; x++) {
            let offset = vec2<f32>(f32(x), f32(y)) * texel;
            sum += textureSampleCompareLevel(shadow_map, shadow_sampler, uv + offset, ndc.z - globals.shadow.z);
        }
    }
    return sum / 9.0;
}

// Diffuse + Blinn-Phong specular from one light.
fn phong(n: vec3<f32>, view: vec3<f32>, light: vec4<f32>) -> vec2<f32> {
    let l = light.xyz;
    let diffuse = max(dot(n, l), 0.0);
    let h = normalize(l + view);
    let specular = select(0.0, pow(max(dot(n, h), 0.0), draw.material.y), diffuse > 0.0);
    return vec2<f32>(diffuse, specular) * light.w;
}

@fragment
fn fs_main(in: VertexOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var n = normalize(in.normal);
    if (!front) {
        n = -n;
    }
    let view = normalize(globals.eye.xyz - in.world);
    let key = phong(n, view, globals.key) * lit_fraction(in.world);
    let fill = phong(n, view, globals.fill);
    let base = draw.colour.rgb;
    let colour = base * (globals.shadow.y + key.x + fill.x)
        + vec3<f32>(1.0) * draw.material.x * (key.y + fill.y);
    return vec4<f32>(colour, 1.0);
}

// Lines (ropes, wireframe overlay): flat colour, pulled slightly towards the camera so they win
// the depth test against the surface they outline.
@vertex
fn vs_line(v: VertexIn) -> @builtin(position) vec4<f32> {
    var clip = globals.view_proj * vec4<f32>(v.position, 1.0);
    clip.z -= 2e-4 * clip.w;
    return clip;
}

@fragment
fn fs_line() -> @location(0) vec4<f32> {
    return draw.colour;
}

// Shadow pass: depth from the key light.
@vertex
fn vs_shadow(v: VertexIn) -> @builtin(position) vec4<f32> {
    return globals.light_view_proj * vec4<f32>(v.position, 1.0);
}
