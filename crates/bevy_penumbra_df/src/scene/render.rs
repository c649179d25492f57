//! Render-world side of the distance-field scene: the object buffer, the atlas texture
//! and the delta pass. Everything is pooled: the object buffer grows by doubling, the
//! delta pass's writes and params buffers grow with the largest frame seen, and their
//! bind groups are made again only when a buffer changes. Per-view culling is in
//! `cull`. The terrains' records and texture ([`GpuHeightfields`]) exist while the
//! scene has a terrain and are made again only when the terrains change.

use super::{AtlasUpload, DistanceFieldFrame, SceneHeightfields};
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::ShaderType;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferBinding, BufferDescriptor, BufferId, BufferUsages, CachedComputePipelineId,
    ComputePassDescriptor, Extent3d, Origin3d, PipelineCache, ShaderStages, TexelCopyBufferLayout,
    TexelCopyTextureInfo, Texture, TextureAspect, TextureDescriptor, TextureDimension,
    TextureFormat, TextureUsages, TextureView, TextureViewDescriptor,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::{Extract, ExtractSchedule, Render, RenderStartup, RenderSystems};
use penumbra_df_core::heightfield::{Heightfield, HeightfieldRecord, HeightfieldTexture};
use penumbra_df_core::object::{ObjectRecord, RECORD_BYTES};
use penumbra_df_core::table::{
    DELTA_PARAMS_STRIDE, DeltaChunk, DeltaWrite, Deltas, writes_per_chunk,
};
use std::collections::BTreeMap;
use std::num::NonZeroU64;
use std::sync::Arc;

/// The scene's GPU resources (render world). Absent buffers mean no caster has ever
/// existed: nothing was allocated.
#[derive(Resource, Default)]
pub struct DistanceFieldGpu {
    /// The object buffer (`array<DistanceFieldObject>`), `capacity` slots.
    pub objects: Option<Buffer>,
    /// Slots allocated in `objects`.
    pub capacity: u32,
    /// Slots in use (live or free), as of this frame.
    pub slot_count: u32,
    /// The atlas (`R16Float`, 3D) and its size in voxels.
    pub atlas: Option<(Texture, TextureView, UVec3)>,
    /// The brick table (`R32Uint`, 2D, `penumbra_df_core::bricks::TABLE_WIDTH` wide) and
    /// its rows, once a volume has been placed as bricks.
    pub brick_table: Option<(Texture, TextureView, u32)>,
    /// Writes not yet applied (kept while the delta pipeline compiles).
    pending: BTreeMap<u32, ObjectRecord>,
    /// The delta pass's pooled buffers and bind groups.
    deltas: Option<DeltaBuffers>,
    /// This frame's dispatches of the delta pass.
    frame_chunks: Vec<DeltaChunk>,
    /// Most writes one dispatch binds (from the device's storage-binding limit).
    writes_per_chunk: u32,
    /// Counts frames whose object buffer or atlas contents changed (records written,
    /// SDFs uploaded, the buffer grown or the atlas created); see
    /// [`DistanceFieldGpu::generation`].
    generation: u64,
}

impl DistanceFieldGpu {
    /// Changes whenever the object buffer's or the atlas's contents change: a pass whose
    /// result depends only on them (and inputs of its own) can skip a frame in which
    /// this and its inputs are as when it last ran.
    pub fn generation(&self) -> u64 {
        self.generation
    }

    /// Counts a change of the atlas's contents made by a pass (a re-bake).
    pub(crate) fn touch(&mut self) {
        self.generation += 1;
    }

    /// Whether object writes are held back (the delta pipeline compiling): the object
    /// buffer is then behind the main world's records.
    pub fn deltas_held_back(&self) -> bool {
        !self.pending.is_empty()
    }
}

/// The delta pass's buffers: the frame's writes (all chunks back to back) and one
/// `DeltaParams` per chunk, with a bind group per chunk.
struct DeltaBuffers {
    writes: Buffer,
    params: Buffer,
    /// Writes `writes` holds.
    capacity: u32,
    /// Per chunk, and the object buffer they bind.
    bind_groups: Vec<BindGroup>,
    objects: Option<BufferId>,
}

