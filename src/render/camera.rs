//! Where the preview looks from: a camera that frames everything the bake moves through, a key
//! light with an orthographic shadow frustum around it, and the floor under it all.

use glam::{Mat4, Vec3};

/// Camera, lights and floor of a preview, fixed for the whole sequence so frames compare.
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub eye: Vec3,
    pub view_proj: Mat4,
    pub light_view_proj: Mat4,
    /// Unit vectors towards the key (shadowing) and the fill light.
    pub key: Vec3,
    pub fill: Vec3,
    /// Height of the floor [m] and its half extent.
    pub floor_y: f32,
    pub floor_half: f32,
    pub floor_centre: Vec3,
}

/// Vertical field of view [rad].
const FOV_Y: f32 = 0.61; // 35°

impl View {
    /// Frames the box `lo`..`hi` (every vertex of every frame) for an image `aspect` wide per unit
    /// of height, looking from the front right and a little above.
    pub fn framing(lo: Vec3, hi: Vec3, aspect: f32) -> View {
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(1e-3);
        let (azimuth, elevation) = (35f32.to_radians(), 18f32.to_radians());
        let towards_eye = Vec3::new(
            azimuth.sin() * elevation.cos(),
            elevation.sin(),
            azimuth.cos() * elevation.cos(),
        );
        // Fit the bounding sphere in the narrower of the two fields of view.
        let half = (FOV_Y * 0.5).min(((FOV_Y * 0.5).tan() * aspect).atan());
        let distance = radius / half.sin() * 1.02;
        let eye = centre + towards_eye * distance;
        let near = (distance - 2.0 * radius).max(0.01 * distance);
        let far = distance + 4.0 * radius;
        let view = Mat4::look_at_rh(eye, centre, Vec3::Y);
        let proj = Mat4::perspective_rh(FOV_Y, aspect, near, far);
        let key = Vec3::new(-0.45, 1.0, 0.6).normalize();
        let fill = Vec3::new(0.8, 0.35, -0.3).normalize();
        // The shadow frustum covers the sphere and the floor around it.
        let extent = 1.8 * radius;
        let light_eye = centre + key * 4.0 * radius;
        // The key light is 37° off vertical, so Y is a valid up vector for its view.
        let light_view = Mat4::look_at_rh(light_eye, centre, Vec3::Y);
        let light_proj = Mat4::orthographic_rh(-extent, extent, -extent, extent, 0.0, 8.0 * radius);
        View {
            eye,
            view_proj: proj * view,
            light_view_proj: light_proj * light_view,
            key,
            fill,
            floor_y: lo.y - 0.01 * radius,
            floor_half: 3.0 * radius,
            floor_centre: Vec3::new(centre.x, lo.y - 0.01 * radius, centre.z),
        }
    }
}
