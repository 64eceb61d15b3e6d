//! Writing baked frames: OBJ sequences with materials, glTF 2.0 with the frames as morph
//! targets, PC2 and USD point caches, always through a [`Staging`] folder so a failed bake leaves
//! nothing half-written.

pub mod gltf;
pub mod obj;
pub mod pointcache;
pub mod sequence;
pub mod staging;
pub mod writer;

pub use staging::Staging;
pub use writer::FrameWriter;