/// The scene's compute pipelines.
#[derive(Resource)]
pub struct DistanceFieldPipelines {
    apply_layout: BindGroupLayoutDescriptor,
    apply: CachedComputePipelineId,
    /// Layout of the culling pass (objects, view, culled, count).
    pub cull_layout: BindGroupLayoutDescriptor,
    pub(crate) cull: CachedComputePipelineId,
    /// Layout of the indirect-arguments pass (count, indirect).
    pub indirect_layout: BindGroupLayoutDescriptor,
    pub(crate) indirect: CachedComputePipelineId,
}

#[derive(Resource, Default)]
pub(super) struct ExtractedDistanceFieldFrame(pub(super) DistanceFieldFrame);

/// Render-world system sets of the distance-field scene.
#[derive(SystemSet, Clone, Debug, PartialEq, Eq, Hash)]
pub enum DistanceFieldRenderSystems {
    /// The object buffer and atlas are grown and the frame's uploads queued
    /// (`RenderSystems::PrepareResources`): passes sizing buffers by
    /// `DistanceFieldGpu::slot_count` prepare after it.
    PrepareGpu,
    /// The frame's object writes applied on the GPU (`RenderGraph` schedule, before the
    /// cameras): view-independent passes reading the object buffer run after it.
    ApplyDeltas,
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .init_resource::<DistanceFieldGpu>()
        .init_resource::<ExtractedDistanceFieldFrame>()
        .add_systems(ExtractSchedule, timed(extract_distance_field_frame))
        .configure_sets(
            Render,
            DistanceFieldRenderSystems::PrepareGpu.in_set(RenderSystems::PrepareResources),
        )
        .add_systems(ExtractSchedule, timed(extract_heightfields))
        .add_systems(
            Render,
            (
                timed(prepare_distance_field_gpu),
                timed(prepare_heightfields).run_if(resource_exists::<ExtractedHeightfields>),
            )
                .in_set(DistanceFieldRenderSystems::PrepareGpu),
        )
        .add_systems(
            RenderGraph,
            timed(apply_distance_field_deltas)
                .in_set(DistanceFieldRenderSystems::ApplyDeltas)
                .in_set(bevy::render::renderer::RenderGraphSystems::Render)
                .before(camera_driver),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(RenderStartup, init_distance_field_pipelines);
}

fn init_distance_field_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    device: Res<RenderDevice>,
    library: Option<Res<PenumbraShaderLibrary>>,
    mut gpu: ResMut<DistanceFieldGpu>,
) {
    // Delta uploads bind at most this many writes per dispatch.
    gpu.writes_per_chunk = writes_per_chunk(device.limits().max_storage_buffer_binding_size);
    let Some(library) = library else {
        warn!(
            "Penumbra: shader library missing (add PenumbraPlugins); distance-field passes are off"
        );
        return;
    };
    let apply_layout = BindGroupLayoutDescriptor::new(
        "penumbra_df_apply_deltas_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                storage_buffer_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                uniform_buffer_sized(false, NonZeroU64::new(16)),
            ),
        ),
    );
    let cull_layout = BindGroupLayoutDescriptor::new(
        "penumbra_df_cull_layout",
        &BindGroupLayoutEntries::with_indices(
            ShaderStages::COMPUTE,
            (
                (0, storage_buffer_read_only_sized(false, None)),
                (
                    1,
                    uniform_buffer_sized(false, NonZeroU64::new(super::cull::CULL_VIEW_BYTES)),
                ),
                (2, storage_buffer_sized(false, None)),
                (3, storage_buffer_sized(false, None)),
            ),
        ),
    );
    let indirect_layout = BindGroupLayoutDescriptor::new(
        "penumbra_df_indirect_layout",
        &BindGroupLayoutEntries::with_indices(
            ShaderStages::COMPUTE,
            (
                (3, storage_buffer_sized(false, None)),
                (4, storage_buffer_sized(false, None)),
            ),
        ),
    );
    let queue = |label: &'static str,
                 layout: &BindGroupLayoutDescriptor,
                 path: &str,
                 entry: &'static str| {
        library.queue_compute(&pipeline_cache, label, layout, path, entry)
    };
    let apply = queue(
        "penumbra_df_apply_deltas",
        &apply_layout,
        "df/apply_deltas.wgsl",
        "apply_deltas",
    );
    let cull = queue("penumbra_df_cull", &cull_layout, "df/cull.wgsl", "cull");
    let indirect = queue(
        "penumbra_df_write_indirect",
        &indirect_layout,
        "df/cull.wgsl",
        "write_indirect",
    );
    commands.insert_resource(DistanceFieldPipelines {
        apply_layout,
        apply,
        cull_layout,
        cull,
        indirect_layout,
        indirect,
    });
}

