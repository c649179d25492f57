//! DFAO's pipelines: the trace, the upsample (and deferred MSAA's per-sample one) and the
//! temporal pass (and its multisampled-motion variant), queued at startup or for the
//! first view that needs them.

use crate::shader_library::PenumbraShaderLibrary;
use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, texture_2d, texture_2d_multisampled, texture_3d,
    texture_depth_2d_multisampled, texture_storage_2d, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroupLayoutDescriptor, BindGroupLayoutEntries, CachedComputePipelineId,
    ComputePipelineDescriptor, PipelineCache, ShaderStages, ShaderType, StorageTextureAccess,
    TextureFormat, TextureSampleType, TextureView,
};
use bevy::render::renderer::RenderDevice;
use penumbra_df_core::ao::{AoTemporalView, AoTraceView};

/// The passes' pipelines.
#[derive(Resource)]
pub(super) struct AoPipelines {
    pub(super) trace_layout: BindGroupLayoutDescriptor,
    pub(super) trace: CachedComputePipelineId,
    pub(super) upsample_layout: BindGroupLayoutDescriptor,
    pub(super) upsample: CachedComputePipelineId,
    /// Deferred MSAA's per-sample upsample (`PENUMBRA_SAMPLE_UPSAMPLE`): the upsample's
    /// layout, then the multisampled depth and G-buffer and the pixels' classes; queued
    /// for the first deferred MSAA view.
    pub(super) sample_upsample_layout: BindGroupLayoutDescriptor,
    pub(super) sample_upsample: Option<CachedComputePipelineId>,
    pub(super) temporal_layout: BindGroupLayoutDescriptor,
    pub(super) temporal: CachedComputePipelineId,
    /// The temporal pass of deferred MSAA views (`MULTISAMPLED_MOTION`: the motion
    /// vectors multisampled); queued for the first such view.
    pub(super) temporal_msaa_layout: BindGroupLayoutDescriptor,
    pub(super) temporal_msaa: Option<CachedComputePipelineId>,
    /// Bound when the scene has no SDF volume (analytic casters only).
    pub(super) empty_atlas: TextureView,
    /// Bound when no volume is placed as bricks.
    pub(super) empty_brick_table: TextureView,
}

pub(super) fn init_ao_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    device: Res<RenderDevice>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return; // warned by the scene plugin
    };
    let view_bytes = AoTraceView::min_size();
    let trace_layout = BindGroupLayoutDescriptor::new(
        "penumbra_dfao_trace_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                storage_buffer_read_only_sized(false, None),
                texture_3d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Uint),
                uniform_buffer_sized(false, Some(view_bytes)),
                texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly),
                storage_buffer_read_only_sized(false, None),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Uint),
            ),
        ),
    );
    let upsample_entries = (
        texture_2d(TextureSampleType::Float { filterable: false }),
        texture_2d(TextureSampleType::Float { filterable: false }),
        texture_2d(TextureSampleType::Uint),
        uniform_buffer_sized(false, Some(view_bytes)),
        texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly),
    );
    let upsample_layout = BindGroupLayoutDescriptor::new(
        "penumbra_dfao_upsample_layout",
        &BindGroupLayoutEntries::sequential(ShaderStages::COMPUTE, upsample_entries),
    );
    let (e0, e1, e2, e3, e4) = upsample_entries;
    let sample_upsample_layout = BindGroupLayoutDescriptor::new(
        "penumbra_dfao_sample_upsample_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                e0,
                e1,
                e2,
                e3,
                e4,
                texture_depth_2d_multisampled(),
                texture_2d_multisampled(TextureSampleType::Uint),
                texture_2d(TextureSampleType::Uint),
            ),
        ),
    );
    let float = || texture_2d(TextureSampleType::Float { filterable: false });
    let temporal_layout_with = |label, motion| {
        BindGroupLayoutDescriptor::new(
            label,
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    float(),
                    float(),
                    float(),
                    float(),
                    texture_2d(TextureSampleType::Uint),
                    motion,
                    uniform_buffer_sized(false, Some(AoTemporalView::min_size())),
                    texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly),
                    texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly),
                    texture_storage_2d(TextureFormat::Rgba16Float, StorageTextureAccess::WriteOnly),
                ),
            ),
        )
    };
    let temporal_layout = temporal_layout_with("penumbra_dfao_temporal_layout", float());
    let temporal_msaa_layout = temporal_layout_with(
        "penumbra_dfao_temporal_msaa_layout",
        texture_2d_multisampled(TextureSampleType::Float { filterable: false }),
    );
    let temporal = library.queue_compute(
        &pipeline_cache,
        "penumbra_dfao_temporal",
        &temporal_layout,
        "df/ao_temporal.wgsl",
        "temporal",
    );
    // Group 1: the camera's global distance field (an empty one without).
    let trace = library.queue_compute_layouts(
        &pipeline_cache,
        "penumbra_dfao_trace",
        &[trace_layout.clone(), crate::global_field::read_layout()],
        "df/ao_trace.wgsl",
        "trace",
    );
    let upsample = library.queue_compute(
        &pipeline_cache,
        "penumbra_dfao_upsample",
        &upsample_layout,
        "df/ao_upsample.wgsl",
        "upsample",
    );
    commands.insert_resource(AoPipelines {
        trace_layout,
        trace,
        upsample_layout,
        upsample,
        sample_upsample_layout,
        sample_upsample: None,
        temporal_layout,
        temporal,
        temporal_msaa_layout,
        temporal_msaa: None,
        empty_atlas: crate::shader_library::empty_atlas(&device),
        empty_brick_table: crate::shader_library::empty_brick_table(&device),
    });
}

/// Queues deferred MSAA's per-sample upsample (once).
pub(super) fn queue_sample_upsample(
    pipelines: &mut AoPipelines,
    library: &PenumbraShaderLibrary,
    pipeline_cache: &PipelineCache,
) -> CachedComputePipelineId {
    *pipelines.sample_upsample.get_or_insert_with(|| {
        pipeline_cache.queue_compute_pipeline(ComputePipelineDescriptor {
            label: Some("penumbra_dfao_sample_upsample".into()),
            layout: vec![pipelines.sample_upsample_layout.clone()],
            shader: library.handle("df/ao_upsample.wgsl"),
            shader_defs: vec!["PENUMBRA_SAMPLE_UPSAMPLE".into()],
            entry_point: Some("upsample_samples".into()),
            ..default()
        })
    })
}

/// Queues deferred MSAA's temporal pass (once).
pub(super) fn queue_temporal_msaa(
    pipelines: &mut AoPipelines,
    library: &PenumbraShaderLibrary,
    pipeline_cache: &PipelineCache,
) -> CachedComputePipelineId {
    *pipelines.temporal_msaa.get_or_insert_with(|| {
        pipeline_cache.queue_compute_pipeline(ComputePipelineDescriptor {
            label: Some("penumbra_dfao_temporal_msaa".into()),
            layout: vec![pipelines.temporal_msaa_layout.clone()],
            shader: library.handle("df/ao_temporal.wgsl"),
            shader_defs: vec!["MULTISAMPLED_MOTION".into()],
            entry_point: Some("temporal".into()),
            ..default()
        })
    })
}
