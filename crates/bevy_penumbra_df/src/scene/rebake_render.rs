//! Render-world side of the GPU re-bake ([`super::DistanceFieldRebake`]): per re-baked
//! mesh its latest bake, kept until it is in the atlas (a volume not yet placed waits;
//! one placed again, or written over by an upload, is baked again from the buffers
//! without a new upload), and a pooled triangle buffer (grown, never shrunk), uniform
//! and output buffer with their bind group, written only for a new pose; the pass
//! (`penumbra_df_rebake`, its pipeline queued at the first bake) in the `RenderGraph`
//! schedule after the object deltas and before the global field's compose and the
//! cameras, each bake a dispatch and a copy into its atlas region.

use super::rebake::{RebakeJob, RebakeJobs};
use super::render::{DistanceFieldGpu, DistanceFieldRenderSystems, ExtractedDistanceFieldFrame};
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
    BindGroup, BindGroupEntries, BindGroupLayout, BindGroupLayoutDescriptor,
    BindGroupLayoutEntries, Buffer, BufferUsages, CachedComputePipelineId, ComputePassDescriptor,
    Extent3d, Origin3d, PipelineCache, ShaderStages, ShaderType, TexelCopyBufferInfo,
    TexelCopyBufferLayout, TexelCopyTextureInfo, TextureAspect,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::{Extract, ExtractSchedule, Render, RenderStartup};
use penumbra_df_core::atlas::AtlasRegion;
use penumbra_df_core::rebake::RebakeParams;

/// One re-baked mesh in the render world: its latest bake (kept until it is in the
/// atlas: a volume not yet placed waits for its place), where its volume is now, its
/// pooled buffers and what they and the atlas hold.
struct MeshRebake {
    latest: RebakeJob,
    /// The volume's region this frame, when placed with its full cube.
    region: Option<AtlasRegion>,
    buffers: Option<RebakeBuffers>,
    /// The bake whose triangles and uniform are in the buffers.
    uploaded: Option<u64>,
    /// The bake last written into the atlas, and where.
    written: Option<(u64, AtlasRegion)>,
}

/// One re-baked mesh's buffers.
struct RebakeBuffers {
    corners: Buffer,
    params: Buffer,
    output: Buffer,
    bind_group: BindGroup,
}

/// The re-baked meshes by main-world entity, and this frame's bakes.
#[derive(Resource, Default)]
struct RebakeGpu {
    meshes: HashMap<Entity, MeshRebake>,
    dispatches: Vec<Entity>,
}

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

/// Takes this frame's bakes, drops the meshes no longer re-baked (and their buffers),
/// and finds where each volume is: a volume placed at a reduced resolution (the atlas
/// full) is not re-baked, its cube would not fit.
fn extract_rebakes(
    mut rebakes: ResMut<RebakeGpu>,
    jobs: Extract<Option<Res<RebakeJobs>>>,
    scene: Extract<Option<Res<DistanceFieldScene>>>,
) {
    let (Some(jobs), Some(scene)) = (jobs.as_deref(), scene.as_deref()) else {
        rebakes.meshes.clear();
        return;
    };
    if !rebakes.meshes.is_empty() {
        rebakes.meshes.retain(|mesh, _| jobs.live.contains(mesh));
    }
    for job in &jobs.jobs {
        match rebakes.meshes.get_mut(&job.mesh) {
            Some(mesh) => mesh.latest = job.clone(),
            None => {
                rebakes.meshes.insert(
                    job.mesh,
                    MeshRebake {
                        latest: job.clone(),
                        region: None,
                        buffers: None,
                        uploaded: None,
                        written: None,
                    },
                );
            }
        }
    }
    for mesh in rebakes.meshes.values_mut() {
        mesh.region = scene
            .volume_region(mesh.latest.volume)
            .filter(|region| region.dims == mesh.latest.grid.dims());
    }
}