fn extract_distance_field_frame(
    mut extracted: ResMut<ExtractedDistanceFieldFrame>,
    frame: Extract<Res<DistanceFieldFrame>>,
) {
    // O(changes): an unchanged scene clones two empty vectors.
    extracted.0 = DistanceFieldFrame::clone(&frame);
}

/// Grows the object buffer, creates the atlas on first use, writes the frame's atlas
/// uploads, and uploads the frame's record writes into the pooled delta buffers (kept
/// pending while the delta pipeline compiles).
pub(super) fn prepare_distance_field_gpu(
    allocations: Res<PenumbraGpuAllocations>,
    frame: Res<ExtractedDistanceFieldFrame>,
    mut gpu: ResMut<DistanceFieldGpu>,
    pipelines: Option<Res<DistanceFieldPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    let frame = &frame.0;
    let gpu = &mut *gpu;
    gpu.frame_chunks.clear();
    if frame.deltas.slot_count == 0 && gpu.objects.is_none() {
        return; // no caster has ever existed
    }
    let before = (gpu.objects.as_ref().map(Buffer::id), gpu.atlas.is_some());
    grow_object_buffer(gpu, &frame.deltas, &allocations, &device, &queue);
    if let Some(size) = frame.atlas_size
        && gpu.atlas.is_none()
    {
        let texture = allocations.texture(
            &device,
            &TextureDescriptor {
                label: Some("penumbra_df_atlas"),
                size: Extent3d {
                    width: size.x,
                    height: size.y,
                    depth_or_array_layers: size.z,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: TextureDimension::D3,
                format: TextureFormat::R16Float,
                usage: TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_DST,
                view_formats: &[],
            },
        );
        let view = texture.create_view(&TextureViewDescriptor::default());
        gpu.atlas = Some((texture, view, size));
    }
    if let Some((texture, _, _)) = &gpu.atlas {
        for upload in &frame.uploads {
            write_atlas(&queue, texture, upload);
        }
    }
    if let Some(table) = &frame.brick_table {
        write_brick_table(gpu, table, &allocations, &device, &queue);
    }
    let after = (gpu.objects.as_ref().map(Buffer::id), gpu.atlas.is_some());
    let changed = !frame.uploads.is_empty() || frame.brick_table.is_some();
    if before != after || (gpu.atlas.is_some() && changed) {
        gpu.generation += 1;
    }
    for w in &frame.deltas.writes {
        gpu.pending.insert(w.slot, w.record);
    }
    let ready = pipelines
        .as_ref()
        .filter(|p| pipeline_cache.get_compute_pipeline(p.apply).is_some());
    let (Some(pipelines), false) = (ready, gpu.pending.is_empty()) else {
        return;
    };
    let deltas = Deltas {
        writes: std::mem::take(&mut gpu.pending)
            .into_iter()
            .map(|(slot, record)| DeltaWrite { slot, record })
            .collect(),
        slot_count: gpu.slot_count,
    };
    let upload = deltas.upload(gpu.writes_per_chunk.max(64));
    let objects = gpu.objects.as_ref().expect("grown above");
    let buffers = fit_delta_buffers(
        &mut gpu.deltas,
        deltas.writes.len() as u32,
        gpu.writes_per_chunk.max(64),
        &allocations,
        &device,
    );
    if buffers.objects != Some(objects.id()) || buffers.bind_groups.is_empty() {
        buffers.bind_groups = delta_bind_groups(
            buffers,
            objects,
            gpu.writes_per_chunk.max(64),
            &allocations,
            &device,
            &pipeline_cache.get_bind_group_layout(&pipelines.apply_layout),
        );
        buffers.objects = Some(objects.id());
    }
    queue.write_buffer(&buffers.writes, 0, &upload.writes);
    queue.write_buffer(&buffers.params, 0, &upload.params);
    gpu.frame_chunks = upload.chunks;
    gpu.generation += 1;
}

/// The delta buffers, grown to hold `writes` writes (never shrunk).
fn fit_delta_buffers<'a>(
    pool: &'a mut Option<DeltaBuffers>,
    writes: u32,
    per_chunk: u32,
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
) -> &'a mut DeltaBuffers {
    if pool.as_ref().is_some_and(|b| b.capacity >= writes) {
        return pool.as_mut().expect("checked");
    }
    let capacity = writes.max(64).next_power_of_two();
    let chunks = capacity.div_ceil(per_chunk) as u64;
    let buffer = |label, size, usage: BufferUsages| {
        allocations.sized_buffer(device, label, size, usage | BufferUsages::COPY_DST)
    };
    pool.insert(DeltaBuffers {
        writes: buffer(
            "penumbra_df_object_writes",
            capacity as u64 * DeltaWrite::BYTES as u64,
            BufferUsages::STORAGE,
        ),
        params: buffer(
            "penumbra_df_object_writes_params",
            chunks * DELTA_PARAMS_STRIDE,
            BufferUsages::UNIFORM,
        ),
        capacity,
        bind_groups: Vec::new(),
        objects: None,
    })
}

