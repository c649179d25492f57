//! Main world: the billboards as the pass reads them, and the images' mip chains for
//! the texture array. An image keeps its layer while a billboard shows it, so a changed
//! or added image changes one layer (the render world uploads that one); a layer no
//! billboard shows is freed, and a mip chain no billboard refers to is dropped.

use super::{BillboardReflections, ReflectionBillboard};
use bevy::camera::visibility::RenderLayers;
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use penumbra_cinematic_core::reflections::Billboard;
use penumbra_cinematic_core::reflections::pass::GpuBillboard;
use penumbra_cinematic_core::reflections::texture::MipChain;
use std::sync::Arc;

/// The most images the texture array holds (WebGPU's guaranteed array layers).
pub(super) const MAX_ARRAY_LAYERS: usize = 256;
/// The largest image side (WebGPU's guaranteed 2D texture size).
pub(super) const MAX_IMAGE_SIDE: u32 = 8192;
/// The most memory the texture array may take, bytes.
pub(super) const MAX_ARRAY_BYTES: u64 = 256 << 20;

/// The images of the texture array: one layer each, all `size`.
#[derive(Debug)]
pub(super) struct ImageArray {
    pub(super) size: UVec2,
    /// Layer `k`'s image; `None` where the layer is free (no billboard shows its image
    /// now; a new image takes the first free layer).
    pub(super) layers: Vec<Option<Arc<MipChain>>>,
}

/// Which image each layer holds, kept from frame to frame (cleared when the array's
/// size changes).
#[derive(Default)]
pub(super) struct LayerSlots {
    size: Option<UVec2>,
    images: Vec<Option<AssetId<Image>>>,
}

impl LayerSlots {
    /// Frees the layers of images not in `shown`, and the free layers at the end.
    fn keep_only(&mut self, shown: &HashSet<AssetId<Image>>) {
        for slot in &mut self.images {
            if slot.is_some_and(|id| !shown.contains(&id)) {
                *slot = None;
            }
        }
        while self.images.last() == Some(&None) {
            self.images.pop();
        }
    }

    /// `id`'s layer: the one it has, else the first free one, else a new one while there
    /// are fewer than `max`.
    fn layer_of(&mut self, id: AssetId<Image>, max: usize) -> Option<usize> {
        if let Some(k) = self.images.iter().position(|s| *s == Some(id)) {
            return Some(k);
        }
        if let Some(k) = self.images.iter().position(Option::is_none) {
            self.images[k] = Some(id);
            return Some(k);
        }
        (self.images.len() < max).then(|| {
            self.images.push(Some(id));
            self.images.len() - 1
        })
    }
}

/// The billboards the reflection cameras see this frame (empty while there is no such
/// camera), and the array their `layer`s index.
#[derive(Resource, Default)]
pub(super) struct ReflectionScene {
    pub(super) billboards: Vec<GpuBillboard>,
    /// The distinct render layers of the billboards, in entity order: bit `i` of a
    /// billboard's `layers` is group `i` (at most [`MAX_LAYER_GROUPS`]).
    pub(super) groups: Vec<RenderLayers>,
    /// A new `Arc` whenever the array's content changes.
    pub(super) images: Option<Arc<ImageArray>>,
}

/// Each billboard image's mip chain (`None`: unreadable), made once per image version;
/// dropped when no billboard refers to the image, or no camera reflects.
#[derive(Resource, Default)]
pub(super) struct ReflectionMipChains(pub(super) HashMap<AssetId<Image>, Option<Arc<MipChain>>>);

/// A billboard image's linear texels, or why it cannot be read: its size is checked
/// first (a 20,000² image was converted to 16 bytes a texel, ~6.4 GB, before it was
/// refused), then its data (as long as the size says) and format, then each texel
/// (finite).
pub(super) fn linear_texels(image: &Image) -> Result<(UVec2, Vec<Vec4>), String> {
    let size = image.size();
    if !((1..=MAX_IMAGE_SIDE).contains(&size.x) && (1..=MAX_IMAGE_SIDE).contains(&size.y)) {
        return Err(format!(
            "{}×{} texels (1 to {MAX_IMAGE_SIDE} a side)",
            size.x, size.y
        ));
    }
    crate::image_data::check_texel_data(image)?;
    let mut texels = Vec::with_capacity((size.x * size.y) as usize);
    for y in 0..size.y {
        for x in 0..size.x {
            let c = image
                .get_color_at(x, y)
                .map_err(|e| {
                    format!(
                        "its format {:?} cannot be read texel by texel ({e})",
                        image.texture_descriptor.format
                    )
                })?
                .to_linear();
            let texel = Vec4::new(c.red, c.green, c.blue, c.alpha);
            if !texel.is_finite() {
                return Err(format!(
                    "texel ({x}, {y}) is {texel}: texels must be finite"
                ));
            }
            texels.push(texel);
        }
    }
    Ok((size, texels))
}

/// What was already warned about (once per entity or image until it is fixed).
#[derive(Default)]
pub(super) struct Warned {
    entities: HashSet<Entity>,
    images: HashSet<AssetId<Image>>,
    layer_groups: bool,
}

