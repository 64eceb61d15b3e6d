//! Off-screen preview renders with wgpu (no window; lavapipe works): garments, characters and a
//! floor, Blinn-Phong shading with a shadow-mapped key light and a fill light, both sides of the
//! cloth lit as themselves, 4 × multisampling, an optional wireframe overlay, and a camera that
//! frames everything the bake moves through ([`camera`]). Frames become
//! `preview/frame_0001.png …` and a contact sheet.
//!
//! Each frame uploads the meshes' positions and normals, renders the shadow map and then the
//! image, and reads it back once. Shaders: `shaders/render.wgsl`.

pub mod camera;
mod setup;
pub mod sheet;
pub mod tube;

use crate::error::{Error, Result};
use crate::export::spool::Recorded;
use crate::gpu::GpuContext;
use crate::mesh::vertex_normals;
use crate::mesh::AnimatedMesh;
use camera::View;
use glam::Vec3;
use std::path::{Path, PathBuf};

/// How to render.
#[derive(Clone, Copy, Debug)]
pub struct RenderOptions {
    pub width: u32,
    pub height: u32,
    /// Draw every triangle's edges over the shading.
    pub wireframe: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 1280,
            height: 720,
            wireframe: false,
        }
    }
}

/// Per-frame uniforms (`Globals` in render.wgsl).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Globals {
    view_proj: [[f32; 4]; 4],
    light_view_proj: [[f32; 4]; 4],
    eye: [f32; 4],
    key: [f32; 4],
    fill: [f32; 4],
    shadow: [f32; 4],
}

/// Per-draw uniforms (`Draw` in render.wgsl), one 256-byte slot each.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DrawUniform {
    colour: [f32; 4],
    material: [f32; 4],
}

const DRAW_SLOT: u64 = 256;
const SHADOW_SIZE: u32 = 2048;
const SAMPLES: u32 = 4;
const COLOUR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Background: a light grey-blue.
const CLEAR: wgpu::Color = wgpu::Color {
    r: 0.62,
    g: 0.68,
    b: 0.75,
    a: 1.0,
};

/// GPU buffers of one mesh: interleaved position + normal, triangle and edge indices.
struct MeshBuffers {
    vertices: wgpu::Buffer,
    triangles: Option<(wgpu::Buffer, u32)>,
    edges: Option<(wgpu::Buffer, u32)>,
    vertex_count: u32,
}

/// An off-screen renderer for one sequence of meshes.
pub struct Renderer {
    ctx: GpuContext,
    options: RenderOptions,
    view: View,
    meshes: Vec<MeshBuffers>,
    floor: MeshBuffers,
    pipelines: setup::Pipelines,
    targets: setup::Targets,
}

/// The bounding box of every drawn vertex of every frame (a vertex in no triangle of a mesh
/// with triangles, such as a particle torn free, is not drawn and does not count).
pub fn bounds(meshes: &[AnimatedMesh]) -> Option<(Vec3, Vec3)> {
    let mut lo = Vec3::splat(f32::MAX);
    let mut hi = Vec3::splat(f32::MIN);
    let mut any = false;
    for m in meshes {
        let n = m.frames.first().map_or(0, Vec::len);
        let mut drawn = vec![m.triangles.is_empty(); n];
        for &i in m.triangles.iter().flatten() {
            drawn[i as usize] = true;
        }
        for frame in &m.frames {
            for (p, _) in frame.iter().zip(&drawn).filter(|(_, d)| **d) {
                lo = lo.min(*p);
                hi = hi.max(*p);
                any = true;
            }
        }
    }
    any.then_some((lo, hi))
}

/// Unique edges of `triangles` as line-list indices.
fn edges(triangles: &[[u32; 3]]) -> Vec<u32> {
    let mut e: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    e.sort_unstable();
    e.dedup();
    e.into_iter().flat_map(|(a, b)| [a, b]).collect()
}

/// Interleaved position + normal of a frame.
fn interleave(positions: &[Vec3], triangles: &[[u32; 3]]) -> Vec<[f32; 6]> {
    let normals = if triangles.is_empty() {
        vec![Vec3::Y; positions.len()]
    } else {
        vertex_normals(triangles, positions)
    };
    positions
        .iter()
        .zip(&normals)
        .map(|(p, n)| [p.x, p.y, p.z, n.x, n.y, n.z])
        .collect()
}

impl Renderer {
    /// Prepares buffers, pipelines and the camera for `meshes` (every frame is used for framing).
    pub fn new(
        ctx: GpuContext,
        meshes: &[AnimatedMesh],
        options: RenderOptions,
    ) -> Result<Renderer> {
        Renderer::framing(ctx, meshes, bounds(meshes), options)
    }

