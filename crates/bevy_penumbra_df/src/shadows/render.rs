//! Render-world side of distance-field shadows: per-view mask textures and pooled buffers (`resources`), and the light-cull, grid and
//! mask passes.

use super::DistanceFieldShadows;
use super::msaa::{SampleMasks, SampleTraceInputs, layer_views, queue_sample_trace};
use super::resources::{
    CULL_VIEW_BYTES, DistanceFieldShadowResources, ShadowViewParams, UPSAMPLE_VIEW_BYTES,
    ViewTextures,
};
use crate::face_normals::ViewFaceNormalTexture;
use crate::gpu_allocations::PenumbraGpuAllocations;
use crate::lighting::msaa_render::{DeferredMsaaTextures, pixel_prepass};
use crate::lighting::{
    PenumbraLightingInputs, PenumbraLightingView, PenumbraShadowedLight, ShadowedLightKind,
};
use crate::scene::{DistanceFieldGpu, GpuHeightfields};
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::core_pipeline::schedule::Core3d;
use bevy::pbr::{
    ExtractedDirectionalLight, ExtractedPointLight, GlobalClusterableObjectMeta, prepare_lights,
};
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_3d,
    texture_storage_2d, uniform_buffer_sized,
};
use bevy::render::render_resource::{
    BindGroupLayoutDescriptor, BindGroupLayoutEntries, CachedComputePipelineId,
    ComputePassDescriptor, Extent3d, PipelineCache, ShaderStages, StorageTextureAccess, Texture,
    TextureDescriptor, TextureDimension, TextureFormat, TextureSampleType, TextureUsages,
    TextureView, TextureViewDescriptor, TextureViewDimension,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::sync_world::MainEntity;
use bevy::render::view::ExtractedView;
use bevy::render::{ExtractSchedule, Render, RenderStartup, RenderSystems};
use penumbra_df_core::cull::{CameraOrigin, Frustum, grid_64};
use penumbra_df_core::object::{tile_of, tile_relative};
use penumbra_df_core::shadow::{
    SHADOW_GRID_BYTES, SHADOW_GRID_VIEW_BYTES, SHADOW_LIGHT_BYTES, SHADOW_TRACE_VIEW_BYTES,
    ShadowLight, ShadowLightKind, TRACE_FACE_NORMALS, TRACE_GBUFFER_NORMALS, half_size,
};
use std::num::NonZeroU64;

/// One distance-field-shadowed light this frame (render world).
#[derive(Clone, Debug)]
pub struct DistanceFieldShadowedLight {
    kind: FrameLightKind,
    /// The light's main-world entity.
    light: MainEntity,
    pub(super) settings: DistanceFieldShadows,
}

#[derive(Clone, Copy, Debug)]
enum FrameLightKind {
    /// Unit vector toward the light.
    Directional(Vec3),
    /// World position, source radius, range, clustered light id; for spot lights the
    /// direction the spot points and the cosine of its outer angle.
    Positional {
        position: Vec3,
        radius: f32,
        range: f32,
        light_id: u32,
        spot: Option<(Vec3, f32)>,
    },
}

impl DistanceFieldShadowedLight {
    /// Whether it is a directional light.
    pub(super) fn is_directional(&self) -> bool {
        matches!(self.kind, FrameLightKind::Directional(_))
    }

    /// Which light it is, as Bevy's shaders name it: a directional light by its
    /// direction, a point or spot light by its clustered id.
    pub fn kind(&self) -> ShadowedLightKind {
        match self.kind {
            FrameLightKind::Directional(direction) => ShadowedLightKind::Directional { direction },
            FrameLightKind::Positional { light_id, .. } => {
                ShadowedLightKind::Clustered { light_id }
            }
        }
    }

    /// Point and spot lights: world position and range (the farthest point they light).
    pub fn reach(&self) -> Option<(Vec3, f32)> {
        match self.kind {
            FrameLightKind::Directional(_) => None,
            FrameLightKind::Positional {
                position, range, ..
            } => Some((position, range)),
        }
    }

    /// The light as the passes see it from a camera (or any origin) at `camera`;
    /// `None` for a light beyond the tile range.
    pub fn shadow_light(&self, camera: &CameraOrigin) -> Option<ShadowLight> {
        let (s, _) = self.settings.resolve();
        let (kind, source, range, spot) = match self.kind {
            FrameLightKind::Directional(d) => (
                ShadowLightKind::Directional(d),
                (0.5 * s.angular_diameter).tan(),
                0.0,
                None,
            ),
            FrameLightKind::Positional {
                position,
                radius,
                range,
                spot,
                ..
            } => {
                let tile = tile_of(position)?;
                let relative = camera.relative(tile, tile_relative(position, tile));
                (
                    ShadowLightKind::Positional(relative),
                    radius.max(0.0),
                    range,
                    spot,
                )
            }
        };
        Some(ShadowLight {
            kind,
            source,
            max_distance: s.max_distance,
            bias: s.bias,
            shaping: s.shaping,
            range,
            max_steps: s.max_steps,
            max_view_distance: s.max_view_distance,
            spot,
        })
    }
}

/// This frame's distance-field-shadowed lights (render world, filled in
/// `RenderSystems::PrepareResources`), in mask-layer order: point and spot lights only
/// while Bevy clusters them (visible). Other features that take these lights'
/// visibility from the distance fields (hair) read it.
#[derive(Resource, Default)]
pub struct DistanceFieldShadowedLights(Vec<DistanceFieldShadowedLight>);

impl DistanceFieldShadowedLights {
    /// The lights, in mask-layer order.
    pub fn lights(&self) -> &[DistanceFieldShadowedLight] {
        &self.0
    }
}

/// A view's mask texture: one `R32Float` layer per shadowed light.
#[derive(Component)]
pub struct DistanceFieldShadowMasks {
    /// All layers, as the lighting pass reads them.
    array: TextureView,
    /// Per layer, a storage view.
    pub(super) layers: Vec<TextureView>,
    size: UVec2,
    /// Half-resolution lights' traces, upsampled into their layer: (storage view,
    /// sampled view), at [`half_size`].
    half: Option<(TextureView, TextureView)>,
    /// Deferred MSAA: the edge pixels' masks per sample.
    samples: Option<SampleMasks>,
}

/// The passes' pipelines.
#[derive(Resource)]
pub(super) struct ShadowPipelines {
    pub(super) cull_layout: BindGroupLayoutDescriptor,
    cull: CachedComputePipelineId,
    pub(super) trace_layout: BindGroupLayoutDescriptor,
    trace: CachedComputePipelineId,
    pub(super) upsample_layout: BindGroupLayoutDescriptor,
    upsample: CachedComputePipelineId,
    /// The per-sample trace of deferred MSAA views (`msaa.rs`), queued for the first.
    pub(super) sample_trace_layout: BindGroupLayoutDescriptor,
    pub(super) sample_trace: Option<CachedComputePipelineId>,
    pub(super) grid_layout: BindGroupLayoutDescriptor,
    /// The light-space grid's passes: reset, bounds, count, scan, fill.
    grid: [CachedComputePipelineId; 5],
    /// Bound when the scene has no SDF volume (analytic casters only).
    empty_atlas: TextureView,
    /// Bound when no volume is placed as bricks.
    empty_brick_table: TextureView,
    /// Bound when the view has no deferred G-buffer (no normals: no own-shadow term).
    empty_gbuffer: TextureView,
    /// Bound for the face normals and their depth when the view has no face-normal
    /// prepass.
    pub(super) empty_face: TextureView,
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .init_resource::<DistanceFieldShadowedLights>()
        .init_resource::<super::consumers::ShadowMapConsumers>()
        .init_resource::<super::consumers::NoShadowMapReaders>()
        .add_systems(
            ExtractSchedule,
            timed(super::consumers::extract_no_shadow_map_readers),
        )
        .add_systems(
            Render,
            (
                timed(super::consumers::skip_unread_shadow_maps)
                    .in_set(RenderSystems::CreateViews)
                    .before(prepare_lights),
                timed(prepare_distance_field_shadows)
                    .in_set(RenderSystems::PrepareResources)
                    .after(crate::scene::DistanceFieldRenderSystems::PrepareGpu),
                timed(prepare_distance_field_shadow_bind_groups)
                    .in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(
            Core3d,
            timed(distance_field_shadows)
                .in_set(crate::lighting::render::PenumbraLightingSystems::Inputs),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(RenderStartup, init_shadow_pipelines);
}

fn init_shadow_pipelines(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    device: Res<RenderDevice>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return; // warned by the scene plugin
    };
    let cull_layout = BindGroupLayoutDescriptor::new(
        "penumbra_df_shadow_cull_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                storage_buffer_read_only_sized(false, None),
                uniform_buffer_sized(false, NonZeroU64::new(CULL_VIEW_BYTES)),
                uniform_buffer_sized(false, NonZeroU64::new(SHADOW_LIGHT_BYTES as u64)),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, None),
            ),
        ),
    );
    let trace_layout = BindGroupLayoutDescriptor::new(
        "penumbra_df_shadow_trace_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                texture_3d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Float { filterable: false }),
                uniform_buffer_sized(false, NonZeroU64::new(SHADOW_TRACE_VIEW_BYTES as u64)),
                uniform_buffer_sized(false, NonZeroU64::new(SHADOW_LIGHT_BYTES as u64)),
                texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
                storage_buffer_read_only_sized(false, NonZeroU64::new(SHADOW_GRID_BYTES as u64)),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                uniform_buffer_sized(false, NonZeroU64::new(SHADOW_GRID_VIEW_BYTES as u64)),
                texture_2d(TextureSampleType::Uint),
                storage_buffer_read_only_sized(false, None),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Uint),
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Float { filterable: false }),
            ),
        ),
    );
    let grid_layout = BindGroupLayoutDescriptor::new(
        "penumbra_df_shadow_grid_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_read_only_sized(false, None),
                uniform_buffer_sized(false, NonZeroU64::new(SHADOW_GRID_VIEW_BYTES as u64)),
                storage_buffer_sized(false, NonZeroU64::new(SHADOW_GRID_BYTES as u64)),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, None),
                storage_buffer_sized(false, NonZeroU64::new(4096)),
            ),
        ),
    );
    let upsample_layout = BindGroupLayoutDescriptor::new(
        "penumbra_df_shadow_upsample_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                texture_2d(TextureSampleType::Float { filterable: false }),
                texture_2d(TextureSampleType::Float { filterable: false }),
                uniform_buffer_sized(false, NonZeroU64::new(UPSAMPLE_VIEW_BYTES)),
                texture_storage_2d(TextureFormat::R32Float, StorageTextureAccess::WriteOnly),
            ),
        ),
    );
    let queue = |label: &'static str,
                 layout: &BindGroupLayoutDescriptor,
                 path: &str,
                 entry: &'static str| {
        library.queue_compute(&pipeline_cache, label, layout, path, entry)
    };
    let cull = queue(
        "penumbra_df_shadow_cull",
        &cull_layout,
        "df/shadow_cull.wgsl",
        "cull",
    );
    let trace = queue(
        "penumbra_df_shadow_trace",
        &trace_layout,
        "df/shadow_trace.wgsl",
        "trace",
    );
    let upsample = queue(
        "penumbra_df_shadow_upsample",
        &upsample_layout,
        "df/shadow_upsample.wgsl",
        "upsample",
    );
    let grid = [
        "grid_reset",
        "grid_bounds",
        "grid_count",
        "grid_scan",
        "grid_fill",
    ]
    .map(|entry| {
        queue(
            "penumbra_df_shadow_grid",
            &grid_layout,
            "df/shadow_grid_build.wgsl",
            entry,
        )
    });
    commands.insert_resource(ShadowPipelines {
        cull_layout,
        cull,
        trace_layout,
        trace,
        upsample_layout,
        upsample,
        sample_trace_layout: super::msaa::sample_trace_layout(),
        sample_trace: None,
        grid_layout,
        grid,
        empty_atlas: crate::shader_library::empty_atlas(&device),
        empty_brick_table: crate::shader_library::empty_brick_table(&device),
        empty_gbuffer: device
            .create_texture(&TextureDescriptor {
                label: Some("penumbra_df_empty_gbuffer"),
                size: Extent3d::default(),
                mip_level_count: 1,
                sample_count: 1,
                dimension: TextureDimension::D2,
                format: TextureFormat::Rgba32Uint,
                usage: TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            })
            .create_view(&TextureViewDescriptor::default()),
        empty_face: device
            .create_texture(&TextureDescriptor {
                label: Some("penumbra_df_empty_face_normals"),
                size: Extent3d::default(),
                mip_level_count: 1,
                sample_count: 1,
                dimension: TextureDimension::D2,
                format: TextureFormat::Rgba16Float,
                usage: TextureUsages::TEXTURE_BINDING,
                view_formats: &[],
            })
            .create_view(&TextureViewDescriptor::default()),
    });
}

