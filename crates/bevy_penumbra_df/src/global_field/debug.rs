//! Render-world side of the global field's debug views
//! ([`DistanceFieldDebugMode::GlobalField`] and the two after it, on a camera with a
//! [`GlobalDistanceField`](super::GlobalDistanceField)): a pooled uniform and
//! composed-brick bits per view, and a fullscreen pass after tonemapping that
//! sphere-traces the camera's clipmaps (`shaders/df/global_field_debug.wgsl`, its group
//! 1 the field's read group).

use super::render::{ViewGlobalField, read_layout};
use crate::debug_view::render::{draw_over_view, fullscreen_pipeline};
use crate::debug_view::{DistanceFieldDebugMode, DistanceFieldDebugView};
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::{Core3dSystems, FullscreenShader, schedule::Core3d};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, uniform_buffer_sized,
};
use bevy::render::render_resource::encase::UniformBuffer;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferUsages, CachedRenderPipelineId, PipelineCache, ShaderStages, ShaderType, TextureFormat,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::view::{ExtractedView, ViewTarget};
use bevy::render::{Render, RenderStartup, RenderSystems};
use penumbra_df_core::clipmap::debug::{FieldDebugMode, FieldDebugParams, composed_bits};

#[derive(Resource)]
struct FieldDebugPipelines {
    layout: BindGroupLayoutDescriptor,
    shader: Handle<Shader>,
    by_format: HashMap<TextureFormat, CachedRenderPipelineId>,
}

/// A view's uniform, composed-brick bits and their bind group (pooled; the bits'
/// buffer is made again only when the clipmaps' layout grows it).
#[derive(Component)]
pub struct FieldDebugResources {
    uniform: Buffer,
    updated: Buffer,
    group: BindGroup,
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .add_systems(
            Render,
            (
                timed(prepare_field_debug_pipelines)
                    .in_set(RenderSystems::Prepare)
                    .before(RenderSystems::PrepareResources),
                timed(prepare_field_debug_resources)
                    .in_set(RenderSystems::PrepareBindGroups)
                    .after(super::render::prepare_global_field_bind_groups),
            ),
        )
        .add_systems(
            Core3d,
            timed(global_field_debug_view)
                .in_set(Core3dSystems::PostProcess)
                .after(bevy::core_pipeline::tonemapping::tonemapping),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(RenderStartup, init_field_debug_pipelines);
}

fn init_field_debug_pipelines(mut commands: Commands, library: Option<Res<PenumbraShaderLibrary>>) {
    let Some(library) = library else {
        return;
    };
    commands.insert_resource(FieldDebugPipelines {
        layout: BindGroupLayoutDescriptor::new(
            "penumbra_global_field_debug_layout",
            &BindGroupLayoutEntries::sequential(
                ShaderStages::FRAGMENT,
                (
                    uniform_buffer_sized(false, Some(FieldDebugParams::min_size())),
                    storage_buffer_read_only_sized(false, None),
                ),
            ),
        ),
        shader: library.handle("df/global_field_debug.wgsl"),
        by_format: HashMap::default(),
    });
}

fn field_mode(view: &DistanceFieldDebugView) -> Option<FieldDebugMode> {
    match view.mode {
        DistanceFieldDebugMode::GlobalField => Some(FieldDebugMode::Shaded),
        DistanceFieldDebugMode::ClipmapLevels => Some(FieldDebugMode::Levels),
        DistanceFieldDebugMode::GlobalFieldUpdates => Some(FieldDebugMode::Updates),
        DistanceFieldDebugMode::StepCount | DistanceFieldDebugMode::Shaded => None,
    }
}

fn prepare_field_debug_pipelines(
    views: Query<(&ViewTarget, &DistanceFieldDebugView)>,
    pipelines: Option<ResMut<FieldDebugPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    fullscreen: Res<FullscreenShader>,
) {
    let Some(mut pipelines) = pipelines else {
        return;
    };
    for (target, view) in &views {
        let format = target.main_texture_format();
        if field_mode(view).is_none() || pipelines.by_format.contains_key(&format) {
            continue;
        }
        let id = pipeline_cache.queue_render_pipeline(fullscreen_pipeline(
            "penumbra_global_field_debug",
            vec![pipelines.layout.clone(), read_layout()],
            &pipelines.shader,
            "global_field_debug",
            format,
            &fullscreen,
        ));
        pipelines.by_format.insert(format, id);
    }
}

type FieldDebugViewItem<'a> = (
    Entity,
    &'a ExtractedView,
    &'a DistanceFieldDebugView,
    Option<&'a ViewGlobalField>,
    Option<&'a mut FieldDebugResources>,
);