    /// Prepares buffers and pipelines for `meshes` (their first frame) and a camera that frames
    /// the box `bounds` (every vertex the sequence draws).
    pub fn framing(
        ctx: GpuContext,
        meshes: &[AnimatedMesh],
        bounds: Option<(Vec3, Vec3)>,
        options: RenderOptions,
    ) -> Result<Renderer> {
        let drawable = meshes
            .iter()
            .any(|m| m.frames.first().is_some_and(|f| !f.is_empty()));
        let (lo, hi) = bounds
            .filter(|_| drawable)
            .ok_or_else(|| Error::InvalidArgument {
                flag: "render".into(),
                reason: "nothing to render: the bake has no garment or character vertices".into(),
            })?;
        if options.width == 0
            || options.height == 0
            || options.width > 8192
            || options.height > 8192
        {
            return Err(Error::InvalidArgument {
                flag: "--size".into(),
                reason: format!(
                    "{}×{} is outside 1…8192 pixels per side",
                    options.width, options.height
                ),
            });
        }
        let view = View::framing(lo, hi, options.width as f32 / options.height as f32);
        let device = &ctx.device;
        let buffer = |label: &str, bytes: &[u8], usage| setup::buffer(device, label, bytes, usage);
        let mesh_buffers = |m: &AnimatedMesh| MeshBuffers::upload(device, m, options.wireframe);
        let gpu_meshes: Vec<MeshBuffers> = meshes.iter().map(mesh_buffers).collect();
        let (c, h) = (view.floor_centre, view.floor_half);
        let floor_mesh = AnimatedMesh {
            name: "floor".into(),
            triangles: vec![[0, 2, 1], [0, 3, 2]],
            uvs: None,
            colour: [0.8, 0.8, 0.78, 1.0],
            frames: vec![vec![
                c + Vec3::new(-h, 0.0, -h),
                c + Vec3::new(h, 0.0, -h),
                c + Vec3::new(h, 0.0, h),
                c + Vec3::new(-h, 0.0, h),
            ]],
            topology: Vec::new(),
            solid: None,
        };
        let floor = mesh_buffers(&floor_mesh);
        // Draw slots: one per mesh, then the floor, then the wireframe colour (the bind groups
        // keep these buffers alive).
        let mut slots = vec![0u8; DRAW_SLOT as usize * (meshes.len() + 2)];
        let mut put = |slot: usize, colour: [f32; 4], material: [f32; 4]| {
            let u = DrawUniform { colour, material };
            let at = slot * DRAW_SLOT as usize;
            slots[at..at + std::mem::size_of::<DrawUniform>()]
                .copy_from_slice(bytemuck::bytes_of(&u));
        };
        for (i, m) in meshes.iter().enumerate() {
            put(i, m.colour, [0.25, 32.0, 0.0, 0.0]);
        }
        put(meshes.len(), floor_mesh.colour, [0.05, 8.0, 0.0, 0.0]);
        put(meshes.len() + 1, [0.05, 0.05, 0.08, 1.0], [0.0; 4]);
        let draws = buffer("draws", &slots, wgpu::BufferUsages::UNIFORM);
        let globals_value = Globals {
            view_proj: view.view_proj.to_cols_array_2d(),
            light_view_proj: view.light_view_proj.to_cols_array_2d(),
            eye: view.eye.extend(1.0).to_array(),
            key: view.key.extend(0.85).to_array(),
            fill: view.fill.extend(0.35).to_array(),
            shadow: [1.0 / SHADOW_SIZE as f32, 0.22, 0.0015, 0.0],
        };
        let globals = buffer(
            "globals",
            bytemuck::bytes_of(&globals_value),
            wgpu::BufferUsages::UNIFORM,
        );

        let targets = setup::Targets::new(device, options.width, options.height);

        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipelines = setup::Pipelines::new(device, &globals, &draws, &targets.shadow_view);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(Error::Gpu {
                reason: format!("{}: preview pipelines: {e}", ctx.adapter.name),
            });
        }
        Ok(Renderer {
            options,
            view,
            meshes: gpu_meshes,
            floor,
            pipelines,
            targets,
            ctx,
        })
    }

    /// The camera and lights.
    pub fn view(&self) -> &View {
        &self.view
    }

    /// Renders frame `k` of `meshes` (the meshes the renderer was built for) to an RGBA image.
    pub fn render(&mut self, meshes: &[AnimatedMesh], k: usize) -> Result<image::RgbaImage> {
        self.upload(meshes, k);
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("preview frame"),
            });
        self.shadow_pass(&mut encoder);
        self.image_pass(&mut encoder);
        self.read_back(encoder, k)
    }

    /// Writes frame `k`'s vertices (and its faces, when tearing changed them) to the GPU.
    fn upload(&mut self, meshes: &[AnimatedMesh], k: usize) {
        let queue = &self.ctx.queue;
        for (m, gpu) in meshes.iter().zip(self.meshes.iter_mut()) {
            let frame = &m.frames[k.min(m.frames.len() - 1)];
            let triangles = m.triangles_at(k);
            if let Some((buffer, count)) = &mut gpu.triangles {
                // Tearing only removes faces: a different count is different faces.
                if *count != triangles.len() as u32 * 3 {
                    queue.write_buffer(buffer, 0, bytemuck::cast_slice(triangles));
                    *count = triangles.len() as u32 * 3;
                    if let Some((buffer, count)) = &mut gpu.edges {
                        let e = edges(triangles);
                        queue.write_buffer(buffer, 0, bytemuck::cast_slice(&e));
                        *count = e.len() as u32;
                    }
                }
            }
            queue.write_buffer(
                &gpu.vertices,
                0,
                bytemuck::cast_slice(&interleave(frame, triangles)),
            );
        }
    }

    /// Every mesh, then the floor, with its draw slot.
    fn drawn(&self) -> impl Iterator<Item = (usize, &MeshBuffers)> {
        self.meshes
            .iter()
            .enumerate()
            .chain(std::iter::once((self.meshes.len(), &self.floor)))
    }

    /// The key light's shadow map.
    fn shadow_pass(&self, encoder: &mut wgpu::CommandEncoder) {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("shadow"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.targets.shadow_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipelines.shadow_pipeline);
        pass.set_bind_group(0, &self.pipelines.shadow_group, &[]);
        for (_, m) in self.drawn() {
            if let Some((indices, count)) = &m.triangles {
                pass.set_vertex_buffer(0, m.vertices.slice(..));
                pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..*count, 0, 0..1);
            }
        }
    }

    /// The shaded image: surfaces (or rope strips), then the wireframe over them.
    fn image_pass(&self, encoder: &mut wgpu::CommandEncoder) {
        let resolve = self.targets.resolved.create_view(&Default::default());
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("image"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.targets.msaa_view,
                depth_slice: None,
                resolve_target: Some(&resolve),
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(CLEAR),
                    store: wgpu::StoreOp::Discard,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.targets.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        let p = &self.pipelines;
        pass.set_bind_group(0, &p.main_group, &[]);
        let slot = |i: usize| [(i as u64 * DRAW_SLOT) as u32];
        for (i, m) in self.drawn() {
            pass.set_vertex_buffer(0, m.vertices.slice(..));
            pass.set_bind_group(1, &p.draw_group, &slot(i));
            match &m.triangles {
                Some((indices, count)) => {
                    pass.set_pipeline(&p.surface_pipeline);
                    pass.set_index_buffer(indices.slice(..), wgpu::IndexFormat::Uint32);
                    pass.draw_indexed(0..*count, 0, 0..1);
                }
                None => {
                    pass.set_pipeline(&p.line_strip_pipeline);
                    pass.draw(0..m.vertex_count, 0..1);
                }
            }
            if let Some((edges, count)) = &m.edges {
                pass.set_pipeline(&p.line_list_pipeline);
                pass.set_bind_group(1, &p.draw_group, &slot(self.meshes.len() + 1));
                pass.set_index_buffer(edges.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..*count, 0, 0..1);
            }
        }
    }

    /// Copies the image out, submits `encoder` and reads the pixels back (frame `k`, for
    /// errors). An image of one flat colour drew nothing: an error, not a picture.
    fn read_back(&self, mut encoder: wgpu::CommandEncoder, k: usize) -> Result<image::RgbaImage> {
        let (w, h) = (self.options.width, self.options.height);
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.targets.resolved,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &self.targets.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.targets.padded_row),
                    rows_per_image: Some(h),
                },
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
        let gpu_error = |e: &dyn std::fmt::Display| Error::Gpu {
            reason: format!("{}: preview: {e}", self.ctx.adapter.name),
        };
        let scope = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        self.ctx.queue.submit([encoder.finish()]);
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(gpu_error(&e));
        }
        let slice = self.targets.readback.slice(..);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        self.ctx
            .device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| gpu_error(&e))?;
        let mut pixels = Vec::with_capacity((w * h * 4) as usize);
        {
            let data = slice
                .get_mapped_range()
                .map_err(|e| gpu_error(&format!("{e:?}")))?;
            for row in data
                .chunks(self.targets.padded_row as usize)
                .take(h as usize)
            {
                pixels.extend_from_slice(&row[..(w * 4) as usize]);
            }
        }
        self.targets.readback.unmap();
        let image = image::RgbaImage::from_raw(w, h, pixels).expect("width × height × 4 bytes");
        let first = *image.get_pixel(0, 0);
        if image.pixels().all(|p| *p == first) {
            return Err(Error::Gpu {
                reason: format!(
                    "{}: preview frame {} came out as one flat colour",
                    self.ctx.adapter.name,
                    k + 1
                ),
            });
        }
        Ok(image)
    }
}

