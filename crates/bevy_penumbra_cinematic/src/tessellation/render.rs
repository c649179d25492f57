//! The tessellation's GPU plumbing: extraction, the pipelines, the per-entity uniform
//! and bind group (pooled), and the dispatch that runs the three passes, stamps the
//! totals with the tessellation's generation and copies the pool into the output mesh's
//! buffers.

use super::TessellationState;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::mesh::Mesh;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::extract_component::ExtractComponent;
use bevy::render::mesh::allocator::MeshAllocator;
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, uniform_buffer_sized,
};
use bevy::render::render_resource::encase::UniformBuffer;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferId, BufferUsages, CachedComputePipelineId, ComputePassDescriptor, PipelineCache,
    ShaderStages, ShaderType,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::storage::{GpuShaderBuffer, ShaderBuffer};
use bevy::render::sync_component::SyncComponent;
use bevy::render::{Render, RenderApp, RenderStartup, RenderSystems};
use bevy_penumbra_df::system_times::timed;
use bevy_penumbra_df::{PenumbraGpuAllocations, PenumbraShaderLibrary};
use penumbra_cinematic_core::scan::ScanPlan;
use penumbra_cinematic_core::tessellation::MAX_BIAS;
use penumbra_cinematic_core::tessellation::uniform::{TOTALS_BYTES, TessellationUniform};

/// Storage buffers the passes bind at once.
const STORAGE_BUFFERS: u32 = 8;

/// Bytes of one group's sums in the allocation: `MAX_BIAS` biases × (vertices, indices).
const GROUP_SUMS_BYTES: u64 = MAX_BIAS as u64 * 8;

/// Most workgroups per dispatch dimension (WebGPU's default limit).
const MAX_GROUPS: u32 = 65_535;

/// Where in the totals the generation they are for goes (the last reserved word, which
/// the passes leave alone).
const STAMP_OFFSET: u64 = TOTALS_BYTES - 4;

pub(super) fn build(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
        return;
    };
    render_app
        .add_systems(RenderStartup, init_tessellation_pipeline)
        .add_systems(
            Render,
            timed(prepare_tessellation_bind_groups).in_set(RenderSystems::PrepareBindGroups),
        )
        .add_systems(
            RenderGraph,
            timed(tessellate)
                .in_set(bevy::render::renderer::RenderGraphSystems::Render)
                .before(camera_driver),
        );
}

pub(super) fn finish(app: &mut App) {
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
        return;
    };
    let Some(device) = render_app.world().get_resource::<RenderDevice>() else {
        return;
    };
    let limit = device.limits().max_storage_buffers_per_shader_stage;
    if limit < STORAGE_BUFFERS {
        warn!(
            "Penumbra: tessellation needs {STORAGE_BUFFERS} storage buffers per compute \
             stage, this GPU has {limit}: `Tessellated` meshes are drawn untessellated"
        );
        render_app
            .world_mut()
            .insert_resource(TessellationUnsupported);
    }
}

/// Set when the GPU cannot run the passes.
#[derive(Resource)]
struct TessellationUnsupported;

/// A tessellated entity as extracted.
#[derive(Component, Clone, Debug)]
pub struct ExtractedTessellation {
    output: AssetId<Mesh>,
    buffers: [AssetId<ShaderBuffer>; 7],
    uniform: TessellationUniform,
    generation: u64,
    vertex_bytes: u64,
    index_bytes: u64,
}

impl SyncComponent for TessellationState {
    type Target = (ExtractedTessellation, GpuTessellation);
}

impl ExtractComponent for TessellationState {
    type QueryData = &'static TessellationState;
    type QueryFilter = ();
    type Out = ExtractedTessellation;

    fn extract_component(state: &TessellationState) -> Option<ExtractedTessellation> {
        let uniform = state.uniform?;
        Some(ExtractedTessellation {
            output: state.output.id(),
            buffers: [
                state.input.vertices.id(),
                state.input.patches.id(),
                state.texels.id(),
                state.states.id(),
                state.totals.id(),
                state.out_vertices.id(),
                state.out_indices.id(),
            ],
            uniform,
            generation: state.generation,
            vertex_bytes: 4 * u64::from(uniform.vertex_words) * u64::from(state.vertex_budget),
            index_bytes: 4 * u64::from(state.index_budget),
        })
    }
}

#[derive(Resource)]
struct TessellationPipeline {
    layout: BindGroupLayoutDescriptor,
    factors: CachedComputePipelineId,
    /// The allocation's three dispatches: reduce, choose, place.
    allocate: [CachedComputePipelineId; 3],
    emit: CachedComputePipelineId,
}