/// One bind group per chunk the buffers can hold: writes `k × per_chunk..` and params
/// `k × DELTA_PARAMS_STRIDE`.
fn delta_bind_groups(
    buffers: &DeltaBuffers,
    objects: &Buffer,
    per_chunk: u32,
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    layout: &bevy::render::render_resource::BindGroupLayout,
) -> Vec<BindGroup> {
    let chunk_bytes = per_chunk as u64 * DeltaWrite::BYTES as u64;
    let total = buffers.writes.size();
    (0..total.div_ceil(chunk_bytes))
        .map(|k| {
            let offset = k * chunk_bytes;
            allocations.bind_group(
                device,
                "penumbra_df_apply_deltas",
                layout,
                &BindGroupEntries::sequential((
                    objects.as_entire_binding(),
                    BufferBinding {
                        buffer: &buffers.writes,
                        offset,
                        size: NonZeroU64::new(chunk_bytes.min(total - offset)),
                    },
                    BufferBinding {
                        buffer: &buffers.params,
                        offset: k * DELTA_PARAMS_STRIDE,
                        size: NonZeroU64::new(16),
                    },
                )),
            )
        })
        .collect()
}

/// Grows the object buffer to hold `deltas.slot_count` slots (doubling; old contents
/// copied on the GPU).
fn grow_object_buffer(
    gpu: &mut DistanceFieldGpu,
    deltas: &Deltas,
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    queue: &RenderQueue,
) {
    gpu.slot_count = gpu.slot_count.max(deltas.slot_count);
    if gpu.objects.is_some() && gpu.slot_count <= gpu.capacity {
        return;
    }
    let capacity = gpu.slot_count.max(64).next_power_of_two();
    let buffer = allocations.buffer(
        device,
        &BufferDescriptor {
            label: Some("penumbra_df_objects"),
            size: capacity as u64 * RECORD_BYTES as u64,
            usage: BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST,
            mapped_at_creation: false,
        },
    );
    if let Some(old) = &gpu.objects {
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(
            old,
            0,
            &buffer,
            0,
            gpu.capacity as u64 * RECORD_BYTES as u64,
        );
        queue.submit([encoder.finish()]);
    }
    gpu.objects = Some(buffer);
    gpu.capacity = capacity;
}