/// A Penumbra-lit view's masks and pooled shadow resources, if it has them yet.
type ShadowViewQuery<'a> = (
    Entity,
    &'a ExtractedView,
    &'a PenumbraLightingView,
    Option<&'a DistanceFieldShadowMasks>,
    Option<&'a mut DistanceFieldShadowResources>,
);

/// Collects the frame's shadowed lights; gives every Penumbra-lit view a mask texture
/// and its pooled buffers, and tells its lighting pass which lights read which layer.
/// Without casters or without shadowed lights, views get nothing (and lights stay
/// unshadowed).
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
fn prepare_distance_field_shadows(
    mut commands: Commands,
    device: Res<RenderDevice>,
    allocations: Res<PenumbraGpuAllocations>,
    gpu: Option<Res<DistanceFieldGpu>>,
    clustered: Option<Res<GlobalClusterableObjectMeta>>,
    mut frame: ResMut<DistanceFieldShadowedLights>,
    lights: Query<(
        Entity,
        &MainEntity,
        &DistanceFieldShadows,
        Option<&ExtractedDirectionalLight>,
        Option<&ExtractedPointLight>,
    )>,
    mut views: Query<ShadowViewQuery>,
    mut pipelines: Option<ResMut<ShadowPipelines>>,
    library: Option<Res<PenumbraShaderLibrary>>,
    pipeline_cache: Res<PipelineCache>,
) {
    frame.0.clear();
    let slots = gpu
        .as_ref()
        .filter(|g| g.objects.is_some())
        .map(|g| g.slot_count);
    let mut sorted: Vec<_> = lights.iter().collect();
    sorted.sort_by_key(|(entity, ..)| *entity);
    for (entity, &light, settings, directional, point) in sorted {
        let kind = if let Some(d) = directional {
            FrameLightKind::Directional(d.transform.back().as_vec3())
        } else if let Some(p) = point {
            let Some(id) = clustered
                .as_ref()
                .and_then(|c| c.entity_to_index.get(&entity).copied())
            else {
                continue; // not visible this frame
            };
            FrameLightKind::Positional {
                position: p.transform.translation(),
                radius: p.radius,
                range: p.range,
                light_id: id as u32,
                // Bevy's spot lights point along their forward axis.
                spot: p
                    .spot_light_angles
                    .map(|(_, outer)| (p.transform.forward().as_vec3(), outer.cos())),
            }
        } else {
            continue; // not a light Penumbra shadows
        };
        frame.0.push(DistanceFieldShadowedLight {
            kind,
            light,
            settings: settings.clone(),
        });
    }
    let ready = pipelines.as_ref().is_some_and(|p| {
        pipeline_cache.get_compute_pipeline(p.cull).is_some()
            && pipeline_cache.get_compute_pipeline(p.trace).is_some()
            && pipeline_cache.get_compute_pipeline(p.upsample).is_some()
            && p.grid
                .iter()
                .all(|&g| pipeline_cache.get_compute_pipeline(g).is_some())
    });
    for (entity, view, lighting_view, masks, resources) in &mut views {
        let (Some(slots), true, false) = (slots, ready, frame.0.is_empty()) else {
            // No mask: the lights are unshadowed (their shadow maps are off). Pooled
            // buffers are kept for when they come back.
            commands
                .entity(entity)
                .remove::<(DistanceFieldShadowMasks, PenumbraLightingInputs)>();
            continue;
        };
        // Deferred MSAA: edge pixels traced per sample, once that pass has compiled.
        let sample_trace = match (
            lighting_view.msaa.as_ref().filter(|m| m.sample_occlusion),
            pipelines.as_deref_mut(),
            library.as_deref(),
        ) {
            (Some(_), Some(p), Some(library)) => {
                Some(queue_sample_trace(p, library, &pipeline_cache))
            }
            _ => None,
        };
        let samples =
            sample_trace.is_some_and(|id| pipeline_cache.get_compute_pipeline(id).is_some());
        let size = view.viewport.zw().max(UVec2::ONE);
        let layers = frame.0.len();
        let half = frame.0.iter().any(|l| l.settings.half_resolution);
        let fresh = match masks {
            Some(m)
                if m.size == size
                    && m.layers.len() == layers
                    && m.half.is_some() == half
                    && m.samples.is_some() == samples =>
            {
                None
            }
            _ => Some(create_masks(
                &allocations,
                &device,
                size,
                layers as u32,
                half,
                samples,
            )),
        };
        let Some((array, sample_masks)) = fresh.as_ref().or(masks).map(|m| {
            let samples = m.samples.as_ref().map(|s| s.array.clone());
            (m.array.clone(), samples)
        }) else {
            continue;
        };
        let mut view_entity = commands.entity(entity);
        match resources {
            Some(mut r) => r.fit(&allocations, &device, &frame.0, slots),
            None => {
                let mut r = DistanceFieldShadowResources::new(&allocations, &device);
                r.fit(&allocations, &device, &frame.0, slots);
                view_entity.insert(r);
            }
        }
        let lights = frame
            .0
            .iter()
            .enumerate()
            .map(|(layer, light)| PenumbraShadowedLight {
                kind: match light.kind {
                    FrameLightKind::Directional(direction) => {
                        ShadowedLightKind::Directional { direction }
                    }
                    FrameLightKind::Positional { light_id, .. } => {
                        ShadowedLightKind::Clustered { light_id }
                    }
                },
                layer: layer as u32,
                light: light.light,
            })
            .collect();
        if let Some(masks) = fresh {
            view_entity.insert(masks);
        }
        view_entity.insert(PenumbraLightingInputs {
            lights,
            masks: array,
            sample_masks,
        });
    }
}

