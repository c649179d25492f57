//! Hair under distance-field-shadowed lights (`shadows` feature): each strand point's
//! visibility through the distance fields, traced once per frame for all cameras.
//!
//! Penumbra's masks shade deferred pixels only; hair is forward, and a material's bind
//! group cannot hold a view's textures. So the visibility is computed where the strands
//! are, not where the pixels are: while [`DistanceFieldShadows`] lights exist, a hair
//! entity gets two buffers — its centre-line points (hair space, the strip mesh's
//! order) and `penumbra::hair::shadows`'s `HairShadows` (up to
//! [`MAX_HAIR_SHADOW_LIGHTS`] lights, matched to Bevy's by clustered id or direction, and
//! one visibility per light per point). A compute pass (`hair/df_visibility.wgsl`,
//! `RenderGraph` schedule after the object deltas, before the cameras) marches every
//! point toward each light through every shadow-casting object whose bounding sphere
//! meets its cone — the mask pass's march, relative to the hair's own origin, without
//! the surface's own-shadow term (a strand has no tangent plane). The vertex shader
//! reads its point's visibility; along a strand it is interpolated between points. The
//! lights' shadow maps are not read for those lights: the hair carries
//! [`ReadsNoShadowMaps`] while it takes every such light that reaches it (all
//! directional ones; point and spot lights whose range meets its bounding sphere: out
//! of range they light it with no shadow map either), so a light that only hair kept
//! mapped renders no shadow map.
//!
//! Limits: hair casts no distance-field shadow (it is no caster) — under such a light
//! neither the hair itself nor other surfaces get its shadow; skinned hair keeps the
//! lights' shadow maps (one warning); terrains (`DistanceFieldHeightfield`) do not
//! shadow hair; with more than four reaching a hair, it reads their shadow maps and,
//! the decision being per frame and not per light, every distance-field-shadowed light
//! renders its map (`bevy_penumbra_df`'s `ShadowMapConsumers`); along a
//! segment the shadow is linear between the points; the trace is view-independent, so
//! a directional light's `max_view_distance` counts from the hair's origin, not from a
//! camera.
//!
//! Cost: nothing while no light has [`DistanceFieldShadows`]. Per hair entity, 16 bytes
//! per point twice (points, visibility) and one dispatch in a frame where it is visible
//! and something it reads changed — the scene's objects or SDFs, its transform, its
//! strands, the lights reaching it — (a still scene traces nothing: the visibilities
//! stay in their buffer; [`HairShadowTraces`] counts dispatches): per point and light,
//! a march of the objects in its cone, found among those its workgroup of 64 points
//! listed together, 128 slots at a time (a bounding sphere and cone test per object
//! slot per workgroup). In the benchmark's stress scene (45,000 points, 1,000 casters,
//! ten moving: traced every frame) that took lavapipe's frame from ~1.78 to ~1.43 s at
//! 320 × 180.

use super::material::{HAIR_SHADOWS_HEADER_BYTES, MAX_HAIR_SHADOW_LIGHTS};
use super::{Hair, HairBuilt, HairMaterial, HairShadowBuffers, HairStrands};
use bevy::asset::RenderAssetUsages;
use bevy::core_pipeline::schedule::camera_driver;
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_resource::binding_types::{
    storage_buffer_read_only_sized, storage_buffer_sized, texture_2d, texture_3d,
    uniform_buffer_sized,
};
use bevy::render::render_resource::encase::UniformBuffer;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferId, BufferUsages, CachedComputePipelineId, ComputePassDescriptor, PipelineCache,
    ShaderStages, ShaderType, TextureSampleType, TextureView, TextureViewId,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderGraph, RenderQueue};
use bevy::render::storage::{GpuShaderBuffer, ShaderBuffer};
use bevy::render::sync_component::SyncComponent;
use bevy::render::{Render, RenderApp, RenderStartup, RenderSystems};
use bevy_penumbra_df::lighting::ShadowedLightKind;
use bevy_penumbra_df::scene::{DistanceFieldGpu, DistanceFieldRenderSystems};
use bevy_penumbra_df::shadows::DistanceFieldShadowedLights;
use bevy_penumbra_df::system_times::timed;
use bevy_penumbra_df::{
    DistanceFieldShadows, PenumbraGpuAllocations, PenumbraShaderLibrary, ReadsNoShadowMaps,
};
use penumbra_cinematic_core::hair::strands::check_strands;
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::object::TILE_SIZE;
use penumbra_df_core::shadow::{SHADOW_LIGHT_BYTES, words_to_bytes};
use std::num::NonZeroU64;

