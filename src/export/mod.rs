//! Writing baked frames: OBJ sequences now (glTF and point caches follow), always through a
//! [`Staging`] folder so a failed bake leaves nothing half-written.

pub mod obj;
pub mod staging;
pub mod writer;

pub use staging::Staging;
pub use writer::FrameWriter;
