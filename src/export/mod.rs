//! Writing baked frames as they are made: OBJ sequences with materials, glTF 2.0 with the frames
//! as morph targets, PC2 and USD point caches, Alembic caches, each a [`sink::FrameSink`] fed
//! one frame at a time (the USD layer from a spool of them), and always through a [`Staging`] folder so a failed bake leaves nothing half-written.

pub mod alembic;
pub mod gltf;
pub mod obj;
pub mod pointcache;
pub mod sequence;
pub mod sink;
pub mod spool;
pub mod staging;

pub use staging::Staging;
