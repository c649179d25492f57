//! Render-world side of the GPU re-bake ([`super::DistanceFieldRebake`]): per re-baked
//! mesh a pooled triangle buffer (grown, never shrunk), uniform and output buffer with
//! their bind group, written only on the frames it bakes; the pass (`penumbra_df_rebake`)
//! in the `RenderGraph` schedule after the object deltas and before the global field's
//! compose and the cameras, each bake a dispatch and a copy into its atlas region.

use super::rebake::{RebakeJob, RebakeJobs};
use super::render::{DistanceFieldGpu, DistanceFieldRenderSystems};
use super::{DistanceFieldScene, apply_distance_field_deltas};
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, uniform_buffer_sized,
};
use bevy::render::render_resource::encase::UniformBuffer;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferUsages, CachedComputePipelineId, ComputePassDescriptor, Extent3d, Origin3d,
    PipelineCache, ShaderStages, ShaderType, TexelCopyBufferInfo, TexelCopyBufferLayout,
    TexelCopyTextureInfo, TextureAspect,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::{Extract, ExtractSchedule, Render, RenderStartup};
use penumbra_df_core::atlas::AtlasRegion;
use penumbra_df_core::rebake::RebakeParams;

/// This frame's bakes with their atlas regions, and the meshes still re-baked.
#[derive(Resource, Default)]
struct ExtractedRebakes {
    jobs: Vec<(RebakeJob, AtlasRegion)>,
    live: Vec<Entity>,
}

/// One re-baked mesh's buffers (pooled by its main-world entity).
struct RebakeBuffers {
    corners: Buffer,
    params: Buffer,
    output: Buffer,
    bind_group: BindGroup,
}

/// The pass's pipeline and the pooled buffers; `dispatches` are this frame's bakes.
#[derive(Resource, Default)]
struct RebakeGpu {
    buffers: HashMap<Entity, RebakeBuffers>,
    dispatches: Vec<(Entity, RebakeJob, AtlasRegion)>,
}

/// The pass's layout, and its pipeline once queued: that waits for the first bake, so
/// an app without re-baked meshes compiles nothing (and its other pipelines' compile
/// order is unchanged).
#[derive(Resource)]
struct RebakePipeline {
    layout: BindGroupLayoutDescriptor,
    pipeline: Option<CachedComputePipelineId>,
}

impl RebakePipeline {
    /// The pipeline, queued on the first call.
    fn queue(
        &mut self,
        library: &PenumbraShaderLibrary,
        pipeline_cache: &PipelineCache,
    ) -> CachedComputePipelineId {
        *self.pipeline.get_or_insert_with(|| {
            library.queue_compute(
                pipeline_cache,
                "penumbra_df_rebake",
                &self.layout,
                "df/rebake.wgsl",
                "rebake",
            )
        })
    }
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .init_resource::<ExtractedRebakes>()
        .init_resource::<RebakeGpu>()
        .add_systems(ExtractSchedule, timed(extract_rebakes))
        .add_systems(
            Render,
            timed(prepare_rebakes)
                .in_set(DistanceFieldRenderSystems::PrepareGpu)
                .after(super::render::prepare_distance_field_gpu),
        )
        .add_systems(
            RenderGraph,
            timed(rebake_fields)
                .in_set(DistanceFieldRenderSystems::ApplyDeltas)
                .in_set(bevy::render::renderer::RenderGraphSystems::Render)
                .after(apply_distance_field_deltas)
                .before(crate::global_field::compose_global_fields)
                .before(camera_driver),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(RenderStartup, init_rebake_pipeline);
}

fn init_rebake_pipeline(mut commands: Commands) {
    let layout = BindGroupLayoutDescriptor::new(
        "penumbra_df_rebake_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                uniform_buffer_sized(false, Some(RebakeParams::min_size())),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_sized(false, None),
            ),
        ),
    );
    commands.insert_resource(RebakePipeline {
        layout,
        pipeline: None,
    });
}

/// The bakes whose volume has its full cube in the atlas (a volume placed at a reduced
/// resolution, the atlas being full, is not re-baked: its cube would not fit).
fn extract_rebakes(
    mut extracted: ResMut<ExtractedRebakes>,
    jobs: Extract<Option<Res<RebakeJobs>>>,
    scene: Extract<Option<Res<DistanceFieldScene>>>,
) {
    extracted.jobs.clear();
    extracted.live.clear();
    let (Some(jobs), Some(scene)) = (jobs.as_deref(), scene.as_deref()) else {
        return;
    };
    extracted.live.extend_from_slice(&jobs.live);
    extracted.jobs.extend(jobs.jobs.iter().filter_map(|job| {
        let region = scene.volume_region(job.volume)?;
        (region.dims == job.grid.dims()).then(|| (job.clone(), region))
    }));
}