/// Lists this frame's bakes: each mesh whose latest bake is not in its volume's region
/// (a new pose, a volume placed or moved, or its region written over by an upload this
/// frame), writing the triangles and uniform of a new pose into its pooled buffers
/// (grown when the triangles outgrow them).
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_rebakes(
    mut rebakes: ResMut<RebakeGpu>,
    frame: Res<ExtractedDistanceFieldFrame>,
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
    let (Some(mut pipeline), Some(library), false, Some(_)) = (
        pipeline,
        library,
        rebakes.meshes.is_empty(),
        gpu.atlas.as_ref(),
    ) else {
        return;
    };
    let id = pipeline.queue(&library, &pipeline_cache);
    if pipeline_cache.get_compute_pipeline(id).is_none() {
        return; // compiling: the fields wait
    }
    let layout = pipeline_cache.get_bind_group_layout(&pipeline.layout);
    for (&entity, mesh) in &mut rebakes.meshes {
        let Some(region) = mesh.region else {
            continue; // not placed yet
        };
        let job = &mesh.latest;
        let overwritten = frame.0.uploads.iter().any(|u| u.region == region);
        if mesh.written == Some((job.sequence, region)) && !overwritten {
            continue; // in the atlas already
        }
        if mesh.uploaded != Some(job.sequence) {
            let buffers = fit_buffers(&mut mesh.buffers, job, &layout, &allocations, &device);
            write_job(buffers, job, &queue);
            mesh.uploaded = Some(job.sequence);
        }
        mesh.written = Some((job.sequence, region));
        rebakes.dispatches.push(entity);
    }
    if !rebakes.dispatches.is_empty() {
        gpu.touch();
    }
}

/// The mesh's buffers, made again when the job's triangles or cube outgrow them.
fn fit_buffers<'a>(
    buffers: &'a mut Option<RebakeBuffers>,
    job: &RebakeJob,
    layout: &BindGroupLayout,
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
) -> &'a RebakeBuffers {
    let corner_bytes = (job.corners.len() as u64 * 16).max(16);
    let output_bytes = job.grid.output_bytes();
    let fits = buffers
        .as_ref()
        .is_some_and(|b| b.corners.size() >= corner_bytes && b.output.size() == output_bytes);
    if fits {
        return buffers.as_ref().expect("checked above");
    }
    let corners = allocations.sized_buffer(
        device,
        "penumbra_df_rebake_corners",
        corner_bytes.next_power_of_two(),
        BufferUsages::STORAGE | BufferUsages::COPY_DST,
    );
    let params = allocations.sized_buffer(
        device,
        "penumbra_df_rebake_params",
        RebakeParams::min_size().get(),
        BufferUsages::UNIFORM | BufferUsages::COPY_DST,
    );
    let output = allocations.sized_buffer(
        device,
        "penumbra_df_rebake_samples",
        output_bytes,
        BufferUsages::STORAGE | BufferUsages::COPY_SRC,
    );
    let bind_group = allocations.bind_group(
        device,
        "penumbra_df_rebake_bind_group",
        layout,
        &BindGroupEntries::sequential((
            params.as_entire_binding(),
            corners.as_entire_binding(),
            output.as_entire_binding(),
        )),
    );
    buffers.insert(RebakeBuffers {
        corners,
        params,
        output,
        bind_group,
    })
}

/// Writes the job's triangles and uniform.
fn write_job(buffers: &RebakeBuffers, job: &RebakeJob, queue: &RenderQueue) {
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
        for (mesh, buffers, _) in dispatches(&rebakes) {
            pass.set_bind_group(0, &buffers.bind_group, &[]);
            let groups = mesh.latest.grid.workgroups();
            pass.dispatch_workgroups(groups.x, groups.y, groups.z);
        }
    }
    for (mesh, buffers, region) in dispatches(&rebakes) {
        let job = &mesh.latest;
        let r = job.grid.resolution;
        ctx.command_encoder().copy_buffer_to_texture(
            TexelCopyBufferInfo {
                buffer: &buffers.output,
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

/// This frame's bakes: each mesh, its buffers and the region written.
fn dispatches(
    rebakes: &RebakeGpu,
) -> impl Iterator<Item = (&MeshRebake, &RebakeBuffers, AtlasRegion)> {
    rebakes.dispatches.iter().filter_map(|entity| {
        let mesh = rebakes.meshes.get(entity)?;
        Some((mesh, mesh.buffers.as_ref()?, mesh.written?.1))
    })
}
