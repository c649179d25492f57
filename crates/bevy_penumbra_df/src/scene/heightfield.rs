//! [`DistanceFieldHeightfield`]: terrain from a height image, as a distance-field
//! caster for the CPU queries ([`super::DistanceFieldQuery`]) and the global distance
//! field (composed into it like objects; the GPU form is
//! `penumbra_df_core::heightfield::HeightfieldTexture`, uploaded by `render.rs` while the
//! scene has a terrain). The distance is `penumbra_df_core::heightfield`'s conservative
//! one (its module docs: per-tile slope bounds).

use bevy::asset::AssetEvent;
use bevy::prelude::*;
use bevy::render::render_resource::TextureFormat;
use penumbra_df_core::heightfield::Heightfield;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Terrain from a single-channel height image over a world rectangle centred on the
/// entity (x and z; its rotation and scale are ignored — a warning says so), solid
/// below. A caster of the CPU queries, the global distance field, DFAO and
/// distance-field shadows (module docs).
///
/// Cost: the heights once on the CPU (4 bytes a sample) and a slope bound per 8 × 8
/// cells, rebuilt when the image or the settings change, and the same again on the GPU
/// (one `R32Float` texture for all terrains), uploaded only then. Per frame: each DFAO
/// cone and each shadow ray near a terrain marches it (up to the steps of the pass).
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone)]
#[require(Transform)]
pub struct DistanceFieldHeightfield {
    /// The heights, the image's first channel: `R8Unorm`, `R16Unorm`, `R32Float`, or as
    /// Bevy loads PNGs — `Rgba8Unorm(Srgb)` (8-bit, grey or colour), `R16Uint` (16-bit
    /// grey, the usual terrain heightmap), `Rg16Uint` (with alpha), `Rgba16Unorm` or
    /// `Rgba16Uint` — at least 2 × 2 texels, row 0 at −z. Other formats or sizes are
    /// refused with one warning.
    pub heights: Handle<Image>,
    /// World size in x and z, metres. Must be finite and positive.
    pub size: Vec2,
    /// Metres per unit of the image's value (unorm values run 0–1). Default 1.
    pub height_scale: f32,
}

impl Default for DistanceFieldHeightfield {
    fn default() -> Self {
        Self {
            heights: Handle::default(),
            size: Vec2::splat(100.0),
            height_scale: 1.0,
        }
    }
}

/// The terrain a [`DistanceFieldHeightfield`] made (world coordinates), or why none.
#[derive(Component, Clone, Debug)]
pub enum HeightfieldTerrain {
    /// Built.
    Ready(Arc<Heightfield>),
    /// Refused (warned once).
    Refused(String),
}

/// Heights in metres from an image, or why not.
pub fn image_heights(image: &Image, height_scale: f32) -> Result<(UVec2, Vec<f32>), String> {
    let size = image.size();
    let Some(data) = image.data.as_ref() else {
        return Err(
            "the height image has no CPU data (keep its RenderAssetUsages::MAIN_WORLD)".into(),
        );
    };
    let n = (size.x as usize) * (size.y as usize);
    let format = image.texture_descriptor.format;
    // The first channel of each texel: `stride` bytes apart.
    let unorm8 = |stride: usize| -> Vec<f32> {
        data.chunks_exact(stride)
            .take(n)
            .map(|c| f32::from(c[0]) / 255.0)
            .collect()
    };
    let unorm16 = |stride: usize| -> Vec<f32> {
        data.chunks_exact(stride)
            .take(n)
            .map(|c| f32::from(u16::from_le_bytes([c[0], c[1]])) / 65535.0)
            .collect()
    };
    let values: Vec<f32> = match format {
        TextureFormat::R8Unorm => unorm8(1),
        // 8-bit PNGs, grey ones too (Bevy expands them to RGBA): the red byte as it is.
        TextureFormat::Rgba8Unorm | TextureFormat::Rgba8UnormSrgb => unorm8(4),
        // 16-bit grey PNGs (the usual terrain heightmap: Bevy loads them as `R16Uint`,
        // with alpha as `Rg16Uint`) and 16-bit colour ones: 0 to 65535.
        TextureFormat::R16Unorm | TextureFormat::R16Uint => unorm16(2),
        TextureFormat::Rg16Uint => unorm16(4),
        TextureFormat::Rgba16Unorm | TextureFormat::Rgba16Uint => unorm16(8),
        TextureFormat::R32Float => data
            .chunks_exact(4)
            .take(n)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        other => {
            return Err(format!(
                "height image format {other:?} is not one of R8Unorm, Rgba8Unorm(Srgb), \
                 R16Unorm, R16Uint, Rg16Uint, Rgba16Unorm, Rgba16Uint or R32Float"
            ));
        }
    };
    if values.len() != n || size.x < 2 || size.y < 2 {
        return Err(format!(
            "height image of {}×{} with {} samples: needs at least 2 × 2, one value each",
            size.x,
            size.y,
            values.len()
        ));
    }
    if !height_scale.is_finite() {
        return Err(format!("height_scale = {height_scale} is not finite"));
    }
    let heights: Vec<f32> = values.into_iter().map(|v| v * height_scale).collect();
    // A float image can hold NaN or infinities, and a huge height times the scale can
    // overflow: a terrain must be finite everywhere.
    if let Some(i) = heights.iter().position(|h| !h.is_finite()) {
        return Err(format!(
            "height image texel ({}, {}) is {} (after height_scale {height_scale}): heights \
             must be finite",
            i % size.x as usize,
            i / size.x as usize,
            heights[i]
        ));
    }
    Ok((size, heights))
}

