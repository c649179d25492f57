//! Distance-field shadows under deferred MSAA ([`DeferredMsaa::sample_occlusion`]): the
//! mask pass traces every pixel once, from the representative sample the classification
//! writes; a second dispatch of the same shader (`PENUMBRA_SAMPLE_TRACE`) traces the
//! samples of the pixels shaded per sample (class 2) into a mask at twice the view's
//! size, which the per-sample lighting reads. Its threads are samples in 2×2 blocks (an
//! 8×8 tile covers 4×4 pixels), so the tiled culling stays as tight as the per-pixel
//! pass's; a tile without an edge sample gathers no caster and exits.
//!
//! [`DeferredMsaa::sample_occlusion`]: crate::DeferredMsaa::sample_occlusion

use super::render::ShadowPipelines;
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::shader_library::PenumbraShaderLibrary;
use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, texture_2d, texture_2d_multisampled, texture_3d,
    texture_depth_2d_multisampled, texture_storage_2d, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroupLayoutDescriptor, BindGroupLayoutEntries, CachedComputePipelineId,
    ComputePipelineDescriptor, Extent3d, PipelineCache, ShaderStages, StorageTextureAccess,
    Texture, TextureDescriptor, TextureDimension, TextureFormat, TextureSampleType, TextureUsages,
    TextureView, TextureViewDescriptor, TextureViewDimension,
};
use bevy::render::renderer::RenderDevice;
use penumbra_df_core::shadow::{
    SHADOW_GRID_BYTES, SHADOW_GRID_VIEW_BYTES, SHADOW_LIGHT_BYTES, SHADOW_TRACE_VIEW_BYTES,
};
use std::num::NonZeroU64;

/// The per-sample trace's layout: the mask pass's, with the multisampled depth (4) and
/// G-buffer (12), and the pixels' classes (15).
pub(super) fn sample_trace_layout() -> BindGroupLayoutDescriptor {
    BindGroupLayoutDescriptor::new(
        "penumbra_df_shadow_sample_trace_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                texture_3d(TextureSampleType::Float { filterable: false }),
                texture_depth_2d_multisampled(),
                uniform_buffer_sized(false, NonZeroU64::new(SHADOW_TRACE_VIEW_BYTES as u64)),
                uniform_buffer_sized(false, NonZeroU64::new(SHADOW_LIGHT_BYTES as u64)),
                texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                storage_buffer_read_only_sized(false, NonZeroU64::new(SHADOW_GRID_BYTES as u64)),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                uniform_buffer_sized(false, NonZeroU64::new(SHADOW_GRID_VIEW_BYTES as u64)),
                texture_2d_multisampled(TextureSampleType::Uint),
                storage_buffer_read_only_sized(false, None),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Uint),
                texture_2d(TextureSampleType::Uint),
            ),
        ),
    )
}

/// Queues the per-sample trace (once: the first deferred MSAA view asks for it).
pub(super) fn queue_sample_trace(
    pipelines: &mut ShadowPipelines,
    library: &PenumbraShaderLibrary,
    pipeline_cache: &PipelineCache,
) -> CachedComputePipelineId {
    *pipelines.sample_trace.get_or_insert_with(|| {
        pipeline_cache.queue_compute_pipeline(ComputePipelineDescriptor {
            label: Some("penumbra_df_shadow_sample_trace".into()),
            layout: vec![pipelines.sample_trace_layout.clone()],
            shader: library.handle("df/shadow_trace.wgsl"),
            shader_defs: vec!["PENUMBRA_SAMPLE_TRACE".into()],
            entry_point: Some("trace".into()),
            ..default()
        })
    })
}

/// A view's per-sample masks: one `R32Float` layer per shadowed light at twice the
/// view's size (`lighting/msaa.wgsl`'s `msaa_sample_texel`).
pub(super) struct SampleMasks {
    /// All layers, as the lighting pass reads them.
    pub(super) array: TextureView,
    /// Per layer, a storage view.
    pub(super) layers: Vec<TextureView>,
}

impl SampleMasks {
    pub(super) fn new(
        allocations: &PenumbraGpuAllocations,
        device: &RenderDevice,
        view_size: UVec2,
        layers: u32,
    ) -> SampleMasks {
        let texture = allocations.texture(
            device,
            &TextureDescriptor {
                label: Some("penumbra_df_shadow_sample_masks"),
                size: Extent3d {
                    width: 2 * view_size.x,
                    height: 2 * view_size.y,
                    depth_or_array_layers: layers,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: TextureDimension::D2,
                format: TextureFormat::R32Float,
                usage: TextureUsages::STORAGE_BINDING | TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            },
        );
        SampleMasks {
            array: texture.create_view(&TextureViewDescriptor {
                label: Some("penumbra_df_shadow_sample_masks"),
                dimension: Some(TextureViewDimension::D2Array),
                ..default()
            }),
            layers: layer_views(&texture, layers),
        }
    }
}

/// One storage view per layer of `texture`.
pub(super) fn layer_views(texture: &Texture, layers: u32) -> Vec<TextureView> {
    (0..layers)
        .map(|layer| {
            texture.create_view(&TextureViewDescriptor {
                label: Some("penumbra_df_shadow_mask_layer"),
                dimension: Some(TextureViewDimension::D2),
                base_array_layer: layer,
                array_layer_count: Some(1),
                ..default()
            })
        })
        .collect()
}

/// What the per-sample trace binds besides the mask pass's inputs.
pub(super) struct SampleTraceInputs<'a> {
    /// The multisampled depth and G-buffer, the pixels' classes.
    pub(super) depth: &'a TextureView,
    pub(super) gbuffer: &'a TextureView,
    pub(super) class: &'a TextureView,
    /// Per light, the storage view of its per-sample layer.
    pub(super) layers: &'a [TextureView],
}