/// Writes each shadowed view's uniforms for this frame and (re)makes the bind groups
/// whose resources changed.
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
fn prepare_distance_field_shadow_bind_groups(
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    allocations: Res<PenumbraGpuAllocations>,
    gpu: Option<Res<DistanceFieldGpu>>,
    terrains: Option<Res<GpuHeightfields>>,
    pipelines: Option<Res<ShadowPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    frame: Res<DistanceFieldShadowedLights>,
    mut views: Query<(
        &ExtractedView,
        &DistanceFieldShadowMasks,
        &ViewPrepassTextures,
        Option<&DeferredMsaaTextures>,
        Option<&ViewFaceNormalTexture>,
        &mut DistanceFieldShadowResources,
    )>,
) {
    let (Some(gpu), Some(pipelines)) = (gpu, pipelines) else {
        return;
    };
    let Some(objects) = gpu.objects.as_ref() else {
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
    for (view, masks, prepass, msaa, face, mut resources) in &mut views {
        let (depth, gbuffer) = pixel_prepass(prepass, msaa);
        let samples = masks
            .samples
            .as_ref()
            .zip(msaa)
            .zip(prepass.depth_view())
            .map(|((samples, msaa), depth)| SampleTraceInputs {
                depth,
                gbuffer: &msaa.gbuffer_view,
                class: &msaa.class.default_view,
                layers: &samples.layers,
            });
        let (Some(depth), Some(camera)) =
            (depth, CameraOrigin::at(view.world_from_view.translation()))
        else {
            continue;
        };
        // The G-buffer's normals give the surface's own shadow (back faces and the
        // terminator); `PenumbraLighting` cameras always have it.
        let rotation = Mat3::from(view.world_from_view.affine().matrix3);
        let clip_from_relative = view.clip_from_view * Mat4::from_mat3(rotation).inverse();
        let params = ShadowViewParams {
            camera,
            frustum: Frustum::from_clip_from_relative(clip_from_relative),
            view_from_clip: view.clip_from_view.inverse(),
            world_from_view: rotation,
            size: masks.size,
            origin: view.viewport.xy(),
            slots: gpu.slot_count,
            inputs: if gbuffer.is_some() {
                TRACE_GBUFFER_NORMALS
            } else {
                0
            } | if face.is_some() {
                TRACE_FACE_NORMALS
            } else {
                0
            },
            heightfields: terrains.as_ref().map_or(0, |t| t.count),
        };
        let (terrain_records, heights) = match terrains.as_ref() {
            Some(t) => (t.records.clone(), t.texture.clone()),
            None => resources
                .no_terrain
                .get_or_insert_with(|| crate::scene::no_heightfields(&allocations, &device))
                .clone(),
        };
        let textures = ViewTextures {
            objects,
            atlas,
            brick_table,
            depth,
            gbuffer: gbuffer.unwrap_or(&pipelines.empty_gbuffer),
            face: face.map_or((&pipelines.empty_face, &pipelines.empty_face), |f| {
                (&f.normal.default_view, &f.depth.default_view)
            }),
            terrain: (&terrain_records, &heights),
            layers: &masks.layers,
            half: masks.half.as_ref(),
            samples,
        };
        resources.update(
            &allocations,
            &device,
            &queue,
            &pipelines,
            &pipeline_cache,
            &params,
            &frame.0,
            &textures,
        );
    }
}

/// The view's shadow passes: per light, clear its counters, cull the object buffer to
/// the light, build the light-space grid (directional lights), write the light's mask
/// layer (and upsample it from half resolution). Dispatches only.
fn distance_field_shadows(
    view: ViewQuery<(&DistanceFieldShadowMasks, &DistanceFieldShadowResources)>,
    gpu: Option<Res<DistanceFieldGpu>>,
    pipelines: Option<Res<ShadowPipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (masks, resources) = view.into_inner();
    let (Some(gpu), Some(pipelines)) = (gpu, pipelines) else {
        return;
    };
    let (Some(cull), Some(trace), Some(upsample)) = (
        pipeline_cache.get_compute_pipeline(pipelines.cull),
        pipeline_cache.get_compute_pipeline(pipelines.trace),
        pipeline_cache.get_compute_pipeline(pipelines.upsample),
    ) else {
        return;
    };
    let sample_trace = pipelines
        .sample_trace
        .and_then(|id| pipeline_cache.get_compute_pipeline(id));
    let grid_pipelines: Option<Vec<_>> = pipelines
        .grid
        .iter()
        .map(|&g| pipeline_cache.get_compute_pipeline(g))
        .collect();
    let Some(grid_pipelines) = grid_pipelines else {
        return;
    };
    let slots = gpu.slot_count;
    let (groups, _) = grid_64(slots);
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_df_shadows");
    for r in &resources.lights {
        let Some(bind) = &r.bind_groups else {
            continue;
        };
        let encoder = ctx.command_encoder();
        encoder.clear_buffer(&r.count, 0, None);
        if r.use_grid {
            encoder.clear_buffer(&r.grid, 0, None);
            encoder.clear_buffer(&r.cursors, 0, None);
        }
        let mut pass = encoder.begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_df_shadows"),
            timestamp_writes: None,
        });
        pass.set_pipeline(cull);
        pass.set_bind_group(0, &bind.cull, &[]);
        pass.dispatch_workgroups(groups[0], groups[1], groups[2]);
        if let (true, Some(grid)) = (r.use_grid, &bind.grid) {
            // Reset, bounds, count, scan, fill: one thread per culled caster (at most
            // `slots`), the scan in one workgroup.
            let per_caster = slots.div_ceil(64).max(1);
            for (pipeline, x) in grid_pipelines
                .iter()
                .zip([1, per_caster, per_caster, 1, per_caster])
            {
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, grid, &[]);
                pass.dispatch_workgroups(x, 1, 1);
            }
        }
        let trace_size = if r.half {
            half_size(masks.size)
        } else {
            masks.size
        };
        pass.set_pipeline(trace);
        pass.set_bind_group(0, &bind.trace, &[]);
        pass.dispatch_workgroups(trace_size.x.div_ceil(8), trace_size.y.div_ceil(8), 1);
        if let (Some(group), Some(pipeline)) = (&bind.sample_trace, sample_trace) {
            // Deferred MSAA: the edge pixels' samples, one thread each.
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(masks.size.x.div_ceil(4), masks.size.y.div_ceil(4), 1);
        }
        drop(pass);
        if let Some(upsample_bind) = bind.upsample.as_ref().filter(|_| r.half) {
            // Its own pass: the half texture, written as storage above, is read as a
            // sampled texture here.
            let mut pass = ctx
                .command_encoder()
                .begin_compute_pass(&ComputePassDescriptor {
                    label: Some("penumbra_df_shadows_upsample"),
                    timestamp_writes: None,
                });
            pass.set_pipeline(upsample);
            pass.set_bind_group(0, upsample_bind, &[]);
            pass.dispatch_workgroups(masks.size.x.div_ceil(8), masks.size.y.div_ceil(8), 1);
        }
    }
    time_span.end(ctx.command_encoder());
}

