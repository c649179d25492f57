//! CPU model of deferred shading with 4× MSAA (#18; Samaritan, GDC 2011; Lauritzen,
//! *Deferred Rendering for Current and Future Rendering Pipelines*, 2010): a
//! multisampled G-buffer, each pixel classified as an **edge** when its samples differ
//! — in depth beyond what the surface's own slope explains, in normal beyond a cone, in
//! material, or where some sample sees nothing — then shaded once where they agree (from
//! the mean of the samples' G-buffer: the standard pattern's centroid is the pixel
//! centre, so the model shades the centre; sample 0 alone sits 0.4 px off and errs by
//! up to 0.07 on a small ball's shading gradient) and once per sample on edges, and
//! resolved with a box filter over the samples.
//!
//! The scene side is a small rasteriser of [`Scene`]: each sample is the hit of the
//! camera ray through its position in the pixel (Vulkan's standard 4× pattern,
//! [`SAMPLE_POSITIONS_4X`]); the depth slope is what the GPU derives from sample 0's
//! G-buffer position and normal (`lighting/msaa_view.wgsl`) — the change of view depth
//! over one pixel across sample 0's tangent plane, in x plus in y. Ground truth for the image is 4 × 4 supersampling
//! ([`render_truth`]), and for the classifier the samples' primitive ids
//! ([`primitive_edge`]).

use crate::camera::{PerspectiveCamera, Ray};
use crate::pbr;
use crate::pbr::{DirectionalLight, Material};
use crate::scene::{Hit, Object, Scene, Shape};
use glam::{Vec2, Vec3};

/// Vulkan's (and D3D's) standard 4× sample positions within a pixel, from its top-left
/// corner.
pub const SAMPLE_POSITIONS_4X: [Vec2; 4] = [
    Vec2::new(0.375, 0.125),
    Vec2::new(0.875, 0.375),
    Vec2::new(0.125, 0.625),
    Vec2::new(0.625, 0.875),
];

/// What the G-buffer holds of one sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GSample {
    /// View depth (distance along the camera's forward axis), metres.
    pub view_z: f32,
    /// Unit world normal.
    pub normal: Vec3,
    /// Material id.
    pub material: u32,
}

/// One pixel of the multisampled G-buffer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GPixel {
    /// The samples (`None`: nothing drawn there — the sky).
    pub samples: [Option<GSample>; 4],
    /// `|∂z/∂x| + |∂z/∂y|` of sample 0's surface, metres per pixel.
    pub z_slope: f32,
}

/// The edge test's thresholds (the shader's uniform).
pub use penumbra_df_core::msaa::EdgeParams as EdgeTest;

/// Whether a pixel's samples differ (it is shaded per sample).
pub fn is_edge(pixel: &GPixel, test: &EdgeTest) -> bool {
    let count = (test.sample_count as usize).clamp(1, 4);
    let Some(first) = pixel.samples[0] else {
        return pixel.samples[..count].iter().any(Option::is_some);
    };
    let allowed = test.slope_scale * pixel.z_slope + test.relative_depth * first.view_z;
    pixel.samples[1..count].iter().any(|s| match s {
        None => true,
        Some(s) => {
            s.material != first.material
                || (s.view_z - first.view_z).abs() > allowed
                || s.normal.dot(first.normal) < test.normal_cos
        }
    })
}

/// The resolve: the mean of the samples' colours.
pub fn resolve(colors: &[Vec3]) -> Vec3 {
    colors.iter().copied().sum::<Vec3>() / colors.len().max(1) as f32
}

/// How a pixel is shaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Shading {
    /// One sample at the pixel centre (no anti-aliasing).
    NoAa,
    /// Per pixel where the samples agree, per sample on edges.
    Classified,
    /// Every sample shaded.
    PerSample,
}

/// A rendered pixel: its linear colour, whether it was classified an edge, and whether
/// its samples hit different primitives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MsaaPixel {
    /// Linear radiance × exposure.
    pub color: Vec3,
    /// Shaded per sample by the classifier.
    pub edge: bool,
    /// Its samples see different primitives (or some see none): a true edge.
    pub primitive_edge: bool,
}

/// The camera's forward axis (world).
fn forward(camera: &PerspectiveCamera) -> Vec3 {
    camera
        .world_from_view
        .transform_vector3(-Vec3::Z)
        .normalize()
}

/// The view depth of the ray through pixel position `(px, py)` across the plane of
/// `hit`.
fn plane_z(camera: &PerspectiveCamera, hit: &Hit, px: f32, py: f32) -> Option<f32> {
    let ray = camera.ray(px, py);
    let denom = ray.dir.dot(hit.normal);
    if denom.abs() < 1e-6 {
        return None;
    }
    let t = (hit.position - ray.origin).dot(hit.normal) / denom;
    (t > 0.0).then(|| (ray.at(t) - ray.origin).dot(forward(camera)))
}

