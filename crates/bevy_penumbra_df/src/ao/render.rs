//! Render-world side of DFAO: per-view textures, the trace and upsample passes, and the
//! input the lighting pass reads.

use super::pipeline::{AoPipelines, init_ao_pipelines, queue_sample_upsample, queue_temporal_msaa};
use super::{DistanceFieldAoDebugView, DistanceFieldSpecularOcclusion, ExtractedDfao};
use crate::global_field::ViewGlobalField;
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::lighting::msaa_render::{DeferredMsaaTextures, pixel_prepass};
use crate::lighting::{PenumbraAoInput, PenumbraLightingView};
use crate::scene::{DistanceFieldGpu, GpuHeightfields};
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::prepass::{MotionVectorPrepass, ViewPrepassTextures};
use bevy::core_pipeline::schedule::Core3d;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::encase::UniformBuffer as EncaseBuffer;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, Buffer, BufferId, BufferUsages, ComputePassDescriptor, Extent3d,
    PipelineCache, ShaderType, TextureDescriptor, TextureDimension, TextureFormat, TextureUsages,
    TextureView, TextureViewDescriptor, TextureViewId,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::view::ExtractedView;
use bevy::render::{Render, RenderStartup, RenderSystems};
use penumbra_df_core::ao::{AoTemporalView, AoTraceView, jitter, trace_size, view_divisor};
use penumbra_df_core::cull::CameraOrigin;

/// A view's AO textures: the trace's (at the divisor's size), above divisor 1 the
/// full-size upsample (otherwise the trace is full-size), and with the temporal filter
/// two history pairs (the blend of each pixel's own AO and bent normal; distance and
/// confidence), written in turn: frame `f` writes pair `f mod 2` and reads the other,
/// and what the lighting pass binds — that blend, with the spatial fill where a pixel's
/// confidence is low — in `filtered` (one texture for every frame: its bind group
/// stays).
#[derive(Component)]
pub struct ViewAoTextures {
    trace: TextureView,
    full: Option<TextureView>,
    /// Deferred MSAA: the per-sample upsample's output, at twice the view's size.
    samples: Option<TextureView>,
    history: Option<[[TextureView; 2]; 2]>,
    filtered: Option<TextureView>,
    size: UVec2,
    divisor: u32,
    /// Frames prepared since the textures were made (the jitter and history pair).
    frame: u32,
    /// The camera's position in the previous frame (None: no history yet).
    previous_eye: Option<Vec3>,
}

impl ViewAoTextures {
    /// Before the temporal filter: the upsample's output, or the trace's.
    fn unfiltered(&self) -> &TextureView {
        self.full.as_ref().unwrap_or(&self.trace)
    }

    /// What the lighting pass reads this frame.
    fn result(&self) -> &TextureView {
        self.filtered.as_ref().unwrap_or_else(|| self.unfiltered())
    }
}

/// What a view's bind groups bind: the object buffer; atlas, depth, G-buffer and trace
/// views; the full-size view; the motion vectors and first history view; the
/// per-sample upsample's depth, G-buffer, classes and output.
type BindKey = (
    [BufferId; 2],
    [TextureViewId; 6],
    Option<TextureViewId>,
    Option<[TextureViewId; 2]>,
    Option<[TextureViewId; 4]>,
);