/// Distinct `RenderLayers` among the billboards told apart (a bit each in
/// `GpuBillboard::layers`).
pub(super) const MAX_LAYER_GROUPS: usize = 32;

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
        Option<&RenderLayers>,
    )>,
    images: Res<Assets<Image>>,
    mut image_events: MessageReader<AssetEvent<Image>>,
    mut chains: ResMut<ReflectionMipChains>,
    mut slots: Local<LayerSlots>,
    mut warned: Local<Warned>,
    mut scene: ResMut<ReflectionScene>,
) {
    let chains = &mut chains.0;
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
        *slots = LayerSlots::default();
        return;
    }
    // Mip chains no billboard refers to (shown or not) are dropped.
    let referenced: HashSet<AssetId<Image>> = billboards.iter().map(|b| b.1.image.id()).collect();
    chains.retain(|id, _| referenced.contains(id));
    let mut list: Vec<_> = billboards.iter().filter(|b| b.3.get()).collect();
    list.sort_by_key(|b| b.0);
    // Valid quads whose image is loaded and readable.
    let mut valid: Vec<(Entity, Billboard, AssetId<Image>, f32, RenderLayers)> = Vec::new();
    for (entity, billboard, transform, _, layers) in list {
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
        let chain = chains
            .entry(id)
            .or_insert_with(|| match linear_texels(image) {
                Ok((size, texels)) => Some(Arc::new(MipChain::from_straight_alpha(
                    size.x, size.y, &texels,
                ))),
                Err(why) => {
                    if warned.images.insert(id) {
                        warn!(
                            "Penumbra: ReflectionBillboard image {id:?}: {why}; its billboards \
                             are skipped"
                        );
                    }
                    None
                }
            });
        if chain.is_none() {
            continue;
        }
        valid.push((
            entity,
            quad,
            id,
            billboard.emissive.max(0.0),
            // None: layer 0, Bevy's default.
            layers.cloned().unwrap_or_default(),
        ));
    }
    // The array's size: the one most billboards' images have (ties: the larger).
    let mut counts: HashMap<UVec2, usize> = HashMap::default();
    for (_, _, id, _, _) in &valid {
        let c = chains[id].as_ref().expect("readable");
        *counts.entry(UVec2::new(c.width, c.height)).or_default() += 1;
    }
    let size = counts
        .iter()
        .max_by_key(|(size, n)| (**n, size.x * size.y, size.x))
        .map(|(size, _)| *size);
    // One layer's bytes: `Rgba16Float` and its mip chain (at most 4/3 of level 0).
    let layer_bytes = size.map_or(0, |s| u64::from(s.x) * u64::from(s.y) * 8 * 4 / 3);
    let max_layers = MAX_ARRAY_LAYERS.min((MAX_ARRAY_BYTES / layer_bytes.max(1)) as usize);
    if slots.size != size {
        *slots = LayerSlots { size, ..default() };
    }
    let of_size = |id: &AssetId<Image>| {
        let c = chains[id].as_ref().expect("readable");
        Some(UVec2::new(c.width, c.height)) == size
    };
    slots.keep_only(&valid.iter().map(|v| v.2).filter(of_size).collect());
    let mut gpu = Vec::with_capacity(valid.len());
    let mut groups: Vec<RenderLayers> = Vec::new();
    for (entity, quad, id, emissive, layers) in valid {
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
        let Some(layer) = slots.layer_of(id, max_layers) else {
            if warned.entities.insert(entity) {
                warn!(
                    "Penumbra: ReflectionBillboard on {entity}: its image would be beyond \
                     the reflection array's {MAX_ARRAY_LAYERS} layers or {} MiB; skipped",
                    MAX_ARRAY_BYTES >> 20
                );
            }
            continue;
        };
        warned.entities.remove(&entity);
        let group = match groups.iter().position(|g| *g == layers) {
            Some(i) => Some(i),
            None if groups.len() < MAX_LAYER_GROUPS => {
                groups.push(layers);
                Some(groups.len() - 1)
            }
            None => None,
        };
        if group.is_none() && !warned.layer_groups {
            warned.layer_groups = true;
            warn!(
                "Penumbra: ReflectionBillboards with more than {MAX_LAYER_GROUPS} distinct \
                 RenderLayers; those past it are reflected by every camera"
            );
        }
        gpu.push(GpuBillboard {
            center: quad.center,
            layer: layer as u32,
            half_x: quad.half_x,
            emissive,
            half_y: quad.half_y,
            layers: group.map_or(u32::MAX, |i| 1 << i),
        });
    }
    let chains_now: Vec<Option<Arc<MipChain>>> = slots
        .images
        .iter()
        .map(|slot| slot.map(|id| chains[&id].clone().expect("readable")))
        .collect();
    let same_images = match (&scene.images, size) {
        (Some(array), Some(size)) => {
            array.size == size
                && array.layers.len() == chains_now.len()
                && array
                    .layers
                    .iter()
                    .zip(&chains_now)
                    .all(|(a, b)| match (a, b) {
                        (Some(a), Some(b)) => Arc::ptr_eq(a, b),
                        (a, b) => a.is_none() && b.is_none(),
                    })
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
    if scene.groups != groups {
        scene.groups = groups;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Billboard images of every format, size class and data length
    /// (`penumbra_test::awkward_images`): one finite texel per texel of the image, or
    /// refused with a reason; never a panic.
    #[test]
    fn billboard_images_of_every_format_and_size_are_read_or_refused() {
        penumbra_test::awkward_images::check_image_reader(
            "billboard images",
            34,
            linear_texels,
            |(size, texels)| {
                assert_eq!(
                    texels.len(),
                    (size.x * size.y) as usize,
                    "one texel per texel"
                );
                (
                    Some(*size),
                    texels.iter().flat_map(|t| t.to_array()).collect(),
                )
            },
        );
    }
}