type HeightfieldItem = (
    Entity,
    Ref<'static, DistanceFieldHeightfield>,
    Ref<'static, GlobalTransform>,
    Option<&'static HeightfieldTerrain>,
);

/// (Re)builds the terrain of heightfields whose settings, transform or image changed.
pub(super) fn build_heightfields(
    mut commands: Commands,
    images: Res<Assets<Image>>,
    mut image_events: MessageReader<AssetEvent<Image>>,
    heightfields: Query<HeightfieldItem>,
) {
    let changed_images: Vec<AssetId<Image>> = image_events
        .read()
        .filter_map(|e| match e {
            AssetEvent::Added { id }
            | AssetEvent::Modified { id }
            | AssetEvent::LoadedWithDependencies { id } => Some(*id),
            _ => None,
        })
        .collect();
    for (entity, settings, transform, terrain) in &heightfields {
        let image_changed = changed_images.contains(&settings.heights.id());
        if terrain.is_some() && !settings.is_changed() && !transform.is_changed() && !image_changed
        {
            continue;
        }
        let Some(image) = images.get(&settings.heights) else {
            continue; // still loading
        };
        let (_, rotation, translation) = transform.to_scale_rotation_translation();
        let built = image_heights(image, settings.height_scale).and_then(|(size, heights)| {
            let heights = heights.into_iter().map(|h| h + translation.y).collect();
            let origin = Vec2::new(translation.x, translation.z) - 0.5 * settings.size;
            Heightfield::new(size, origin, settings.size, heights).map_err(|e| e.to_string())
        });
        let next = match built {
            Ok(h) => {
                if rotation.angle_between(Quat::IDENTITY) > 1e-4 {
                    warn!(
                        "Penumbra: DistanceFieldHeightfield on {entity}: its rotation is ignored"
                    );
                }
                HeightfieldTerrain::Ready(Arc::new(h))
            }
            Err(why) => {
                warn!("Penumbra: DistanceFieldHeightfield on {entity}: {why}; no terrain");
                HeightfieldTerrain::Refused(why)
            }
        };
        commands.entity(entity).insert(next);
    }
}

/// The scene's built terrains, in entity order (deterministic), with a generation that
/// changes with them and this frame's changed bounds (for the global field's dirty
/// regions).
#[derive(Resource, Default, Clone, Debug)]
pub struct SceneHeightfields {
    generation: u64,
    terrains: BTreeMap<Entity, Arc<Heightfield>>,
    dirty: Vec<(Vec3, Vec3)>,
}

impl SceneHeightfields {
    /// Changes whenever a terrain appears, changes or goes.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// The terrains.
    pub fn terrains(&self) -> impl Iterator<Item = &Arc<Heightfield>> {
        self.terrains.values()
    }

