//! Render-world side of the global distance field: per camera, the pooled clipmap
//! buffers (field, validity bits, view uniform, jobs), the compose pass in the
//! `RenderGraph` schedule (after the object deltas, before the cameras), and the bind
//! group that passes reading the field bind as their group 1
//! (`shaders/df/global_field.wgsl`).
//!
//! The main world hands out the bricks to compose and marks them valid at once; the
//! render world composes them the same frame — unless its compose pipeline is still
//! compiling or object writes are held back (the delta pipeline compiling): the bricks
//! then wait in the camera's backlog (later jobs for the same storage brick replace
//! earlier ones), at most the camera's brick budget leaves it per frame, and a brick
//! waiting there is uploaded as invalid, so a reader never sees a stale brick.

use super::GlobalDistanceFieldState;
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::scene::{DistanceFieldGpu, DistanceFieldRenderSystems, GpuHeightfields};
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_3d,
    uniform_buffer_sized,
};
use bevy::render::render_resource::encase::{StorageBuffer, UniformBuffer};
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferId, BufferUsages, CachedComputePipelineId, ComputePassDescriptor, PipelineCache,
    ShaderStages, ShaderType, TextureSampleType, TextureView, TextureViewId,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::{Render, RenderStartup, RenderSystems};
use penumbra_df_core::clipmap::{
    BRICK_WORDS, BrickJob, ClipmapLayout, ComposeJob, ComposeParams, GlobalFieldView, field_words,
};
use penumbra_df_core::object::RECORD_BYTES;
use std::collections::BTreeMap;

/// Most compose workgroups (bricks) one dispatch may have (wgpu's per-dimension limit).
const MAX_DISPATCH: usize = 65_535;

/// A global-field camera's frame as extracted: its layout and budget, the bricks the
/// main world handed out, the view of its clipmaps and their validity bits.
#[derive(Component, Clone, Debug)]
pub struct ExtractedGlobalField {
    pub(super) layout: ClipmapLayout,
    pub(super) budget: usize,
    pub(super) jobs: Vec<BrickJob>,
    pub(super) view: GlobalFieldView,
    pub(super) valid: Vec<u32>,
}

impl ExtractedGlobalField {
    pub(super) fn new(state: &GlobalDistanceFieldState, camera: Vec3) -> Self {
        let clipmaps = state.clipmaps();
        ExtractedGlobalField {
            layout: *state.layout(),
            budget: state.budget,
            jobs: state.update.jobs.clone(),
            view: GlobalFieldView::new(clipmaps, camera.as_dvec3()),
            valid: GlobalFieldView::valid_bits(clipmaps),
        }
    }
}

/// What a camera's compose bind group binds: the object buffer, the atlas and brick
/// table, the jobs, the terrains.
type ComposeKey = (
    BufferId,
    [TextureViewId; 2],
    BufferId,
    BufferId,
    TextureViewId,
);

/// A camera's clipmaps on the GPU (pooled: made again only when the layout changes).
#[derive(Component)]
pub struct ViewGlobalField {
    layout: ClipmapLayout,
    field: Buffer,
    valid: Buffer,
    view: Buffer,
    jobs: Buffer,
    job_capacity: u32,
    params: Buffer,
    /// Bound as the object buffer before any caster exists (never read then).
    no_objects: Buffer,
    /// Bound as the terrains while the scene has none (never read then).
    no_heightfields: (Buffer, TextureView),
    /// Bricks handed out but not yet composed, by their first word in `field`.
    backlog: BTreeMap<u32, ComposeJob>,
    /// Bricks composed this frame (workgroups of the compose dispatch).
    dispatch: u32,
    /// Their jobs (for the debug view of this frame's updates).
    composed: Vec<ComposeJob>,
    /// The view and validity bits last written.
    uploaded: Option<(GlobalFieldView, Vec<u32>)>,
    compose_group: Option<(BindGroup, ComposeKey)>,
    /// Group 1 of the passes that read the field.
    read_group: BindGroup,
}

impl ViewGlobalField {
    /// The bind group of the field for passes reading it (their group 1).
    pub fn read_group(&self) -> &BindGroup {
        &self.read_group
    }