/// Writes the whole brick table, growing its texture (in powers of two rows) when the
/// table outgrew it.
fn write_brick_table(
    gpu: &mut DistanceFieldGpu,
    table: &[u32],
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    queue: &RenderQueue,
) {
    let width = penumbra_df_core::bricks::TABLE_WIDTH;
    let rows = (table.len() as u32).div_ceil(width).max(1);
    if gpu.brick_table.as_ref().is_none_or(|(_, _, r)| *r < rows) {
        let rows = rows.next_power_of_two();
        let texture = allocations.texture(
            device,
            &TextureDescriptor {
                label: Some("penumbra_df_brick_table"),
                size: Extent3d {
                    width,
                    height: rows,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: TextureDimension::D2,
                format: TextureFormat::R32Uint,
                usage: TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_DST,
                view_formats: &[],
            },
        );
        let view = texture.create_view(&TextureViewDescriptor::default());
        gpu.brick_table = Some((texture, view, rows));
    }
    let Some((texture, _, _)) = &gpu.brick_table else {
        return;
    };
    let mut bytes: Vec<u8> = table.iter().flat_map(|e| e.to_le_bytes()).collect();
    bytes.resize((rows * width * 4) as usize, 0);
    queue.write_texture(
        TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: Origin3d::ZERO,
            aspect: TextureAspect::All,
        },
        &bytes,
        TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(width * 4),
            rows_per_image: Some(rows),
        },
        Extent3d {
            width,
            height: rows,
            depth_or_array_layers: 1,
        },
    );
}

fn write_atlas(queue: &RenderQueue, texture: &Texture, upload: &AtlasUpload) {
    let d = upload.region.dims;
    let bytes: Vec<u8> = upload.data.iter().flat_map(|h| h.to_le_bytes()).collect();
    queue.write_texture(
        TexelCopyTextureInfo {
            texture,
            mip_level: 0,
            origin: Origin3d {
                x: upload.region.origin.x,
                y: upload.region.origin.y,
                z: upload.region.origin.z,
            },
            aspect: TextureAspect::All,
        },
        &bytes,
        TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(d.x * 2),
            rows_per_image: Some(d.y),
        },
        Extent3d {
            width: d.x,
            height: d.y,
            depth_or_array_layers: d.z,
        },
    );
}

/// The delta pass: one dispatch per chunk of this frame's writes.
pub(crate) fn apply_distance_field_deltas(
    mut ctx: RenderContext,
    gpu: Res<DistanceFieldGpu>,
    pipelines: Option<Res<DistanceFieldPipelines>>,
    pipeline_cache: Res<PipelineCache>,
) {
    let (Some(buffers), Some(pipelines), false) =
        (&gpu.deltas, pipelines, gpu.frame_chunks.is_empty())
    else {
        return;
    };
    let Some(pipeline) = pipeline_cache.get_compute_pipeline(pipelines.apply) else {
        return; // checked in prepare; kept for safety
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_df_apply_deltas");
    let mut pass = ctx
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_df_apply_deltas"),
            timestamp_writes: None,
        });
    pass.set_pipeline(pipeline);
    for (chunk, bind_group) in gpu.frame_chunks.iter().zip(&buffers.bind_groups) {
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(chunk.groups[0], chunk.groups[1], chunk.groups[2]);
    }
    drop(pass);
    time_span.end(ctx.command_encoder());
}

/// The terrains as of the last change (render world), cloned only when they change.
#[derive(Resource, Default)]
struct ExtractedHeightfields {
    generation: u64,
    terrains: Vec<Arc<Heightfield>>,
    /// The generation last prepared.
    prepared: Option<u64>,
}

/// The scene's terrains on the GPU (`shaders/df/heightfield.wgsl`): present only while
/// the scene has at least one terrain that fits.
#[derive(Resource)]
pub struct GpuHeightfields {
    /// `array<HeightfieldRecord>`, `count` of them.
    pub records: Buffer,
    /// The heights and slope bounds (`R32Float`, 2D).
    pub texture: TextureView,
    /// Terrains in `records`.
    pub count: u32,
}

