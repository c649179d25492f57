//! Render-world side of the distance-field scene: the object buffer, the atlas texture,
//! the delta pass and per-view GPU culling.

use super::{AtlasUpload, DistanceFieldFrame};
use crate::shader_library::PenumbraShaderLibrary;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer, BufferDescriptor,
    BufferInitDescriptor, BufferUsages, CachedComputePipelineId, ComputePassDescriptor, Extent3d,
    Origin3d, PipelineCache, ShaderStages, TexelCopyBufferLayout, TexelCopyTextureInfo, Texture,
    TextureAspect, TextureDescriptor, TextureDimension, TextureFormat, TextureUsages, TextureView,
    TextureViewDescriptor,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::{Extract, ExtractSchedule, Render, RenderStartup, RenderSystems};
use penumbra_df_core::cull::{CameraOrigin, Frustum, cull_view_words, grid_64};
use penumbra_df_core::object::{ObjectRecord, RECORD_BYTES};
use penumbra_df_core::table::{DeltaWrite, Deltas};
use std::collections::BTreeMap;
use std::num::NonZeroU64;

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
    /// Writes not yet applied (kept while the delta pipeline compiles).
    pending: BTreeMap<u32, ObjectRecord>,
    /// This frame's writes buffer, its params uniform and its dispatch size.
    frame_writes: Option<(Buffer, Buffer, [u32; 3])>,
}

/// The scene's compute pipelines.
#[derive(Resource)]
pub struct DistanceFieldPipelines {
    apply_layout: BindGroupLayoutDescriptor,
    apply: CachedComputePipelineId,
    /// Layout of the culling pass (objects, view, culled, count).
    pub cull_layout: BindGroupLayoutDescriptor,
    cull: CachedComputePipelineId,
    /// Layout of the indirect-arguments pass (count, indirect).
    pub indirect_layout: BindGroupLayoutDescriptor,
    indirect: CachedComputePipelineId,
}

#[derive(Resource, Default)]
struct ExtractedDistanceFieldFrame(DistanceFieldFrame);

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .init_resource::<DistanceFieldGpu>()
        .init_resource::<ExtractedDistanceFieldFrame>()
        .add_systems(ExtractSchedule, extract_distance_field_frame)
        .add_systems(
            Render,
            prepare_distance_field_gpu.in_set(RenderSystems::PrepareResources),
        )
        .add_systems(
            RenderGraph,
            apply_distance_field_deltas.before(camera_driver),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(RenderStartup, init_distance_field_pipelines);
}

fn init_distance_field_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
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
                    uniform_buffer_sized(false, NonZeroU64::new(CULL_VIEW_BYTES)),
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

fn prepare_distance_field_gpu(
    frame: Res<ExtractedDistanceFieldFrame>,
    mut gpu: ResMut<DistanceFieldGpu>,
    pipelines: Option<Res<DistanceFieldPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    let frame = &frame.0;
    let gpu = &mut *gpu;
    gpu.frame_writes = None;
    if frame.deltas.slot_count == 0 && gpu.objects.is_none() {
        return; // no caster has ever existed
    }
    grow_object_buffer(gpu, &frame.deltas, &device, &queue);
    if let Some(size) = frame.atlas_size
        && gpu.atlas.is_none()
    {
        let texture = device.create_texture(&TextureDescriptor {
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
        });
        let view = texture.create_view(&TextureViewDescriptor::default());
        gpu.atlas = Some((texture, view, size));
    }
    if let Some((texture, _, _)) = &gpu.atlas {
        for upload in &frame.uploads {
            write_atlas(&queue, texture, upload);
        }
    }
    for w in &frame.deltas.writes {
        gpu.pending.insert(w.slot, w.record);
    }
    let ready = pipelines
        .as_ref()
        .is_some_and(|p| pipeline_cache.get_compute_pipeline(p.apply).is_some());
    if gpu.pending.is_empty() || !ready {
        return;
    }
    let deltas = Deltas {
        writes: std::mem::take(&mut gpu.pending)
            .into_iter()
            .map(|(slot, record)| DeltaWrite { slot, record })
            .collect(),
        slot_count: gpu.slot_count,
    };
    let upload = deltas.upload();
    let writes = device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some("penumbra_df_object_writes"),
        contents: &upload.writes,
        usage: BufferUsages::STORAGE,
    });
    let params = device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some("penumbra_df_object_writes_params"),
        contents: &upload.params,
        usage: BufferUsages::UNIFORM,
    });
    let groups = upload.groups;
    gpu.frame_writes = Some((writes, params, groups));
}

