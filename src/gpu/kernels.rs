//! Every compute pipeline, built once per device from the WGSL in `shaders/` (each kernel file
//! is compiled together with `shaders/common.wgsl`, the one definition of the shared structs,
//! and `shaders/hash.wgsl`, the grids' hash).

use super::layout::GpuParams;

/// The shared WGSL: the grids' hash, structs, bindings and constraint functions.
pub const COMMON: &str = concat!(
    include_str!("../../shaders/hash.wgsl"),
    include_str!("../../shaders/common.wgsl")
);

/// Kernel files and their entry points.
pub const KERNEL_FILES: [(&str, &str, &[&str]); 7] = [
    (
        "predict.wgsl",
        include_str!("../../shaders/predict.wgsl"),
        &["predict"],
    ),
    (
        "project.wgsl",
        include_str!("../../shaders/project.wgsl"),
        &["project"],
    ),
    (
        "sweep.wgsl",
        include_str!("../../shaders/sweep.wgsl"),
        &["sweep", "sweep_separator", "jacobi", "copy_scratch", "pbd"],
    ),
    (
        "finish.wgsl",
        include_str!("../../shaders/finish.wgsl"),
        &["finish", "finish_static", "attach", "contact_pass"],
    ),
    (
        "residual.wgsl",
        include_str!("../../shaders/residual.wgsl"),
        &["residual_partial", "residual_total"],
    ),
    (
        "particles.wgsl",
        include_str!("../../shaders/particles.wgsl"),
        &[
            "pc_clear",
            "pc_count",
            "pc_scan",
            "pc_scatter",
            "pc_order",
            "pc_push_out",
        ],
    ),
    (
        "forces.wgsl",
        include_str!("../../shaders/forces.wgsl"),
        &["wind_faces", "field_accelerate", "field_work_done"],
    ),
];

/// Collision functions, one file per module of `src/collide/`, included by the kernels that
/// call them.
pub const COLLIDERS: &str = include_str!("../../shaders/colliders.wgsl");
pub const SHELLS: &str = include_str!("../../shaders/shells.wgsl");

/// The full source of one kernel file: the common part, the collision functions it calls, then
/// the file.
pub fn source(file: &str) -> String {
    let (_, text, _) = KERNEL_FILES
        .iter()
        .find(|(f, _, _)| *f == file)
        .expect("known kernel file");
    let collisions = if file == "finish.wgsl" {
        format!("{COLLIDERS}\n{SHELLS}\n")
    } else {
        String::new()
    };
    format!("{COMMON}\n{collisions}{text}")
}

/// Bindings of group 0: 1 uniform, 6 read-write and 7 read-only storage buffers.
const READ_WRITE: std::ops::RangeInclusive<u32> = 1..=6;
const READ_ONLY: std::ops::RangeInclusive<u32> = 7..=13;

/// The pipelines of every stage and the bind group layouts they share (cloning shares them).
#[derive(Clone)]
pub struct Kernels {
    pub group0: wgpu::BindGroupLayout,
    pub group1: wgpu::BindGroupLayout,
    /// Particle–particle collisions (a uniform, one read-only and five read-write buffers),
    /// attachments (two read-only buffers) and characters' shells (three read-only buffers and
    /// the read-write nearby lists of collision passes).
    pub group2: wgpu::BindGroupLayout,
    /// Force fields (a uniform, six read-only and three read-write buffers), read with group 0
    /// by the force kernels only.
    pub group3: wgpu::BindGroupLayout,
    pub predict: wgpu::ComputePipeline,
    pub project: wgpu::ComputePipeline,
    pub sweep: wgpu::ComputePipeline,
    /// A small model's separator, every colour in one workgroup.
    pub sweep_separator: wgpu::ComputePipeline,
    pub jacobi: wgpu::ComputePipeline,
    pub copy_scratch: wgpu::ComputePipeline,
    pub pbd: wgpu::ComputePipeline,
    /// `finish` and `contact_pass` compiled for what the scene collides with: the code for what
    /// it lacks is compiled out (the WGSL `override`s `SHELLS` and `COLLIDERS`), so a kernel
    /// never pays for collisions it cannot have.
    pub finish: wgpu::ComputePipeline,
    pub finish_static: wgpu::ComputePipeline,
    pub attach: wgpu::ComputePipeline,
    pub contact_pass: wgpu::ComputePipeline,
    pub residual_partial: wgpu::ComputePipeline,
    pub residual_total: wgpu::ComputePipeline,
    pub pc_clear: wgpu::ComputePipeline,
    pub pc_count: wgpu::ComputePipeline,
    pub pc_scan: wgpu::ComputePipeline,
    pub pc_scatter: wgpu::ComputePipeline,
    pub pc_order: wgpu::ComputePipeline,
    pub pc_push_out: wgpu::ComputePipeline,
    pub wind_faces: wgpu::ComputePipeline,
    pub field_accelerate: wgpu::ComputePipeline,
    pub field_work_done: wgpu::ComputePipeline,
    /// Characters' shells placed from their skins (scenes with shells only).
    pub skin: Option<super::skin::SkinKernels>,
    /// Keyframed attachments and colliders posed for every substep of a frame.
    pub drive: super::drive::DriveKernel,
    /// The strain limit after a substep.
    pub limit: super::limit::LimitKernel,
}