fn init_tessellation_pipeline(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return;
    };
    let layout = BindGroupLayoutDescriptor::new(
        "penumbra_tessellation_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, Some(TessellationUniform::min_size())),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, None),
            ),
        ),
    );
    let queue = |label: &'static str, entry: &'static str| {
        library.queue_compute_layouts(
            &pipeline_cache,
            label,
            std::slice::from_ref(&layout),
            "tessellation/tessellate.wgsl",
            entry,
        )
    };
    let factors = queue("penumbra_tessellation_factors", "factors");
    let allocate = [
        queue("penumbra_tessellation_allocate_reduce", "allocate_reduce"),
        queue("penumbra_tessellation_allocate_choose", "allocate_choose"),
        queue("penumbra_tessellation_allocate_place", "allocate_place"),
    ];
    let emit = queue("penumbra_tessellation_emit", "emit");
    commands.insert_resource(TessellationPipeline {
        layout,
        factors,
        allocate,
        emit,
    });
}

/// A tessellated entity's pooled GPU state.
#[derive(Component)]
pub struct GpuTessellation {
    uniform: Buffer,
    /// The uniform last written.
    written: Vec<u8>,
    group: Option<(BindGroup, [BufferId; 8])>,
    /// The allocation's per-group sums (`ScanPlan::group_sums_len` × `MAX_BIAS` biases ×
    /// `vec2<u32>`): grown, never shrunk.
    group_sums: Option<Buffer>,
    /// The generation and the mesh buffers last tessellated into.
    done: Option<(u64, BufferId, u64, BufferId, u64)>,
    patch_count: u32,
}

#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_tessellation_bind_groups(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    allocations: Res<PenumbraGpuAllocations>,
    pipeline_cache: Res<PipelineCache>,
    pipeline: Option<Res<TessellationPipeline>>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    mut entities: Query<(Entity, &ExtractedTessellation, Option<&mut GpuTessellation>)>,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    for (entity, extracted, gpu) in &mut entities {
        let Some(bound) = extracted
            .buffers
            .iter()
            .map(|id| buffers.get(*id).map(|b| &b.buffer))
            .collect::<Option<Vec<_>>>()
        else {
            continue; // not uploaded yet
        };
        let mut fresh = None;
        let gpu = match gpu {
            Some(gpu) => gpu.into_inner(),
            None => fresh.insert(GpuTessellation {
                uniform: allocations.sized_buffer(
                    &device,
                    "penumbra_tessellation_uniform",
                    TessellationUniform::min_size().get(),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                written: Vec::new(),
                group: None,
                group_sums: None,
                done: None,
                patch_count: 0,
            }),
        };
        let mut bytes = UniformBuffer::new(Vec::new());
        bytes.write(&extracted.uniform).expect("encodes");
        let bytes = bytes.into_inner();
        if bytes != gpu.written {
            queue.write_buffer(&gpu.uniform, 0, &bytes);
            gpu.written = bytes;
        }
        gpu.patch_count = extracted.uniform.patch_count;
        let sums_bytes =
            u64::from(ScanPlan::new(gpu.patch_count).group_sums_len()) * GROUP_SUMS_BYTES;
        let group_sums = match gpu.group_sums.take() {
            Some(b) if b.size() >= sums_bytes => b,
            _ => allocations.sized_buffer(
                &device,
                "penumbra_tessellation_group_sums",
                sums_bytes,
                BufferUsages::STORAGE,
            ),
        };
        let group_sums = gpu.group_sums.insert(group_sums);
        let ids: [BufferId; 8] =
            std::array::from_fn(|i| bound.get(i).map_or(group_sums.id(), |b| b.id()));
        if gpu.group.as_ref().is_none_or(|(_, b)| *b != ids) {
            let group = allocations.bind_group(
                &device,
                "penumbra_tessellation",
                &pipeline_cache.get_bind_group_layout(&pipeline.layout),
                &BindGroupEntries::sequential((
                    gpu.uniform.as_entire_binding(),
                    bound[0].as_entire_binding(),
                    bound[1].as_entire_binding(),
                    bound[2].as_entire_binding(),
                    bound[3].as_entire_binding(),
                    bound[4].as_entire_binding(),
                    bound[5].as_entire_binding(),
                    bound[6].as_entire_binding(),
                    group_sums.as_entire_binding(),
                )),
            );
            gpu.group = Some((group, ids));
            gpu.done = None;
        }
        if let Some(fresh) = fresh {
            commands.entity(entity).insert(fresh);
        }
    }
}

