//! Render-world side of buffer dumps: a pooled output/staging buffer pair per dumping
//! view, the dump pass, and the asynchronous read-back.

use super::{AoPlanes, PenumbraBufferDump, RawDump};
use crate::face_normals::{FaceNormalPrepass, ViewFaceNormalTexture};
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::lighting::msaa_render::{DeferredMsaaTextures, pixel_prepass};
use crate::lighting::render::{PenumbraLightingInputs, PenumbraLightingPipeline};
use crate::lighting::{PenumbraAoInput, PenumbraLightingView};
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::pbr::ScreenSpaceAmbientOcclusionResources;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::binding_types::{
    storage_buffer_sized, texture_2d, texture_2d_array, uniform_buffer,
};
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferId, BufferUsages, CachedComputePipelineId, ComputePassDescriptor, Extent3d, MapMode,
    PipelineCache, ShaderStages, ShaderType, TextureDescriptor, TextureDimension, TextureFormat,
    TextureSampleType, TextureUsages, TextureView, TextureViewDescriptor, TextureViewId,
    UniformBuffer,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::sync_world::MainEntity;
use bevy::render::view::ExtractedView;
use bevy::render::{Render, RenderStartup, RenderSystems};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::Sender;

/// `DumpView` of `buffer_dump.wgsl`.
#[derive(ShaderType, Clone, Copy, Default)]
struct DumpView {
    view_from_clip: Mat4,
    /// Width, height, mask layers, 1 when the G-buffer is bound.
    size: UVec4,
    /// x: 1 when the AO texture is bound; y: 1 when the face-normal target is.
    ao: UVec4,
}

/// The render world's end of the read-back channel.
#[derive(Resource)]
struct DumpSender(Sender<RawDump>);

/// The dump pipeline and what it binds when a view has no G-buffer (views without
/// masks bind the lighting pass's white layer).
#[derive(Resource)]
struct BufferDumpPipeline {
    layout: BindGroupLayoutDescriptor,
    pipeline: CachedComputePipelineId,
    /// An empty G-buffer, for views without one (normals read as 0).
    no_gbuffer: TextureView,
}

/// The resources a dump bind group binds.
type BindKey = (
    TextureViewId,
    TextureViewId,
    TextureViewId,
    BufferId,
    TextureViewId,
    TextureViewId,
);

/// A dumping view's pooled buffers and its bind group.
#[derive(Component)]
struct ViewBufferDump {
    /// Pixels and mask layers the buffers are sized for.
    size: UVec2,
    layers: u32,
    /// Whether the buffers hold the AO and bent-normal planes (DFAO's, else SSAO's).
    ao: bool,
    /// Whether they hold the face-normal planes.
    face: bool,
    /// The pass's output (storage) and its copy for mapping.
    output: Buffer,
    staging: Buffer,
    uniform: UniformBuffer<DumpView>,
    /// The bind group and what it binds (depth, G-buffer, masks, uniform): made again
    /// only when one of them changes.
    bind_group: Option<(BindKey, BindGroup)>,
    /// Asked for this frame, and bound.
    active: bool,
    /// The main-world lights of the mask layers, this frame.
    lights: Vec<Entity>,
    /// What the AO planes hold this frame.
    ao_dumped: AoPlanes,
    /// Whether the face-normal planes are written this frame.
    face_dumped: bool,
    /// Copied this frame, to be mapped in `Cleanup`.
    copied: Arc<AtomicBool>,
    /// The staging buffer is being mapped or read: no new copy into it.
    busy: Arc<AtomicBool>,
}

pub(super) fn build(render_app: &mut SubApp, sender: Sender<RawDump>) {
    render_app
        .insert_resource(DumpSender(sender))
        .add_systems(
            Render,
            (
                (
                    timed(prepare_buffer_dumps),
                    timed(prepare_buffer_dump_bind_groups),
                )
                    .chain()
                    .in_set(RenderSystems::PrepareBindGroups),
                timed(map_buffer_dumps).in_set(RenderSystems::Cleanup),
            ),
        )
        .add_systems(
            Core3d,
            timed(penumbra_buffer_dump).in_set(Core3dSystems::PostProcess),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(RenderStartup, init_buffer_dump_pipeline);
}

fn init_buffer_dump_pipeline(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    device: Res<RenderDevice>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return;
    };
    let layout = BindGroupLayoutDescriptor::new(
        "penumbra_buffer_dump_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Uint),
                texture_2d_array(TextureSampleType::Float { filterable: false }),
                uniform_buffer::<DumpView>(false),
                storage_buffer_sized(false, None),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Float { filterable: false }),
            ),
        ),
    );
    let pipeline = library.queue_compute(
        &pipeline_cache,
        "penumbra_buffer_dump",
        &layout,
        "lighting/buffer_dump.wgsl",
        "dump",
    );
    let no_gbuffer = device.create_texture(&TextureDescriptor {
        label: Some("penumbra_buffer_dump_no_gbuffer"),
        size: Extent3d::default(),
        mip_level_count: 1,
        sample_count: 1,
        dimension: TextureDimension::D2,
        format: TextureFormat::Rgba32Uint,
        usage: TextureUsages::TEXTURE_BINDING,
        view_formats: &[],
    });
    commands.insert_resource(BufferDumpPipeline {
        layout,
        pipeline,
        no_gbuffer: no_gbuffer.create_view(&TextureViewDescriptor::default()),
    });
}