    /// This frame's changed regions: the bounds (min, max) of each terrain that
    /// appeared, changed or went, before and after.
    pub fn dirty(&self) -> &[(Vec3, Vec3)] {
        &self.dirty
    }
}

/// Follows the built terrains into [`SceneHeightfields`]; a terrain goes with its
/// [`DistanceFieldHeightfield`].
pub(super) fn collect_heightfields(
    mut commands: Commands,
    mut scene: ResMut<SceneHeightfields>,
    changed: Query<(Entity, &HeightfieldTerrain), Changed<HeightfieldTerrain>>,
    mut removed_terrains: RemovedComponents<HeightfieldTerrain>,
    mut removed_settings: RemovedComponents<DistanceFieldHeightfield>,
) {
    scene.dirty.clear();
    let mut gone: Vec<Entity> = removed_terrains.read().collect();
    for entity in removed_settings.read() {
        if let Ok(mut e) = commands.get_entity(entity) {
            e.try_remove::<HeightfieldTerrain>();
        }
        gone.push(entity);
    }
    let mut changed_any = false;
    for entity in gone {
        if let Some(old) = scene.terrains.remove(&entity) {
            scene.dirty.push(old.bounds());
            changed_any = true;
        }
    }
    for (entity, terrain) in &changed {
        if let Some(old) = scene.terrains.remove(&entity) {
            scene.dirty.push(old.bounds());
        }
        if let HeightfieldTerrain::Ready(h) = terrain {
            scene.dirty.push(h.bounds());
            scene.terrains.insert(entity, h.clone());
        }
        changed_any = true;
    }
    if changed_any {
        scene.generation += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::asset::RenderAssetUsages;
    use bevy::render::render_resource::{Extent3d, TextureDimension};

    fn image(format: TextureFormat, data: Vec<u8>) -> Image {
        Image::new(
            Extent3d {
                width: 2,
                height: 2,
                depth_or_array_layers: 1,
            },
            TextureDimension::D2,
            data,
            format,
            RenderAssetUsages::all(),
        )
    }

    /// 16-bit grey PNGs (Bevy's `R16Uint`, `Rg16Uint` with alpha) and 8-bit ones
    /// (expanded to RGBA) are heightmaps too (`R16Uint` was refused, #47): the first
    /// channel, 0 to 1, times the scale.
    #[test]
    fn png_heightmaps_of_every_usual_format_read() {
        let u16s = |v: &[u16], channels: usize| -> Vec<u8> {
            v.iter()
                .flat_map(|&x| {
                    let mut texel = vec![0u8; 2 * channels];
                    texel[..2].copy_from_slice(&x.to_le_bytes());
                    texel
                })
                .collect()
        };
        let want = [0.0, 0.5, 1.0, 0.25];
        let raw = [0u16, 32768, 65535, 16384];
        for (format, data) in [
            (TextureFormat::R16Uint, u16s(&raw, 1)),
            (TextureFormat::Rg16Uint, u16s(&raw, 2)),
            (TextureFormat::Rgba16Unorm, u16s(&raw, 4)),
            (TextureFormat::R16Unorm, u16s(&raw, 1)),
        ] {
            let (size, heights) = image_heights(&image(format, data), 2.0).unwrap();
            assert_eq!(size, UVec2::new(2, 2));
            for (h, w) in heights.iter().zip(want) {
                assert!((h - 2.0 * w).abs() < 1e-4, "{format:?}: {heights:?}");
            }
        }
        let rgba8 = [0u8, 128, 255, 64]
            .iter()
            .flat_map(|&b| [b, 0, 0, 255])
            .collect();
        let (_, heights) =
            image_heights(&image(TextureFormat::Rgba8UnormSrgb, rgba8), 1.0).unwrap();
        assert!((heights[2] - 1.0).abs() < 1e-6 && (heights[1] - 128.0 / 255.0).abs() < 1e-6);
        let e = image_heights(&image(TextureFormat::Rg8Unorm, vec![0; 8]), 1.0).unwrap_err();
        assert!(e.contains("Rg8Unorm") && e.contains("R16Uint"), "{e}");
    }
}