/// Runs the three passes for every entity whose view, settings or mesh buffers changed
/// since its last tessellation, then copies its pools into its output mesh's buffers.
/// Dispatches and copies only, and a 4-byte write per entity: the low 32 bits of the
/// generation into the totals (a queue write, so before the passes; the main world reads
/// the totals back until it sees its latest generation there).
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn tessellate(
    mut ctx: RenderContext,
    queue: Res<RenderQueue>,
    mut entities: Query<(&ExtractedTessellation, &mut GpuTessellation)>,
    pipeline: Option<Res<TessellationPipeline>>,
    pipeline_cache: Res<PipelineCache>,
    mesh_allocator: Res<MeshAllocator>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    unsupported: Option<Res<TessellationUnsupported>>,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    if unsupported.is_some() {
        return;
    }
    let (Some(factors), Some(reduce), Some(choose), Some(place), Some(emit)) = (
        pipeline_cache.get_compute_pipeline(pipeline.factors),
        pipeline_cache.get_compute_pipeline(pipeline.allocate[0]),
        pipeline_cache.get_compute_pipeline(pipeline.allocate[1]),
        pipeline_cache.get_compute_pipeline(pipeline.allocate[2]),
        pipeline_cache.get_compute_pipeline(pipeline.emit),
    ) else {
        return;
    };
    let mut work = Vec::new();
    for (extracted, mut gpu) in &mut entities {
        let (Some(vertex_slice), Some(index_slice)) = (
            mesh_allocator.mesh_vertex_slice(&extracted.output),
            mesh_allocator.mesh_index_slice(&extracted.output),
        ) else {
            continue; // the output mesh is not allocated yet
        };
        let (Some(totals), Some(pool_vertices), Some(pool_indices)) = (
            buffers.get(extracted.buffers[4]),
            buffers.get(extracted.buffers[5]),
            buffers.get(extracted.buffers[6]),
        ) else {
            continue;
        };
        let stride = 4 * u64::from(extracted.uniform.vertex_words);
        // The output mesh's slices hold the pool (they were made together); a mismatch
        // would overflow the copy.
        let fits = |range: &std::ops::Range<u32>, bytes: u64, element: u64| {
            u64::from(range.end - range.start) * element >= bytes
        };
        if !fits(&vertex_slice.range, extracted.vertex_bytes, stride)
            || !fits(&index_slice.range, extracted.index_bytes, 4)
        {
            continue;
        }
        let target = (
            extracted.generation,
            vertex_slice.buffer.id(),
            u64::from(vertex_slice.range.start) * stride,
            index_slice.buffer.id(),
            u64::from(index_slice.range.start) * 4,
        );
        if gpu.done == Some(target) || gpu.group.is_none() {
            continue;
        }
        gpu.done = Some(target);
        // Truncated: the main world compares the low bits.
        let stamp = extracted.generation as u32;
        queue.write_buffer(&totals.buffer, STAMP_OFFSET, &stamp.to_le_bytes());
        work.push((
            gpu.group.as_ref().expect("checked").0.clone(),
            gpu.patch_count,
            (
                pool_vertices.buffer.clone(),
                vertex_slice.buffer.clone(),
                target.2,
                extracted.vertex_bytes,
            ),
            (
                pool_indices.buffer.clone(),
                index_slice.buffer.clone(),
                target.4,
                extracted.index_bytes,
            ),
        ));
    }
    if work.is_empty() {
        return;
    }
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_tessellation");
    // Indices past the output stay 0: degenerate triangles.
    for (.., indices) in &work {
        ctx.command_encoder().clear_buffer(&indices.0, 0, None);
    }
    // Every entity's passes in one compute pass (each dispatch sees the last one's
    // writes), then the copies into the meshes' buffers.
    {
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor {
                label: Some("penumbra_tessellation"),
                timestamp_writes: None,
            });
        for (group, patch_count, ..) in &work {
            pass.set_bind_group(0, group, &[]);
            pass.set_pipeline(factors);
            let [x, y, z] = penumbra_cinematic_core::dispatch::workgroups_2d(*patch_count, 64);
            pass.dispatch_workgroups(x, y, z);
            for (allocate, groups) in [reduce, choose, place]
                .into_iter()
                .zip(ScanPlan::new(*patch_count).workgroups())
            {
                pass.set_pipeline(allocate);
                pass.dispatch_workgroups(groups, 1, 1);
            }
            pass.set_pipeline(emit);
            pass.dispatch_workgroups(
                (*patch_count).min(MAX_GROUPS),
                patch_count.div_ceil(MAX_GROUPS),
                1,
            );
        }
    }
    let encoder = ctx.command_encoder();
    for (_, _, vertices, indices) in &work {
        encoder.copy_buffer_to_buffer(&vertices.0, 0, &vertices.1, vertices.2, vertices.3);
        encoder.copy_buffer_to_buffer(&indices.0, 0, &indices.1, indices.2, indices.3);
    }
    time_span.end(ctx.command_encoder());
}
