//! The GPU backend: Projective Dynamics with red-black Gauss-Seidel (and Jacobi, PBD) in wgpu
//! compute shaders (`shaders/`), the CPU solvers of `sim` being the reference it must match.
//!
//! - [`context`]: adapter and device, errors, the `auto` choice;
//! - [`layout`]: Pod mirrors of the WGSL structs;
//! - [`kernels`]: every pipeline, built once;
//! - [`fields`]: force fields' buffers;
//! - [`skin`]: characters' shells placed from their meshes' vertices;
//! - [`drive`]: keyframed attachments and colliders posed for every substep;
//! - [`limit`]: the strain limit after each substep;
//! - [`solver`]: a scene's buffers and the frame loop.

pub mod buffers;
pub mod context;
pub mod drive;
pub mod fields;
pub mod kernels;
pub mod layout;
pub mod limit;
pub mod skin;
pub mod solver;

pub use context::GpuContext;
pub use solver::GpuSimulation;
