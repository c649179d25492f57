//! Render-world upload of billboard reflections' scene: the billboards' storage buffer
//! (rewritten when they change) and the images' texture array (a changed image uploads
//! its own layer; nothing on a steady frame).

use super::collect::{ImageArray, MAX_ARRAY_BYTES, MAX_ARRAY_LAYERS, ReflectionScene};
use bevy::camera::visibility::RenderLayers;
use bevy::prelude::*;
use bevy::render::Extract;
use bevy::render::render_resource::encase::StorageBuffer;
use bevy::render::render_resource::{
    Buffer, BufferUsages, Extent3d, Origin3d, ShaderType, TexelCopyBufferLayout,
    TexelCopyTextureInfo, Texture, TextureAspect, TextureDescriptor, TextureDimension,
    TextureFormat, TextureUsages, TextureView, TextureViewDescriptor, TextureViewDimension,
};
use bevy::render::renderer::{RenderDevice, RenderQueue};
use bevy_penumbra_df::PenumbraGpuAllocations;
use penumbra_cinematic_core::reflections::pass::GpuBillboard;
use penumbra_cinematic_core::reflections::texture::MipChain;
use std::sync::Arc;

/// Uploads of the billboards' texture array since startup (render world): a changed
/// image uploads its layer alone; a steady scene uploads nothing.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReflectionImageUploads {
    /// Array textures made (the first, and on a new image size, more layers than it
    /// holds, or under a quarter of them used).
    pub textures: u64,
    /// Layers (images with their mip chains) written.
    pub layers: u64,
}

/// The texture array on the GPU and what each of its layers holds.
#[derive(Default)]
pub(super) struct UploadedArray {
    texture: Option<Texture>,
    layers: Vec<Option<Arc<MipChain>>>,
    /// The images last uploaded.
    array: Option<Arc<ImageArray>>,
}

/// The billboards and images on the GPU.
#[derive(Resource, Default)]
pub(super) struct ReflectionGpuScene {
    pub(super) billboards: Vec<GpuBillboard>,
    /// The billboards' render-layer groups (`ReflectionScene::groups`).
    pub(super) groups: Vec<RenderLayers>,
    pub(super) images: Option<Arc<ImageArray>>,
    /// Storage buffer and its capacity in billboards.
    pub(super) buffer: Option<(Buffer, usize)>,
    pub(super) array: Option<TextureView>,
    pub(super) mip_count: u32,
    /// The billboards changed since their last upload.
    dirty: bool,
}

pub(super) fn extract_reflection_scene(
    mut gpu: ResMut<ReflectionGpuScene>,
    scene: Extract<Res<ReflectionScene>>,
) {
    if scene.is_changed() {
        gpu.billboards.clone_from(&scene.billboards);
        gpu.groups.clone_from(&scene.groups);
        gpu.images.clone_from(&scene.images);
        gpu.dirty = true;
    }
}

/// Uploads the billboards when they change (the buffer grows by powers of two) and the
/// texture array when its images do; nothing on frames where neither did.
pub(super) fn prepare_reflection_scene(
    mut gpu: ResMut<ReflectionGpuScene>,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mut uploaded: Local<UploadedArray>,
    mut uploads: ResMut<ReflectionImageUploads>,
) {
    let gpu = &mut *gpu;
    if gpu.images.is_none() || gpu.billboards.is_empty() {
        return;
    }
    let needed = gpu.billboards.len();
    if gpu.buffer.as_ref().is_none_or(|(_, cap)| *cap < needed) {
        let capacity = needed.next_power_of_two();
        let buffer = allocations.sized_buffer(
            &device,
            "penumbra_reflection_billboards",
            capacity as u64 * GpuBillboard::min_size().get(),
            BufferUsages::STORAGE | BufferUsages::COPY_DST,
        );
        gpu.buffer = Some((buffer, capacity));
        gpu.dirty = true;
    }
    if gpu.dirty {
        let mut bytes = StorageBuffer::new(Vec::new());
        bytes.write(&gpu.billboards).expect("billboards encode");
        let (buffer, _) = gpu.buffer.as_ref().expect("just made");
        queue.write_buffer(buffer, 0, bytes.as_ref());
        gpu.dirty = false;
    }
    let images = gpu.images.clone().expect("checked");
    if uploaded
        .array
        .as_ref()
        .is_some_and(|u| Arc::ptr_eq(u, &images))
    {
        return;
    }
    let Some(first) = images.layers.iter().flatten().next() else {
        return;
    };
    let mip_count = first.levels.len() as u32;
    let layers = images.layers.len() as u32;
    // The texture is kept while the images' size holds and their layers fit (it grows
    // to the next power of two, shrinks when a quarter is used).
    let fits = uploaded.texture.as_ref().is_some_and(|t| {
        t.width() == images.size.x
            && t.height() == images.size.y
            && t.mip_level_count() == mip_count
            && (layers <= t.depth_or_array_layers())
            && (layers * 4 > t.depth_or_array_layers() || t.depth_or_array_layers() == 1)
    });
    if !fits {
        let layer_bytes = u64::from(images.size.x) * u64::from(images.size.y) * 8 * 4 / 3;
        let most = (MAX_ARRAY_BYTES / layer_bytes.max(1)).clamp(1, MAX_ARRAY_LAYERS as u64) as u32;
        let capacity = layers.next_power_of_two().min(most).max(layers);
        let texture = allocations.texture(
            &device,
            &TextureDescriptor {
                label: Some("penumbra_reflection_images"),
                size: Extent3d {
                    width: images.size.x,
                    height: images.size.y,
                    depth_or_array_layers: capacity,
                },
                mip_level_count: mip_count,
                sample_count: 1,
                dimension: TextureDimension::D2,
                format: TextureFormat::Rgba16Float,
                usage: TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_DST,
                view_formats: &[],
            },
        );
        gpu.array = Some(texture.create_view(&TextureViewDescriptor {
            dimension: Some(TextureViewDimension::D2Array),
            ..default()
        }));
        gpu.mip_count = mip_count;
        uploaded.texture = Some(texture);
        uploaded.layers.clear();
        uploads.textures += 1;
    }
    let texture = uploaded.texture.clone().expect("just made");
    uploaded.layers.resize(images.layers.len(), None);
    for (layer, chain) in images.layers.iter().enumerate() {
        let Some(chain) = chain else {
            continue; // free: what it held is never sampled
        };
        if uploaded.layers[layer]
            .as_ref()
            .is_some_and(|u| Arc::ptr_eq(u, chain))
        {
            continue;
        }
        upload_layer(&queue, &texture, layer as u32, chain);
        uploaded.layers[layer] = Some(chain.clone());
        uploads.layers += 1;
    }
    uploaded.array = Some(images);
}

/// One image's mip chain into layer `layer` of the array.
fn upload_layer(queue: &RenderQueue, texture: &Texture, layer: u32, chain: &MipChain) {
    for (level, texels) in chain.levels.iter().enumerate() {
        let (w, h) = chain.level_size(level);
        let bits: Vec<u8> = texels
            .iter()
            .flat_map(|t| t.to_array())
            .flat_map(|x| half::f16::from_f32(x).to_le_bytes())
            .collect();
        queue.write_texture(
            TexelCopyTextureInfo {
                texture,
                mip_level: level as u32,
                origin: Origin3d {
                    x: 0,
                    y: 0,
                    z: layer,
                },
                aspect: TextureAspect::All,
            },
            &bits,
            TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(w * 8),
                rows_per_image: Some(h),
            },
            Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
    }
}
