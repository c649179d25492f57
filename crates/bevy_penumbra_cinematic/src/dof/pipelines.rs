//! Scatter bokeh's pipelines: the layouts of its four passes, the shaders' variants (MSAA
//! depth, the view's format), the layers' format and the device check.

use super::render::ExtractedBokeh;
use bevy::core_pipeline::FullscreenShader;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{
    sampler, storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_depth_2d,
    texture_depth_2d_multisampled, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroupLayoutDescriptor, BindGroupLayoutEntries, BlendComponent, BlendFactor, BlendOperation,
    BlendState, CachedComputePipelineId, CachedRenderPipelineId, ColorTargetState, ColorWrites,
    ComputePipelineDescriptor, DownlevelFlags, FilterMode, FragmentState, PipelineCache,
    PrimitiveState, PrimitiveTopology, RenderPipelineDescriptor, Sampler, SamplerBindingType,
    SamplerDescriptor, ShaderStages, ShaderType, TextureFormat, TextureSampleType, VertexState,
    WgpuFeatures,
};
use bevy::render::renderer::{RenderAdapter, RenderDevice};
use bevy::render::view::{Msaa, ViewTarget};
use bevy_penumbra_df::PenumbraShaderLibrary;
use penumbra_cinematic_core::dof::BokehView;

/// The half-resolution layers' format where the device blends 32-bit floats: the
/// layers sum hundreds of small weights per texel at large circles of confusion, which
/// `Rgba16Float` rounds by several per cent.
const LAYER_FORMAT: TextureFormat = TextureFormat::Rgba32Float;
/// The layers' format otherwise.
const LAYER_FORMAT_FALLBACK: TextureFormat = TextureFormat::Rgba16Float;

/// The passes' layouts, shaders and pipelines. Pipelines vary by the view's MSAA (the
/// depth binding) and, for the composite, the view's colour format.
#[derive(Resource)]
pub(super) struct BokehPipelines {
    /// Indexed by `multisampled as usize`.
    pub(super) sprites_layout: [BindGroupLayoutDescriptor; 2],
    /// The compaction: counts, slots, list, draw arguments.
    pub(super) compact_layout: BindGroupLayoutDescriptor,
    pub(super) reduce: CachedComputePipelineId,
    pub(super) scan: CachedComputePipelineId,
    pub(super) compact: CachedComputePipelineId,
    pub(super) scatter_layout: BindGroupLayoutDescriptor,
    pub(super) composite_layout: [BindGroupLayoutDescriptor; 2],
    pub(super) sprites_shader: Handle<Shader>,
    pub(super) composite_shader: Handle<Shader>,
    pub(super) sprites: [Option<CachedComputePipelineId>; 2],
    /// Near half, far half, near quarter, far quarter (`SCATTER_LAYERS`).
    pub(super) scatter: [CachedRenderPipelineId; 4],
    pub(super) composite: HashMap<(TextureFormat, bool), CachedRenderPipelineId>,
    /// Linear, clamp-to-edge: the aperture.
    pub(super) sampler: Sampler,
    /// [`LAYER_FORMAT`], or [`LAYER_FORMAT_FALLBACK`] without `FLOAT32_BLENDABLE`.
    pub(super) layer_format: TextureFormat,
}

/// The scatter pass's layers, one draw each: the draw's label, the texture's, near,
/// quarter resolution.
pub(super) const SCATTER_LAYERS: [(&str, &str, bool, bool); 4] = [
    (
        "penumbra_bokeh_scatter_near",
        "penumbra_bokeh_near",
        true,
        false,
    ),
    (
        "penumbra_bokeh_scatter_far",
        "penumbra_bokeh_far",
        false,
        false,
    ),
    (
        "penumbra_bokeh_scatter_near_quarter",
        "penumbra_bokeh_near_quarter",
        true,
        true,
    ),
    (
        "penumbra_bokeh_scatter_far_quarter",
        "penumbra_bokeh_far_quarter",
        false,
        true,
    ),
];

/// A view's pipelines (ids into the pipeline cache).
#[derive(Component, Clone, Copy)]
pub struct ViewBokehPipelines {
    pub(super) sprites: CachedComputePipelineId,
    pub(super) composite: CachedRenderPipelineId,
}