    /// Bricks waiting in the render world's backlog.
    pub fn backlog(&self) -> usize {
        self.backlog.len()
    }

    /// Bricks composed this frame.
    pub fn composed(&self) -> u32 {
        self.dispatch
    }

    /// The layout of the clipmaps.
    pub fn layout(&self) -> &ClipmapLayout {
        &self.layout
    }

    /// The jobs of the bricks composed this frame.
    pub fn composed_jobs(&self) -> &[ComposeJob] {
        &self.composed
    }
}

/// The compose pipeline.
#[derive(Resource)]
pub(crate) struct GlobalFieldPipelines {
    compose_layout: BindGroupLayoutDescriptor,
    compose: CachedComputePipelineId,
    /// Bound as the atlas where no SDF volume exists.
    empty_atlas: TextureView,
    /// Bound where no volume is placed as bricks.
    empty_brick_table: TextureView,
}

/// The layout of the bind group passes reading the field use as their group 1
/// (`shaders/df/global_field.wgsl`): field words, validity bits, view.
pub(crate) fn read_layout() -> BindGroupLayoutDescriptor {
    BindGroupLayoutDescriptor::new(
        "penumbra_global_field_read_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE | ShaderStages::FRAGMENT,
            (
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                uniform_buffer_sized(false, Some(GlobalFieldView::min_size())),
            ),
        ),
    )
}

/// A group 1 for a reader on a camera without a global field: an empty field (no
/// level) that is never read. Small buffers, made once per reader view.
pub(crate) fn empty_read_group(
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    pipeline_cache: &PipelineCache,
) -> BindGroup {
    let words = allocations.sized_buffer(
        device,
        "penumbra_global_field_empty",
        16,
        BufferUsages::STORAGE,
    );
    let view = uniform_bytes(&GlobalFieldView::default());
    let view_buffer = allocations.sized_buffer(
        device,
        "penumbra_global_field_empty_view",
        view.len() as u64,
        BufferUsages::UNIFORM,
    );
    // All zero: `level_count` 0.
    allocations.bind_group(
        device,
        "penumbra_global_field_empty",
        &pipeline_cache.get_bind_group_layout(&read_layout()),
        &BindGroupEntries::sequential((
            words.as_entire_binding(),
            words.as_entire_binding(),
            view_buffer.as_entire_binding(),
        )),
    )
}

fn uniform_bytes<T: ShaderType + bevy::render::render_resource::encase::internal::WriteInto>(
    value: &T,
) -> Vec<u8> {
    let mut bytes = UniformBuffer::new(Vec::new());
    bytes.write(value).expect("fixed-size uniform");
    bytes.into_inner()
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .add_systems(
            Render,
            (
                timed(prepare_global_field_buffers)
                    .in_set(RenderSystems::PrepareResources)
                    .after(DistanceFieldRenderSystems::PrepareGpu),
                timed(prepare_global_field_bind_groups).in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(
            RenderGraph,
            timed(compose_global_fields)
                .after(crate::scene::apply_distance_field_deltas)
                .in_set(bevy::render::renderer::RenderGraphSystems::Render)
                .before(camera_driver),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(RenderStartup, init_global_field_pipelines);
}

fn init_global_field_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    device: Res<RenderDevice>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return; // warned by the scene plugin
    };
    let compose_layout = BindGroupLayoutDescriptor::new(
        "penumbra_global_field_compose_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                storage_buffer_read_only_sized(false, None),
                texture_3d(TextureSampleType::Float { filterable: false }),
                storage_buffer_read_only_sized(false, None),
                uniform_buffer_sized(false, Some(ComposeParams::min_size())),
                storage_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Uint),
            ),
        ),
    );
    let compose = library.queue_compute(
        &pipeline_cache,
        "penumbra_global_field_compose",
        &compose_layout,
        "df/global_compose.wgsl",
        "compose",
    );
    commands.insert_resource(GlobalFieldPipelines {
        compose_layout,
        compose,
        empty_atlas: crate::shader_library::empty_atlas(&device),
        empty_brick_table: crate::shader_library::empty_brick_table(&device),
    });
}