/// A sequence to render, a frame at a time.
pub trait FrameSource {
    /// How many frames.
    fn frames(&self) -> usize;
    /// The box of every vertex any frame draws (the camera frames it).
    fn bounds(&self) -> Option<(Vec3, Vec3)>;
    /// Every mesh at frame `k`, one frame each with that frame's faces.
    fn meshes_at(&mut self, k: usize) -> Result<Vec<AnimatedMesh>>;
}

/// Meshes with every frame in memory (a glTF read back).
pub struct InMemory<'a>(pub &'a [AnimatedMesh]);

/// A mesh of one frame to draw: `positions` with `triangles`.
fn at_frame(
    name: &str,
    colour: [f32; 4],
    positions: Vec<Vec3>,
    triangles: &[[u32; 3]],
) -> AnimatedMesh {
    AnimatedMesh {
        name: name.to_string(),
        triangles: triangles.to_vec(),
        uvs: None,
        colour,
        frames: vec![positions],
        topology: Vec::new(),
        solid: None,
    }
}

impl FrameSource for InMemory<'_> {
    fn frames(&self) -> usize {
        self.0.iter().map(|m| m.frames.len()).max().unwrap_or(0)
    }

    fn bounds(&self) -> Option<(Vec3, Vec3)> {
        bounds(self.0)
    }

    fn meshes_at(&mut self, k: usize) -> Result<Vec<AnimatedMesh>> {
        Ok(self
            .0
            .iter()
            .map(|m| {
                let frame = m.frames[k.min(m.frames.len() - 1)].clone();
                at_frame(&m.name, m.colour, frame, m.triangles_at(k))
            })
            .collect())
    }
}