fn array_view(texture: &Texture) -> TextureView {
    texture.create_view(&TextureViewDescriptor {
        label: Some("penumbra_df_shadow_masks"),
        dimension: Some(TextureViewDimension::D2Array),
        ..default()
    })
}

/// An `R32Float` mask texture (written as storage, read as a texture).
fn mask_texture(
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    label: &'static str,
    size: UVec2,
    layers: u32,
) -> Texture {
    allocations.texture(
        device,
        &TextureDescriptor {
            label: Some(label),
            size: Extent3d {
                width: size.x,
                height: size.y,
                depth_or_array_layers: layers,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: TextureDimension::D2,
            format: TextureFormat::R32Float,
            usage: TextureUsages::STORAGE_BINDING | TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        },
    )
}

fn create_masks(
    allocations: &PenumbraGpuAllocations,
    device: &RenderDevice,
    size: UVec2,
    layers: u32,
    half: bool,
    samples: bool,
) -> DistanceFieldShadowMasks {
    let texture = mask_texture(
        allocations,
        device,
        "penumbra_df_shadow_masks",
        size,
        layers,
    );
    let samples = samples.then(|| SampleMasks::new(allocations, device, size, layers));
    let layers = layer_views(&texture, layers);
    let half = half.then(|| {
        let texture = mask_texture(
            allocations,
            device,
            "penumbra_df_shadow_half_mask",
            half_size(size),
            1,
        );
        // Separate views for writing (storage) and reading (sampled).
        (
            texture.create_view(&TextureViewDescriptor::default()),
            texture.create_view(&TextureViewDescriptor::default()),
        )
    });
    DistanceFieldShadowMasks {
        array: array_view(&texture),
        layers,
        size,
        half,
        samples,
    }
}
