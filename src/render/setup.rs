//! What a renderer creates once, by kind: the images it draws into ([`Targets`]), each mesh's
//! buffers ([`MeshBuffers::upload`]), and the pipelines with their bind groups ([`Pipelines`]).

use super::{
    edges, interleave, AnimatedMesh, DrawUniform, MeshBuffers, COLOUR_FORMAT, DEPTH_FORMAT,
    SAMPLES, SHADOW_SIZE,
};
use wgpu::util::DeviceExt;

/// A buffer initialised with `bytes`.
pub(super) fn buffer(
    device: &wgpu::Device,
    label: &str,
    bytes: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytes,
        usage,
    })
}

/// The images a renderer draws into: the shadow map, the multisampled colour and depth, the
/// resolved image, and the buffer it is read back through (rows padded to 256 bytes).
pub(super) struct Targets {
    pub shadow_view: wgpu::TextureView,
    pub msaa_view: wgpu::TextureView,
    pub depth_view: wgpu::TextureView,
    pub resolved: wgpu::Texture,
    pub readback: wgpu::Buffer,
    pub padded_row: u32,
}

impl Targets {
    pub(super) fn new(device: &wgpu::Device, width: u32, height: u32) -> Targets {
        let options = (width, height);
        let texture = |label: &str, size: (u32, u32), format, samples, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width: size.0,
                    height: size.1,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let attach = wgpu::TextureUsages::RENDER_ATTACHMENT;
        let size = options;
        let shadow = texture(
            "shadow map",
            (SHADOW_SIZE, SHADOW_SIZE),
            DEPTH_FORMAT,
            1,
            attach | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let msaa = texture("colour", size, COLOUR_FORMAT, SAMPLES, attach);
        let depth = texture("depth", size, DEPTH_FORMAT, SAMPLES, attach);
        let resolved = texture(
            "image",
            size,
            COLOUR_FORMAT,
            1,
            attach | wgpu::TextureUsages::COPY_SRC,
        );
        let padded_row = (options.0 * 4).div_ceil(256) * 256;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("image readback"),
            size: padded_row as u64 * options.1 as u64,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let shadow_view = shadow.create_view(&Default::default());
        Targets {
            shadow_view,
            msaa_view: msaa.create_view(&Default::default()),
            depth_view: depth.create_view(&Default::default()),
            resolved,
            readback,
            padded_row,
        }
    }
}

impl MeshBuffers {
    /// A mesh's vertex buffer (frame 0, interleaved with normals) and index buffers.
    pub(super) fn upload(device: &wgpu::Device, m: &AnimatedMesh, wireframe: bool) -> MeshBuffers {
        let buffer = |label: &str, bytes: &[u8], usage| buffer(device, label, bytes, usage);
        let vertex_usage = wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST;
        // Index buffers start with the first frame's faces, the most there will be (tearing
        // only removes faces), and are rewritten when the faces change.
        let index_usage = wgpu::BufferUsages::INDEX | wgpu::BufferUsages::COPY_DST;
        let first = m.triangles_at(0);
        MeshBuffers {
            vertices: buffer(
                &m.name,
                bytemuck::cast_slice(&interleave(&m.frames[0], first)),
                vertex_usage,
            ),
            triangles: (!first.is_empty()).then(|| {
                (
                    buffer("triangles", bytemuck::cast_slice(first), index_usage),
                    first.len() as u32 * 3,
                )
            }),
            edges: (wireframe && !first.is_empty()).then(|| {
                let e = edges(first);
                (
                    buffer("edges", bytemuck::cast_slice(&e), index_usage),
                    e.len() as u32,
                )
            }),
            vertex_count: m.frames[0].len() as u32,
        }
    }
}

/// The preview's pipelines (shadow pass, lit surfaces, wireframe lines, rope strips) and the bind
/// groups they draw with.
pub(super) struct Pipelines {
    pub shadow_pipeline: wgpu::RenderPipeline,
    pub surface_pipeline: wgpu::RenderPipeline,
    pub line_list_pipeline: wgpu::RenderPipeline,
    pub line_strip_pipeline: wgpu::RenderPipeline,
    pub shadow_group: wgpu::BindGroup,
    pub main_group: wgpu::BindGroup,
    pub draw_group: wgpu::BindGroup,
}

impl Pipelines {
    /// Builds them over the per-frame `globals`, the per-draw `draws` slots and the shadow map
    /// (long: three bind group layouts and their groups, each mostly wgpu's required fields).
    pub(super) fn new(
        device: &wgpu::Device,
        globals: &wgpu::Buffer,
        draws: &wgpu::Buffer,
        shadow_view: &wgpu::TextureView,
    ) -> Pipelines {
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("shadow sampler"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            compare: Some(wgpu::CompareFunction::LessEqual),
            ..Default::default()
        });