impl FrameSource for Recorded {
    fn frames(&self) -> usize {
        self.frames
    }

    fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.bounds
    }

    fn meshes_at(&mut self, k: usize) -> Result<Vec<AnimatedMesh>> {
        (0..self.meshes.len())
            .map(|m| {
                let positions = self.positions(m, k)?;
                let info = &self.meshes[m];
                Ok(at_frame(
                    &info.name,
                    info.colour,
                    positions,
                    self.triangles_at(m, k),
                ))
            })
            .collect()
    }
}

pub use crate::report::RenderSummary;

/// Renders every frame of `source` into `dir/preview/frame_<first_frame>.png …` (the shot's
/// frame numbers, four digits at least) plus `dir/preview/contact_sheet.png`, holding one
/// frame at a time.
pub fn render_sequence(
    ctx: GpuContext,
    source: &mut dyn FrameSource,
    options: RenderOptions,
    dir: &Path,
    first_frame: u32,
) -> Result<RenderSummary> {
    let adapter = ctx.describe();
    let bounds = source.bounds();
    let diagonal = bounds.map_or(1.0, |(lo, hi)| (hi - lo).length());
    let radius = tube::RADIUS_OF_DIAGONAL * diagonal;
    let frames = source.frames();
    let first = tube::ropes_as_tubes(&source.meshes_at(0)?, radius);
    let mut renderer = Renderer::framing(ctx, &first, bounds, options)?;
    let preview = dir.join("preview");
    std::fs::create_dir_all(&preview).map_err(|e| Error::io(&preview, "cannot create", e))?;
    let picks = sheet::picks(frames, sheet::THUMBNAILS);
    let mut thumbnails = Vec::new();
    let start = std::time::Instant::now();
    for k in 0..frames {
        let meshes = match k {
            0 => first.clone(),
            _ => tube::ropes_as_tubes(&source.meshes_at(k)?, radius),
        };
        let image = renderer.render(&meshes, k)?;
        let path = preview.join(format!("frame_{:04}.png", first_frame as usize + k));
        save_png(&image, &path)?;
        if picks.contains(&k) {
            thumbnails.push((k + 1, sheet::thumbnail(&image)));
        }
    }
    let ms = start.elapsed().as_secs_f64() * 1e3 / frames.max(1) as f64;
    let sheet_path = preview.join("contact_sheet.png");
    save_png(&sheet::compose(&thumbnails), &sheet_path)?;
    Ok(RenderSummary {
        frames,
        width: options.width,
        height: options.height,
        adapter,
        ms_per_frame: ms,
        contact_sheet: "preview/contact_sheet.png".into(),
    })
}

/// Saves an RGBA image as PNG.
pub fn save_png(image: &image::RgbaImage, path: &Path) -> Result<PathBuf> {
    image
        .save_with_format(path, image::ImageFormat::Png)
        .map_err(|e| Error::io(path, "cannot write", std::io::Error::other(e.to_string())))?;
    Ok(path.to_path_buf())
}
