//! Characters' shells placed on the GPU (`shaders/skin.wgsl`): a moving character whose mesh
//! keeps its topology has a [`Skin`](crate::collide::skin::Skin), each shell particle bound to a
//! triangle. The GPU keeps the binding, the mesh's triangles and welding, and a window of two
//! character frames' vertices; each frame uploads only the character frames it reaches that the
//! window lacks (usually one), and a few words per substep saying where it starts and ends. A
//! mesh whose vertices at one place (flat shading, UV seams) share their bits in every frame
//! goes up one position per weld slot (P's mannequin: 31 KB a frame on average over 30 frames,
//! 100 KB per vertex; a flat-shaded CesiumMan as little as the smooth one, 39 KB, not 232 KB),
//! against 18.7 MB of shell particles and grids at every substep before the GPU placed them. One compute pass then sums the frames' smooth normals, places every
//! substep's shell particles and builds its grid, before the frame's simulation pass reads
//! them: no CPU work per substep.

use super::buffers::ContactGroup;
use crate::collide::shell::frame_weight;
use crate::collide::ShellCollider;
use crate::sim::Simulation;
use bytemuck::{Pod, Zeroable};
use wgpu::util::DeviceExt;

/// The kernel file, after the grids' hash it shares with the shell kernels.
pub const SOURCE: &str = concat!(
    include_str!("../../shaders/hash.wgsl"),
    include_str!("../../shaders/skin.wgsl")
);

/// Entry points, in the order a frame runs them.
pub const ENTRIES: [&str; 6] = [
    "skin_normals",
    "skin_clear",
    "skin_place",
    "skin_scan",
    "skin_scatter",
    "skin_order",
];

/// The WGSL names of the bindings, in binding order (`tests/shaders.rs` checks them).
pub const BINDINGS: [&str; 15] = [
    "skin",
    "skin_info",
    "skin_time",
    "corners",
    "barycentric",
    "window",
    "mesh_triangles",
    "vertex_slot",
    "slot_start",
    "slot_faces",
    "shell_particle",
    "shell_grid",
    "keys",
    "cursor",
    "slot_normal",
];

/// Bindings 1 to this one are read-only storage (0 is the uniform, the rest read-write).
const LAST_READ_ONLY: u32 = 9;

/// Constants of a frame's placing (WGSL `SkinFrame`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuSkinFrame {
    pub shell_stride: u32,
    pub grid_stride: u32,
    pub resident: u32,
    pub bound: u32,
    pub cursor_stride: u32,
    pub pad: [u32; 3],
}

/// A shell placed on the GPU (WGSL `SkinInfo`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuSkinInfo {
    pub first: u32,
    pub count: u32,
    pub grid: u32,
    pub table: u32,
    pub cell: f32,
    pub bound: u32,
    pub window: u32,
    pub vertices: u32,
    pub cursor: u32,
    pub triangles: u32,
    pub vertex: u32,
    pub weld: u32,
    pub slots: u32,
    pub faces: u32,
    pub normals: u32,
    pub pad: u32,
}

/// Where one substep starts and ends for one shell (WGSL `SkinTime`): window slots and weights.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuSkinTime {
    pub to_a: u32,
    pub to_b: u32,
    pub to_w: f32,
    pub from_a: u32,
    pub from_b: u32,
    pub from_w: f32,
    pub pad: [u32; 2],
}

/// The WGSL structs and the sizes of their Rust mirrors, for the layout test.
pub const MIRRORS: [(&str, usize); 3] = [
    ("SkinFrame", std::mem::size_of::<GpuSkinFrame>()),
    ("SkinInfo", std::mem::size_of::<GpuSkinInfo>()),
    ("SkinTime", std::mem::size_of::<GpuSkinTime>()),
];

/// Character frames the GPU holds per shell.
const SLOTS: usize = 2;

/// Threads per workgroup (the kernels' `GROUP`) and the scan's workgroup.
const GROUP: u32 = 64;

/// The skin kernels and their bind group layout, built once per device.
#[derive(Clone)]
pub struct SkinKernels {
    own: super::kernels::OwnGroup,
}

impl SkinKernels {
    pub fn new(device: &wgpu::Device) -> SkinKernels {
        let file = super::kernels::OwnGroupFile {
            label: "drape skin",
            file: "skin.wgsl",
            source: SOURCE,
            entries: &ENTRIES,
            bindings: BINDINGS.len() as u32,
            last_read_only: LAST_READ_ONLY,
            before: &[],
        };
        SkinKernels {
            own: super::kernels::OwnGroup::new(device, &file),
        }
    }
}