/// Writes each global-field debug view's uniform and this frame's composed-brick
/// bits, making its buffers and bind group on first use.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_field_debug_resources(
    mut commands: Commands,
    mut views: Query<FieldDebugViewItem>,
    pipelines: Option<Res<FieldDebugPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mut warned: Local<(bool, bool)>,
) {
    let Some(pipelines) = pipelines else {
        return;
    };
    for (entity, extracted, settings, field, resources) in &mut views {
        let Some(mode) = field_mode(settings) else {
            continue;
        };
        let Some(field) = field else {
            if !warned.0 {
                warn!(
                    "Penumbra: DistanceFieldDebugView {:?} needs a GlobalDistanceField on the \
                     camera; the image is left as it is",
                    settings.mode
                );
                warned.0 = true;
            }
            continue;
        };
        if extracted.clip_from_view.w_axis.w == 1.0 {
            if !warned.1 {
                warn!("Penumbra: DistanceFieldDebugView supports perspective cameras only");
                warned.1 = true;
            }
            continue;
        }
        let world_from_view = extracted.world_from_view.affine();
        let view_from_relative = Mat4::from_mat3a(world_from_view.matrix3).inverse();
        let params = FieldDebugParams {
            relative_from_clip: (extracted.clip_from_view * view_from_relative).inverse(),
            mode: mode as u32,
            max_steps: settings.max_steps.clamp(1, 4096),
            max_distance: settings.max_distance.max(0.0),
        };
        let layout = field.layout();
        let bits_size = u64::from(layout.bricks_per_level().div_ceil(32) * layout.levels) * 4;
        let mut fresh = None;
        let resources = match resources {
            Some(r) if r.updated.size() >= bits_size => r.into_inner(),
            _ => {
                let uniform = allocations.sized_buffer(
                    &device,
                    "penumbra_global_field_debug",
                    FieldDebugParams::min_size().get(),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                );
                let updated = allocations.sized_buffer(
                    &device,
                    "penumbra_global_field_debug_updated",
                    bits_size,
                    BufferUsages::STORAGE | BufferUsages::COPY_DST,
                );
                let group = allocations.bind_group(
                    &device,
                    "penumbra_global_field_debug",
                    &pipeline_cache.get_bind_group_layout(&pipelines.layout),
                    &BindGroupEntries::sequential((
                        uniform.as_entire_binding(),
                        updated.as_entire_binding(),
                    )),
                );
                fresh.insert(FieldDebugResources {
                    uniform,
                    updated,
                    group,
                })
            }
        };
        let mut bytes = UniformBuffer::new(Vec::new());
        bytes.write(&params).expect("fixed-size uniform");
        queue.write_buffer(&resources.uniform, 0, bytes.as_ref());
        // Only the updates view reads this frame's composed bricks.
        if mode == FieldDebugMode::Updates {
            let bits = composed_bits(layout, field.composed_jobs());
            let bytes: Vec<u8> = bits.iter().flat_map(|w| w.to_le_bytes()).collect();
            queue.write_buffer(&resources.updated, 0, &bytes);
        }
        if let Some(fresh) = fresh {
            commands.entity(entity).insert(fresh);
        }
    }
}

/// Draws the view's clipmaps over its image. Draws only.
fn global_field_debug_view(
    view: ViewQuery<(
        &ViewTarget,
        &DistanceFieldDebugView,
        &ViewGlobalField,
        &FieldDebugResources,
    )>,
    pipelines: Option<Res<FieldDebugPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (target, settings, field, resources) = view.into_inner();
    let Some(pipelines) = pipelines else {
        return;
    };
    if field_mode(settings).is_none() {
        return;
    }
    let Some(pipeline) = pipelines
        .by_format
        .get(&target.main_texture_format())
        .and_then(|id| pipeline_cache.get_render_pipeline(*id))
    else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_global_field_debug");
    draw_over_view(
        &mut ctx,
        target,
        "penumbra_global_field_debug",
        pipeline,
        &[&resources.group, field.read_group()],
    );
    time_span.end(ctx.command_encoder());
}