/// A light's slot when nothing was traced (`HAIR_SHADOW_UNTRACED`): lit.
const UNTRACED: u32 = 4;

/// `hair/df_visibility.wgsl`'s `HairShadowParams`.
#[derive(ShaderType, Clone, Copy, Debug, Default, PartialEq)]
struct HairShadowParams {
    origin_from_local: Mat4,
    origin_tile: IVec4,
    origin_offset: Vec4,
    point_count: u32,
    light_count: u32,
    object_count: u32,
    reserved: u32,
}

pub(super) fn build(app: &mut App) {
    app.add_systems(
        PostUpdate,
        timed(build_hair_shadows)
            .after(super::build_hair)
            .after(bevy::asset::AssetEventSystems)
            .after(bevy::mesh::mark_3d_meshes_as_changed_if_their_assets_changed)
            .after(TransformSystems::Propagate),
    )
    .add_plugins(ExtractComponentPlugin::<HairShadowBuffers>::default());
    let Some(render_app) = app.get_sub_app_mut(RenderApp) else {
        return;
    };
    render_app
        .init_resource::<HairShadowTraces>()
        .add_systems(
            Render,
            timed(prepare_hair_shadows).in_set(RenderSystems::PrepareBindGroups),
        )
        .add_systems(
            RenderGraph,
            timed(trace_hair_shadows)
                .after(DistanceFieldRenderSystems::ApplyDeltas)
                .in_set(bevy::render::renderer::RenderGraphSystems::Render)
                .before(camera_driver),
        );
}

pub(super) fn finish(app: &mut App) {
    if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
        render_app.add_systems(RenderStartup, init_hair_shadow_pipeline);
    }
}