fn extract_heightfields(
    mut commands: Commands,
    main: Extract<Option<Res<SceneHeightfields>>>,
    extracted: Option<ResMut<ExtractedHeightfields>>,
) {
    let Some(main) = main.as_ref() else {
        return;
    };
    match extracted {
        Some(e) if e.generation == main.generation() => {}
        Some(mut e) => {
            e.generation = main.generation();
            e.terrains = main.terrains().cloned().collect();
        }
        None if main.generation() == 0 => {}
        None => commands.insert_resource(ExtractedHeightfields {
            generation: main.generation(),
            terrains: main.terrains().cloned().collect(),
            prepared: None,
        }),
    }
}

/// Uploads the terrains when they changed: the records and the texture, made again
/// (terrains change rarely); none while there is no terrain. Terrains beyond the
/// device's 2D texture size are left out with a warning.
fn prepare_heightfields(
    mut commands: Commands,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    mut extracted: ResMut<ExtractedHeightfields>,
) {
    if extracted.prepared == Some(extracted.generation) {
        return;
    }
    extracted.prepared = Some(extracted.generation);
    let terrains: Vec<&Heightfield> = extracted.terrains.iter().map(|t| &**t).collect();
    let (packed, refused) =
        HeightfieldTexture::pack(&terrains, device.limits().max_texture_dimension_2d);
    for (i, why) in refused {
        warn!("Penumbra: heightfield {i} stays out of the GPU's distance fields: {why}");
    }
    if packed.records.is_empty() {
        commands.remove_resource::<GpuHeightfields>();
        return;
    }
    let (records, texture) = heightfield_resources(&packed, &allocations, &device, &queue);
    commands.insert_resource(GpuHeightfields {
        records,
        texture,
        count: packed.records.len() as u32,
    });
}

/// A zeroed terrain record and a 1 × 1 heightfield texture: what passes bind as the
/// terrains while the scene has none (never read then).
pub(crate) fn no_heightfields(
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
) -> (Buffer, TextureView) {
    let records = allocations.sized_buffer(
        device,
        "penumbra_no_heightfields",
        HeightfieldRecord::min_size().get(),
        BufferUsages::STORAGE,
    );
    let texture = allocations.texture(
        device,
        &TextureDescriptor {
            label: Some("penumbra_no_heightfield_texture"),
            size: Extent3d::default(),
            mip_level_count: 1,
            sample_count: 1,
            dimension: TextureDimension::D2,
            format: TextureFormat::R32Float,
            usage: TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        },
    );
    (
        records,
        texture.create_view(&TextureViewDescriptor::default()),
    )
}

/// The records buffer and the texture of `packed` (at least one record: an empty
/// texture's records are zeros), uploaded.
fn heightfield_resources(
    packed: &HeightfieldTexture,
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    queue: &RenderQueue,
) -> (Buffer, TextureView) {
    use bevy::render::render_resource::encase::StorageBuffer;
    let mut records = packed.records.clone();
    if records.is_empty() {
        records.push(HeightfieldRecord::default());
    }
    let mut bytes = StorageBuffer::new(Vec::new());
    bytes.write(&records).expect("encodes");
    let buffer = allocations.sized_buffer(
        device,
        "penumbra_heightfield_records",
        (records.len() as u64 * HeightfieldRecord::min_size().get()).max(16),
        BufferUsages::STORAGE | BufferUsages::COPY_DST,
    );
    queue.write_buffer(&buffer, 0, bytes.as_ref());
    let size = Extent3d {
        width: packed.width,
        height: packed.rows,
        depth_or_array_layers: 1,
    };
    let texture = allocations.texture(
        device,
        &TextureDescriptor {
            label: Some("penumbra_heightfield_texture"),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: TextureDimension::D2,
            format: TextureFormat::R32Float,
            usage: TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_DST,
            view_formats: &[],
        },
    );
    let texels: Vec<u8> = packed.texels.iter().flat_map(|v| v.to_le_bytes()).collect();
    queue.write_texture(
        TexelCopyTextureInfo {
            texture: &texture,
            mip_level: 0,
            origin: Origin3d::ZERO,
            aspect: TextureAspect::All,
        },
        &texels,
        TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(4 * packed.width),
            rows_per_image: Some(packed.rows),
        },
        size,
    );
    (
        buffer,
        texture.create_view(&TextureViewDescriptor::default()),
    )
}