/// Grows the object buffer to hold `deltas.slot_count` slots (doubling; old contents
/// copied on the GPU).
fn grow_object_buffer(
    gpu: &mut DistanceFieldGpu,
    deltas: &Deltas,
    device: &RenderDevice,
    queue: &RenderQueue,
) {
    gpu.slot_count = gpu.slot_count.max(deltas.slot_count);
    if gpu.objects.is_some() && gpu.slot_count <= gpu.capacity {
        return;
    }
    let capacity = gpu.slot_count.max(64).next_power_of_two();
    let buffer = device.create_buffer(&BufferDescriptor {
        label: Some("penumbra_df_objects"),
        size: capacity as u64 * RECORD_BYTES as u64,
        usage: BufferUsages::STORAGE | BufferUsages::COPY_SRC | BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
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

fn apply_distance_field_deltas(
    mut ctx: RenderContext,
    gpu: Res<DistanceFieldGpu>,
    pipelines: Option<Res<DistanceFieldPipelines>>,
    pipeline_cache: Res<PipelineCache>,
) {
    let (Some((writes, params, groups)), Some(objects), Some(pipelines)) =
        (&gpu.frame_writes, &gpu.objects, pipelines)
    else {
        return;
    };
    let Some(pipeline) = pipeline_cache.get_compute_pipeline(pipelines.apply) else {
        return; // checked in prepare; kept for safety
    };
    let bind_group = ctx.render_device().create_bind_group(
        "penumbra_df_apply_deltas",
        &pipeline_cache.get_bind_group_layout(&pipelines.apply_layout),
        &BindGroupEntries::sequential((
            objects.as_entire_binding(),
            writes.as_entire_binding(),
            params.as_entire_binding(),
        )),
    );
    let mut pass = ctx
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_df_apply_deltas"),
            timestamp_writes: None,
        });
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, &bind_group, &[]);
    pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
}

/// Size of the culling pass's view uniform (`CullView` in `df/cull.wgsl`).
const CULL_VIEW_BYTES: u64 = 144;

/// One view's culling output: the compact list of surviving slots, its count and
/// indirect dispatch arguments.
pub struct CulledObjects {
    /// `array<u32>` of slots.
    pub list: Buffer,
    /// The count (`u32`).
    pub count: Buffer,
    /// `[x, y, z]` workgroups of 64 for passes walking the list.
    pub indirect: Buffer,
}

/// Culls the object buffer for a camera (camera-relative `clip_from_relative`, world
/// position `camera`) and records the passes in `ctx`. `None` while pipelines compile
/// or without objects.
pub fn cull_objects(
    ctx: &mut RenderContext,
    gpu: &DistanceFieldGpu,
    pipelines: &DistanceFieldPipelines,
    pipeline_cache: &PipelineCache,
    clip_from_relative: Mat4,
    camera: Vec3,
) -> Option<CulledObjects> {
    let objects = gpu.objects.as_ref()?;
    let cull = pipeline_cache.get_compute_pipeline(pipelines.cull)?;
    let indirect_pipeline = pipeline_cache.get_compute_pipeline(pipelines.indirect)?;
    let origin = CameraOrigin::at(camera)?;
    let frustum = Frustum::from_clip_from_relative(clip_from_relative);
    let slots = gpu.slot_count;
    let (groups, groups_x) = grid_64(slots);
    let view = cull_view_words(&frustum, &origin, slots, groups_x);
    let view: Vec<u8> = view.iter().flat_map(|w| w.to_le_bytes()).collect();
    let device = ctx.render_device().clone();
    let view = device.create_buffer_with_data(&BufferInitDescriptor {
        label: Some("penumbra_df_cull_view"),
        contents: &view,
        usage: BufferUsages::UNIFORM,
    });
    let zeroed = |label: &'static str, size: u64, usage: BufferUsages| {
        device.create_buffer_with_data(&BufferInitDescriptor {
            label: Some(label),
            contents: &vec![0u8; size as usize],
            usage: BufferUsages::STORAGE | usage,
        })
    };
    let list = zeroed(
        "penumbra_df_culled",
        slots.max(1) as u64 * 4,
        BufferUsages::empty(),
    );
    let count = zeroed("penumbra_df_culled_count", 4, BufferUsages::COPY_SRC);
    let indirect = zeroed("penumbra_df_culled_indirect", 12, BufferUsages::INDIRECT);
    let cull_bind = device.create_bind_group(
        "penumbra_df_cull",
        &pipeline_cache.get_bind_group_layout(&pipelines.cull_layout),
        &BindGroupEntries::with_indices((
            (0, objects.as_entire_binding()),
            (1, view.as_entire_binding()),
            (2, list.as_entire_binding()),
            (3, count.as_entire_binding()),
        )),
    );
    let indirect_bind = device.create_bind_group(
        "penumbra_df_indirect",
        &pipeline_cache.get_bind_group_layout(&pipelines.indirect_layout),
        &BindGroupEntries::with_indices((
            (3, count.as_entire_binding()),
            (4, indirect.as_entire_binding()),
        )),
    );
    let mut pass = ctx
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_df_cull"),
            timestamp_writes: None,
        });
    pass.set_pipeline(cull);
    pass.set_bind_group(0, &cull_bind, &[]);
    pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
    pass.set_pipeline(indirect_pipeline);
    pass.set_bind_group(0, &indirect_bind, &[]);
    pass.dispatch_workgroups(1, 1, 1);
    drop(pass);
    Some(CulledObjects {
        list,
        count,
        indirect,
    })
}
