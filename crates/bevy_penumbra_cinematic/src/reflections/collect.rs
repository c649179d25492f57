//! Main world: the billboards as the pass reads them, and the images' mip chains for
//! the texture array (rebuilt only when the set of images or one of them changes).

use super::{BillboardReflections, ReflectionBillboard};
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use penumbra_cinematic_core::reflections::Billboard;
use penumbra_cinematic_core::reflections::pass::GpuBillboard;
use penumbra_cinematic_core::reflections::texture::MipChain;
use std::sync::Arc;

/// The most images the texture array holds (WebGPU's guaranteed array layers).
const MAX_LAYERS: usize = 256;
/// The largest image side (WebGPU's guaranteed 2D texture size).
const MAX_IMAGE_SIDE: u32 = 8192;
/// The most memory the texture array may take, bytes.
const MAX_ARRAY_BYTES: u64 = 256 << 20;

/// The images of the texture array: one layer each, all `size`.
#[derive(Debug)]
pub(super) struct ImageArray {
    pub(super) size: UVec2,
    pub(super) layers: Vec<Arc<MipChain>>,
}

/// The billboards the reflection cameras see this frame (empty while there is no such
/// camera), and the array their `layer`s index.
#[derive(Resource, Default)]
pub(super) struct ReflectionScene {
    pub(super) billboards: Vec<GpuBillboard>,
    /// A new `Arc` whenever the array's content changes.
    pub(super) images: Option<Arc<ImageArray>>,
}

/// A billboard image's linear texels, or `None` when its format cannot be read.
fn linear_texels(image: &Image) -> Option<(UVec2, Vec<Vec4>)> {
    let size = image.size();
    let mut texels = Vec::with_capacity((size.x * size.y) as usize);
    for y in 0..size.y {
        for x in 0..size.x {
            let c = image.get_color_at(x, y).ok()?.to_linear();
            texels.push(Vec4::new(c.red, c.green, c.blue, c.alpha));
        }
    }
    Some((size, texels))
}

/// What was already warned about (once per entity or image until it is fixed).
#[derive(Default)]
pub(super) struct Warned {
    entities: HashSet<Entity>,
    images: HashSet<AssetId<Image>>,
}