/// Writes each bake's triangles and uniform into its pooled buffers (grown when the
/// triangles outgrow them), and lets go of the buffers of meshes no longer re-baked.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_rebakes(
    extracted: Res<ExtractedRebakes>,
    mut rebakes: ResMut<RebakeGpu>,
    mut gpu: ResMut<DistanceFieldGpu>,
    pipeline: Option<ResMut<RebakePipeline>>,
    library: Option<Res<PenumbraShaderLibrary>>,
    pipeline_cache: Res<PipelineCache>,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    let rebakes = &mut *rebakes;
    rebakes.dispatches.clear();
    if !rebakes.buffers.is_empty() {
        rebakes
            .buffers
            .retain(|mesh, _| extracted.live.contains(mesh));
    }
    let (Some(mut pipeline), Some(library), false, Some(_)) = (
        pipeline,
        library,
        extracted.jobs.is_empty(),
        gpu.atlas.as_ref(),
    ) else {
        return;
    };
    let id = pipeline.queue(&library, &pipeline_cache);
    if pipeline_cache.get_compute_pipeline(id).is_none() {
        return; // compiling: the fields wait
    }
    let layout = pipeline_cache.get_bind_group_layout(&pipeline.layout);
    for (job, region) in &extracted.jobs {
        let corner_bytes = (job.corners.len() * 16) as u64;
        let output_bytes = job.grid.output_bytes();
        let fits = rebakes.buffers.get(&job.mesh).is_some_and(|b| {
            b.corners.size() >= corner_bytes.max(16) && b.output.size() == output_bytes
        });
        if !fits {
            let corners = allocations.sized_buffer(
                &device,
                "penumbra_df_rebake_corners",
                corner_bytes.max(16).next_power_of_two(),
                BufferUsages::STORAGE | BufferUsages::COPY_DST,
            );
            let params = allocations.sized_buffer(
                &device,
                "penumbra_df_rebake_params",
                RebakeParams::min_size().get(),
                BufferUsages::UNIFORM | BufferUsages::COPY_DST,
            );
            let output = allocations.sized_buffer(
                &device,
                "penumbra_df_rebake_samples",
                output_bytes,
                BufferUsages::STORAGE | BufferUsages::COPY_SRC,
            );
            let bind_group = allocations.bind_group(
                &device,
                "penumbra_df_rebake_bind_group",
                &layout,
                &BindGroupEntries::sequential((
                    params.as_entire_binding(),
                    corners.as_entire_binding(),
                    output.as_entire_binding(),
                )),
            );
            rebakes.buffers.insert(
                job.mesh,
                RebakeBuffers {
                    corners,
                    params,
                    output,
                    bind_group,
                },
            );
        }
        let buffers = &rebakes.buffers[&job.mesh];
        let bytes: Vec<u8> = job
            .corners
            .iter()
            .flatten()
            .flat_map(|f| f.to_le_bytes())
            .collect();
        if !bytes.is_empty() {
            queue.write_buffer(&buffers.corners, 0, &bytes);
        }
        let mut uniform = UniformBuffer::new(Vec::new());
        uniform
            .write(&job.grid.params(job.corners.len() as u32 / 3))
            .expect("a plain uniform encodes");
        queue.write_buffer(&buffers.params, 0, uniform.as_ref());
        rebakes.dispatches.push((job.mesh, job.clone(), *region));
    }
    if !rebakes.dispatches.is_empty() {
        gpu.touch();
    }
}

/// The pass: per bake, the samples computed and copied into the volume's atlas region.
fn rebake_fields(
    mut ctx: RenderContext,
    rebakes: Res<RebakeGpu>,
    gpu: Res<DistanceFieldGpu>,
    pipeline: Option<Res<RebakePipeline>>,
    pipeline_cache: Res<PipelineCache>,
) {
    let (Some(pipeline), Some((atlas, _, _)), false) =
        (pipeline, gpu.atlas.as_ref(), rebakes.dispatches.is_empty())
    else {
        return;
    };
    let Some(compute) = pipeline
        .pipeline
        .and_then(|id| pipeline_cache.get_compute_pipeline(id))
    else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_df_rebake");
    {
        let mut pass = ctx
            .command_encoder()
            .begin_compute_pass(&ComputePassDescriptor {
                label: Some("penumbra_df_rebake"),
                timestamp_writes: None,
            });
        pass.set_pipeline(compute);
        for (mesh, job, _) in &rebakes.dispatches {
            pass.set_bind_group(0, &rebakes.buffers[mesh].bind_group, &[]);
            let groups = job.grid.workgroups();
            pass.dispatch_workgroups(groups.x, groups.y, groups.z);
        }
    }
    for (mesh, job, region) in &rebakes.dispatches {
        let r = job.grid.resolution;
        ctx.command_encoder().copy_buffer_to_texture(
            TexelCopyBufferInfo {
                buffer: &rebakes.buffers[mesh].output,
                layout: TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(job.grid.bytes_per_row()),
                    rows_per_image: Some(r),
                },
            },
            TexelCopyTextureInfo {
                texture: atlas,
                mip_level: 0,
                origin: Origin3d {
                    x: region.origin.x,
                    y: region.origin.y,
                    z: region.origin.z,
                },
                aspect: TextureAspect::All,
            },
            Extent3d {
                width: r,
                height: r,
                depth_or_array_layers: r,
            },
        );
    }
    time_span.end(ctx.command_encoder());
}
