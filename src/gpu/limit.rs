//! Strain limiting on the GPU (`shaders/limit.wgsl`; `solver.strain_limit`): the structural
//! springs in the CPU's colour order ([`LimitOrder`]) are uploaded with the model, and after
//! each substep's `finish` one dispatch of one workgroup runs every sweep the substep needs, as
//! `sim::limit` does on the CPU. The springs the first sweep of each substep found past the
//! limit are summed on the GPU and read back with the frame (`report.json`'s
//! `strain_limited_per_frame`). No CPU work per substep.

use super::buffers::{init, READ, RW};
use crate::sim::limit::{LimitOrder, SWEEPS};
use bytemuck::{Pod, Zeroable};

/// The kernel file, after common.wgsl (its group-0 bindings and `Spring`).
pub fn source() -> String {
    format!(
        "{}\n{}",
        super::kernels::COMMON,
        include_str!("../../shaders/limit.wgsl")
    )
}

/// The entry point.
pub const ENTRY: &str = "limit_strain";

/// The bind group's index in the kernel's layout (group 0 is the state's).
pub const GROUP_INDEX: u32 = 3;

/// The WGSL names of the bindings of group 3, in binding order (`tests/shaders.rs` checks them).
pub const BINDINGS: [&str; 4] = ["limit", "limit_colour_start", "limit_order", "limit_pulled"];

/// Bindings 1 to this one are read-only storage (0 is the uniform, the rest read-write).
const LAST_READ_ONLY: u32 = 2;

/// The limit's constants (WGSL `Limit`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuLimit {
    pub strain: f32,
    pub colours: u32,
    pub sweeps: u32,
    pub pad: u32,
}

/// The WGSL structs and the sizes of their Rust mirrors, for the layout test.
pub const MIRRORS: [(&str, usize); 1] = [("Limit", std::mem::size_of::<GpuLimit>())];

/// The kernel and its bind group layout, built once per device.
#[derive(Clone)]
pub struct LimitKernel {
    own: super::kernels::OwnGroup,
}

impl LimitKernel {
    /// The kernel, reading group 0 through `group0` (the other kernels' state and model).
    pub fn new(device: &wgpu::Device, group0: &wgpu::BindGroupLayout) -> LimitKernel {
        let source = source();
        let file = super::kernels::OwnGroupFile {
            label: "drape strain limit",
            file: "limit.wgsl",
            source: &source,
            entries: &[ENTRY],
            bindings: BINDINGS.len() as u32,
            last_read_only: LAST_READ_ONLY,
            before: &[Some(group0), None, None],
        };
        LimitKernel {
            own: super::kernels::OwnGroup::new(device, &file),
        }
    }
}

/// A simulation's strain limit on the GPU.
pub struct StrainLimit {
    pub group: wgpu::BindGroup,
    pub pipeline: wgpu::ComputePipeline,
    /// Springs past the limit this frame (one u32), read back with the frame.
    pub pulled: wgpu::Buffer,
}

impl StrainLimit {
    /// The limit `strain` on the structural springs of `order` (the kernel reads the state
    /// through group 0).
    pub fn new(
        device: &wgpu::Device,
        kernel: &LimitKernel,
        order: &LimitOrder,
        strain: f32,
    ) -> StrainLimit {
        let constants = GpuLimit {
            strain,
            colours: order.colours() as u32,
            sweeps: SWEEPS,
            pad: 0,
        };
        let uniform = init(
            device,
            "limit",
            bytemuck::bytes_of(&constants),
            wgpu::BufferUsages::UNIFORM,
        );
        let colour_start = init(
            device,
            "limit_colour_start",
            bytemuck::cast_slice(&order.colour_start),
            READ,
        );
        let springs = init(
            device,
            "limit_order",
            bytemuck::cast_slice(&order.springs),
            READ,
        );
        let pulled = init(device, "limit_pulled", &[0u8; 4], RW);
        let resources = [&uniform, &colour_start, &springs, &pulled];
        let group = kernel.own.bind(device, "drape strain limit", &resources);
        StrainLimit {
            group,
            pipeline: kernel.own.pipelines[0].clone(),
            pulled,
        }
    }
}
