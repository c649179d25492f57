//! The examples' night street: neon sign images (one size: billboard reflections keep
//! their images in one texture array) and boxes that are drawn and cast. Used by
//! `reflections` and `samaritan`.

use bevy::asset::RenderAssetUsages;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use penumbra::prelude::*;

/// All sign images share one size (one texture array).
pub const SIGN: UVec2 = UVec2::new(64, 32);

/// A neon sign's image: a glowing frame and bars of `colour` on transparent black (the
/// shape cut out by alpha), straight alpha, sRGB.
pub fn sign_image(colour: [u8; 3], bars: u32) -> Image {
    let mut data = Vec::with_capacity((SIGN.x * SIGN.y * 4) as usize);
    for y in 0..SIGN.y {
        for x in 0..SIGN.x {
            let frame = x < 3 || y < 3 || x >= SIGN.x - 3 || y >= SIGN.y - 3;
            let slot = (x.saturating_sub(8)) * bars / (SIGN.x - 16);
            let bar = (8..SIGN.x - 8).contains(&x)
                && (9..SIGN.y - 9).contains(&y)
                && (x - 8) % ((SIGN.x - 16) / bars) < (SIGN.x - 16) / bars / 2
                && slot < bars;
            let on = frame || bar;
            let [r, g, b] = colour;
            data.extend_from_slice(&if on { [r, g, b, 255] } else { [8, 8, 10, 0] });
        }
    }
    Image::new(
        Extent3d {
            width: SIGN.x,
            height: SIGN.y,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::default(),
    )
}

/// A box that is both drawn and a distance-field caster.
pub fn building(
    size: Vec3,
    at: Vec3,
    material: Handle<StandardMaterial>,
    meshes: &mut Assets<Mesh>,
) -> impl Bundle {
    (
        Mesh3d(meshes.add(Cuboid::from_size(size))),
        MeshMaterial3d(material),
        Transform::from_translation(at),
        DistanceFieldCaster {
            source: CasterSource::Cuboid {
                half_size: size * 0.5,
            },
            ..default()
        },
    )
}

/// A lit sign: what reflects (a `ReflectionBillboard` of `luminance` cd/m²) and an
/// emissive quad of the same image and size that shows it. Bevy's deferred G-buffer
/// keeps emissive light unexposed (its lighting pass cannot tell
/// `emissive_exposure_weight`): the quad carries the luminance times `exposure`.
pub fn sign(
    image: Handle<Image>,
    size: Vec2,
    luminance: f32,
    exposure: f32,
    transform: Transform,
    meshes: &mut Assets<Mesh>,
    materials: &mut Assets<StandardMaterial>,
) -> impl Bundle {
    let shown = luminance * exposure;
    (
        ReflectionBillboard {
            image: image.clone(),
            size,
            emissive: luminance,
        },
        Mesh3d(meshes.add(Rectangle::from_size(size))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::BLACK,
            emissive: LinearRgba::rgb(shown, shown, shown),
            emissive_texture: Some(image.clone()),
            base_color_texture: Some(image),
            alpha_mode: AlphaMode::Mask(0.5),
            ..default()
        })),
        transform,
    )
}