/// Sizes each dumping view's buffer pair (kept while its size and light count are).
#[allow(clippy::type_complexity, reason = "a Bevy system")]
fn prepare_buffer_dumps(
    mut commands: Commands,
    device: Res<RenderDevice>,
    allocations: Res<PenumbraGpuAllocations>,
    views: Query<
        (
            Entity,
            &ExtractedView,
            Option<&PenumbraLightingInputs>,
            Has<PenumbraAoInput>,
            Has<ScreenSpaceAmbientOcclusionResources>,
            Has<FaceNormalPrepass>,
            Option<&ViewBufferDump>,
        ),
        (With<PenumbraBufferDump>, With<PenumbraLightingView>),
    >,
    mut warned: Local<bool>,
) {
    for (entity, view, inputs, dfao, ssao, face, dump) in &views {
        let ao = dfao || ssao;
        let size = view.viewport.zw().max(UVec2::ONE);
        let layers = inputs.map_or(0, |i| i.lights.len() as u32);
        if dump
            .is_some_and(|d| d.size == size && d.layers == layers && d.ao == ao && d.face == face)
        {
            continue;
        }
        let planes = 4 + layers + if ao { 4 } else { 0 } + if face { 3 } else { 0 };
        let bytes = u64::from(size.x) * u64::from(size.y) * u64::from(planes) * 4;
        let limits = device.limits();
        if bytes
            > limits
                .max_storage_buffer_binding_size
                .min(limits.max_buffer_size)
        {
            if !std::mem::replace(&mut *warned, true) {
                warn!(
                    "Penumbra: buffer dump of {}×{} pixels, {layers} lights ({bytes} bytes) \
                     exceeds the device's storage-buffer limit: not dumped",
                    size.x, size.y
                );
            }
            commands.entity(entity).remove::<ViewBufferDump>();
            continue;
        }
        let output = allocations.sized_buffer(
            &device,
            "penumbra_buffer_dump",
            bytes,
            BufferUsages::STORAGE | BufferUsages::COPY_SRC,
        );
        let staging = allocations.sized_buffer(
            &device,
            "penumbra_buffer_dump_staging",
            bytes,
            BufferUsages::MAP_READ | BufferUsages::COPY_DST,
        );
        commands.entity(entity).insert(ViewBufferDump {
            size,
            layers,
            ao,
            face,
            output,
            staging,
            uniform: UniformBuffer::default(),
            bind_group: None,
            active: false,
            lights: Vec::new(),
            ao_dumped: AoPlanes::None,
            face_dumped: false,
            copied: Arc::default(),
            busy: Arc::default(),
        });
    }
}