/// Why the passes cannot run on this device, if they cannot.
pub(super) fn unsupported(world: &World) -> Option<String> {
    let (Some(adapter), Some(device)) = (
        world.get_resource::<RenderAdapter>(),
        world.get_resource::<RenderDevice>(),
    ) else {
        return Some("there is no renderer".into());
    };
    let needed = DownlevelFlags::COMPUTE_SHADERS
        | DownlevelFlags::VERTEX_STORAGE
        | DownlevelFlags::INDIRECT_EXECUTION;
    let flags = adapter.get_downlevel_capabilities().flags;
    if !flags.contains(needed) {
        return Some(format!(
            "the device lacks {:?}",
            needed.difference(flags & needed)
        ));
    }
    if device.limits().max_storage_buffers_per_shader_stage < 2 {
        return Some("the device allows fewer than 2 storage buffers per stage".into());
    }
    None
}

pub(super) fn init_bokeh_pipelines(
    mut commands: Commands,
    device: Res<RenderDevice>,
    pipeline_cache: Res<PipelineCache>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        warn!("Penumbra: the shader library is not registered; no bokeh depth of field");
        return;
    };
    let view_bytes = Some(BokehView::min_size());
    let depth = |multisampled: bool| {
        if multisampled {
            texture_depth_2d_multisampled()
        } else {
            texture_depth_2d()
        }
    };
    let color = || texture_2d(TextureSampleType::Float { filterable: false });
    let sprites_layout = [false, true].map(|ms| {
        BindGroupLayoutDescriptor::new(
            "penumbra_bokeh_sprites_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::COMPUTE,
                (
                    uniform_buffer_sized(false, view_bytes),
                    color(),
                    depth(ms),
                    storage_buffer_sized(false, None),
                    storage_buffer_sized(false, None),
                ),
            ),
        )
    });
    let compact_layout = BindGroupLayoutDescriptor::new(
        "penumbra_bokeh_compact_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, view_bytes),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, None),
            ),
        ),
    );
    let compact_shader = library.handle("dof/compact.wgsl");
    let compact_pipeline = |label: &'static str, entry: &'static str| {
        pipeline_cache.queue_compute_pipeline(ComputePipelineDescriptor {
            label: Some(label.into()),
            layout: vec![compact_layout.clone()],
            shader: compact_shader.clone(),
            entry_point: Some(entry.into()),
            ..default()
        })
    };
    let reduce = compact_pipeline("penumbra_bokeh_reduce", "reduce_main");
    let scan = compact_pipeline("penumbra_bokeh_scan", "scan_groups_main");
    let compact = compact_pipeline("penumbra_bokeh_compact", "compact_main");
    let scatter_layout = BindGroupLayoutDescriptor::new(
        "penumbra_bokeh_scatter_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::VERTEX_FRAGMENT,
            (
                uniform_buffer_sized(false, view_bytes),
                storage_buffer_read_only_sized(false, None),
                texture_2d(TextureSampleType::Float { filterable: true }),
                sampler(SamplerBindingType::Filtering),
                storage_buffer_read_only_sized(false, None),
                // The layers' first indices (the draws' argument buffer).
                storage_buffer_read_only_sized(false, None),
            ),
        ),
    );
    let composite_layout = [false, true].map(|ms| {
        BindGroupLayoutDescriptor::new(
            "penumbra_bokeh_composite_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::FRAGMENT,
                (
                    uniform_buffer_sized(false, view_bytes),
                    color(),
                    depth(ms),
                    color(),
                    color(),
                    color(),
                    color(),
                ),
            ),
        )
    });
    let layer_format = if device.features().contains(WgpuFeatures::FLOAT32_BLENDABLE) {
        LAYER_FORMAT
    } else {
        warn!(
            "Penumbra: the device cannot blend Rgba32Float; bokeh layers are Rgba16Float \
             (energy off by a few per cent at large circles of confusion)"
        );
        LAYER_FORMAT_FALLBACK
    };
    let scatter_shader = library.handle("dof/scatter.wgsl");
    let additive = BlendComponent {
        src_factor: BlendFactor::One,
        dst_factor: BlendFactor::One,
        operation: BlendOperation::Add,
    };
    let layer = Some(ColorTargetState {
        format: layer_format,
        blend: Some(BlendState {
            color: additive,
            alpha: additive,
        }),
        write_mask: ColorWrites::ALL,
    });
    // One draw per layer (`scatter.wgsl`), in `SCATTER_LAYERS`' order.
    let scatter = SCATTER_LAYERS.map(|(label, _, near, quarter)| {
        let mut shader_defs = Vec::new();
        if near {
            shader_defs.push("NEAR_LAYER".into());
        }
        if quarter {
            shader_defs.push("QUARTER_LAYER".into());
        }
        pipeline_cache.queue_render_pipeline(RenderPipelineDescriptor {
            label: Some(label.into()),
            layout: vec![scatter_layout.clone()],
            // Four vertices per sprite (`scatter.wgsl`).
            primitive: PrimitiveState {
                topology: PrimitiveTopology::TriangleStrip,
                ..default()
            },
            vertex: VertexState {
                shader: scatter_shader.clone(),
                shader_defs: shader_defs.clone(),
                entry_point: Some("vertex".into()),
                ..default()
            },
            fragment: Some(FragmentState {
                shader: scatter_shader.clone(),
                shader_defs,
                entry_point: Some("fragment".into()),
                targets: vec![layer.clone()],
            }),
            ..default()
        })
    });
    commands.insert_resource(BokehPipelines {
        layer_format,
        sprites_layout,
        compact_layout,
        reduce,
        scan,
        compact,
        scatter_layout,
        composite_layout,
        sprites_shader: library.handle("dof/sprites.wgsl"),
        composite_shader: library.handle("dof/composite.wgsl"),
        sprites: [None, None],
        scatter,
        composite: HashMap::default(),
        sampler: device.create_sampler(&SamplerDescriptor {
            label: Some("penumbra_bokeh_sampler"),
            mag_filter: FilterMode::Linear,
            min_filter: FilterMode::Linear,
            ..default()
        }),
    });
}