/// A view's uniforms and bind groups (remade only when a bound resource changes).
#[derive(Component)]
pub struct ViewAoBindGroups {
    uniform: Buffer,
    temporal_uniform: Buffer,
    key: Option<BindKey>,
    trace: Option<BindGroup>,
    upsample: Option<BindGroup>,
    /// Deferred MSAA's per-sample upsample.
    sample_upsample: Option<BindGroup>,
    /// The temporal pass of even and odd frames.
    temporal: Option<[BindGroup; 2]>,
    /// This frame's parity (which `temporal` group runs).
    parity: usize,
    /// The trace's group 1: the camera's global field, or `no_field`.
    far: Option<BindGroup>,
    /// An empty global field (made when first needed).
    no_field: Option<BindGroup>,
    /// No terrain (made when first needed).
    no_terrain: Option<(Buffer, TextureView)>,
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .add_systems(
            Render,
            (
                timed(prepare_dfao_textures)
                    .in_set(RenderSystems::PrepareResources)
                    .after(crate::scene::DistanceFieldRenderSystems::PrepareGpu),
                timed(prepare_dfao_bind_groups)
                    .in_set(RenderSystems::PrepareBindGroups)
                    .after(crate::global_field::render::prepare_global_field_bind_groups),
            ),
        )
        .add_systems(
            Core3d,
            timed(distance_field_ambient_occlusion)
                .in_set(crate::lighting::render::PenumbraLightingSystems::Inputs),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(RenderStartup, init_ao_pipelines);
}

fn ao_texture(
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    label: &'static str,
    size: UVec2,
) -> TextureView {
    allocations
        .texture(
            device,
            &TextureDescriptor {
                label: Some(label),
                size: Extent3d {
                    width: size.x,
                    height: size.y,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: TextureDimension::D2,
                format: TextureFormat::Rgba16Float,
                usage: TextureUsages::STORAGE_BINDING | TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            },
        )
        .create_view(&TextureViewDescriptor::default())
}

/// Gives every DFAO view its textures (pooled: remade only when the view's size or
/// the divisor changes) and tells its lighting pass to read them. Views without casters
/// or before the pipelines compile get nothing: their AO is 1.
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
fn prepare_dfao_textures(
    mut commands: Commands,
    device: Res<RenderDevice>,
    allocations: Res<PenumbraGpuAllocations>,
    gpu: Option<Res<DistanceFieldGpu>>,
    mut pipelines: Option<ResMut<AoPipelines>>,
    library: Option<Res<PenumbraShaderLibrary>>,
    pipeline_cache: Res<PipelineCache>,
    views: Query<(
        Entity,
        &ExtractedView,
        &PenumbraLightingView,
        &ExtractedDfao,
        Option<&ViewAoTextures>,
        Has<MotionVectorPrepass>,
    )>,
) {
    // Which passes' pipelines have compiled (trace, upsample, temporal).
    let compiled = pipelines.as_ref().map_or([false; 3], |p| {
        [p.trace, p.upsample, p.temporal]
            .map(|id| pipeline_cache.get_compute_pipeline(id).is_some())
    });
    let has_objects = gpu.as_ref().is_some_and(|g| g.objects.is_some());
    for (entity, view, lighting_view, &ExtractedDfao(resolved), textures, motion) in &views {
        // Deferred MSAA: edge pixels upsampled per sample, once that pass has compiled.
        let sample_upsample = match (
            lighting_view.msaa.as_ref().filter(|m| m.sample_occlusion),
            pipelines.as_deref_mut(),
            library.as_deref(),
        ) {
            (Some(_), Some(p), Some(library)) => {
                Some(queue_sample_upsample(p, library, &pipeline_cache))
            }
            _ => None,
        };
        let samples =
            sample_upsample.is_some_and(|id| pipeline_cache.get_compute_pipeline(id).is_some());
        // Without motion vectors (the prepass removed by hand) there is no temporal
        // filter: each frame stands alone. The objects-per-tile view shows the trace's
        // counts unfiltered.
        let temporal = resolved.temporal
            && motion
            && resolved.debug != DistanceFieldAoDebugView::ObjectsPerTile;
        // Deferred MSAA views read multisampled motion vectors: their own pipeline. The
        // lighting reads the filtered texture only once that pass can write it.
        let temporal_compiled = match (
            &lighting_view.msaa,
            pipelines.as_deref_mut(),
            library.as_deref(),
        ) {
            (None, ..) => compiled[2],
            (Some(_), Some(p), Some(library)) if temporal => pipeline_cache
                .get_compute_pipeline(queue_temporal_msaa(p, library, &pipeline_cache))
                .is_some(),
            _ => false,
        };
        let size = view.viewport.zw().max(UVec2::ONE);
        // A small view traces more of its pixels (`view_divisor`).
        let divisor = view_divisor(size, resolved.divisor, resolved.min_trace_rows);
        // Only the passes this view runs need to have compiled.
        let ready =
            compiled[0] && (divisor <= 1 || compiled[1]) && (!temporal || temporal_compiled);
        if !(ready && has_objects) {
            commands.entity(entity).remove::<PenumbraAoInput>();
            continue;
        }
        let mut fresh = None;
        let textures = match textures {
            Some(t)
                if t.size == size
                    && t.divisor == divisor
                    && t.history.is_some() == temporal
                    && t.samples.is_some() == samples =>
            {
                t
            }
            _ => {
                let texture = |label| ao_texture(&allocations, &device, label, size);
                fresh = Some(ViewAoTextures {
                    trace: ao_texture(
                        &allocations,
                        &device,
                        "penumbra_dfao_trace",
                        trace_size(size, divisor),
                    ),
                    full: (divisor > 1).then(|| texture("penumbra_dfao")),
                    samples: samples.then(|| {
                        ao_texture(&allocations, &device, "penumbra_dfao_samples", 2 * size)
                    }),
                    history: temporal.then(|| {
                        [0, 1].map(|_| {
                            [
                                texture("penumbra_dfao_history"),
                                texture("penumbra_dfao_history_state"),
                            ]
                        })
                    }),
                    filtered: temporal.then(|| texture("penumbra_dfao_filtered")),
                    size,
                    divisor,
                    frame: 0,
                    previous_eye: None,
                });
                fresh.as_ref().expect("just set")
            }
        };
        let input = PenumbraAoInput {
            texture: textures.result().clone(),
            samples: textures.samples.clone(),
            contrast: resolved.contrast,
            min_occlusion: resolved.min_occlusion,
            tint: resolved.tint,
            specular_occlusion: match resolved.specular {
                DistanceFieldSpecularOcclusion::None => 0,
                DistanceFieldSpecularOcclusion::NonDirectional => 1,
                DistanceFieldSpecularOcclusion::ConeCone => 2,
            },
            debug_view: match resolved.debug {
                DistanceFieldAoDebugView::None => 0,
                DistanceFieldAoDebugView::AmbientOcclusion => 1,
                DistanceFieldAoDebugView::BentNormal => 2,
                DistanceFieldAoDebugView::ObjectsPerTile => 3,
            },
        };
        let mut view_entity = commands.entity(entity);
        view_entity.insert(input);
        if let Some(fresh) = fresh {
            view_entity.insert(fresh);
        }
    }
}

/// Writes each DFAO view's uniform and (re)makes its bind groups when a bound resource
/// changed.
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
fn prepare_dfao_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    allocations: Res<PenumbraGpuAllocations>,
    gpu: Option<Res<DistanceFieldGpu>>,
    terrains: Option<Res<GpuHeightfields>>,
    pipelines: Option<Res<AoPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut views: Query<
        (
            Entity,
            &ExtractedView,
            &ExtractedDfao,
            &mut ViewAoTextures,
            &ViewPrepassTextures,
            Option<&DeferredMsaaTextures>,
            Option<&mut ViewAoBindGroups>,
            Option<&ViewGlobalField>,
        ),
        With<PenumbraAoInput>,
    >,
) {
    let (Some(gpu), Some(pipelines)) = (gpu, pipelines) else {
        return;
    };
    let Some(objects) = gpu.objects.as_ref() else {
        return;
    };
    let atlas = gpu
        .atlas
        .as_ref()
        .map_or(&pipelines.empty_atlas, |(_, view, _)| view);
    let brick_table = gpu
        .brick_table
        .as_ref()
        .map_or(&pipelines.empty_brick_table, |(_, view, _)| view);
    for (entity, view, ExtractedDfao(settings), mut textures, prepass, msaa, groups, field) in
        &mut views
    {
        let (depth, gbuffer) = pixel_prepass(prepass, msaa);
        let (Some(depth), Some(gbuffer), Some(camera)) = (
            depth,
            gbuffer,
            CameraOrigin::at(view.world_from_view.translation()),
        ) else {
            continue;
        };
        // Deferred MSAA: the multisampled depth and G-buffer, the classes, the output.
        let samples = textures
            .samples
            .clone()
            .zip(msaa)
            .zip(prepass.depth_view())
            .map(|((out, msaa), depth)| {
                [
                    depth.clone(),
                    msaa.gbuffer_view.clone(),
                    msaa.class.default_view.clone(),
                    out,
                ]
            });
        let motion = prepass.motion_vectors_view();
        let frame = textures.frame;
        let eye = view.world_from_view.translation();
        let view_from_clip = view.clip_from_view.inverse();
        let world_from_view = Mat3::from(view.world_from_view.affine().matrix3);
        let temporal = textures.history.is_some() && motion.is_some();
        let mut uniform = AoTraceView::new(
            &camera,
            view_from_clip,
            world_from_view,
            textures.size,
            textures.divisor,
            if temporal {
                jitter(frame, textures.divisor)
            } else {
                UVec2::ZERO
            },
            gpu.slot_count,
            &settings.trace,
        );
        uniform.tile_objects_debug =
            u32::from(settings.debug == DistanceFieldAoDebugView::ObjectsPerTile);
        if field.is_some() {
            uniform = uniform.with_far_field(&settings.trace, settings.global_field_start);
        }
        uniform.heightfield_count = terrains.as_ref().map_or(0, |t| t.count);
        uniform.origin = view.viewport.xy();
        let mut bytes = EncaseBuffer::new(Vec::new());
        bytes.write(&uniform).expect("fixed-size uniform");
        let temporal_uniform = AoTemporalView {
            view_from_clip,
            world_from_view,
            previous_offset: textures.previous_eye.map_or(Vec3::ZERO, |p| p - eye),
            history_valid: u32::from(textures.previous_eye.is_some()),
            full_size: textures.size,
            confidence: 1,
            spatial_fill: 1,
            origin: view.viewport.xy(),
        };
        let mut temporal_bytes = EncaseBuffer::new(Vec::new());
        temporal_bytes
            .write(&temporal_uniform)
            .expect("fixed-size uniform");
        textures.frame = frame.wrapping_add(1);
        textures.previous_eye = temporal.then_some(eye);
        let mut fresh = None;
        let groups = match groups {
            Some(g) => g.into_inner(),
            None => {
                fresh = Some(ViewAoBindGroups {
                    uniform: allocations.sized_buffer(
                        &device,
                        "penumbra_dfao_view",
                        AoTraceView::min_size().get(),
                        BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                    ),
                    temporal_uniform: allocations.sized_buffer(
                        &device,
                        "penumbra_dfao_temporal_view",
                        AoTemporalView::min_size().get(),
                        BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                    ),
                    key: None,
                    trace: None,
                    upsample: None,
                    sample_upsample: None,
                    temporal: None,
                    parity: 0,
                    far: None,
                    no_field: None,
                    no_terrain: None,
                });
                fresh.as_mut().expect("just set")
            }
        };
        groups.far = Some(match field {
            Some(field) => field.read_group().clone(),
            None => groups
                .no_field
                .get_or_insert_with(|| {
                    crate::global_field::empty_read_group(&allocations, &device, &pipeline_cache)
                })
                .clone(),
        });
        queue.write_buffer(&groups.uniform, 0, bytes.as_ref());
        queue.write_buffer(&groups.temporal_uniform, 0, temporal_bytes.as_ref());
        groups.parity = (frame % 2) as usize;
        let history = textures.history.as_ref().filter(|_| temporal);
        let (terrain_records, heights) = match terrains.as_ref() {
            Some(t) => (&t.records, &t.texture),
            None => {
                let none = groups
                    .no_terrain
                    .get_or_insert_with(|| crate::scene::no_heightfields(&allocations, &device));
                (&none.0, &none.1)
            }
        };
        let key = (
            [objects.id(), terrain_records.id()],
            [
                atlas.id(),
                depth.id(),
                gbuffer.id(),
                textures.trace.id(),
                heights.id(),
                brick_table.id(),
            ],
            textures.full.as_ref().map(TextureView::id),
            motion.zip(history).map(|(m, h)| [m.id(), h[0][0].id()]),
            samples.as_ref().map(|s| s.each_ref().map(|v| v.id())),
        );
        if groups.key != Some(key) {
            groups.trace = Some(allocations.bind_group(
                &device,
                "penumbra_dfao_trace",
                &pipeline_cache.get_bind_group_layout(&pipelines.trace_layout),
                &BindGroupEntries::sequential((
                    objects.as_entire_binding(),
                    atlas,
                    depth,
                    gbuffer,
                    groups.uniform.as_entire_binding(),
                    &textures.trace,
                    terrain_records.as_entire_binding(),
                    heights,
                    brick_table,
                )),
            ));
            groups.upsample = textures.full.as_ref().map(|full| {
                allocations.bind_group(
                    &device,
                    "penumbra_dfao_upsample",
                    &pipeline_cache.get_bind_group_layout(&pipelines.upsample_layout),
                    &BindGroupEntries::sequential((
                        &textures.trace,
                        depth,
                        gbuffer,
                        groups.uniform.as_entire_binding(),
                        full,
                    )),
                )
            });
            groups.sample_upsample = samples.as_ref().map(|[ms_depth, ms_gbuffer, class, out]| {
                let layout = &pipelines.sample_upsample_layout;
                allocations.bind_group(
                    &device,
                    "penumbra_dfao_sample_upsample",
                    &pipeline_cache.get_bind_group_layout(layout),
                    &BindGroupEntries::sequential((
                        &textures.trace,
                        depth,
                        gbuffer,
                        groups.uniform.as_entire_binding(),
                        out,
                        ms_depth,
                        ms_gbuffer,
                        class,
                    )),
                )
            });
            let filtered = textures.filtered.as_ref();
            groups.temporal =
                motion
                    .zip(history)
                    .zip(filtered)
                    .map(|((motion, pairs), filtered)| {
                        // Parity p writes pair p and reads the other.
                        [0, 1].map(|p| {
                            let (read, write) = (&pairs[1 - p], &pairs[p]);
                            allocations.bind_group(
                                &device,
                                "penumbra_dfao_temporal",
                                &pipeline_cache.get_bind_group_layout(if msaa.is_some() {
                                    &pipelines.temporal_msaa_layout
                                } else {
                                    &pipelines.temporal_layout
                                }),
                                &BindGroupEntries::sequential((
                                    textures.unfiltered(),
                                    &read[0],
                                    &read[1],
                                    depth,
                                    gbuffer,
                                    motion,
                                    groups.temporal_uniform.as_entire_binding(),
                                    &write[0],
                                    &write[1],
                                    filtered,
                                )),
                            )
                        })
                    });
            groups.key = Some(key);
        }
        if let Some(fresh) = fresh {
            commands.entity(entity).insert(fresh);
        }
    }
}

/// The view's DFAO passes: the trace, then (above divisor 1) the upsample, then (with
/// the temporal filter) the temporal pass. Dispatches only.
fn distance_field_ambient_occlusion(
    view: ViewQuery<(
        &ViewAoBindGroups,
        &ViewAoTextures,
        &PenumbraAoInput,
        Has<DeferredMsaaTextures>,
    )>,
    pipelines: Option<Res<AoPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (groups, textures, _, msaa) = view.into_inner();
    let Some(pipelines) = pipelines else {
        return;
    };
    // `prepare_dfao_textures` gave the view its input only once the passes it runs
    // had compiled.
    let Some(trace) = pipeline_cache.get_compute_pipeline(pipelines.trace) else {
        return;
    };
    let upsample = pipeline_cache.get_compute_pipeline(pipelines.upsample);
    let sample_upsample = pipelines
        .sample_upsample
        .and_then(|id| pipeline_cache.get_compute_pipeline(id));
    let temporal = if msaa {
        pipelines.temporal_msaa
    } else {
        Some(pipelines.temporal)
    }
    .and_then(|id| pipeline_cache.get_compute_pipeline(id));
    let (Some(trace_group), Some(far_group)) = (&groups.trace, &groups.far) else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_dfao");
    {
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor {
                label: Some("penumbra_dfao_trace"),
                timestamp_writes: None,
            });
        pass.set_pipeline(trace);
        pass.set_bind_group(0, trace_group, &[]);
        pass.set_bind_group(1, far_group, &[]);
        let size = trace_size(textures.size, textures.divisor);
        pass.dispatch_workgroups(size.x.div_ceil(8), size.y.div_ceil(8), 1);
    }
    if let (Some(upsample_group), Some(upsample)) = (&groups.upsample, upsample) {
        // Its own pass: the trace, written as storage above, is sampled here.
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor {
                label: Some("penumbra_dfao_upsample"),
                timestamp_writes: None,
            });
        pass.set_pipeline(upsample);
        pass.set_bind_group(0, upsample_group, &[]);
        pass.dispatch_workgroups(textures.size.x.div_ceil(8), textures.size.y.div_ceil(8), 1);
    }
    if let (Some(group), Some(pipeline)) = (&groups.sample_upsample, sample_upsample) {
        // Deferred MSAA: the edge pixels' samples, one thread each (the trace is
        // sampled here, as by the upsample).
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor {
                label: Some("penumbra_dfao_sample_upsample"),
                timestamp_writes: None,
            });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(textures.size.x.div_ceil(4), textures.size.y.div_ceil(4), 1);
    }
    if let (Some(temporal_groups), Some(temporal)) = (&groups.temporal, temporal) {
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor {
                label: Some("penumbra_dfao_temporal"),
                timestamp_writes: None,
            });
        pass.set_pipeline(temporal);
        pass.set_bind_group(0, &temporal_groups[groups.parity], &[]);
        pass.dispatch_workgroups(textures.size.x.div_ceil(8), textures.size.y.div_ceil(8), 1);
    }
    time_span.end(ctx.command_encoder());
}
