//! Perspective camera rays matching Bevy's `Camera3d` + `PerspectiveProjection`.

use glam::{Mat4, Vec3};

/// A ray with an origin and a unit direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point (world space).
    pub origin: Vec3,
    /// Unit direction.
    pub dir: Vec3,
}

impl Ray {
    /// The point at parameter `t` (world units along the ray).
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// A pinhole camera: Bevy's perspective projection with a vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerspectiveCamera {
    /// World-from-camera transform (Bevy's `GlobalTransform` of the camera entity).
    pub world_from_view: Mat4,
    /// Vertical field of view in radians (Bevy's default: π/4).
    pub fov_y: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl PerspectiveCamera {
    /// A camera at `eye` looking at `target` with +Y up, like
    /// `Transform::from_translation(eye).looking_at(target, Vec3::Y)`.
    pub fn looking_at(eye: Vec3, target: Vec3, fov_y: f32, width: u32, height: u32) -> Self {
        // `look_at_rh` gives view-from-world; Bevy's transform is its inverse.
        let world_from_view = Mat4::look_at_rh(eye, target, Vec3::Y).inverse();
        Self {
            world_from_view,
            fov_y,
            width,
            height,
        }
    }

    /// The camera ray through a point of the image in pixel coordinates (origin top-left,
    /// +y down; the centre of pixel `(x, y)` is `(x + 0.5, y + 0.5)`).
    pub fn ray(&self, px: f32, py: f32) -> Ray {
        let ndc_x = px / self.width as f32 * 2.0 - 1.0;
        let ndc_y = 1.0 - py / self.height as f32 * 2.0;
        let tan_half = (self.fov_y * 0.5).tan();
        let aspect = self.width as f32 / self.height as f32;
        let dir_view = Vec3::new(ndc_x * tan_half * aspect, ndc_y * tan_half, -1.0);
        Ray {
            origin: self.world_from_view.transform_point3(Vec3::ZERO),
            dir: self.world_from_view.transform_vector3(dir_view).normalize(),
        }
    }

    /// The pixel-space position of a world point, or `None` behind the camera.
    pub fn project(&self, world: Vec3) -> Option<(f32, f32)> {
        let v = self.world_from_view.inverse().transform_point3(world);
        if v.z >= 0.0 {
            return None;
        }
        let tan_half = (self.fov_y * 0.5).tan();
        let aspect = self.width as f32 / self.height as f32;
        let ndc_x = v.x / (-v.z * tan_half * aspect);
        let ndc_y = v.y / (-v.z * tan_half);
        Some((
            (ndc_x + 1.0) * 0.5 * self.width as f32,
            (1.0 - ndc_y) * 0.5 * self.height as f32,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_hits_target_and_projection_inverts_rays() {
        let cam = PerspectiveCamera::looking_at(
            Vec3::new(3.0, 2.0, 5.0),
            Vec3::new(0.0, 0.5, 0.0),
            std::f32::consts::FRAC_PI_4,
            160,
            120,
        );
        let centre = cam.ray(80.0, 60.0);
        let to_target = (Vec3::new(0.0, 0.5, 0.0) - centre.origin).normalize();
        assert!(centre.dir.dot(to_target) > 0.999_999);
        for &(x, y) in &[(0.5, 0.5), (159.5, 3.0), (20.0, 110.0)] {
            let r = cam.ray(x, y);
            let (px, py) = cam.project(r.at(7.0)).unwrap();
            assert!((px - x).abs() < 1e-3 && (py - y).abs() < 1e-3, "{px},{py}");
        }
        // Image top is world up.
        assert!(cam.ray(80.0, 0.0).dir.y > centre.dir.y);
        assert!(cam.ray(0.0, 60.0).dir.cross(centre.dir).y < 0.0);
    }
}