/// The centre-line points of `strands` (drawable ones, the strip mesh's order), as
/// `vec4`s, and their bounding sphere.
fn centre_line_points(strands: &HairStrands) -> (Vec<u8>, u32, Vec3, f32) {
    let (kept, _) = check_strands(strands.strands.clone());
    let points: Vec<Vec3> = kept.iter().flat_map(|s| s.points.iter().copied()).collect();
    let (lo, hi) = points.iter().fold(
        (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let center = if points.is_empty() {
        Vec3::ZERO
    } else {
        0.5 * (lo + hi)
    };
    let radius = points
        .iter()
        .map(|p| p.distance(center))
        .fold(0.0, f32::max);
    let bytes = points
        .iter()
        .flat_map(|p| p.extend(1.0).to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    (bytes, points.len() as u32, center, radius)
}

/// Where a distance-field-shadowed light reaches: `None` everywhere (directional),
/// else its position and range.
type LightReach = Option<(Vec3, f32)>;

/// Whether a light reaching `reach` can light a sphere (centre, radius): a point or spot
/// light lights nothing beyond its range (Bevy's clustering). Conservative by a hair, so
/// that the render world's choice of lights (`prepare_hair_shadows`, the same test on
/// the extracted frame) never holds more than this counts.
fn reaches(reach: LightReach, (center, radius): (Vec3, f32)) -> bool {
    reach.is_none_or(|(at, range)| {
        let r = range + radius;
        at.distance(center) <= r + r * 1e-3 + 1e-3
    })
}

/// While distance-field-shadowed lights exist, gives each drawn [`Hair`] entity its
/// points and visibility buffers (again when its strip mesh is rebuilt) and points its
/// material at them; marks it [`ReadsNoShadowMaps`] while it takes every such light
/// that can reach it from the distance fields (lights out of range light it with no
/// shadow map either).
#[allow(clippy::type_complexity, reason = "a Bevy query")]
fn build_hair_shadows(
    mut commands: Commands,
    lights: Query<
        (&GlobalTransform, Option<&PointLight>, Option<&SpotLight>),
        With<DistanceFieldShadows>,
    >,
    hairs: Query<(
        Entity,
        &Hair,
        &HairBuilt,
        &GlobalTransform,
        Option<&Mesh3d>,
        Option<&HairShadowBuffers>,
        Has<ReadsNoShadowMaps>,
    )>,
    strands: Res<Assets<HairStrands>>,
    buffers: Option<ResMut<Assets<ShaderBuffer>>>,
    mut materials: ResMut<Assets<HairMaterial>>,
    mut warned: Local<bevy::platform::collections::HashSet<Entity>>,
) {
    let Some(mut buffers) = buffers else {
        return; // no renderer
    };
    let reach: Vec<LightReach> = lights
        .iter()
        .map(|(transform, point, spot)| {
            let range = point.map(|p| p.range).or(spot.map(|s| s.range))?;
            Some((transform.translation(), range))
        })
        .collect();
    let light_count = reach.len();
    for (entity, hair, built, transform, mesh, shadow_buffers, reads_none) in &hairs {
        let current = shadow_buffers.filter(|b| mesh.is_some_and(|m| m.id() == b.mesh));
        let wants_none = current.is_some_and(|b| {
            let sphere = (
                transform.transform_point(b.center),
                b.radius * transform.scale().abs().max_element(),
            );
            reach.iter().filter(|r| reaches(**r, sphere)).count() <= MAX_HAIR_SHADOW_LIGHTS
        });
        if wants_none != reads_none {
            if wants_none {
                commands.entity(entity).insert(ReadsNoShadowMaps);
            } else {
                commands.entity(entity).remove::<ReadsNoShadowMaps>();
            }
        }
        if light_count == 0 || current.is_some() {
            continue;
        }
        let (Some(mesh), Some(asset)) = (mesh, strands.get(&hair.strands)) else {
            continue;
        };
        if asset.joints.is_some() {
            if warned.insert(entity) {
                warn!(
                    "Penumbra: hair on {entity} is skinned: distance-field-shadowed lights \
                     shadow it with their shadow maps"
                );
            }
            continue;
        }
        let (points, count, center, radius) = centre_line_points(asset);
        let shadows = buffers.add(ShaderBuffer::with_size(
            HAIR_SHADOWS_HEADER_BYTES + 16 * count.max(1) as usize,
            RenderAssetUsages::RENDER_WORLD,
        ));
        let points = buffers.add(ShaderBuffer::new(&points, RenderAssetUsages::RENDER_WORLD));
        if let Some(mut material) = materials.get_mut(&built.material) {
            material.shadows = shadows.clone();
        }
        commands.entity(entity).insert(HairShadowBuffers {
            points,
            shadows,
            point_count: count,
            center,
            radius,
            mesh: mesh.id(),
        });
    }
}

/// A hair entity's frame as extracted.
#[derive(Component, Clone, Debug)]
pub struct ExtractedHairShadows {
    points: AssetId<ShaderBuffer>,
    shadows: AssetId<ShaderBuffer>,
    point_count: u32,
    world_from_local: Mat4,
    /// World-space bounding sphere of the points.
    sphere: (Vec3, f32),
    visible: bool,
}

impl SyncComponent for HairShadowBuffers {
    type Target = (ExtractedHairShadows, GpuHairShadows);
}

impl ExtractComponent for HairShadowBuffers {
    type QueryData = (
        &'static HairShadowBuffers,
        &'static GlobalTransform,
        &'static ViewVisibility,
    );
    type QueryFilter = ();
    type Out = ExtractedHairShadows;

    fn extract_component(
        (buffers, transform, visibility): (&HairShadowBuffers, &GlobalTransform, &ViewVisibility),
    ) -> Option<ExtractedHairShadows> {
        let world_from_local = transform.to_matrix();
        let scale = transform.scale().abs().max_element();
        Some(ExtractedHairShadows {
            points: buffers.points.id(),
            shadows: buffers.shadows.id(),
            point_count: buffers.point_count,
            world_from_local,
            sphere: (
                world_from_local.transform_point3(buffers.center),
                buffers.radius * scale,
            ),
            visible: visibility.get(),
        })
    }
}

/// What a bind group binds: objects, atlas and brick table, points, visibility.
type BoundIds = (BufferId, [TextureViewId; 2], BufferId, BufferId);

/// A hair entity's pooled GPU state.
#[derive(Component)]
pub struct GpuHairShadows {
    params: Buffer,
    lights: Buffer,
    /// The header last written into its `HairShadows`.
    header: Vec<u8>,
    /// The uniforms last written (params, lights): a static scene uploads nothing.
    uniforms: (Vec<u8>, Vec<u8>),
    /// The bind group and the ids of what it binds.
    group: Option<(BindGroup, BoundIds)>,
    /// This frame's workgroups, two-dimensional past 65,535 (0: not traced).
    dispatch: [u32; 3],
    /// What the visibilities in its buffer were last traced from: the scene's
    /// [`DistanceFieldGpu::generation`] and the points' and visibilities' assets. With
    /// the uniforms, header and bind group unchanged too, the trace is skipped.
    traced: Option<(u64, AssetId<ShaderBuffer>, AssetId<ShaderBuffer>)>,
}

/// Hair visibility traces dispatched since startup, per hair entity and frame (render
/// world): a still scene adds none.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HairShadowTraces(pub u64);

#[derive(Resource)]
struct HairShadowPipeline {
    layout: BindGroupLayoutDescriptor,
    trace: CachedComputePipelineId,
    /// Bound while the scene has no SDF volume (analytic casters only).
    no_atlas: TextureView,
    /// Bound while no volume is placed as bricks.
    no_brick_table: TextureView,
}

fn init_hair_shadow_pipeline(
    mut commands: Commands,
    pipeline_cache: Res<PipelineCache>,
    device: Res<RenderDevice>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return;
    };
    let layout = BindGroupLayoutDescriptor::new(
        "penumbra_hair_df_visibility_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::COMPUTE,
            (
                storage_buffer_read_only_sized(false, None),
                texture_3d(TextureSampleType::Float { filterable: false }),
                storage_buffer_read_only_sized(false, None),
                storage_buffer_sized(false, None),
                uniform_buffer_sized(false, Some(HairShadowParams::min_size())),
                uniform_buffer_sized(
                    false,
                    NonZeroU64::new((SHADOW_LIGHT_BYTES * MAX_HAIR_SHADOW_LIGHTS) as u64),
                ),
                texture_2d(TextureSampleType::Uint),
            ),
        ),
    );
    let trace = library.queue_compute_layouts(
        &pipeline_cache,
        "penumbra_hair_df_visibility",
        std::slice::from_ref(&layout),
        "hair/df_visibility.wgsl",
        "hair_df_visibility",
    );
    let no_atlas = bevy_penumbra_df::shader_library::empty_atlas(&device);
    commands.insert_resource(HairShadowPipeline {
        layout,
        trace,
        no_atlas,
        no_brick_table: bevy_penumbra_df::shader_library::empty_brick_table(&device),
    });
}

/// `HairShadows`' header: the lights (kind, id, slot; direction), traced or not.
fn header_bytes(lights: &[(ShadowedLightKind, u32)], point_count: u32) -> Vec<u8> {
    let mut words: Vec<u32> = vec![lights.len() as u32, point_count, 0, 0];
    for i in 0..MAX_HAIR_SHADOW_LIGHTS {
        let (kind, id, slot, direction) = match lights.get(i) {
            Some((ShadowedLightKind::Directional { direction }, slot)) => (0, 0, *slot, *direction),
            Some((ShadowedLightKind::Clustered { light_id }, slot)) => {
                (1, *light_id, *slot, Vec3::ZERO)
            }
            None => (0, 0, UNTRACED, Vec3::ZERO),
        };
        words.extend([kind, id, slot, 0]);
        words.extend(direction.extend(0.0).to_array().map(f32::to_bits));
    }
    words_to_bytes(&words)
}

/// Per hair entity: picks the distance-field-shadowed lights that reach it (at most
/// four), writes its header when it changes, its uniforms, and (re)makes its bind
/// group when a bound resource changes. Hair out of every view is not traced.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn prepare_hair_shadows(
    mut commands: Commands,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
    allocations: Res<PenumbraGpuAllocations>,
    pipeline_cache: Res<PipelineCache>,
    pipeline: Option<Res<HairShadowPipeline>>,
    buffers: Res<RenderAssets<GpuShaderBuffer>>,
    df: Option<Res<DistanceFieldGpu>>,
    lights: Option<Res<DistanceFieldShadowedLights>>,
    mut hairs: Query<(Entity, &ExtractedHairShadows, Option<&mut GpuHairShadows>)>,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    let ready = pipeline_cache
        .get_compute_pipeline(pipeline.trace)
        .is_some();
    let scene = df.as_deref().and_then(|df| {
        let objects = df.objects.as_ref()?;
        let atlas = df
            .atlas
            .as_ref()
            .map_or(&pipeline.no_atlas, |(_, view, _)| view);
        let brick_table = df
            .brick_table
            .as_ref()
            .map_or(&pipeline.no_brick_table, |(_, view, _)| view);
        Some((
            objects,
            (atlas, brick_table),
            df.slot_count,
            df.generation(),
        ))
    });
    let all_lights = lights.as_deref().map_or(&[][..], |l| l.lights());
    for (entity, hair, gpu) in &mut hairs {
        let (Some(points), Some(shadows)) = (buffers.get(hair.points), buffers.get(hair.shadows))
        else {
            continue; // not uploaded yet
        };
        let mut fresh = None;
        let gpu = match gpu {
            Some(gpu) => gpu.into_inner(),
            None => fresh.insert(GpuHairShadows {
                params: allocations.sized_buffer(
                    &device,
                    "penumbra_hair_df_params",
                    HairShadowParams::min_size().get(),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                lights: allocations.sized_buffer(
                    &device,
                    "penumbra_hair_df_lights",
                    (SHADOW_LIGHT_BYTES * MAX_HAIR_SHADOW_LIGHTS) as u64,
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                header: Vec::new(),
                uniforms: (Vec::new(), Vec::new()),
                group: None,
                dispatch: [0; 3],
                traced: None,
            }),
        };
        let translation = hair.world_from_local.w_axis.truncate();
        let origin = CameraOrigin::at(translation);
        // The lights that reach the hair's sphere, as the march sees them.
        let (center, radius) = hair.sphere;
        let reaching: Vec<_> = all_lights
            .iter()
            .filter(|l| {
                l.reach()
                    .is_none_or(|(at, range)| at.distance(center) <= range + radius)
            })
            .filter_map(|l| Some((l.kind(), l.shadow_light(&origin?)?)))
            .take(MAX_HAIR_SHADOW_LIGHTS)
            .collect();
        let traced = ready && hair.visible && scene.is_some() && origin.is_some();
        let slots: Vec<_> = reaching
            .iter()
            .enumerate()
            .map(|(i, (kind, _))| (*kind, if traced { i as u32 } else { UNTRACED }))
            .collect();
        let header = header_bytes(&slots, hair.point_count);
        // Whether anything the trace reads, besides the scene, changed since it ran.
        let mut changed = false;
        if header != gpu.header {
            queue.write_buffer(&shadows.buffer, 0, &header);
            gpu.header = header;
            changed = true;
        }
        gpu.dispatch = [0; 3];
        if let (true, Some(origin), Some((objects, (atlas, brick_table), slot_count, generation))) =
            (traced, origin, scene)
        {
            let origin_world = IVec3::from_array(origin.tile).as_dvec3() * f64::from(TILE_SIZE)
                + origin.offset.as_dvec3();
            let mut origin_from_local = hair.world_from_local;
            origin_from_local.w_axis = (translation.as_dvec3() - origin_world)
                .as_vec3()
                .extend(1.0);
            let params = HairShadowParams {
                origin_from_local,
                origin_tile: IVec3::from_array(origin.tile).extend(0),
                origin_offset: origin.offset.extend(0.0),
                point_count: hair.point_count,
                light_count: reaching.len() as u32,
                object_count: slot_count,
                reserved: 0,
            };
            let mut bytes = UniformBuffer::new(Vec::new());
            bytes.write(&params).expect("encodes");
            let params = bytes.into_inner();
            if params != gpu.uniforms.0 {
                queue.write_buffer(&gpu.params, 0, &params);
                gpu.uniforms.0 = params;
                changed = true;
            }
            let mut words = Vec::with_capacity(SHADOW_LIGHT_BYTES / 4 * MAX_HAIR_SHADOW_LIGHTS);
            for (_, light) in &reaching {
                words.extend(light.to_words());
            }
            words.resize(SHADOW_LIGHT_BYTES / 4 * MAX_HAIR_SHADOW_LIGHTS, 0);
            let lights = words_to_bytes(&words);
            if lights != gpu.uniforms.1 {
                queue.write_buffer(&gpu.lights, 0, &lights);
                gpu.uniforms.1 = lights;
                changed = true;
            }
            let ids = (
                objects.id(),
                [atlas.id(), brick_table.id()],
                points.buffer.id(),
                shadows.buffer.id(),
            );
            if gpu.group.as_ref().is_none_or(|(_, bound)| *bound != ids) {
                let group = allocations.bind_group(
                    &device,
                    "penumbra_hair_df_visibility",
                    &pipeline_cache.get_bind_group_layout(&pipeline.layout),
                    &BindGroupEntries::sequential((
                        objects.as_entire_binding(),
                        atlas,
                        points.buffer.as_entire_binding(),
                        shadows.buffer.as_entire_binding(),
                        gpu.params.as_entire_binding(),
                        gpu.lights.as_entire_binding(),
                        brick_table,
                    )),
                );
                gpu.group = Some((group, ids));
                changed = true;
            }
            // Traced again only when the scene or an input changed: a still scene with
            // still hair reads last frame's visibilities.
            let key = (generation, hair.points, hair.shadows);
            if !reaching.is_empty() && (changed || gpu.traced != Some(key)) {
                gpu.dispatch =
                    penumbra_cinematic_core::dispatch::workgroups_2d(hair.point_count, 64);
                gpu.traced = Some(key);
            }
        }
        if let Some(fresh) = fresh {
            commands.entity(entity).insert(fresh);
        }
    }
}

/// The trace: one dispatch per visible hair entity with lights. Dispatches only.
fn trace_hair_shadows(
    mut ctx: RenderContext,
    hairs: Query<&GpuHairShadows>,
    pipeline: Option<Res<HairShadowPipeline>>,
    pipeline_cache: Res<PipelineCache>,
    mut traces: ResMut<HairShadowTraces>,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    if hairs.iter().all(|h| h.dispatch[0] == 0) {
        return;
    }
    let Some(trace) = pipeline_cache.get_compute_pipeline(pipeline.trace) else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_hair_df_visibility");
    let mut pass = ctx
        .command_encoder()
        .begin_compute_pass(&ComputePassDescriptor {
            label: Some("penumbra_hair_df_visibility"),
            timestamp_writes: None,
        });
    pass.set_pipeline(trace);
    for hair in &hairs {
        let Some((group, _)) = &hair.group else {
            continue;
        };
        if hair.dispatch[0] == 0 {
            continue;
        }
        pass.set_bind_group(0, group, &[]);
        let [x, y, z] = hair.dispatch;
        pass.dispatch_workgroups(x, y, z);
        traces.0 += 1;
    }
    drop(pass);
    time_span.end(ctx.command_encoder());
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The header the shaders read: counts, then per light its kind, id and slot and
    /// (directional) its direction; unused entries untraced.
    #[test]
    fn header_layout() {
        let bytes = header_bytes(
            &[
                (ShadowedLightKind::Directional { direction: Vec3::Y }, 0),
                (ShadowedLightKind::Clustered { light_id: 7 }, 1),
            ],
            10,
        );
        assert_eq!(bytes.len(), HAIR_SHADOWS_HEADER_BYTES);
        let word = |i: usize| u32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap());
        assert_eq!([word(0), word(1)], [2, 10]);
        assert_eq!([word(4), word(5), word(6)], [0, 0, 0]);
        assert_eq!(f32::from_bits(word(9)), 1.0);
        assert_eq!([word(12), word(13), word(14)], [1, 7, 1]);
        assert_eq!(word(22), UNTRACED);
    }

    /// A directional light reaches everything; a point or spot light its range plus the
    /// sphere's radius (a hair more, never less).
    #[test]
    fn lights_reach_within_their_range() {
        let sphere = (Vec3::new(0.0, 0.0, 10.0), 1.0);
        assert!(reaches(None, sphere));
        assert!(reaches(Some((Vec3::ZERO, 9.0)), sphere));
        assert!(reaches(Some((Vec3::ZERO, 8.999)), sphere));
        assert!(!reaches(Some((Vec3::ZERO, 8.9)), sphere));
        assert!(!reaches(Some((Vec3::new(0.0, 0.0, -100.0), 14.0)), sphere));
    }
}
