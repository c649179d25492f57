//! What the hair tests share: an orthographic camera of one world unit per pixel under
//! 4× MSAA (HDR, no tonemapping: a white strand's resolved value is its coverage), the
//! atlas of one hair whose alpha falls off across it, and that atlas's bilinear alpha on
//! the CPU.

#![allow(dead_code, reason = "each test uses part of it")]

use bevy::camera::{Hdr, ScalingMode};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy_penumbra_cinematic::hair::Strand;

/// The atlas: one hair, `ATLAS_W` texels across, 4 along.
pub const ATLAS_W: usize = 16;

/// The atlas's alpha across the hair (texel i of `ATLAS_W`): a rounded bump, opaque in
/// the middle, clear at the edges.
pub fn atlas_alpha(i: usize) -> u8 {
    let x = (i as f32 + 0.5) / ATLAS_W as f32 * 2.0 - 1.0;
    ((1.0 - x * x).max(0.0).sqrt() * 255.0).round() as u8
}

/// Bilinear alpha of the atlas at strip point `uv` (clamp to edge; the atlas is constant
/// along the hair).
pub fn atlas_sample(uv: Vec2) -> f32 {
    let x = uv.y.clamp(0.0, 1.0) * ATLAS_W as f32 - 0.5;
    let i = x.floor();
    let t = x - i;
    let at = |k: f32| atlas_alpha(k.clamp(0.0, ATLAS_W as f32 - 1.0) as usize) as f32 / 255.0;
    at(i) * (1.0 - t) + at(i + 1.0) * t
}

/// The atlas as an image.
pub fn atlas_image() -> Image {
    let mut texels = Vec::new();
    for _ in 0..4 {
        for i in 0..ATLAS_W {
            texels.extend([255, 255, 255, atlas_alpha(i)]);
        }
    }
    Image::new(
        Extent3d {
            width: ATLAS_W as u32,
            height: 4,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        texels,
        TextureFormat::Rgba8Unorm,
        bevy::asset::RenderAssetUsages::RENDER_WORLD,
    )
}

/// A world point of pixel coordinates `p` (y down) in a view `height` pixels tall.
pub fn to_world(p: Vec2, height: u32) -> Vec3 {
    Vec3::new(p.x, height as f32 - p.y, 0.0)
}

/// A straight strand from pixel `a` to pixel `b`, `width` pixels wide.
pub fn pixel_strand(a: Vec2, b: Vec2, width: f32, height: u32) -> Strand {
    Strand {
        points: vec![to_world(a, height), to_world(b, height)],
        width,
        slot: 0,
    }
}

/// The orthographic camera: world (x, y) at pixel (x, height − y), black background.
pub fn pixel_camera(width: u32, height: u32) -> impl Bundle {
    (
        Camera3d::default(),
        Hdr,
        Tonemapping::None,
        Msaa::Sample4,
        Camera {
            clear_color: ClearColorConfig::Custom(Color::BLACK),
            ..default()
        },
        Projection::Orthographic(OrthographicProjection {
            scaling_mode: ScalingMode::Fixed {
                width: width as f32,
                height: height as f32,
            },
            ..OrthographicProjection::default_3d()
        }),
        Transform::from_xyz(width as f32 / 2.0, height as f32 / 2.0, 10.0).looking_at(
            Vec3::new(width as f32 / 2.0, height as f32 / 2.0, 0.0),
            Vec3::Y,
        ),
    )
}

/// Saves a coverage image (grey levels) as `name.png` in the test output folder.
pub fn save_coverage(name: &str, image: &[[f32; 4]], width: u32, height: u32) {
    let dir = penumbra_test::output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let bytes: Vec<u8> = image
        .iter()
        .flat_map(|p| {
            let v = (p[0].clamp(0.0, 1.0) * 255.0) as u8;
            [v, v, v, 255]
        })
        .collect();
    penumbra_test::image::RgbaImage::from_raw(width, height, bytes)
        .unwrap()
        .save(dir.join(format!("{name}.png")))
        .unwrap();
}
