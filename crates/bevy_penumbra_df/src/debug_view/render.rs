//! Render-world side of the debug view.

use super::{DistanceFieldDebugMode, DistanceFieldDebugView};
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::scene::{CulledObjects, DistanceFieldGpu, DistanceFieldPipelines};
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::{Core3dSystems, FullscreenShader, schedule::Core3d};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, texture_2d, texture_3d, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferId, BufferUsages, CachedRenderPipelineId, ColorTargetState, ColorWrites, FragmentState,
    Operations, PipelineCache, RenderPassColorAttachment, RenderPassDescriptor, RenderPipeline,
    RenderPipelineDescriptor, ShaderStages, TextureFormat, TextureSampleType, TextureView,
    TextureViewId,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::view::{ExtractedView, ViewTarget};
use bevy::render::{Render, RenderStartup, RenderSystems};
use penumbra_df_core::cull::CameraOrigin;
use std::num::NonZeroU64;

/// Bytes of the `DebugView` uniform in `df/debug_view.wgsl`.
const DEBUG_VIEW_BYTES: u64 = 64 + 16 + 16 + 16;

#[derive(Resource)]
struct DebugViewPipelines {
    layout: BindGroupLayoutDescriptor,
    shader: Handle<Shader>,
    by_format: HashMap<TextureFormat, CachedRenderPipelineId>,
    /// Bound when no SDF volume exists (analytic-only scenes).
    empty_atlas: TextureView,
    /// Bound when no volume is placed as bricks.
    empty_brick_table: TextureView,
}

/// A debug view's uniform and bind group (render world), reused across frames.
#[derive(Component)]
struct DebugViewResources {
    uniform: Buffer,
    /// The bind group and the object buffer, culled list, atlas and brick table it binds.
    bind_group: Option<(BindGroup, [BufferId; 2], [TextureViewId; 2])>,
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .add_systems(
            Render,
            (
                timed(prepare_debug_view_pipelines)
                    .in_set(RenderSystems::Prepare)
                    .before(RenderSystems::PrepareResources),
                timed(prepare_debug_view_resources)
                    .in_set(RenderSystems::PrepareResources)
                    .after(crate::scene::DistanceFieldRenderSystems::PrepareGpu),
                timed(prepare_debug_view_bind_groups).in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(
            Core3d,
            // After tonemapping: the debug image is shown as it is (it is not a radiance).
            // Left unordered, HDR cameras were tonemapped in some runs and not in others.
            timed(distance_field_debug_view)
                .in_set(Core3dSystems::PostProcess)
                .after(bevy::core_pipeline::tonemapping::tonemapping),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(RenderStartup, init_debug_view_pipelines);
}

fn init_debug_view_pipelines(
    mut commands: Commands,
    device: Res<RenderDevice>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return; // warned by the scene plugin
    };
    let layout = BindGroupLayoutDescriptor::new(
        "penumbra_df_debug_view_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::FRAGMENT,
            (
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                texture_3d(TextureSampleType::Float { filterable: false }),
                uniform_buffer_sized(false, NonZeroU64::new(DEBUG_VIEW_BYTES)),
                texture_2d(TextureSampleType::Uint),
            ),
        ),
    );
    commands.insert_resource(DebugViewPipelines {
        layout,
        shader: library.handle("df/debug_view.wgsl"),
        by_format: HashMap::default(),
        empty_atlas: crate::shader_library::empty_atlas(&device),
        empty_brick_table: crate::shader_library::empty_brick_table(&device),
    });
}

fn prepare_debug_view_pipelines(
    views: Query<(&ViewTarget, &DistanceFieldDebugView)>,
    pipelines: Option<ResMut<DebugViewPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    fullscreen: Res<FullscreenShader>,
) {
    let Some(mut pipelines) = pipelines else {
        return;
    };
    for (target, view) in &views {
        let format = target.main_texture_format();
        if view.mode.is_global_field() || pipelines.by_format.contains_key(&format) {
            continue; // the global field's modes have their own pipeline
        }
        let id = pipeline_cache.queue_render_pipeline(fullscreen_pipeline(
            "penumbra_df_debug_view",
            vec![pipelines.layout.clone()],
            &pipelines.shader,
            "debug_view",
            format,
            &fullscreen,
        ));
        pipelines.by_format.insert(format, id);
    }
}

/// A debug view's inputs and pooled resources.
type DebugViewQuery<'a> = (
    Entity,
    &'a ExtractedView,
    &'a DistanceFieldDebugView,
    Option<&'a mut CulledObjects>,
    Option<&'a mut DebugViewResources>,
);