/// A camera's buffers for `layout`.
fn view_buffers(
    layout: ClipmapLayout,
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    pipeline_cache: &PipelineCache,
) -> ViewGlobalField {
    let buffer = |label, size: u64, usage: BufferUsages| {
        allocations.sized_buffer(device, label, size.max(16), usage | BufferUsages::COPY_DST)
    };
    let valid_words = u64::from(layout.levels) * u64::from(layout.bricks_per_level().div_ceil(32));
    let field = buffer(
        "penumbra_global_field",
        field_words(&layout) * 4,
        BufferUsages::STORAGE,
    );
    let valid = buffer(
        "penumbra_global_field_valid",
        valid_words * 4,
        BufferUsages::STORAGE,
    );
    let view = buffer(
        "penumbra_global_field_view",
        GlobalFieldView::min_size().get(),
        BufferUsages::UNIFORM,
    );
    let read_group = allocations.bind_group(
        device,
        "penumbra_global_field_read",
        &pipeline_cache.get_bind_group_layout(&read_layout()),
        &BindGroupEntries::sequential((
            field.as_entire_binding(),
            valid.as_entire_binding(),
            view.as_entire_binding(),
        )),
    );
    ViewGlobalField {
        layout,
        field,
        valid,
        view,
        jobs: job_buffer(64, allocations, device),
        job_capacity: 64,
        params: buffer(
            "penumbra_global_field_compose_params",
            ComposeParams::min_size().get(),
            BufferUsages::UNIFORM,
        ),
        no_objects: buffer(
            "penumbra_global_field_no_objects",
            RECORD_BYTES as u64,
            BufferUsages::STORAGE,
        ),
        no_heightfields: crate::scene::no_heightfields(allocations, device),
        backlog: BTreeMap::new(),
        dispatch: 0,
        composed: Vec::new(),
        uploaded: None,
        compose_group: None,
        read_group,
    }
}

fn job_buffer(
    capacity: u32,
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
) -> Buffer {
    allocations.sized_buffer(
        device,
        "penumbra_global_field_compose_jobs",
        u64::from(capacity) * ComposeJob::min_size().get(),
        BufferUsages::STORAGE | BufferUsages::COPY_DST,
    )
}

/// Gives every global-field camera its buffers, queues the handed-out bricks, writes
/// this frame's jobs when the compose pass can run, and uploads the view and the
/// validity bits (bricks still queued cleared) when they changed.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_global_field_buffers(
    mut commands: Commands,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    pipeline_cache: Res<PipelineCache>,
    pipelines: Option<Res<GlobalFieldPipelines>>,
    gpu: Res<DistanceFieldGpu>,
    terrains: Option<Res<GpuHeightfields>>,
    mut views: Query<(Entity, &ExtractedGlobalField, Option<&mut ViewGlobalField>)>,
) {
    let can_compose = pipelines
        .as_ref()
        .is_some_and(|p| pipeline_cache.get_compute_pipeline(p.compose).is_some())
        && !gpu.deltas_held_back();
    for (entity, extracted, buffers) in &mut views {
        let mut fresh = None;
        let buffers = match buffers {
            Some(b) if b.layout == extracted.layout => b.into_inner(),
            _ => fresh.insert(view_buffers(
                extracted.layout,
                &allocations,
                &device,
                &pipeline_cache,
            )),
        };
        let layout = &extracted.layout;
        for &job in &extracted.jobs {
            let job = ComposeJob::new(layout, job);
            buffers.backlog.insert(job.word, job);
        }
        buffers.dispatch = 0;
        buffers.composed.clear();
        if can_compose && !buffers.backlog.is_empty() {
            let take = buffers
                .backlog
                .len()
                .min(extracted.budget.max(1))
                .min(MAX_DISPATCH);
            let keys: Vec<u32> = buffers.backlog.keys().take(take).copied().collect();
            let jobs: Vec<ComposeJob> = keys
                .iter()
                .map(|k| buffers.backlog.remove(k).expect("listed"))
                .collect();
            if jobs.len() as u32 > buffers.job_capacity {
                buffers.job_capacity = (jobs.len() as u32).next_power_of_two();
                buffers.jobs = job_buffer(buffers.job_capacity, &allocations, &device);
            }
            let mut bytes = StorageBuffer::new(Vec::new());
            bytes.write(&jobs).expect("encodes");
            queue.write_buffer(&buffers.jobs, 0, bytes.as_ref());
            let params = ComposeParams {
                heightfield_count: terrains.as_ref().map_or(0, |t| t.count),
                ..ComposeParams::new(layout, gpu.slot_count, jobs.len() as u32)
            };
            queue.write_buffer(&buffers.params, 0, &uniform_bytes(&params));
            buffers.dispatch = jobs.len() as u32;
            buffers.composed = jobs;
        }
        let mut valid = extracted.valid.clone();
        let words_per_level = layout.bricks_per_level().div_ceil(32);
        for job in buffers.backlog.values() {
            let brick = job.word / BRICK_WORDS - job.level * layout.bricks_per_level();
            let word = (job.level * words_per_level + brick / 32) as usize;
            valid[word] &= !(1 << (brick % 32));
        }
        let upload = (extracted.view, valid);
        if buffers.uploaded.as_ref() != Some(&upload) {
            queue.write_buffer(&buffers.view, 0, &uniform_bytes(&upload.0));
            let bits: Vec<u8> = upload.1.iter().flat_map(|w| w.to_le_bytes()).collect();
            queue.write_buffer(&buffers.valid, 0, &bits);
            buffers.uploaded = Some(upload);
        }
        if let Some(fresh) = fresh {
            commands.entity(entity).insert(fresh);
        }
    }
}

