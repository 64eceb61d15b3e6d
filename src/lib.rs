//! drape bakes garment animation: cloth as particles on a grid joined by springs, simulated with
//! Projective Dynamics solved by (red-black) Gauss-Seidel, and written out frame by frame.
//!
//! The stages, in the order data flows through them (and the order `sim::Simulation::substep`
//! runs the per-step ones):
//! 1. [`scene`]: read and validate the scene file (defaults fill everything left out).
//! 2. [`mesh`]: read mesh files (assimp, and glTF by node index) into plain assets, the
//!    animated mesh and vertex normals every later stage shares;
//!    [`character`]: animated bodies as frames at the scene's rate, and their collision shells;
//!    [`garment`]: build each garment's particle grid, springs and colouring.
//! 3. [`sim`]: lay the garments out for the solver ([`sim::Model`], [`sim::State`]) and step
//!    through the substep's stages, written once in [`sim::schedule`] (predict, solve with
//!    [`collide`] passes between shares, commit); on the CPU, or with the same stages in compute
//!    shaders on the GPU ([`gpu`]).
//! 4. [`export`]: write the frames (OBJ sequences, glTF, PC2, USD) into a staging folder;
//!    [`render`]: preview images of them, off-screen on any GPU adapter.
//! 5. [`report`]: `report.json` with counts, timings, accuracy and stability.
//!
//! [`limits`] estimates what a request asks of the machine before anything is allocated.
//! [`bake`] runs the whole pipeline; [`bench`] times the solvers and charts speed against
//! accuracy, with [`massspring`] (the mass-spring integrators of the literature) as reference.

pub mod backend;
pub mod bake;
pub mod bench;
pub mod character;
pub mod collide;
pub mod error;
pub mod export;
pub mod garment;
pub mod gpu;
pub mod limits;
pub mod massspring;
pub mod mesh;
pub mod render;
pub mod report;
pub mod scene;
pub mod sim;

pub use error::{Error, Result};