/// The layout entries of a kernel file compiled with a bind group of its own (`skin.wgsl`,
/// `drive.wgsl`): `count` bindings, 0 a uniform, 1 to `last_read_only` read-only storage, the
/// rest read-write storage.
pub fn own_group_entries(count: u32, last_read_only: u32) -> Vec<wgpu::BindGroupLayoutEntry> {
    (0..count)
        .map(|binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: match binding {
                    0 => wgpu::BufferBindingType::Uniform,
                    b if b <= last_read_only => {
                        wgpu::BufferBindingType::Storage { read_only: true }
                    }
                    _ => wgpu::BufferBindingType::Storage { read_only: false },
                },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect()
}

/// A kernel file compiled with a bind group of its own (`skin.wgsl`, `drive.wgsl`,
/// `limit.wgsl`): the group's layout and one pipeline per entry point.
#[derive(Clone)]
pub struct OwnGroup {
    pub layout: wgpu::BindGroupLayout,
    pub pipelines: Vec<wgpu::ComputePipeline>,
}

/// What an [`OwnGroup`] is compiled from.
pub struct OwnGroupFile<'a> {
    /// The pipelines' and layouts' label ("drape skin").
    pub label: &'a str,
    /// The file's name, the module's label.
    pub file: &'a str,
    pub source: &'a str,
    pub entries: &'a [&'a str],
    /// Its bindings, laid out by [`own_group_entries`].
    pub bindings: u32,
    pub last_read_only: u32,
    /// The layouts of the groups before its own (None for a group it leaves unbound): its own
    /// group is number `before.len()`.
    pub before: &'a [Option<&'a wgpu::BindGroupLayout>],
}

impl OwnGroup {
    pub fn new(device: &wgpu::Device, file: &OwnGroupFile) -> OwnGroup {
        let entries = own_group_entries(file.bindings, file.last_read_only);
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some(file.label),
            entries: &entries,
        });
        let mut groups = file.before.to_vec();
        groups.push(Some(&layout));
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(file.label),
            bind_group_layouts: &groups,
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(file.file),
            source: wgpu::ShaderSource::Wgsl(file.source.into()),
        });
        let pipelines = (file.entries.iter())
            .map(|entry| {
                device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry),
                    layout: Some(&pipeline_layout),
                    module: &module,
                    entry_point: Some(entry),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
            .collect();
        OwnGroup { layout, pipelines }
    }

    /// A bind group of this layout binding each of `buffers` whole, in binding order.
    pub fn bind(
        &self,
        device: &wgpu::Device,
        label: &str,
        buffers: &[&wgpu::Buffer],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = (buffers.iter().enumerate())
            .map(|(binding, b)| wgpu::BindGroupEntry {
                binding: binding as u32,
                resource: b.as_entire_binding(),
            })
            .collect();
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &self.layout,
            entries: &entries,
        })
    }
}

fn storage(binding: u32, read_only: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage { read_only },
            has_dynamic_offset: false,
            min_binding_size: None,
        },
        count: None,
    }
}