/// A simulation's shells placed on the GPU: their buffers and which character frames the
/// window holds.
pub struct SkinMotion {
    group: wgpu::BindGroup,
    pipelines: Vec<wgpu::ComputePipeline>,
    times: wgpu::Buffer,
    window: wgpu::Buffer,
    /// Per resident shell: its index among the simulation's shells and its GPU record.
    resident: Vec<(usize, GpuSkinInfo)>,
    /// Per resident shell, the vertex uploaded for each weld slot when the window holds one
    /// position per slot ([`slot_vertices`]), or None when it holds every vertex.
    gathered: Vec<Option<Vec<u32>>>,
    /// Per resident shell, the character frame in each window slot.
    held: Vec<[Option<usize>; SLOTS]>,
    substeps: u32,
    /// The most particles, buckets and weld slots of a resident shell (the dispatches' width).
    widest: (u32, u32, u32),
}

/// Shells the GPU places itself: moving ones bound to a mesh (the rest are uploaded from the
/// CPU: static ones once, re-sampled ones every substep).
pub fn placed_on_gpu(sim: &Simulation) -> Vec<bool> {
    (sim.drivers.shells.iter())
        .map(|s| {
            let bound = s.skin.as_ref().map(|k| k.particle_triangle.len());
            !s.is_static() && bound == Some(s.most_particles())
        })
        .collect()
}

/// Each weld slot's first vertex, when the GPU can hold one position per slot instead of one
/// per vertex: the mesh has vertices at one place (flat-shaded, split at UV seams) and those
/// sit at the same bits in every frame (skinned alike), so the shell and its normals come out
/// the same. None when no slot holds two vertices or some slot's vertices part in a frame.
fn slot_vertices(skin: &crate::collide::skin::Skin) -> Option<Vec<u32>> {
    let weld = &skin.weld;
    if weld.slots == skin.vertex_count() {
        return None;
    }
    let mut first = vec![u32::MAX; weld.slots];
    for (v, &slot) in weld.slot.iter().enumerate() {
        if first[slot as usize] == u32::MAX {
            first[slot as usize] = v as u32;
        }
    }
    let bits = |p: glam::Vec3| p.to_array().map(f32::to_bits);
    let together = (skin.vertices.iter()).all(|frame| {
        (weld.slot.iter().enumerate())
            .all(|(v, &slot)| bits(frame[v]) == bits(frame[first[slot as usize] as usize]))
    });
    together.then_some(first)
}

/// The frames before and after fractional frame `f` of a shell with frames 0…`last`, and the
/// weight between them (`ShellCollider::advance`'s).
fn frames_at(f: f32, last: usize) -> (usize, usize, f32) {
    let k = (f.floor().max(0.0) as usize).min(last);
    let j = (k + 1).min(last);
    let w = frame_weight(f, k, j);
    // At weight 0 the later frame is not read (it may lie past the window).
    (k, if w == 0.0 { k } else { j }, w)
}

fn groups(count: u32) -> u32 {
    count.div_ceil(GROUP).clamp(1, 65_535)
}