/// Builds [`ReflectionScene`]: every visible, valid billboard in entity order, its image
/// a layer of the array. Skips (one warning each) zero-size or non-finite quads, images
/// of another size than the array's, unreadable or oversized images and images beyond
/// the array's 256 layers.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
pub(super) fn collect_reflection_billboards(
    cameras: Query<(), With<BillboardReflections>>,
    billboards: Query<(
        Entity,
        &ReflectionBillboard,
        &GlobalTransform,
        &InheritedVisibility,
    )>,
    images: Res<Assets<Image>>,
    mut image_events: MessageReader<AssetEvent<Image>>,
    mut chains: Local<HashMap<AssetId<Image>, Option<Arc<MipChain>>>>,
    mut warned: Local<Warned>,
    mut scene: ResMut<ReflectionScene>,
) {
    for event in image_events.read() {
        if let AssetEvent::Modified { id } | AssetEvent::Removed { id } = event {
            chains.remove(id);
            warned.images.remove(id);
        }
    }
    if cameras.is_empty() {
        if !scene.billboards.is_empty() || scene.images.is_some() {
            *scene = ReflectionScene::default();
        }
        chains.clear();
        return;
    }
    let mut list: Vec<_> = billboards.iter().filter(|b| b.3.get()).collect();
    list.sort_by_key(|b| b.0);
    // Valid quads whose image is loaded and readable.
    let mut valid: Vec<(Entity, Billboard, AssetId<Image>, f32)> = Vec::new();
    for (entity, billboard, transform, _) in list {
        let quad = Billboard::from_transform(transform.to_matrix(), billboard.size);
        let quad = match quad {
            Ok(quad) if billboard.emissive.is_finite() => quad,
            Ok(_) => {
                if warned.entities.insert(entity) {
                    warn!(
                        "Penumbra: ReflectionBillboard on {entity}: a non-finite emissive; skipped"
                    );
                }
                continue;
            }
            Err(e) => {
                if warned.entities.insert(entity) {
                    warn!("Penumbra: ReflectionBillboard on {entity}: {e}; skipped");
                }
                continue;
            }
        };
        let id = billboard.image.id();
        let Some(image) = images.get(id) else {
            continue; // loading (or none)
        };
        let chain = chains.entry(id).or_insert_with(|| {
            linear_texels(image)
                .filter(|(size, _)| {
                    (1..=MAX_IMAGE_SIDE).contains(&size.x) && (1..=MAX_IMAGE_SIDE).contains(&size.y)
                })
                .map(|(size, texels)| {
                    Arc::new(MipChain::from_straight_alpha(size.x, size.y, &texels))
                })
        });
        if chain.is_none() {
            if warned.images.insert(id) {
                warn!(
                    "Penumbra: ReflectionBillboard image {id:?} ({:?}) cannot be read texel by \
                     texel (its format, no data in the main world, or over {MAX_IMAGE_SIDE} \
                     texels a side); its billboards are skipped",
                    image.texture_descriptor.format
                );
            }
            continue;
        }
        valid.push((entity, quad, id, billboard.emissive.max(0.0)));
    }
    // The array's size: the one most billboards' images have (ties: the larger).
    let mut counts: HashMap<UVec2, usize> = HashMap::default();
    for (_, _, id, _) in &valid {
        let c = chains[id].as_ref().expect("readable");
        *counts.entry(UVec2::new(c.width, c.height)).or_default() += 1;
    }
    let size = counts
        .iter()
        .max_by_key(|(size, n)| (**n, size.x * size.y, size.x))
        .map(|(size, _)| *size);
    // One layer's bytes: `Rgba16Float` and its mip chain (at most 4/3 of level 0).
    let layer_bytes = size.map_or(0, |s| u64::from(s.x) * u64::from(s.y) * 8 * 4 / 3);
    let mut layers: Vec<AssetId<Image>> = Vec::new();
    let mut gpu = Vec::with_capacity(valid.len());
    for (entity, quad, id, emissive) in valid {
        let c = chains[&id].as_ref().expect("readable");
        if Some(UVec2::new(c.width, c.height)) != size {
            if warned.entities.insert(entity) {
                warn!(
                    "Penumbra: ReflectionBillboard on {entity}: its image is {}×{}, the \
                     reflection array's {}×{}; skipped (all billboard images must share one size)",
                    c.width,
                    c.height,
                    size.map_or(0, |s| s.x),
                    size.map_or(0, |s| s.y),
                );
            }
            continue;
        }
        let layer = match layers.iter().position(|l| *l == id) {
            Some(layer) => layer,
            None if layers.len() < MAX_LAYERS
                && (layers.len() as u64 + 1) * layer_bytes <= MAX_ARRAY_BYTES =>
            {
                layers.push(id);
                layers.len() - 1
            }
            None => {
                if warned.entities.insert(entity) {
                    warn!(
                        "Penumbra: ReflectionBillboard on {entity}: its image would be beyond \
                         the reflection array's {MAX_LAYERS} layers or {} MiB; skipped",
                        MAX_ARRAY_BYTES >> 20
                    );
                }
                continue;
            }
        };
        warned.entities.remove(&entity);
        gpu.push(GpuBillboard {
            center: quad.center,
            layer: layer as u32,
            half_x: quad.half_x,
            emissive,
            half_y: quad.half_y,
            reserved: 0,
        });
    }
    let chains_now: Vec<Arc<MipChain>> = layers
        .iter()
        .map(|id| chains[id].clone().expect("readable"))
        .collect();
    let same_images = match (&scene.images, size) {
        (Some(array), Some(size)) => {
            array.size == size
                && array.layers.len() == chains_now.len()
                && array
                    .layers
                    .iter()
                    .zip(&chains_now)
                    .all(|(a, b)| Arc::ptr_eq(a, b))
        }
        (None, None) => true,
        _ => false,
    };
    if !same_images {
        scene.images = size.map(|size| {
            Arc::new(ImageArray {
                size,
                layers: chains_now,
            })
        });
    }
    if scene.billboards != gpu {
        scene.billboards = gpu;
    }
}