/// (Re)makes a camera's compose bind group when the object buffer, the atlas or its
/// job buffer changed.
pub(crate) fn prepare_global_field_bind_groups(
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    pipeline_cache: Res<PipelineCache>,
    pipelines: Option<Res<GlobalFieldPipelines>>,
    gpu: Res<DistanceFieldGpu>,
    terrains: Option<Res<GpuHeightfields>>,
    mut views: Query<&mut ViewGlobalField>,
) {
    let Some(pipelines) = pipelines else {
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
    for mut buffers in &mut views {
        if buffers.dispatch == 0 {
            continue;
        }
        let buffers = &mut *buffers;
        let objects = gpu.objects.as_ref().unwrap_or(&buffers.no_objects);
        let (records, heights) = terrains.as_ref().map_or(
            (&buffers.no_heightfields.0, &buffers.no_heightfields.1),
            |t| (&t.records, &t.texture),
        );
        let key = (
            objects.id(),
            [atlas.id(), brick_table.id()],
            buffers.jobs.id(),
            records.id(),
            heights.id(),
        );
        if buffers
            .compose_group
            .as_ref()
            .is_some_and(|(_, k)| *k == key)
        {
            continue;
        }
        let group = allocations.bind_group(
            &device,
            "penumbra_global_field_compose",
            &pipeline_cache.get_bind_group_layout(&pipelines.compose_layout),
            &BindGroupEntries::sequential((
                objects.as_entire_binding(),
                atlas,
                buffers.jobs.as_entire_binding(),
                buffers.params.as_entire_binding(),
                buffers.field.as_entire_binding(),
                records.as_entire_binding(),
                heights,
                brick_table,
            )),
        );
        buffers.compose_group = Some((group, key));
    }
}

/// The compose pass: per camera, one workgroup per brick handed out this frame.
/// Dispatches only.
pub(crate) fn compose_global_fields(
    mut ctx: RenderContext,
    views: Query<&ViewGlobalField>,
    pipelines: Option<Res<GlobalFieldPipelines>>,
    pipeline_cache: Res<PipelineCache>,
) {
    let Some(pipelines) = pipelines else {
        return;
    };
    if views.iter().all(|v| v.dispatch == 0) {
        return;
    }
    let Some(pipeline) = pipeline_cache.get_compute_pipeline(pipelines.compose) else {
        return; // checked in prepare; kept for safety
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_global_field_compose");
    let mut pass = ctx
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_global_field_compose"),
            timestamp_writes: None,
        });
    pass.set_pipeline(pipeline);
    for view in &views {
        let Some((group, _)) = view.compose_group.as_ref().filter(|_| view.dispatch > 0) else {
            continue;
        };
        pass.set_bind_group(0, group, &[]);
        pass.dispatch_workgroups(view.dispatch, 1, 1);
    }
    drop(pass);
    time_span.end(ctx.command_encoder());
}