impl SkinMotion {
    /// The buffers for `sim`'s shells that [`placed_on_gpu`] marks, over `contact`'s shell
    /// buffers; None when there are none.
    // Long: the layout of every resident shell, then ten buffers made and bound.
    pub fn new(
        device: &wgpu::Device,
        kernels: &SkinKernels,
        sim: &Simulation,
        contact: &ContactGroup,
    ) -> Option<SkinMotion> {
        let mut resident = Vec::new();
        let (mut bound, mut window, mut cursor) = (0u32, 0u32, 0u32);
        let (mut corners, mut barycentric) = (Vec::new(), Vec::new());
        let mut gathered = Vec::new();
        let mut mesh = Mesh::default();
        for (i, on) in placed_on_gpu(sim).into_iter().enumerate() {
            let (Some(skin), true) = (&sim.drivers.shells[i].skin, on) else {
                continue;
            };
            let shell = contact.shells[i];
            let welded = slot_vertices(skin);
            let vertices = welded.as_ref().map_or(skin.vertex_count(), Vec::len) as u32;
            let at = mesh.add(skin, welded.is_some());
            resident.push((
                i,
                GpuSkinInfo {
                    first: shell.first,
                    count: shell.count,
                    grid: shell.grid,
                    table: shell.table,
                    cell: shell.cell,
                    bound,
                    window,
                    vertices,
                    cursor,
                    triangles: at.triangles,
                    vertex: at.vertex,
                    weld: at.weld,
                    slots: skin.weld.slots as u32,
                    faces: at.faces,
                    normals: at.normals,
                    pad: 0,
                },
            ));
            let slot = |v: u32| skin.weld.slot[v as usize];
            corners.extend(
                (skin.corners().into_iter()).map(|[a, b, c, d]| match welded {
                    Some(_) => [slot(a), slot(b), slot(c), d],
                    None => [a, b, c, d],
                }),
            );
            gathered.push(welded);
            barycentric.extend_from_slice(&skin.barycentric);
            bound += shell.count;
            window += SLOTS as u32 * vertices;
            cursor += shell.table + 1;
        }
        if resident.is_empty() {
            return None;
        }
        let substeps = sim.substeps();
        let r = resident.len() as u32;
        let frame = GpuSkinFrame {
            shell_stride: contact.shell_stride,
            grid_stride: contact.grid_stride,
            resident: r,
            bound,
            cursor_stride: cursor,
            pad: [0; 3],
        };
        let infos: Vec<GpuSkinInfo> = resident.iter().map(|(_, info)| *info).collect();
        let buffer = |label: &str, bytes: &[u8], usage: wgpu::BufferUsages| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: bytes,
                usage,
            })
        };
        let empty = |label: &str, bytes: u64, usage: wgpu::BufferUsages| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16),
                usage,
                mapped_at_creation: false,
            })
        };
        use wgpu::BufferUsages as U;
        let refreshed = U::STORAGE | U::COPY_DST;
        let uniform = buffer("skin", bytemuck::bytes_of(&frame), U::UNIFORM);
        let times = empty("skin_time", 32 * (substeps * r) as u64, refreshed);
        let read = |label: &str, bytes: &[u8]| buffer(label, bytes, U::STORAGE);
        let corners = read("corners", bytemuck::cast_slice(&corners));
        let barycentric = read("barycentric", bytemuck::cast_slice(&barycentric));
        let window = empty("window", 16 * window as u64, refreshed);
        let triangles = read("mesh_triangles", bytemuck::cast_slice(&mesh.triangles));
        let vertex_slot = read("vertex_slot", bytemuck::cast_slice(&mesh.vertex_slot));
        let slot_start = read("slot_start", bytemuck::cast_slice(&mesh.slot_start));
        let slot_faces = read("slot_faces", bytemuck::cast_slice(&mesh.slot_faces));
        let info = read("skin_info", bytemuck::cast_slice(&infos));
        let slot_normal = empty("slot_normal", 16 * mesh.normals as u64, U::STORAGE);
        let keys = empty("keys", 4 * (substeps * bound) as u64, U::STORAGE);
        let cursors = empty("cursor", 4 * (substeps * cursor) as u64, U::STORAGE);
        let resources = [
            &uniform,
            &info,
            &times,
            &corners,
            &barycentric,
            &window,
            &triangles,
            &vertex_slot,
            &slot_start,
            &slot_faces,
            &contact.shell_particle,
            &contact.shell_grid,
            &keys,
            &cursors,
            &slot_normal,
        ];
        let group = kernels.own.bind(device, "drape skin", &resources);
        let widest = (infos.iter()).fold((0, 0, 0), |(c, t, w), i| {
            (c.max(i.count), t.max(i.table + 1), w.max(i.slots))
        });
        Some(SkinMotion {
            group,
            gathered,
            pipelines: kernels.own.pipelines.clone(),
            times,
            window,
            held: vec![[None; SLOTS]; resident.len()],
            resident,
            substeps,
            widest,
        })
    }

    /// Uploads what the frame whose substeps start at substep `first` (counted from the
    /// bake's start) needs: the character frames its substeps reach that the window lacks, and
    /// where each substep starts and ends. Returns the bytes written.
    pub fn upload(&mut self, queue: &wgpu::Queue, shells: &[ShellCollider], first: u64) -> u64 {
        let per_frame = self.substeps as f32;
        let mut times = Vec::with_capacity((self.substeps as usize) * self.resident.len());
        let mut uploaded = 0u64;
        for s in 0..self.substeps as u64 {
            let from = (first + s) as f32 / per_frame;
            let to = (first + s + 1) as f32 / per_frame;
            for (r, (shell, info)) in self.resident.iter().enumerate() {
                let skin = shells[*shell]
                    .skin
                    .as_ref()
                    .expect("resident shells have skins");
                let last = skin.vertices.len() - 1;
                let (fa, fb, fw) = frames_at(from, last);
                let (ta, tb, tw) = frames_at(to, last);
                let mut slot = |frame: usize| {
                    let at = frame % SLOTS;
                    if self.held[r][at] != Some(frame) {
                        let positions = &skin.vertices[frame];
                        let bytes: Vec<glam::Vec4> = match &self.gathered[r] {
                            Some(first) => (first.iter())
                                .map(|&v| positions[v as usize].extend(0.0))
                                .collect(),
                            None => positions.iter().map(|v| v.extend(0.0)).collect(),
                        };
                        let offset = 16 * (info.window + at as u32 * info.vertices) as u64;
                        queue.write_buffer(&self.window, offset, bytemuck::cast_slice(&bytes));
                        uploaded += 16 * bytes.len() as u64;
                        self.held[r][at] = Some(frame);
                    }
                    at as u32
                };
                times.push(GpuSkinTime {
                    to_a: slot(ta),
                    to_b: slot(tb),
                    to_w: tw,
                    from_a: slot(fa),
                    from_b: slot(fb),
                    from_w: fw,
                    pad: [0; 2],
                });
            }
        }
        // Every frame a substep reads must still be in the window after the others came in.
        debug_assert!(self.window_holds_the_frame(shells, first));
        queue.write_buffer(&self.times, 0, bytemuck::cast_slice(&times));
        uploaded + 32 * times.len() as u64
    }

    /// True when the window holds every frame the substeps from `first` read.
    fn window_holds_the_frame(&self, shells: &[ShellCollider], first: u64) -> bool {
        (0..=self.substeps as u64).all(|s| {
            let f = (first + s) as f32 / self.substeps as f32;
            self.resident.iter().enumerate().all(|(r, (shell, _))| {
                let last = shells[*shell].frames.len() - 1;
                let (a, b, _) = frames_at(f, last);
                self.held[r][a % SLOTS] == Some(a) && self.held[r][b % SLOTS] == Some(b)
            })
        })
    }

    /// Records the pass that sums the window's normals, places every substep's shell particles
    /// and builds their grids.
    pub fn record(&self, encoder: &mut wgpu::CommandEncoder) -> u32 {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("drape skin"),
            timestamp_writes: None,
        });
        pass.set_bind_group(0, &self.group, &[]);
        let (particles, buckets, slots) = self.widest;
        let r = self.resident.len() as u32;
        // (x, y) per entry point: the normals per window slot, the rest per substep.
        let s = self.substeps;
        let sizes = [
            (groups(slots), SLOTS as u32),
            (groups(buckets), s),
            (groups(particles), s),
            (1, s),
            (groups(particles), s),
            (groups(buckets), s),
        ];
        let mut dispatched = 0;
        for (pipeline, (x, y)) in self.pipelines.iter().zip(sizes) {
            pass.set_pipeline(pipeline);
            pass.dispatch_workgroups(x, y, r);
            dispatched += 1;
        }
        dispatched
    }
}

