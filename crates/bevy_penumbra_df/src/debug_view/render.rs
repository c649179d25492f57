//! Render-world side of the debug view.

use super::{DistanceFieldDebugMode, DistanceFieldDebugView};
use crate::scene::{DistanceFieldGpu, DistanceFieldPipelines, cull_objects};
use crate::shader_library::PenumbraShaderLibrary;
use bevy::core_pipeline::{Core3dSystems, FullscreenShader, schedule::Core3d};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, texture_3d, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, BufferInitDescriptor,
    BufferUsages, CachedRenderPipelineId, ColorTargetState, ColorWrites, FragmentState, Operations,
    PipelineCache, RenderPassColorAttachment, RenderPassDescriptor, RenderPipelineDescriptor,
    ShaderStages, TextureFormat, TextureSampleType, TextureView,
};
use bevy::render::renderer::{RenderContext, RenderDevice, ViewQuery};
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
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .add_systems(
            Render,
            prepare_debug_view_pipelines.in_set(RenderSystems::Prepare),
        )
        .add_systems(
            Core3d,
            // After tonemapping: the debug image is shown as it is (it is not a radiance).
            // Left unordered, HDR cameras were tonemapped in some runs and not in others.
            distance_field_debug_view
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
            ),
        ),
    );
    commands.insert_resource(DebugViewPipelines {
        layout,
        shader: library.handle("df/debug_view.wgsl"),
        by_format: HashMap::default(),
        empty_atlas: crate::shader_library::empty_atlas(&device),
    });
}

fn prepare_debug_view_pipelines(
    views: Query<&ViewTarget, With<DistanceFieldDebugView>>,
    pipelines: Option<ResMut<DebugViewPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    fullscreen: Res<FullscreenShader>,
) {
    let Some(mut pipelines) = pipelines else {
        return;
    };
    for target in &views {
        let format = target.main_texture_format();
        if pipelines.by_format.contains_key(&format) {
            continue;
        }
        let id = pipeline_cache.queue_render_pipeline(RenderPipelineDescriptor {
            label: Some("penumbra_df_debug_view".into()),
            layout: vec![pipelines.layout.clone()],
            vertex: fullscreen.to_vertex_state(),
            fragment: Some(FragmentState {
                shader: pipelines.shader.clone(),
                entry_point: Some("debug_view".into()),
                targets: vec![Some(ColorTargetState {
                    format,
                    blend: None,
                    write_mask: ColorWrites::ALL,
                })],
                ..default()
            }),
            ..default()
        });
        pipelines.by_format.insert(format, id);
    }
}

#[allow(clippy::too_many_arguments)]
fn distance_field_debug_view(
    view: ViewQuery<(&ViewTarget, &ExtractedView, &DistanceFieldDebugView)>,
    gpu: Res<DistanceFieldGpu>,
    scene_pipelines: Option<Res<DistanceFieldPipelines>>,
    pipelines: Option<Res<DebugViewPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut warned_ortho: Local<bool>,
    mut ctx: RenderContext,
) {
    let (target, extracted, settings) = view.into_inner();
    let (Some(scene_pipelines), Some(pipelines)) = (scene_pipelines, pipelines) else {
        return;
    };
    let Some(pipeline) = pipelines
        .by_format
        .get(&target.main_texture_format())
        .and_then(|id| pipeline_cache.get_render_pipeline(*id))
    else {
        return;
    };
    if extracted.clip_from_view.w_axis.w == 1.0 {
        if !*warned_ortho {
            warn!("Penumbra: DistanceFieldDebugView supports perspective cameras only");
            *warned_ortho = true;
        }
        return;
    }
    let world_from_view = extracted.world_from_view.affine();
    let camera = Vec3::from(world_from_view.translation);
    let view_from_relative = Mat4::from_mat3a(world_from_view.matrix3).inverse();
    let clip_from_relative = extracted.clip_from_view * view_from_relative;
    let Some(objects) = gpu.objects.as_ref() else {
        return; // no caster has ever existed: nothing to trace
    };
    let Some(culled) = cull_objects(
        &mut ctx,
        &gpu,
        &scene_pipelines,
        &pipeline_cache,
        clip_from_relative,
        camera,
    ) else {
        return;
    };
    let Some(origin) = CameraOrigin::at(camera) else {
        return;
    };
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
        DistanceFieldDebugMode::Shaded => 1,
    };
    words.extend([
        mode,
        settings.max_steps.clamp(1, 4096),
        settings.max_distance.max(0.0).to_bits(),
        0,
    ]);
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    let device = ctx.render_device().clone();
    let uniform = device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some("penumbra_df_debug_view"),
        contents: &bytes,
        usage: BufferUsages::UNIFORM,
    });
    let atlas = gpu
        .atlas
        .as_ref()
        .map_or(&pipelines.empty_atlas, |(_, view, _)| view);
    let bind_group = device.create_bind_group(
        "penumbra_df_debug_view",
        &pipeline_cache.get_bind_group_layout(&pipelines.layout),
        &BindGroupEntries::sequential((
            objects.as_entire_binding(),
            culled.list.as_entire_binding(),
            culled.count.as_entire_binding(),
            atlas,
            uniform.as_entire_binding(),
        )),
    );
    let post_process = target.post_process_write();
    let mut pass = ctx
        .command_encoder()
        .begin_render_pass(&RenderPassDescriptor {
            label: Some("penumbra_df_debug_view"),
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
    pass.set_bind_group(0, &bind_group, &[]);
    pass.draw(0..3, 0..1);
}