/// Per debug view: its culling (`CulledObjects`), its uniform and its bind group.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_debug_view_resources(
    mut commands: Commands,
    mut views: Query<DebugViewQuery>,
    gpu: Res<DistanceFieldGpu>,
    scene_pipelines: Option<Res<DistanceFieldPipelines>>,
    pipelines: Option<Res<DebugViewPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mut warned_ortho: Local<bool>,
) {
    let (Some(scene_pipelines), true, true) =
        (scene_pipelines, pipelines.is_some(), gpu.objects.is_some())
    else {
        return; // no caster has ever existed: nothing to trace
    };
    for (entity, extracted, settings, culled, resources) in &mut views {
        if settings.mode.is_global_field() {
            continue; // the global field's debug pass draws it
        }
        if extracted.clip_from_view.w_axis.w == 1.0 {
            if !*warned_ortho {
                warn!("Penumbra: DistanceFieldDebugView supports perspective cameras only");
                *warned_ortho = true;
            }
            continue;
        }
        let world_from_view = extracted.world_from_view.affine();
        let camera = Vec3::from(world_from_view.translation);
        let view_from_relative = Mat4::from_mat3a(world_from_view.matrix3).inverse();
        let clip_from_relative = extracted.clip_from_view * view_from_relative;
        let Some(origin) = CameraOrigin::at(camera) else {
            continue;
        };
        let mut entity_commands = commands.entity(entity);
        CulledObjects::prepare(
            culled,
            &mut entity_commands,
            &gpu,
            &scene_pipelines,
            &pipeline_cache,
            &allocations,
            &device,
            &queue,
            clip_from_relative,
            camera,
        );
        let mut fresh = None;
        let resources = match resources {
            Some(r) => r.into_inner(),
            None => fresh.insert(DebugViewResources {
                uniform: allocations.sized_buffer(
                    &device,
                    "penumbra_df_debug_view",
                    DEBUG_VIEW_BYTES,
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                bind_group: None,
            }),
        };
        let words = debug_view_words(clip_from_relative, &origin, settings);
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        queue.write_buffer(&resources.uniform, 0, &bytes);
        if let Some(fresh) = fresh {
            entity_commands.insert(fresh);
        }
    }
}

/// The `DebugView` uniform of `df/debug_view.wgsl`.
fn debug_view_words(
    clip_from_relative: Mat4,
    origin: &CameraOrigin,
    settings: &DistanceFieldDebugView,
) -> Vec<u32> {
    let mut words: Vec<u32> = clip_from_relative
        .inverse()
        .to_cols_array()
        .map(f32::to_bits)
        .to_vec();
    words.extend([
        origin.tile[0] as u32,
        origin.tile[1] as u32,
        origin.tile[2] as u32,
        0,
    ]);
    words.extend(origin.offset.extend(0.0).to_array().map(f32::to_bits));
    let mode = match settings.mode {
        DistanceFieldDebugMode::StepCount => 0,
        // The global field's modes are drawn by its module (skipped above).
        _ => 1,
    };
    words.extend([
        mode,
        settings.max_steps.clamp(1, 4096),
        settings.max_distance.max(0.0).to_bits(),
        0,
    ]);
    words
}

/// Makes a debug view's bind group when its resources changed.
fn prepare_debug_view_bind_groups(
    mut views: Query<(&CulledObjects, &mut DebugViewResources)>,
    gpu: Res<DistanceFieldGpu>,
    pipelines: Option<Res<DebugViewPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
) {
    let (Some(pipelines), Some(objects)) = (pipelines, gpu.objects.as_ref()) else {
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
    for (culled, mut resources) in &mut views {
        let key = (
            [objects.id(), culled.list.id()],
            [atlas.id(), brick_table.id()],
        );
        if resources.bind_group.as_ref().map(|(_, b, a)| (*b, *a)) == Some(key) {
            continue;
        }
        let bind_group = allocations.bind_group(
            &device,
            "penumbra_df_debug_view",
            &pipeline_cache.get_bind_group_layout(&pipelines.layout),
            &BindGroupEntries::sequential((
                objects.as_entire_binding(),
                culled.list.as_entire_binding(),
                culled.count.as_entire_binding(),
                atlas,
                resources.uniform.as_entire_binding(),
                brick_table,
            )),
        );
        resources.bind_group = Some((bind_group, key.0, key.1));
    }
}

/// Culls the scene for the view, then ray-marches it over the view's image.
fn distance_field_debug_view(
    view: ViewQuery<(&ViewTarget, &CulledObjects, &DebugViewResources)>,
    scene_pipelines: Option<Res<DistanceFieldPipelines>>,
    pipelines: Option<Res<DebugViewPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (target, culled, resources) = view.into_inner();
    let (Some(scene_pipelines), Some(pipelines), Some((bind_group, ..))) =
        (scene_pipelines, pipelines, &resources.bind_group)
    else {
        return;
    };
    let Some(pipeline) = pipelines
        .by_format
        .get(&target.main_texture_format())
        .and_then(|id| pipeline_cache.get_render_pipeline(*id))
    else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_df_debug_view");
    if culled.dispatch(&mut ctx, &scene_pipelines, &pipeline_cache) {
        draw_over_view(
            &mut ctx,
            target,
            "penumbra_df_debug_view",
            pipeline,
            &[bind_group],
        );
    }
    time_span.end(ctx.command_encoder());
}

/// A debug view's fullscreen pipeline: fragment `entry` of `shader` over `layouts`,
/// writing a view's `format` unblended.
pub(crate) fn fullscreen_pipeline(
    label: &'static str,
    layouts: Vec<BindGroupLayoutDescriptor>,
    shader: &Handle<Shader>,
    entry: &'static str,
    format: TextureFormat,
    fullscreen: &FullscreenShader,
) -> RenderPipelineDescriptor {
    RenderPipelineDescriptor {
        label: Some(label.into()),
        layout: layouts,
        vertex: fullscreen.to_vertex_state(),
        fragment: Some(FragmentState {
            shader: shader.clone(),
            entry_point: Some(entry.into()),
            targets: vec![Some(ColorTargetState {
                format,
                blend: None,
                write_mask: ColorWrites::ALL,
            })],
            ..default()
        }),
        ..default()
    }
}

/// Draws a fullscreen `pipeline` with bind groups `groups` (0, 1, …) over the view's
/// image (its post-process destination).
pub(crate) fn draw_over_view(
    ctx: &mut RenderContext,
    target: &ViewTarget,
    label: &'static str,
    pipeline: &RenderPipeline,
    groups: &[&BindGroup],
) {
    let post_process = target.post_process_write();
    let mut pass = ctx
        .command_encoder()
        .begin_render_pass(&RenderPassDescriptor {
            label: Some(label),
            color_attachments: &[Some(RenderPassColorAttachment {
                view: post_process.destination,
                depth_slice: None,
                resolve_target: None,
                ops: Operations::default(),
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
    pass.set_pipeline(pipeline);
    for (index, group) in groups.iter().enumerate() {
        pass.set_bind_group(index as u32, *group, &[]);
    }
    pass.draw(0..3, 0..1);
}