/// The resident shells' meshes as the normals kernel reads them, one after another.
#[derive(Default)]
struct Mesh {
    triangles: Vec<[u32; 4]>,
    vertex_slot: Vec<u32>,
    slot_start: Vec<u32>,
    slot_faces: Vec<u32>,
    /// Slot normals of all shells' two window frames.
    normals: u32,
}

/// Where one shell's mesh starts in [`Mesh`]'s tables.
struct MeshAt {
    triangles: u32,
    vertex: u32,
    weld: u32,
    faces: u32,
    normals: u32,
}

impl Mesh {
    /// Adds `skin`'s mesh; `by_slot`: over one vertex per weld slot ([`slot_vertices`]), its
    /// triangles' corners given as slots, each slot its own.
    fn add(&mut self, skin: &crate::collide::skin::Skin, by_slot: bool) -> MeshAt {
        let at = MeshAt {
            triangles: self.triangles.len() as u32,
            vertex: self.vertex_slot.len() as u32,
            weld: self.slot_start.len() as u32,
            faces: self.slot_faces.len() as u32,
            normals: self.normals,
        };
        // Each slot's triangles, in triangle order, once per corner there: the same lists
        // either way.
        let (start, faces) = skin.weld.slot_faces(&skin.triangles);
        let slot = |v: u32| skin.weld.slot[v as usize];
        self.triangles
            .extend(skin.triangles.iter().map(|&[a, b, c]| {
                if by_slot {
                    [slot(a), slot(b), slot(c), 0]
                } else {
                    [a, b, c, 0]
                }
            }));
        if by_slot {
            self.vertex_slot.extend(0..skin.weld.slots as u32);
        } else {
            self.vertex_slot.extend_from_slice(&skin.weld.slot);
        }
        self.slot_start.extend(start);
        self.slot_faces.extend(faces);
        self.normals += SLOTS as u32 * skin.weld.slots as u32;
        at
    }
}