/// Writes each dumping view's uniform and binds its inputs for this frame.
#[allow(clippy::type_complexity, reason = "a Bevy system")]
fn prepare_buffer_dump_bind_groups(
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    allocations: Res<PenumbraGpuAllocations>,
    pipeline: Option<Res<BufferDumpPipeline>>,
    // Its white mask layer is bound for views without masks.
    lighting: Option<Res<PenumbraLightingPipeline>>,
    pipeline_cache: Res<PipelineCache>,
    mut views: Query<(
        &ExtractedView,
        &ViewPrepassTextures,
        Option<&DeferredMsaaTextures>,
        Option<&PenumbraLightingInputs>,
        Option<&PenumbraAoInput>,
        Option<&ScreenSpaceAmbientOcclusionResources>,
        Option<&ViewFaceNormalTexture>,
        &mut ViewBufferDump,
        Has<PenumbraBufferDump>,
    )>,
) {
    let (Some(pipeline), Some(lighting)) = (pipeline, lighting) else {
        return;
    };
    for (view, prepass, msaa, inputs, dfao, ssao, face, mut dump, asked) in &mut views {
        dump.active = false;
        // Deferred MSAA: the representative sample of each pixel.
        let (depth, gbuffer) = pixel_prepass(prepass, msaa);
        // No longer asked for: the buffers are kept (pooled), the pass does not run.
        let (true, Some(depth)) = (asked, depth) else {
            continue;
        };
        let has_gbuffer = gbuffer.is_some();
        let face = face.filter(|_| dump.face);
        let gbuffer = gbuffer.unwrap_or(&pipeline.no_gbuffer);
        let masks = inputs.filter(|i| i.lights.len() as u32 == dump.layers);
        // DFAO's planes, else (a camera with Bevy's SSAO only) SSAO's visibility.
        let ao = match (dfao, ssao) {
            _ if !dump.ao => None,
            (Some(a), _) => Some((AoPlanes::Dfao, &a.texture)),
            (None, Some(s)) => Some((
                AoPlanes::Ssao,
                &s.screen_space_ambient_occlusion_texture.default_view,
            )),
            (None, None) => None,
        };
        let uniform = DumpView {
            view_from_clip: view.clip_from_view.inverse(),
            size: UVec4::new(
                dump.size.x,
                dump.size.y,
                masks.map_or(0, |_| dump.layers),
                u32::from(has_gbuffer),
            ),
            ao: UVec4::new(u32::from(ao.is_some()), u32::from(face.is_some()), 0, 0),
        };
        let dump = &mut *dump;
        dump.face_dumped = face.is_some();
        dump.uniform.set(uniform);
        dump.uniform.write_buffer(&device, &queue);
        dump.lights = masks.map_or_else(Vec::new, |m| {
            m.lights.iter().map(|l| l.light.id()).collect()
        });
        dump.ao_dumped = ao.map_or(AoPlanes::None, |(planes, _)| planes);
        let mask_view = masks.map_or(&lighting.no_masks, |m| &m.masks);
        let ao_view = ao.map_or(&lighting.no_ao, |(_, texture)| texture);
        let face_view = face.map_or(&lighting.no_ao, |f| &f.normal.default_view);
        let (Some(uniform), Some(uniform_buffer)) = (dump.uniform.binding(), dump.uniform.buffer())
        else {
            continue;
        };
        let key = (
            depth.id(),
            gbuffer.id(),
            mask_view.id(),
            uniform_buffer.id(),
            ao_view.id(),
            face_view.id(),
        );
        if dump.bind_group.as_ref().is_none_or(|(k, _)| *k != key) {
            let bind_group = allocations.bind_group(
                &device,
                "penumbra_buffer_dump",
                &pipeline_cache.get_bind_group_layout(&pipeline.layout),
                &BindGroupEntries::sequential((
                    depth,
                    gbuffer,
                    mask_view,
                    uniform,
                    dump.output.as_entire_binding(),
                    ao_view,
                    face_view,
                )),
            );
            dump.bind_group = Some((key, bind_group));
        }
        dump.active = true;
    }
}

/// The dump pass: copies the view's buffers into the output and the output into the
/// staging buffer (unless that is still being read). Dispatches only.
fn penumbra_buffer_dump(
    view: ViewQuery<&ViewBufferDump>,
    pipeline: Option<Res<BufferDumpPipeline>>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let dump = view.into_inner();
    let (Some(pipeline), true, Some((_, bind_group))) =
        (pipeline, dump.active, dump.bind_group.as_ref())
    else {
        return;
    };
    let Some(compute) = pipeline_cache.get_compute_pipeline(pipeline.pipeline) else {
        return;
    };
    if dump.busy.load(Ordering::Acquire) {
        return;
    }
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_buffer_dump");
    let encoder = ctx.command_encoder();
    {
        let mut pass = encoder.begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_buffer_dump"),
            timestamp_writes: None,
        });
        pass.set_pipeline(compute);
        pass.set_bind_group(0, bind_group, &[]);
        pass.dispatch_workgroups(dump.size.x.div_ceil(8), dump.size.y.div_ceil(8), 1);
    }
    encoder.copy_buffer_to_buffer(&dump.output, 0, &dump.staging, 0, dump.output.size());
    time_span.end(ctx.command_encoder());
    dump.copied.store(true, Ordering::Release);
}

/// After the frame is submitted: maps the staging buffers copied this frame; the
/// callback sends the values to the main world.
fn map_buffer_dumps(views: Query<(&MainEntity, &ViewBufferDump)>, sender: Res<DumpSender>) {
    for (camera, dump) in &views {
        if !dump.copied.swap(false, Ordering::AcqRel) {
            continue;
        }
        dump.busy.store(true, Ordering::Release);
        let staging = dump.staging.clone();
        let busy = dump.busy.clone();
        let sender = sender.0.clone();
        let (camera, size, lights, ao, face) = (
            camera.id(),
            dump.size,
            dump.lights.clone(),
            dump.ao_dumped,
            dump.face_dumped,
        );
        dump.staging
            .slice(..)
            .map_async(MapMode::Read, move |result| {
                if result.is_ok() {
                    let data = {
                        let bytes = staging.slice(..).get_mapped_range();
                        bytes
                            .chunks_exact(4)
                            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                            .collect()
                    };
                    staging.unmap();
                    // The main world may be gone (app exit): nothing to do then.
                    let _ = sender.send(RawDump {
                        camera,
                        size,
                        lights,
                        ao,
                        face,
                        data,
                    });
                }
                busy.store(false, Ordering::Release);
            });
    }
}