/// The G-buffer pixel `(x, y)` of `scene` and its sample rays. Material ids are the
/// objects' indices; `primitives` the same (`None`: the sky).
pub fn sample_pixel(
    scene: &Scene,
    camera: &PerspectiveCamera,
    x: u32,
    y: u32,
) -> (GPixel, [Ray; 4], [Option<usize>; 4]) {
    let f = forward(camera);
    let rays = SAMPLE_POSITIONS_4X.map(|s| camera.ray(x as f32 + s.x, y as f32 + s.y));
    let hits = rays.map(|r| scene.trace(&r));
    let samples = std::array::from_fn(|i| {
        hits[i].map(|h| GSample {
            view_z: (h.position - rays[i].origin).dot(f),
            normal: h.normal,
            material: h.object as u32,
        })
    });
    let z_slope = hits[0].map_or(0.0, |h| {
        let s = SAMPLE_POSITIONS_4X[0];
        let (px, py) = (x as f32 + s.x, y as f32 + s.y);
        let z = (h.position - rays[0].origin).dot(f);
        let dx = plane_z(camera, &h, px + 1.0, py).map_or(f32::INFINITY, |v| (v - z).abs());
        let dy = plane_z(camera, &h, px, py + 1.0).map_or(f32::INFINITY, |v| (v - z).abs());
        dx + dy
    });
    (
        GPixel { samples, z_slope },
        rays,
        hits.map(|h| h.map(|h| h.object)),
    )
}

/// Whether samples see different primitives (or some see none and some do).
pub fn primitive_edge(primitives: &[Option<usize>; 4]) -> bool {
    primitives.iter().any(|p| *p != primitives[0])
}

/// Pixel `(x, y)` rendered with `shading`.
pub fn render_pixel(
    scene: &Scene,
    camera: &PerspectiveCamera,
    x: u32,
    y: u32,
    test: &EdgeTest,
    shading: Shading,
) -> MsaaPixel {
    let (pixel, rays, primitives) = sample_pixel(scene, camera, x, y);
    let edge = is_edge(&pixel, test);
    let color = match shading {
        Shading::NoAa => scene.shade(&camera.ray(x as f32 + 0.5, y as f32 + 0.5)),
        // The samples' mean G-buffer: the pixel centre (the pattern's centroid).
        Shading::Classified if !edge => scene.shade(&camera.ray(x as f32 + 0.5, y as f32 + 0.5)),
        Shading::Classified | Shading::PerSample => resolve(&rays.map(|r| scene.shade(&r))),
    };
    MsaaPixel {
        color,
        edge,
        primitive_edge: primitive_edge(&primitives),
    }
}

/// The truth: pixel `(x, y)` supersampled on a 4 × 4 grid, box-filtered.
pub fn render_truth(scene: &Scene, camera: &PerspectiveCamera, x: u32, y: u32) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for j in 0..4 {
        for i in 0..4 {
            let (px, py) = (
                x as f32 + (i as f32 + 0.5) / 4.0,
                y as f32 + (j as f32 + 0.5) / 4.0,
            );
            sum += scene.shade(&camera.ray(px, py));
        }
    }
    sum / 16.0
}

/// A linear colour as displayed: clamped to [0, 1], sRGB-encoded.
pub fn display(c: Vec3) -> Vec3 {
    c.clamp(Vec3::ZERO, Vec3::ONE)
        .to_array()
        .map(pbr::linear_to_srgb)
        .into()
}

/// The fence's image size.
pub const FENCE_SIZE: (u32, u32) = (96, 64);

fn rect(center: Vec3, normal: Vec3, u: Vec3, half: Vec2, color: Vec3) -> Object {
    Object {
        shape: Shape::Rect {
            center,
            normal: normal.normalize(),
            u: u.normalize(),
            half_size: half,
        },
        material: Material {
            base_color: color,
            ..Material::default()
        },
    }
}

/// The test scene: thin high-contrast geometry against a bright sky: three 2 cm wires (0.4 px), a grille
/// of 3 cm bars, a ball, and a tilted ground whose far edge meets the sky.
pub fn fence() -> Scene {
    let dark = Vec3::splat(0.04);
    let mut objects = vec![rect(
        Vec3::new(0.0, 0.0, -2.0),
        Vec3::new(0.0, 1.0, 0.15),
        Vec3::X,
        Vec2::new(5.0, 4.0),
        Vec3::new(0.5, 0.45, 0.4),
    )];
    for (i, y) in [1.45, 1.62, 1.8].into_iter().enumerate() {
        objects.push(rect(
            Vec3::new(0.0, y, 0.2 * i as f32),
            Vec3::Z,
            Vec3::new(1.0, 0.08 * i as f32, 0.0),
            Vec2::new(4.0, 0.01),
            dark,
        ));
    }
    for i in 0..9 {
        objects.push(rect(
            Vec3::new(-1.9 + 0.14 * i as f32, 0.75, 0.6),
            Vec3::Z,
            Vec3::X,
            Vec2::new(0.015, 0.55),
            dark,
        ));
    }
    objects.push(Object {
        shape: Shape::Sphere {
            center: Vec3::new(1.3, 0.55, 0.3),
            radius: 0.5,
        },
        material: Material {
            base_color: Vec3::new(0.7, 0.15, 0.1),
            ..Material::default()
        },
    });
    Scene {
        objects,
        lights: vec![(
            DirectionalLight {
                direction_to_light: Vec3::new(0.3, 1.0, 0.5).normalize(),
                color_lux: Vec3::splat(8000.0),
            },
            false,
        )],
        ambient: Vec3::splat(400.0),
        background: Vec3::new(1.6, 1.8, 2.2),
        exposure: pbr::exposure_from_ev100(9.7),
    }
}

/// The fence's camera ([`FENCE_SIZE`] pixels).
pub fn fence_camera() -> PerspectiveCamera {
    PerspectiveCamera::looking_at(
        Vec3::new(0.3, 1.3, 4.2),
        Vec3::new(0.0, 1.0, 0.0),
        std::f32::consts::FRAC_PI_4,
        FENCE_SIZE.0,
        FENCE_SIZE.1,
    )
}

#[cfg(test)]
mod tests;
