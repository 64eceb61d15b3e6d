//! Rust mirrors of the structs in `shaders/common.wgsl`: `#[repr(C)]`, bytemuck `Pod`, with
//! explicit padding, each size checked at compile time here and against the WGSL by
//! `tests/wgsl_layout.rs`. Springs, slots and tethers upload straight from `sim::Model`.

use bytemuck::{Pod, Zeroable};

/// Per-dispatch constants (WGSL `Params`), one per 256-byte uniform slot.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuParams {
    /// g·h [m/s], w = 0.
    pub gravity_step: [f32; 4],
    pub particles: u32,
    pub springs: u32,
    pub structural: u32,
    pub colliders: u32,
    pub range_start: u32,
    pub range_end: u32,
    pub predict_next: u32,
    /// `finish`: index of this substep's first collider (colliders that move have one pose
    /// per substep).
    pub collider_base: u32,
    pub step: f32,
    pub inv_step: f32,
    pub keep: f32,
    pub omega: f32,
    /// A sweep's colour in a small model: its high side's range, after `range_start..range_end`
    /// (its low side's); empty otherwise.
    pub range2_start: u32,
    pub range2_end: u32,
    /// A small model's separator, swept in one dispatch: its colours, and where each starts
    /// (and the last ends), four to a vector.
    pub separator_colours: u32,
    pub _pad: u32,
    pub separator_start: [[u32; 4]; SEPARATOR_STARTS / 4],
}

/// Colour starts (and the end) of a small model's separator the uniform holds.
pub const SEPARATOR_STARTS: usize = crate::sim::separator::MAX_COLOURS + 1;
const _: () = assert!(SEPARATOR_STARTS % 4 == 0);

/// Static per-particle data (WGSL `Particle`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuParticle {
    pub inv_mass: f32,
    /// a = m/h² [kg/s²].
    pub inertia: f32,
    /// 1/(a + Σw), 0 for particles that never move.
    pub diag_inv: f32,
    pub contact_radius: f32,
}

/// An analytic collider (WGSL `Collider`): kind 0 plane, 1 sphere, 2 box, 3 capsule, 4 funnel,
/// 5 wedge.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuCollider {
    pub kind: u32,
    pub friction: f32,
    /// Sphere and capsule radius.
    pub radius: f32,
    /// Plane offset n·x.
    pub offset: f32,
    /// Plane normal, sphere or box centre, or capsule start; w = 0.
    pub vector: [f32; 4],
    /// Box half extents or capsule end; w = 1 when the swept test is on.
    pub second: [f32; 4],
    /// Box and wedge orientation, a unit quaternion (x, y, z, w).
    pub rotation: [f32; 4],
    /// How far the collider moved over the substep [m] (xyz; zero when static).
    pub moved: [f32; 4],
}

/// Bytes between two dispatches' parameters: wgpu's minimum uniform offset alignment.
pub const PARAMS_STRIDE: u64 = 256;

/// Constants of the particle–particle collision grid (`Contacts` in the WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuContacts {
    pub inv_cell: f32,
    pub diameter: f32,
    pub table: u32,
    pub enabled: u32,
    pub shells: u32,
    pub shell_stride: u32,
    pub grid_stride: u32,
    /// 1 when `finish` lists nearby shell particles for collision passes.
    pub nearby: u32,
}

/// A shell particle at the end of a substep (`ShellParticle` in the WGSL): position, motion
/// over the substep and skin normal, `w` unused. The CPU hands shells over as
/// [`ShellSnapshot`](crate::collide::shell::ShellSnapshot)s, whose `[Vec4; 3]` per particle has
/// this layout.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuShellParticle {
    pub position: [f32; 4],
    pub motion: [f32; 4],
    pub normal: [f32; 4],
}

/// Bytes of one shell particle in the GPU's buffers.
pub const SHELL_PARTICLE_BYTES: u64 = std::mem::size_of::<GpuShellParticle>() as u64;

const _: () =
    assert!(std::mem::size_of::<GpuShellParticle>() == std::mem::size_of::<[glam::Vec4; 3]>());

/// A character's shell (`ShellInfo` in the WGSL).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuShellInfo {
    pub first: u32,
    pub count: u32,
    pub grid: u32,
    pub table: u32,
    pub radius: f32,
    pub friction: f32,
    pub cell: f32,
    /// Bit 0: swept test on; bit 1: normals present; bit 2: never moves (its data sits in
    /// substep 0's share only).
    pub flags: u32,
}

/// `GpuShellInfo::flags` bits (`shells.wgsl` tests the same).
pub mod shell_flags {
    /// The swept test is on.
    pub const SWEPT: u32 = 1;
    /// The shell has normals.
    pub const NORMALS: u32 = 2;
    /// The shell never moves: its data sits in substep 0's share only.
    pub const STATIC: u32 = 4;
}

const _: () = assert!(std::mem::size_of::<GpuParams>() == 144);
const _: () = assert!(std::mem::size_of::<GpuParticle>() == 16);
const _: () = assert!(std::mem::size_of::<GpuCollider>() == 80);
const _: () = assert!(std::mem::size_of::<crate::sim::model::Slot>() == 12);
const _: () = assert!(std::mem::size_of::<crate::sim::model::ModelSpring>() == 12);
const _: () = assert!(std::mem::size_of::<crate::sim::model::ModelTether>() == 12);

