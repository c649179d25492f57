//! Ground truth for depth of field: the thin lens as an average of pinhole views. Each
//! view's pinhole sits at a point of the aperture (a stratified grid over its square,
//! weighted by the aperture image's transmission) and its rays pass through the same
//! point of the focal plane as the central view's, so the plane in focus stays fixed
//! (the sheared projections a GPU reference renders). Traced here against
//! [`Scene`]'s analytic shapes: nothing is shared with the scatter model.

use super::{Aperture, BokehImage, Lens};
use crate::camera::{PerspectiveCamera, Ray};
use crate::scene::Scene;
use glam::{UVec2, Vec2, Vec3};

/// The pinhole image and its distances along the view axis (the sky at `f32::INFINITY`):
/// the scatter model's input.
pub fn pinhole_image(scene: &Scene, camera: &PerspectiveCamera) -> BokehImage {
    let forward = camera.world_from_view.transform_vector3(-Vec3::Z);
    let mut image = BokehImage {
        size: UVec2::new(camera.width, camera.height),
        color: Vec::new(),
        distance: Vec::new(),
    };
    for y in 0..camera.height {
        for x in 0..camera.width {
            let ray = camera.ray(x as f32 + 0.5, y as f32 + 0.5);
            image.color.push(scene.shade(&ray));
            image.distance.push(
                scene
                    .trace(&ray)
                    .map_or(f32::INFINITY, |h| (h.position - ray.origin).dot(forward)),
            );
        }
    }
    image
}

/// The ray through pixel point `(px, py)` from the pinhole at `offset` (metres, along
/// the camera's right and up axes) that meets the central ray on the focal plane.
pub fn lens_ray(camera: &PerspectiveCamera, lens: &Lens, px: f32, py: f32, offset: Vec2) -> Ray {
    let central = camera.ray(px, py);
    let forward = camera.world_from_view.transform_vector3(-Vec3::Z);
    let on_plane = central.at(lens.focal_distance / central.dir.dot(forward));
    let origin = central.origin
        + camera.world_from_view.transform_vector3(Vec3::X) * offset.x
        + camera.world_from_view.transform_vector3(Vec3::Y) * offset.y;
    Ray {
        origin,
        dir: (on_plane - origin).normalize(),
    }
}

/// The thin lens's image: per pixel centre, the transmission-weighted mean over
/// `grid × grid` pinholes across the aperture's square (`Lens::aperture_diameter`
/// wide), the aperture image upright as seen from behind the camera. Returns the image
/// and the number of pinholes that transmit.
pub fn thin_lens_image(
    scene: &Scene,
    camera: &PerspectiveCamera,
    lens: &Lens,
    aperture: &Aperture,
    grid: u32,
) -> (Vec<Vec3>, usize) {
    let width = lens.aperture_diameter();
    let pinholes: Vec<(Vec2, f32)> = (0..grid * grid)
        .map(|k| {
            let uv = (Vec2::new((k % grid) as f32, (k / grid) as f32) + 0.5) / grid as f32;
            // Image v runs down; the camera's up is +y.
            let offset = Vec2::new(uv.x - 0.5, 0.5 - uv.y) * width;
            (offset, aperture.sample(uv))
        })
        .filter(|&(_, w)| w > 0.0)
        .collect();
    let total: f32 = pinholes.iter().map(|p| p.1).sum();
    let mut out = Vec::with_capacity((camera.width * camera.height) as usize);
    for y in 0..camera.height {
        for x in 0..camera.width {
            let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
            let sum: Vec3 = pinholes
                .iter()
                .map(|&(offset, w)| scene.shade(&lens_ray(camera, lens, px, py, offset)) * w)
                .sum();
            out.push(sum / total);
        }
    }
    (out, pinholes.len())
}