        let uniform_entry = |binding, dynamic: bool| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: dynamic,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = |label: &str, entries: &[wgpu::BindGroupLayoutEntry]| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some(label),
                entries,
            })
        };
        let globals_only = layout("globals", &[uniform_entry(0, false)]);
        let lit = layout(
            "globals and shadow map",
            &[
                uniform_entry(0, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Depth,
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 2,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Comparison),
                    count: None,
                },
            ],
        );
        let per_draw = layout("draw", &[uniform_entry(0, true)]);
        let group = |layout: &wgpu::BindGroupLayout, entries: &[wgpu::BindGroupEntry]| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout,
                entries,
            })
        };
        let shadow_group = group(
            &globals_only,
            &[wgpu::BindGroupEntry {
                binding: 0,
                resource: globals.as_entire_binding(),
            }],
        );
        let main_group = group(
            &lit,
            &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: globals.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(shadow_view),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
            ],
        );
        let draw_group = group(
            &per_draw,
            &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: draws,
                    offset: 0,
                    size: std::num::NonZeroU64::new(std::mem::size_of::<DrawUniform>() as u64),
                }),
            }],
        );

        let (shadow_pipeline, surface_pipeline, line_list_pipeline, line_strip_pipeline) =
            render_pipelines(device, &globals_only, &lit, &per_draw);
        Pipelines {
            shadow_pipeline,
            surface_pipeline,
            line_list_pipeline,
            line_strip_pipeline,
            shadow_group,
            main_group,
            draw_group,
        }
    }
}

/// The four render pipelines over the three bind group layouts: shadow (depth only, biased),
/// lit surfaces, wireframe lines and rope strips (both multisampled).
// Long: four pipeline descriptors, mostly the fields wgpu requires of each.
fn render_pipelines(
    device: &wgpu::Device,
    globals_only: &wgpu::BindGroupLayout,
    lit: &wgpu::BindGroupLayout,
    per_draw: &wgpu::BindGroupLayout,
) -> (
    wgpu::RenderPipeline,
    wgpu::RenderPipeline,
    wgpu::RenderPipeline,
    wgpu::RenderPipeline,
) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("render.wgsl"),
        source: wgpu::ShaderSource::Wgsl(include_str!("../../shaders/render.wgsl").into()),
    });
    let pipeline_layout = |groups: &[Option<&wgpu::BindGroupLayout>]| {
        device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: None,
            bind_group_layouts: groups,
            immediate_size: 0,
        })
    };
    let shadow_layout = pipeline_layout(&[Some(globals_only)]);
    let main_layout = pipeline_layout(&[Some(lit), Some(per_draw)]);
    let vertex_layout = [Some(wgpu::VertexBufferLayout {
        array_stride: 24,
        step_mode: wgpu::VertexStepMode::Vertex,
        attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x3],
    })];
    let pipeline = |label: &str,
                    layout: &wgpu::PipelineLayout,
                    vs: &str,
                    fs: Option<&str>,
                    topology: wgpu::PrimitiveTopology,
                    samples: u32,
                    bias: wgpu::DepthBiasState| {
        let targets = [Some(wgpu::ColorTargetState {
            format: COLOUR_FORMAT,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        })];
        device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some(vs),
                compilation_options: Default::default(),
                buffers: &vertex_layout,
            },
            primitive: wgpu::PrimitiveState {
                topology,
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::LessEqual),
                stencil: Default::default(),
                bias,
            }),
            multisample: wgpu::MultisampleState {
                count: samples,
                ..Default::default()
            },
            fragment: fs.map(|entry| wgpu::FragmentState {
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                targets: &targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    };
    let no_bias = wgpu::DepthBiasState::default();
    let shadow_pipeline = pipeline(
        "shadow",
        &shadow_layout,
        "vs_shadow",
        None,
        wgpu::PrimitiveTopology::TriangleList,
        1,
        wgpu::DepthBiasState {
            constant: 2,
            slope_scale: 2.0,
            clamp: 0.0,
        },
    );
    let surface_pipeline = pipeline(
        "surface",
        &main_layout,
        "vs_main",
        Some("fs_main"),
        wgpu::PrimitiveTopology::TriangleList,
        SAMPLES,
        no_bias,
    );
    let line_list_pipeline = pipeline(
        "wireframe",
        &main_layout,
        "vs_line",
        Some("fs_line"),
        wgpu::PrimitiveTopology::LineList,
        SAMPLES,
        no_bias,
    );
    let line_strip_pipeline = pipeline(
        "ropes",
        &main_layout,
        "vs_line",
        Some("fs_line"),
        wgpu::PrimitiveTopology::LineStrip,
        SAMPLES,
        no_bias,
    );
    (
        shadow_pipeline,
        surface_pipeline,
        line_list_pipeline,
        line_strip_pipeline,
    )
}