/// `Collider.kind` on the GPU (`common.wgsl` names the same values `KIND_*`).
pub mod collider_kind {
    pub const PLANE: u32 = 0;
    pub const SPHERE: u32 = 1;
    pub const BOX: u32 = 2;
    pub const CAPSULE: u32 = 3;
    pub const FUNNEL: u32 = 4;
    pub const WEDGE: u32 = 5;
}

/// Constants the kernels share with the Rust code, by their WGSL name: `tests/shaders.rs`
/// checks that every one is declared in some kernel with this value.
pub const SHARED_CONSTANTS: [(&str, f64); 21] = [
    (
        "SWEPT_PATH_CELLS",
        crate::collide::shell::SWEPT_PATH_CELLS as f64,
    ),
    ("HASH_X", crate::collide::HASH_PRIMES[0] as f64),
    ("HASH_Y", crate::collide::HASH_PRIMES[1] as f64),
    ("HASH_Z", crate::collide::HASH_PRIMES[2] as f64),
    ("NEARBY", crate::collide::shell::NEARBY as f64),
    ("SHELL_FOUND", crate::collide::shell::SHELL_FOUND as f64),
    ("PINCH", crate::collide::shell::PINCH as f64),
    ("INTO_COLLIDER", crate::collide::INTO_COLLIDER as f64),
    ("SKIP_STEPS", crate::collide::particles::SKIP_STEPS as f64),
    ("B_END", crate::sim::model::Slot::B_END as f64),
    ("TINY_LENGTH", crate::sim::constraint::TINY_LENGTH as f64),
    ("KIND_PLANE", collider_kind::PLANE as f64),
    ("KIND_SPHERE", collider_kind::SPHERE as f64),
    ("KIND_BOX", collider_kind::BOX as f64),
    ("KIND_CAPSULE", collider_kind::CAPSULE as f64),
    ("KIND_FUNNEL", collider_kind::FUNNEL as f64),
    ("KIND_WEDGE", collider_kind::WEDGE as f64),
    ("GUST_WAVES", crate::sim::forces::GPU_WAVES as f64),
    ("SHELL_SWEPT", shell_flags::SWEPT as f64),
    ("SHELL_NORMALS", shell_flags::NORMALS as f64),
    ("SHELL_STATIC", shell_flags::STATIC as f64),
];

/// The force kernels' structs (`shaders/forces.wgsl`) with the sizes of their Rust mirrors.
pub const FIELD_MIRRORS: [(&str, usize); 3] = [
    (
        "FieldCounts",
        std::mem::size_of::<super::fields::GpuFieldCounts>(),
    ),
    (
        "FieldWind",
        std::mem::size_of::<crate::sim::forces::GpuWind>(),
    ),
    (
        "FieldWave",
        std::mem::size_of::<crate::sim::forces::GpuWave>(),
    ),
];

/// `(WGSL struct, [(member, byte offset in the Rust mirror)])` from the Rust fields of the same
/// names.
macro_rules! offsets {
    ($name:literal, $t:ty, [$($field:ident),* $(,)?]) => {
        ($name, &[$((stringify!($field), std::mem::offset_of!($t, $field))),*])
    };
}

/// Every member of every mirrored WGSL struct with its offset in the Rust mirror, for the layout
/// test (sizes alone would miss two members swapped).
pub const MIRROR_OFFSETS: [(&str, &[(&str, usize)]); 9] = [
    offsets!(
        "Params",
        GpuParams,
        [
            gravity_step,
            particles,
            springs,
            structural,
            colliders,
            range_start,
            range_end,
            predict_next,
            collider_base,
            step,
            inv_step,
            keep,
            omega,
            range2_start,
            range2_end,
            separator_colours,
            separator_start
        ]
    ),
    offsets!(
        "Particle",
        GpuParticle,
        [inv_mass, inertia, diag_inv, contact_radius]
    ),
    offsets!(
        "Collider",
        GpuCollider,
        [kind, friction, radius, offset, vector, second, rotation, moved]
    ),
    offsets!(
        "Contacts",
        GpuContacts,
        [
            inv_cell,
            diameter,
            table,
            enabled,
            shells,
            shell_stride,
            grid_stride,
            nearby
        ]
    ),
    offsets!(
        "ShellInfo",
        GpuShellInfo,
        [first, count, grid, table, radius, friction, cell, flags]
    ),
    offsets!(
        "ShellParticle",
        GpuShellParticle,
        [position, motion, normal]
    ),
    offsets!("Slot", crate::sim::model::Slot, [neighbour, spring, weight]),
    offsets!("Spring", crate::sim::model::ModelSpring, [a, b, rest]),
    offsets!(
        "Tether",
        crate::sim::model::ModelTether,
        [particle, pin, rest]
    ),
];

/// Every WGSL struct with the size of its Rust mirror, for the layout test.
pub const MIRRORS: [(&str, usize); 9] = [
    ("Params", std::mem::size_of::<GpuParams>()),
    ("Contacts", std::mem::size_of::<GpuContacts>()),
    ("ShellInfo", std::mem::size_of::<GpuShellInfo>()),
    ("ShellParticle", std::mem::size_of::<GpuShellParticle>()),
    ("Particle", std::mem::size_of::<GpuParticle>()),
    ("Collider", std::mem::size_of::<GpuCollider>()),
    ("Slot", std::mem::size_of::<crate::sim::model::Slot>()),
    (
        "Spring",
        std::mem::size_of::<crate::sim::model::ModelSpring>(),
    ),
    (
        "Tether",
        std::mem::size_of::<crate::sim::model::ModelTether>(),
    ),
];