impl Kernels {
    /// Compiles every kernel for `device`.
    /// Compiles every kernel, `finish` and `contact_pass` for a scene with characters' shells
    /// (`shells`) and analytic colliders (`colliders`) or without. (Long: the three bind group
    /// layouts, then one pipeline per entry point, listed.)
    pub fn new(device: &wgpu::Device, shells: bool, colliders: bool) -> Kernels {
        let mut entries = vec![wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: true,
                min_binding_size: wgpu::BufferSize::new(std::mem::size_of::<GpuParams>() as u64),
            },
            count: None,
        }];
        entries.extend(READ_WRITE.map(|b| storage(b, false)));
        entries.extend(READ_ONLY.map(|b| storage(b, true)));
        let group0 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("drape state and model"),
            entries: &entries,
        });
        let group1 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("drape residuals"),
            entries: &[storage(0, false), storage(1, false), storage(2, false)],
        });
        let mut contacts = vec![wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(std::mem::size_of::<
                    super::layout::GpuContacts,
                >() as u64),
            },
            count: None,
        }];
        contacts.push(storage(1, true));
        contacts.extend((2..=6).map(|b| storage(b, false)));
        contacts.extend((7..=11).map(|b| storage(b, true)));
        contacts.push(storage(12, false));
        let group2 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("drape particle collisions"),
            entries: &contacts,
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("drape"),
            bind_group_layouts: &[Some(&group0), Some(&group1), Some(&group2)],
            immediate_size: 0,
        });
        let mut fields = vec![wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        }];
        fields.extend((1..=6).map(|b| storage(b, true)));
        fields.extend((7..=9).map(|b| storage(b, false)));
        let group3 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("drape force fields"),
            entries: &fields,
        });
        // The force kernels read groups 0 and 3 only (within the storage buffers per stage
        // every other kernel needs).
        let fields_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("drape force fields"),
            bind_group_layouts: &[Some(&group0), None, None, Some(&group3)],
            immediate_size: 0,
        });
        let modules: Vec<(&str, wgpu::ShaderModule)> = KERNEL_FILES
            .iter()
            .map(|(file, _, _)| {
                let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                    label: Some(file),
                    source: wgpu::ShaderSource::Wgsl(source(file).into()),
                });
                (*file, module)
            })
            .collect();
        // `constants`: values of the kernels' `override` constants.
        let specialised = |entry: &str, constants: &[(&str, f64)]| {
            let (file, _, _) = KERNEL_FILES
                .iter()
                .find(|(_, _, entries)| entries.contains(&entry))
                .expect("entry point listed");
            let module = &modules
                .iter()
                .find(|(f, _)| f == file)
                .expect("module built")
                .1;
            let layout = if *file == "forces.wgsl" {
                &fields_layout
            } else {
                &layout
            };
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(layout),
                module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants,
                    ..Default::default()
                },
                cache: None,
            })
        };
        let pipeline = |entry: &str| specialised(entry, &[]);
        let on = |present: bool| if present { 1.0 } else { 0.0 };
        let collisions = [("SHELLS", on(shells)), ("COLLIDERS", on(colliders))];
        let specialised_for_scene = |entry: &str| specialised(entry, &collisions);
        Kernels {
            predict: pipeline("predict"),
            project: pipeline("project"),
            sweep: pipeline("sweep"),
            sweep_separator: pipeline("sweep_separator"),
            jacobi: pipeline("jacobi"),
            copy_scratch: pipeline("copy_scratch"),
            pbd: pipeline("pbd"),
            finish: specialised_for_scene("finish"),
            finish_static: pipeline("finish_static"),
            attach: pipeline("attach"),
            contact_pass: specialised_for_scene("contact_pass"),
            residual_partial: pipeline("residual_partial"),
            residual_total: pipeline("residual_total"),
            pc_clear: pipeline("pc_clear"),
            pc_count: pipeline("pc_count"),
            pc_scan: pipeline("pc_scan"),
            pc_scatter: pipeline("pc_scatter"),
            pc_order: pipeline("pc_order"),
            pc_push_out: pipeline("pc_push_out"),
            wind_faces: pipeline("wind_faces"),
            field_accelerate: pipeline("field_accelerate"),
            field_work_done: pipeline("field_work_done"),
            skin: shells.then(|| super::skin::SkinKernels::new(device)),
            drive: super::drive::DriveKernel::new(device),
            limit: super::limit::LimitKernel::new(device, &group0),
            group0,
            group1,
            group2,
            group3,
        }
    }
}
