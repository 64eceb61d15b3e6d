//! Writing baked frames: OBJ sequences now (glTF and point caches follow), always through a
//! [`Staging`] folder so a failed bake leaves nothing half-written.

pub mod obj;
pub mod staging;

pub use staging::Staging;
