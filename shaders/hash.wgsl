// The spatial hash of a grid cell, the one definition every grid's kernels use (the shells',
// particle collisions' and the skin's); compiled ahead of common.wgsl and of skin.wgsl.

// The hash's primes (collide::HASH_PRIMES, checked by tests/shaders.rs).
const HASH_X: i32 = 73856093;
const HASH_Y: i32 = 19349663;
const HASH_Z: i32 = 83492791;

// The spatial hash of cell `c`, wrapping 32-bit products (collide::hash_cell).
fn hash_cell(c: vec3<i32>) -> u32 {
    return bitcast<u32>((c.x * HASH_X) ^ (c.y * HASH_Y) ^ (c.z * HASH_Z));
}

