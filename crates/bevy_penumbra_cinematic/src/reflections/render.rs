//! Render-world side of billboard reflections: the billboards' buffer and texture array
//! (uploaded when they change), each reflecting view's layer texture, pipeline and bind
//! group, and the trace draw before Penumbra's lighting pass.

use super::spheres::{SPHERE_BYTES, SpheresPipeline, ViewCasterSpheres};
use super::upload::{
    ReflectionGpuScene, ReflectionImageUploads, extract_reflection_scene, prepare_reflection_scene,
};
use super::{BillboardReflections, ReflectionDebugView};
use bevy::camera::visibility::RenderLayers;
use bevy::core_pipeline::schedule::Core3d;
use bevy::pbr::{MeshPipelineKey, MeshViewBindGroup, ViewKeyCache};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::binding_types::{
    sampler, storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_2d_array,
    texture_3d, texture_depth_2d, uniform_buffer_sized,
};
use bevy::render::render_resource::encase::UniformBuffer as EncaseBuffer;
use bevy::render::render_resource::{
    AddressMode, BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries,
    Buffer, BufferDescriptor, BufferId, BufferUsages, CachedRenderPipelineId, ColorTargetState,
    ColorWrites, Extent3d, FilterMode, LoadOp, MipmapFilterMode, Operations, PipelineCache,
    RenderPassColorAttachment, RenderPassDescriptor, RenderPipelineDescriptor, Sampler,
    SamplerBindingType, SamplerDescriptor, ShaderStages, ShaderType, StoreOp, TextureDescriptor,
    TextureDimension, TextureFormat, TextureSampleType, TextureUsages, TextureView, TextureViewId,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::sync_component::{SyncComponent, SyncComponentPlugin};
use bevy::render::sync_world::RenderEntity;
use bevy::render::texture::{CachedTexture, TextureCache};
use bevy::render::view::{ExtractedView, ViewTarget};
use bevy::render::{Extract, ExtractSchedule, Render, RenderStartup, RenderSystems};
use bevy_penumbra_df::lighting::{
    DeferredMsaaTextures, PenumbraLightingPipeline, PenumbraLightingSystems, PenumbraLightingView,
    PenumbraSpecularLayer,
};
use bevy_penumbra_df::scene::DistanceFieldGpu;
use bevy_penumbra_df::system_times::timed;
use bevy_penumbra_df::{PenumbraGpuAllocations, PenumbraShaderLibrary};
use penumbra_cinematic_core::reflections::cull::TILE;
use penumbra_cinematic_core::reflections::grid::grid_words;
use penumbra_cinematic_core::reflections::pass::{GpuBillboard, ReflectionUniform};
use penumbra_df_core::cull::CameraOrigin;
use std::num::NonZeroU64;

/// The layer texture's format.
const LAYER_FORMAT: TextureFormat = TextureFormat::Rgba16Float;
/// The tile cull's target (one texel per tile; the lists are its output).
const CULL_FORMAT: TextureFormat = TextureFormat::R8Unorm;
/// Most billboards one tile's list holds (more: the tile tests every billboard).
const MAX_TILE_CAPACITY: u32 = 128;
/// Most shadow casters one tile's list holds (more: the tile's pixels gather from every
/// object).
const MAX_TILE_CASTERS: u32 = 128;

/// A reflecting camera's settings in the render world (clamped).
#[derive(Component, Clone, Debug)]
pub struct ExtractedBillboardReflections(BillboardReflections);

impl SyncComponent for BillboardReflections {
    type Target = (
        ExtractedBillboardReflections,
        ViewReflections,
        ViewReflectionsBindGroup,
        PenumbraSpecularLayer,
    );
}

pub(super) fn sync_plugin() -> SyncComponentPlugin<BillboardReflections> {
    SyncComponentPlugin::default()
}

/// A reflecting view's draws this frame (absent: none).
#[derive(Component)]
pub struct ViewReflections {
    pipeline: CachedRenderPipelineId,
    layer: CachedTexture,
    /// The tile cull's pipeline and target (`None`: no tile culling).
    cull: Option<(CachedRenderPipelineId, CachedTexture)>,
    /// The trace's image size, pixels.
    trace_size: UVec2,
}

/// What a group 2 binds: the uniform, billboard, object, tile-list and sphere buffers;
/// the array, atlas and brick table.
type BoundResources = ([BufferId; 5], [TextureViewId; 3]);

/// A reflecting view's uniform and group 2 (remade when a bound resource changes).
#[derive(Component)]
pub struct ViewReflectionsBindGroup {
    uniform: Buffer,
    /// The tiles' billboard lists and their size in words.
    tile_lists: Buffer,
    tile_words: u64,
    /// The caster spheres' buffer and pass.
    spheres: ViewCasterSpheres,
    group: Option<(BindGroup, BoundResources)>,
    /// Deferred MSAA views: group 3, the representative depth and G-buffer of each pixel
    /// (the single-sample ones the trace reads; Bevy's are multisampled there).
    pixel_group: Option<(BindGroup, [TextureViewId; 2])>,
}

/// Bytes of one distance-field object record.
pub(super) const OBJECT_BYTES: u64 = 128;

/// The trace's group 2, shader and sampler, and its pipelines per view key.
#[derive(Resource)]
pub(super) struct ReflectionPipelines {
    layout: BindGroupLayoutDescriptor,
    /// Group 3 of deferred MSAA views: the representative depth and G-buffer.
    pixel_layout: BindGroupLayoutDescriptor,
    shader: Handle<Shader>,
    cull_shader: Handle<Shader>,
    sampler: Sampler,
    /// Bound while the scene has no distance-field objects: one free record, one voxel.
    no_objects: Buffer,
    no_atlas: TextureView,
    /// Bound while no volume is placed as bricks.
    no_brick_table: TextureView,
    queued: HashMap<(MeshPipelineKey, bool), CachedRenderPipelineId>,
    /// The caster spheres' pass (reflection shadows).
    spheres: SpheresPipeline,
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .init_resource::<ReflectionGpuScene>()
        .init_resource::<ReflectionImageUploads>()
        .add_systems(RenderStartup, init_reflection_pipelines)
        .add_systems(
            ExtractSchedule,
            (
                timed(extract_reflection_scene),
                timed(extract_reflection_cameras),
            ),
        )
        .add_systems(
            Render,
            (
                (
                    timed(prepare_reflection_scene),
                    timed(prepare_reflection_views),
                )
                    .chain()
                    .in_set(RenderSystems::PrepareResources),
                timed(prepare_reflection_bind_groups).in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(
            Core3d,
            timed(billboard_reflections).in_set(PenumbraLightingSystems::Specular),
        );
}

fn init_reflection_pipelines(
    mut commands: Commands,
    library: Option<Res<PenumbraShaderLibrary>>,
    device: Res<RenderDevice>,
    pipeline_cache: Res<PipelineCache>,
) {
    let Some(library) = library else {
        warn!("Penumbra: the shader library is not registered; no billboard reflections");
        return;
    };
    let layout = BindGroupLayoutDescriptor::new(
        "penumbra_reflections_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::FRAGMENT,
            (
                uniform_buffer_sized(false, Some(ReflectionUniform::min_size())),
                storage_buffer_read_only_sized(false, Some(GpuBillboard::min_size())),
                texture_2d_array(TextureSampleType::Float { filterable: true }),
                sampler(SamplerBindingType::Filtering),
                storage_buffer_read_only_sized(false, NonZeroU64::new(OBJECT_BYTES)),
                texture_3d(TextureSampleType::Float { filterable: false }),
                storage_buffer_sized(false, NonZeroU64::new(4)),
                storage_buffer_read_only_sized(false, NonZeroU64::new(SPHERE_BYTES)),
                texture_2d(TextureSampleType::Uint),
            ),
        ),
    );
    let pixel_layout = BindGroupLayoutDescriptor::new(
        "penumbra_reflections_pixel_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::FRAGMENT,
            (texture_depth_2d(), texture_2d(TextureSampleType::Uint)),
        ),
    );
    let sampler = device.create_sampler(&SamplerDescriptor {
        label: Some("penumbra_reflections_sampler"),
        address_mode_u: AddressMode::ClampToEdge,
        address_mode_v: AddressMode::ClampToEdge,
        mag_filter: FilterMode::Linear,
        min_filter: FilterMode::Linear,
        mipmap_filter: MipmapFilterMode::Linear,
        ..default()
    });
    let no_objects = device.create_buffer(&BufferDescriptor {
        label: Some("penumbra_reflections_no_objects"),
        size: OBJECT_BYTES,
        usage: BufferUsages::STORAGE,
        mapped_at_creation: false,
    });
    let no_atlas = bevy_penumbra_df::shader_library::empty_atlas(&device);
    commands.insert_resource(ReflectionPipelines {
        layout,
        pixel_layout,
        shader: library.handle("reflections/trace.wgsl"),
        cull_shader: library.handle("reflections/cull.wgsl"),
        sampler,
        no_objects,
        no_atlas,
        no_brick_table: bevy_penumbra_df::shader_library::empty_brick_table(&device),
        queued: HashMap::default(),
        spheres: SpheresPipeline::new(&pipeline_cache, library.handle("reflections/spheres.wgsl")),
    });
}

fn extract_reflection_cameras(
    mut commands: Commands,
    cameras: Extract<Query<(RenderEntity, &BillboardReflections)>>,
) {
    for (entity, settings) in &cameras {
        if let Ok(mut render) = commands.get_entity(entity) {
            render.insert(ExtractedBillboardReflections(settings.resolve().0));
        }
    }
}

impl ReflectionPipelines {
    /// The trace (or, with `cull`, the tile cull) pipeline of a view key, queued on
    /// first use: Penumbra's lighting pipeline (Bevy's view bind groups for the key) with
    /// the pass's shader, group 2 and target, and no depth test. A multisampled key
    /// (deferred MSAA) reads each pixel's representative depth and G-buffer from group 3.
    fn get(
        &mut self,
        cache: &PipelineCache,
        lighting: &PenumbraLightingPipeline,
        key: MeshPipelineKey,
        cull: bool,
    ) -> CachedRenderPipelineId {
        *self.queued.entry((key, cull)).or_insert_with(|| {
            let (label, shader, entry, format) = if cull {
                (
                    "penumbra_reflections_cull_pipeline",
                    &self.cull_shader,
                    "cull",
                    CULL_FORMAT,
                )
            } else {
                (
                    "penumbra_reflections_pipeline",
                    &self.shader,
                    "fragment",
                    LAYER_FORMAT,
                )
            };
            let mut desc: RenderPipelineDescriptor = lighting.view_descriptor(key);
            desc.label = Some(label.into());
            desc.layout[2] = self.layout.clone();
            desc.depth_stencil = None;
            desc.vertex.shader = shader.clone();
            if key.msaa_samples() > 1 {
                desc.layout.push(self.pixel_layout.clone());
                for def in ["MULTISAMPLED", "PENUMBRA_PIXEL_PREPASS"] {
                    desc.vertex.shader_defs.push(def.into());
                    if let Some(fragment) = desc.fragment.as_mut() {
                        fragment.shader_defs.push(def.into());
                    }
                }
            }
            let fragment = desc.fragment.as_mut().expect("the lighting pass has one");
            fragment.shader = shader.clone();
            fragment.entry_point = Some(entry.into());
            fragment.targets = vec![Some(ColorTargetState {
                format,
                blend: None,
                write_mask: ColorWrites::ALL,
            })];
            cache.queue_render_pipeline(desc)
        })
    }
}

/// Per Penumbra view with [`BillboardReflections`]: while billboards exist, its layer
/// texture (full or half size, from the `TextureCache`) and pipeline, and the
/// `PenumbraSpecularLayer` the lighting pass reads.
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
fn prepare_reflection_views(
    mut commands: Commands,
    views: Query<(
        Entity,
        &ExtractedView,
        &PenumbraLightingView,
        &ViewTarget,
        Option<&ExtractedBillboardReflections>,
        Option<&ViewReflectionsBindGroup>,
        Has<ViewReflections>,
    )>,
    gpu: Res<ReflectionGpuScene>,
    view_key_cache: Res<ViewKeyCache>,
    lighting: Option<Res<PenumbraLightingPipeline>>,
    pipelines: Option<ResMut<ReflectionPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut texture_cache: ResMut<TextureCache>,
    device: Res<RenderDevice>,
) {
    let (Some(lighting), Some(mut pipelines)) = (lighting, pipelines) else {
        return;
    };
    let scene_ready = !gpu.billboards.is_empty() && gpu.array.is_some();
    for (entity, view, _, target, settings, group, drawn) in &views {
        let key = view_key_cache.get(&view.retained_view_entity);
        let (Some(key), Some(settings), true) = (key, settings, scene_ready) else {
            if drawn {
                commands
                    .entity(entity)
                    .remove::<(ViewReflections, PenumbraSpecularLayer)>();
            }
            continue;
        };
        let settings = &settings.0;
        let size = target.main_texture().size();
        let (width, height) = if settings.half_resolution {
            (size.width.div_ceil(2), size.height.div_ceil(2))
        } else {
            (size.width, size.height)
        };
        let layer = texture_cache.get(
            &device,
            TextureDescriptor {
                label: Some("penumbra_reflection_layer"),
                size: Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: TextureDimension::D2,
                format: LAYER_FORMAT,
                usage: TextureUsages::RENDER_ATTACHMENT | TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            },
        );
        let pipeline = pipelines.get(&pipeline_cache, &lighting, *key, false);
        let tiles = UVec2::new(width.div_ceil(TILE), height.div_ceil(TILE));
        let cull = settings.tile_culling.then(|| {
            let target = texture_cache.get(
                &device,
                TextureDescriptor {
                    label: Some("penumbra_reflection_tiles"),
                    size: Extent3d {
                        width: tiles.x,
                        height: tiles.y,
                        depth_or_array_layers: 1,
                    },
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: TextureDimension::D2,
                    format: CULL_FORMAT,
                    usage: TextureUsages::RENDER_ATTACHMENT,
                    view_formats: &[],
                },
            );
            (
                pipelines.get(&pipeline_cache, &lighting, *key, true),
                target,
            )
        });
        // The lighting pass reads the layer only once the trace can write it: its
        // pipeline compiled and its group 2 made (from the view's second frame).
        let traced = pipeline_cache.get_render_pipeline(pipeline).is_some()
            && cull
                .as_ref()
                .is_none_or(|(id, _)| pipeline_cache.get_render_pipeline(*id).is_some())
            && group.is_some_and(|g| g.group.is_some());
        let mut view = commands.entity(entity);
        if traced {
            view.insert(PenumbraSpecularLayer {
                texture: layer.default_view.clone(),
                half_resolution: settings.half_resolution,
                debug_view: settings.debug_view == ReflectionDebugView::Layer,
            });
        } else {
            view.remove::<PenumbraSpecularLayer>();
        }
        view.insert(ViewReflections {
            pipeline,
            layer,
            cull,
            trace_size: UVec2::new(width, height),
        });
    }
}

/// Writes each reflecting view's uniform; remakes its group 2 when the billboards'
/// buffer or the array changed.
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
fn prepare_reflection_bind_groups(
    mut commands: Commands,
    mut views: Query<(
        Entity,
        &ExtractedView,
        &ExtractedBillboardReflections,
        &ViewReflections,
        Option<&mut ViewReflectionsBindGroup>,
        Option<&RenderLayers>,
        Option<&DeferredMsaaTextures>,
    )>,
    gpu: Res<ReflectionGpuScene>,
    df: Option<Res<DistanceFieldGpu>>,
    pipelines: Option<Res<ReflectionPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    let (Some(pipelines), Some((buffer, _)), Some(array), Some(images)) =
        (pipelines, &gpu.buffer, &gpu.array, &gpu.images)
    else {
        return;
    };
    // The distance-field scene, or placeholders (no reflection shadows).
    let (objects, object_count, df_atlas, brick_table) = match df.as_deref() {
        Some(DistanceFieldGpu {
            objects: Some(objects),
            slot_count,
            atlas,
            brick_table,
            ..
        }) => (
            objects,
            *slot_count,
            atlas
                .as_ref()
                .map_or(&pipelines.no_atlas, |(_, view, _)| view),
            brick_table
                .as_ref()
                .map_or(&pipelines.no_brick_table, |(_, view, _)| view),
        ),
        _ => (
            &pipelines.no_objects,
            0,
            &pipelines.no_atlas,
            &pipelines.no_brick_table,
        ),
    };
    let count = gpu.billboards.len() as u32;
    for (entity, view, settings, draw, group, view_layers, msaa) in &mut views {
        let s = &settings.0;
        // The billboards' layer groups this camera sees (Bevy's default: layer 0).
        let view_layers = view_layers.cloned().unwrap_or_default();
        let view_layer_bits = gpu
            .groups
            .iter()
            .enumerate()
            .filter(|(_, g)| g.intersects(&view_layers))
            .fold(0u32, |bits, (i, _)| bits | 1 << i);
        let origin = CameraOrigin::at(view.world_from_view.translation());
        // Tile lists: a count and `capacity` indices per tile.
        let tiles = UVec2::new(
            draw.trace_size.x.div_ceil(TILE),
            draw.trace_size.y.div_ceil(TILE),
        );
        let capacity = if draw.cull.is_some() {
            count.min(MAX_TILE_CAPACITY)
        } else {
            0
        };
        // Far from the tile range (or a NaN camera): no shadows.
        let object_count = if origin.is_some() { object_count } else { 0 };
        let shadow_steps = if s.reflection_shadows {
            s.shadow_steps
        } else {
            0
        };
        // With reflection shadows, the cull lists each tile's casters too.
        let caster_capacity = if capacity > 0 && shadow_steps > 0 {
            object_count.min(MAX_TILE_CASTERS)
        } else {
            0
        };
        let record = capacity
            + 1
            + if caster_capacity > 0 {
                caster_capacity + 1
            } else {
                0
            };
        let tile_words = u64::from(tiles.x * tiles.y) * u64::from(record);
        // More casters than a tile's list holds: the caster grid after the tiles' records
        // (where a tile's list overflows or is long, its pixels gather from it).
        let grid = (caster_capacity > 0 && object_count > MAX_TILE_CASTERS)
            .then(|| u32::try_from(tile_words).ok())
            .flatten();
        let words = tile_words + grid.map_or(0, |_| grid_words(object_count));
        let lists = |words: u64| {
            allocations.sized_buffer(
                &device,
                "penumbra_reflection_tile_lists",
                words.next_power_of_two().max(4) * 4,
                BufferUsages::STORAGE | BufferUsages::COPY_DST,
            )
        };
        let mut fresh = None;
        let group = match group {
            Some(group) => group.into_inner(),
            None => fresh.insert(ViewReflectionsBindGroup {
                uniform: allocations.sized_buffer(
                    &device,
                    "penumbra_reflections_uniform",
                    ReflectionUniform::min_size().get(),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                tile_lists: lists(words),
                tile_words: words.next_power_of_two().max(4),
                spheres: ViewCasterSpheres::new(&allocations, &device, 1),
                group: None,
                pixel_group: None,
            }),
        };
        if group.tile_words < words {
            group.tile_lists = lists(words);
            group.tile_words = words.next_power_of_two().max(4);
        }
        let uniform = ReflectionUniform {
            max_layers: s.max_layers,
            max_distance: s.max_distance,
            anisotropy: s.anisotropy,
            half_resolution: u32::from(s.half_resolution),
            camera_tile: origin.map_or(IVec3::ZERO, |o| IVec3::from_array(o.tile)),
            camera_offset: origin.map_or(Vec3::ZERO, |o| o.offset),
            object_count,
            shadow_steps,
            shadow_softness: s.shadow_softness,
            tiles_x: tiles.x,
            tile_capacity: capacity,
            caster_capacity,
            trace_size: draw.trace_size,
            view_layers: view_layer_bits,
            caster_grid: grid.unwrap_or(0),
            ..ReflectionUniform::new(count, images.size, gpu.mip_count)
        };
        let mut bytes = EncaseBuffer::new(Vec::new());
        bytes
            .write(&uniform)
            .expect("the reflection uniform encodes");
        queue.write_buffer(&group.uniform, 0, bytes.as_ref());
        // The casters' spheres, with reflection shadows.
        group.spheres.prepare(
            &allocations,
            &device,
            &pipeline_cache,
            &pipelines.spheres,
            (&group.uniform, objects, &group.tile_lists),
            if shadow_steps > 0 { object_count } else { 0 },
            grid,
        );
        let key = (
            [
                group.uniform.id(),
                buffer.id(),
                objects.id(),
                group.tile_lists.id(),
                group.spheres.buffer.id(),
            ],
            [array.id(), df_atlas.id(), brick_table.id()],
        );
        if group.group.as_ref().map(|(_, k)| k) != Some(&key) {
            let bind_group = allocations.bind_group(
                &device,
                "penumbra_reflections_bind_group",
                &pipeline_cache.get_bind_group_layout(&pipelines.layout),
                &BindGroupEntries::sequential((
                    group.uniform.as_entire_binding(),
                    buffer.as_entire_binding(),
                    array,
                    &pipelines.sampler,
                    objects.as_entire_binding(),
                    df_atlas,
                    group.tile_lists.as_entire_binding(),
                    group.spheres.buffer.as_entire_binding(),
                    brick_table,
                )),
            );
            group.group = Some((bind_group, key));
        }
        let pixel = msaa.map(|m| (&m.pixel_depth.default_view, &m.pixel_gbuffer.default_view));
        let pixel_key = pixel.map(|(depth, gbuffer)| [depth.id(), gbuffer.id()]);
        if group.pixel_group.as_ref().map(|(_, k)| *k) != pixel_key {
            group.pixel_group = pixel.zip(pixel_key).map(|((depth, gbuffer), key)| {
                let bind_group = allocations.bind_group(
                    &device,
                    "penumbra_reflections_pixel_bind_group",
                    &pipeline_cache.get_bind_group_layout(&pipelines.pixel_layout),
                    &BindGroupEntries::sequential((depth, gbuffer)),
                );
                (bind_group, key)
            });
        }
        if let Some(fresh) = fresh {
            commands.entity(entity).insert(fresh);
        }
    }
}

/// The tile cull (one fragment per tile writes its billboard list), then the trace
/// (one fullscreen draw into the view's layer texture), before Penumbra's lighting pass
/// reads it.
pub fn billboard_reflections(
    view: ViewQuery<(
        &ViewReflections,
        &MeshViewBindGroup,
        Option<&ViewReflectionsBindGroup>,
    )>,
    pipeline_cache: Res<PipelineCache>,
    pipelines: Option<Res<ReflectionPipelines>>,
    mut ctx: RenderContext,
) {
    let (draw, mesh_view, view_group) = view.into_inner();
    let (Some(pipeline), Some(view_group), Some(pipelines)) = (
        pipeline_cache.get_render_pipeline(draw.pipeline),
        view_group,
        pipelines,
    ) else {
        return; // compiling, or the first frame
    };
    let Some((group, _)) = view_group.group.as_ref() else {
        return;
    };
    // Deferred MSAA views' pipelines read the pixels' representative prepass (group 3).
    let pixel_group = view_group.pixel_group.as_ref().map(|(g, _)| g);
    let Some(spheres) = view_group
        .spheres
        .ready(&pipeline_cache, &pipelines.spheres)
    else {
        return; // compiling
    };
    let cull = match &draw.cull {
        Some((id, target)) => match pipeline_cache.get_render_pipeline(*id) {
            Some(cull) => Some((cull, target)),
            None => return, // compiling
        },
        None => None,
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_billboard_reflections");
    if spheres {
        view_group
            .spheres
            .dispatch(ctx.command_encoder(), &pipeline_cache, &pipelines.spheres);
    }
    if let Some((cull, target)) = cull {
        let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
            label: Some("penumbra_reflection_tile_cull"),
            color_attachments: &[Some(RenderPassColorAttachment {
                view: &target.default_view,
                depth_slice: None,
                resolve_target: None,
                ops: Operations {
                    load: LoadOp::Clear(default()),
                    store: StoreOp::Discard,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_render_pipeline(cull);
        pass.set_bind_group(0, &mesh_view.main, &mesh_view.main_offsets);
        pass.set_bind_group(1, &mesh_view.binding_array, &[]);
        pass.set_bind_group(2, group, &[]);
        if let Some(pixel_group) = pixel_group {
            pass.set_bind_group(3, pixel_group, &[]);
        }
        pass.draw(0..3, 0..1);
    }
    let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
        label: Some("penumbra_billboard_reflections"),
        color_attachments: &[Some(RenderPassColorAttachment {
            view: &draw.layer.default_view,
            depth_slice: None,
            resolve_target: None,
            ops: Operations {
                load: LoadOp::Clear(default()),
                store: StoreOp::Store,
            },
        })],
        depth_stencil_attachment: None,
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    pass.set_render_pipeline(pipeline);
    pass.set_bind_group(0, &mesh_view.main, &mesh_view.main_offsets);
    pass.set_bind_group(1, &mesh_view.binding_array, &[]);
    pass.set_bind_group(2, group, &[]);
    if let Some(pixel_group) = pixel_group {
        pass.set_bind_group(3, pixel_group, &[]);
    }
    pass.draw(0..3, 0..1);
    drop(pass);
    time_span.end(ctx.command_encoder());
}