/// Queues each view's pipelines (once per variant).
pub(super) fn prepare_bokeh_pipelines(
    mut commands: Commands,
    views: Query<(Entity, &ViewTarget, &Msaa), With<ExtractedBokeh>>,
    pipelines: Option<ResMut<BokehPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    fullscreen: Res<FullscreenShader>,
) {
    let Some(mut pipelines) = pipelines else {
        return;
    };
    for (entity, target, msaa) in &views {
        let ms = *msaa != Msaa::Off;
        let defs = if ms {
            vec!["MULTISAMPLED".into()]
        } else {
            vec![]
        };
        let sprites = match pipelines.sprites[ms as usize] {
            Some(id) => id,
            None => {
                let id = pipeline_cache.queue_compute_pipeline(ComputePipelineDescriptor {
                    label: Some("penumbra_bokeh_sprites".into()),
                    layout: vec![pipelines.sprites_layout[ms as usize].clone()],
                    shader: pipelines.sprites_shader.clone(),
                    shader_defs: defs.clone(),
                    entry_point: Some("sprites_main".into()),
                    ..default()
                });
                pipelines.sprites[ms as usize] = Some(id);
                id
            }
        };
        let format = target.main_texture_format();
        let composite = match pipelines.composite.get(&(format, ms)) {
            Some(id) => *id,
            None => {
                let id = pipeline_cache.queue_render_pipeline(RenderPipelineDescriptor {
                    label: Some("penumbra_bokeh_composite".into()),
                    layout: vec![pipelines.composite_layout[ms as usize].clone()],
                    vertex: fullscreen.to_vertex_state(),
                    fragment: Some(FragmentState {
                        shader: pipelines.composite_shader.clone(),
                        shader_defs: defs,
                        entry_point: Some("fragment".into()),
                        targets: vec![Some(ColorTargetState {
                            format,
                            blend: None,
                            write_mask: ColorWrites::ALL,
                        })],
                    }),
                    ..default()
                });
                pipelines.composite.insert((format, ms), id);
                id
            }
        };
        commands
            .entity(entity)
            .insert(ViewBokehPipelines { sprites, composite });
    }
}
