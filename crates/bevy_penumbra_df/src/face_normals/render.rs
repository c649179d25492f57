//! The face-normal prepass's render-world plumbing: a sorted render phase of the
//! camera's visible meshes (Bevy's `custom_render_phase` example is the template), its
//! pipeline (positions only, `df/face_normal.wgsl`), the view's pooled target and the
//! pass, after Bevy's prepass and before Penumbra's lighting inputs.

use super::FaceNormalPrepass;
use crate::lighting::render::PenumbraLightingSystems;
use crate::shader_library::PenumbraShaderLibrary;
use crate::system_times::timed;
use bevy::camera::{MainPassResolutionOverride, Viewport};
use bevy::core_pipeline::core_3d::TransparentSortingInfo3d;
use bevy::core_pipeline::schedule::{Core3d, Core3dSystems};
use bevy::ecs::entity::EntityHash;
use bevy::ecs::system::{SystemParamItem, lifetimeless::SRes};
use bevy::material::RenderPhaseType;
use bevy::math::FloatOrd;
use bevy::mesh::MeshVertexBufferLayoutRef;
use bevy::pbr::{
    self, DrawMesh, MeshInputUniform, MeshPipeline, MeshPipelineKey, MeshPipelineSystems,
    MeshPipelineViewLayoutKey, MeshUniform, MorphIndices, PreparedMaterial,
    RenderMaterialInstances, RenderMeshInstances, SetMeshBindGroup, SetMeshViewBindGroup,
    SetMeshViewEmptyBindGroup, SkinUniforms, ViewKeyCache, setup_morph_and_skinning_defs,
};
use bevy::platform::collections::HashSet;
use bevy::prelude::*;
use bevy::render::batching::gpu_preprocessing::{
    BatchedInstanceBuffers, IndirectParametersCpuMetadata, UntypedPhaseIndirectParametersBuffers,
};
use bevy::render::batching::{GetBatchData, GetFullBatchData};
use bevy::render::camera::{DirtySpecializations, ExtractedCamera, PendingQueues};
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::erased_render_asset::ErasedRenderAssets;
use bevy::render::mesh::allocator::MeshAllocator;
use bevy::render::mesh::{PrimitiveTopology, RenderMesh};
use bevy::render::render_asset::RenderAssets;
use bevy::render::render_phase::{
    AddRenderCommand, CachedRenderPipelinePhaseItem, DrawFunctionId, DrawFunctions, PhaseItem,
    PhaseItemExtraIndex, SetItemPipeline, SortedPhaseItem, SortedRenderPhasePlugin,
    ViewSortedRenderPhases, sort_phase_system,
};
use bevy::render::render_resource::{
    CachedRenderPipelineId, ColorTargetState, ColorWrites, CompareFunction, DepthStencilState,
    Extent3d, FragmentState, LoadOp, Operations, PipelineCache, PrimitiveState,
    RenderPassColorAttachment, RenderPassDepthStencilAttachment, RenderPassDescriptor,
    RenderPipelineDescriptor, SpecializedMeshPipeline, SpecializedMeshPipelineError,
    SpecializedMeshPipelines, StoreOp, TextureDescriptor, TextureDimension, TextureFormat,
    TextureUsages, VertexState,
};
use bevy::render::renderer::{RenderContext, RenderDevice, ViewQuery};
use bevy::render::sync_world::MainEntity;
use bevy::render::texture::{CachedTexture, TextureCache};
use bevy::render::view::{ExtractedView, RenderVisibleEntities, RetainedViewEntity};
use bevy::render::{
    Extract, ExtractSchedule, Render, RenderDebugFlags, RenderStartup, RenderSystems,
};
use indexmap::IndexMap;
use nonmax::NonMaxU32;
use std::ops::Range;

/// The target's format: xyz the triangle's unit winding normal (world space), w 1 where
/// a triangle was drawn.
const FACE_NORMAL_FORMAT: TextureFormat = TextureFormat::Rgba16Float;
/// The pass's own depth buffer (reverse-Z, cleared to 0).
const FACE_DEPTH_FORMAT: TextureFormat = TextureFormat::Depth32Float;

/// A face-normal view's target and depth (render world), at the camera target's size.
#[derive(Component, Clone)]
pub struct ViewFaceNormalTexture {
    /// `Rgba16Float`: xyz the triangle's unit winding normal, w 1 where one was drawn.
    pub normal: CachedTexture,
    /// `Depth32Float`, reverse-Z.
    pub depth: CachedTexture,
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        .init_resource::<SpecializedMeshPipelines<FaceNormalPipeline>>()
        .init_resource::<DrawFunctions<FaceNormal3d>>()
        .add_render_command::<FaceNormal3d, DrawFaceNormal>()
        .init_resource::<ViewSortedRenderPhases<FaceNormal3d>>()
        .init_resource::<PendingFaceNormalQueues>()
        .add_systems(ExtractSchedule, timed(extract_face_normal_phases))
        .add_systems(
            Render,
            (
                timed(queue_face_normal_meshes).in_set(RenderSystems::QueueMeshes),
                sort_phase_system::<FaceNormal3d>.in_set(RenderSystems::PhaseSort),
                // Batching: `SortedRenderPhasePlugin` (in `PrepareResourcesBatchPhases`,
                // after Bevy's skins are written).
                timed(prepare_face_normal_textures).in_set(RenderSystems::PrepareResources),
            ),
        )
        .add_systems(
            Core3d,
            timed(face_normal_prepass)
                .after(Core3dSystems::Prepass)
                .before(PenumbraLightingSystems::Inputs)
                .in_set(Core3dSystems::MainPass),
        );
}

pub(super) fn finish(render_app: &mut SubApp) {
    render_app.add_systems(
        RenderStartup,
        init_face_normal_pipeline.after(MeshPipelineSystems),
    );
}

/// Adds the phase's plugin (it needs the main app).
pub(super) fn phase_plugin() -> SortedRenderPhasePlugin<FaceNormal3d, MeshPipeline> {
    SortedRenderPhasePlugin::new(RenderDebugFlags::default())
}

/// The pipeline drawing a mesh's face normals, specialized per mesh layout.
#[derive(Resource)]
pub(super) struct FaceNormalPipeline {
    mesh_pipeline: MeshPipeline,
    shader: Handle<Shader>,
}

fn init_face_normal_pipeline(
    mut commands: Commands,
    mesh_pipeline: Res<MeshPipeline>,
    library: Option<Res<PenumbraShaderLibrary>>,
) {
    let Some(library) = library else {
        return; // warned by the plugin
    };
    commands.insert_resource(FaceNormalPipeline {
        mesh_pipeline: mesh_pipeline.clone(),
        shader: library.handle("df/face_normal.wgsl"),
    });
}

impl SpecializedMeshPipeline for FaceNormalPipeline {
    type Key = MeshPipelineKey;

    fn specialize(
        &self,
        key: Self::Key,
        layout: &MeshVertexBufferLayoutRef,
    ) -> Result<RenderPipelineDescriptor, SpecializedMeshPipelineError> {
        // Skinned and morphed meshes are posed as Bevy's mesh shader poses them; the
        // mesh bind group's layout (lightmapped, skinned, morphed, with motion vectors)
        // is the one `SetMeshBindGroup` binds for the mesh and view.
        let mut shader_defs = Vec::new();
        let mut attributes = vec![Mesh::ATTRIBUTE_POSITION.at_shader_location(0)];
        let mesh_layout = setup_morph_and_skinning_defs(
            &self.mesh_pipeline.mesh_layouts,
            layout,
            1,
            &key,
            &mut shader_defs,
            &mut attributes,
            self.mesh_pipeline.skins_use_uniform_buffers,
        );
        let vertex_buffer_layout = layout.0.get_layout(&attributes)?;
        let view_layout = self
            .mesh_pipeline
            .get_view_layout(MeshPipelineViewLayoutKey::from(key));
        Ok(RenderPipelineDescriptor {
            label: Some("penumbra_face_normal_pipeline".into()),
            layout: vec![
                view_layout.main_layout.clone(),
                view_layout.empty_layout.clone(),
                mesh_layout,
            ],
            vertex: VertexState {
                shader: self.shader.clone(),
                shader_defs: shader_defs.clone(),
                buffers: vec![vertex_buffer_layout],
                ..default()
            },
            fragment: Some(FragmentState {
                shader: self.shader.clone(),
                shader_defs,
                targets: vec![Some(ColorTargetState {
                    format: FACE_NORMAL_FORMAT,
                    blend: None,
                    write_mask: ColorWrites::ALL,
                })],
                ..default()
            }),
            primitive: PrimitiveState {
                topology: key.primitive_topology(),
                strip_index_format: key.strip_index_format(),
                // Both sides: a double-sided sheet's underside is what the camera sees.
                cull_mode: None,
                ..default()
            },
            depth_stencil: Some(DepthStencilState {
                format: FACE_DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(CompareFunction::GreaterEqual),
                stencil: default(),
                bias: default(),
            }),
            ..default()
        })
    }
}

type DrawFaceNormal = (
    SetItemPipeline,
    SetMeshViewBindGroup<0>,
    SetMeshViewEmptyBindGroup<1>,
    SetMeshBindGroup<2>,
    DrawMesh,
);

/// One mesh of the face-normal phase, sorted front to back.
pub(super) struct FaceNormal3d {
    sorting_info: TransparentSortingInfo3d,
    distance: FloatOrd,
    entity: (Entity, MainEntity),
    pipeline: CachedRenderPipelineId,
    draw_function: DrawFunctionId,
    batch_range: Range<u32>,
    extra_index: PhaseItemExtraIndex,
    indexed: bool,
}

impl PhaseItem for FaceNormal3d {
    fn entity(&self) -> Entity {
        self.entity.0
    }

    fn main_entity(&self) -> MainEntity {
        self.entity.1
    }

    fn draw_function(&self) -> DrawFunctionId {
        self.draw_function
    }

    fn batch_range(&self) -> &Range<u32> {
        &self.batch_range
    }

    fn batch_range_mut(&mut self) -> &mut Range<u32> {
        &mut self.batch_range
    }

    fn extra_index(&self) -> PhaseItemExtraIndex {
        self.extra_index.clone()
    }

    fn batch_range_and_extra_index_mut(&mut self) -> (&mut Range<u32>, &mut PhaseItemExtraIndex) {
        (&mut self.batch_range, &mut self.extra_index)
    }
}

impl SortedPhaseItem for FaceNormal3d {
    type SortKey = FloatOrd;

    fn sort_key(&self) -> Self::SortKey {
        self.distance
    }

    fn sort(items: &mut IndexMap<(Entity, MainEntity), FaceNormal3d, EntityHash>) {
        items.sort_by_key(|_, item: &FaceNormal3d| item.distance);
    }

    fn recalculate_sort_keys(
        items: &mut IndexMap<(Entity, MainEntity), Self, EntityHash>,
        view: &ExtractedView,
    ) {
        let rangefinder = view.rangefinder3d();
        for item in items.values_mut() {
            // Front to back: the depth test rejects the hidden early.
            item.distance = FloatOrd(-item.sorting_info.sort_distance(&rangefinder));
        }
    }

    fn indexed(&self) -> bool {
        self.indexed
    }
}

impl CachedRenderPipelinePhaseItem for FaceNormal3d {
    fn cached_pipeline(&self) -> CachedRenderPipelineId {
        self.pipeline
    }
}

/// Where `mesh`'s vertices start in the mesh allocator's slab (0 when not allocated).
fn first_vertex(allocator: &MeshAllocator, mesh: AssetId<Mesh>) -> u32 {
    allocator
        .mesh_vertex_slice(&mesh)
        .map_or(0, |slice| slice.range.start)
}

impl GetBatchData for FaceNormalPipeline {
    type Param = (
        SRes<RenderMeshInstances>,
        SRes<RenderAssets<RenderMesh>>,
        SRes<MeshAllocator>,
        SRes<SkinUniforms>,
        SRes<MorphIndices>,
    );
    type BatchSetCompareData = AssetId<Mesh>;
    type BatchCompareData = ();
    type BufferData = MeshUniform;

    fn get_batch_data(
        param: &SystemParamItem<Self::Param>,
        (_, main_entity): (Entity, MainEntity),
    ) -> Option<(
        Self::BufferData,
        Option<(Self::BatchSetCompareData, Self::BatchCompareData)>,
    )> {
        Some((cpu_mesh_uniform(param, main_entity)?, None))
    }
}

/// The mesh's uniform when the CPU builds them (no GPU preprocessing): its transforms,
/// first vertex, and where its joints and morph weights are, as Bevy's mesh pipeline
/// writes it (the lightmap's slot and UV rectangle are not read here).
fn cpu_mesh_uniform(
    (mesh_instances, _, mesh_allocator, skins, morphs): &SystemParamItem<
        <FaceNormalPipeline as GetBatchData>::Param,
    >,
    main_entity: MainEntity,
) -> Option<MeshUniform> {
    let RenderMeshInstances::CpuBuilding(ref mesh_instances) = **mesh_instances else {
        return None;
    };
    let mesh_instance = mesh_instances.get(&main_entity)?;
    Some(MeshUniform::new(
        &mesh_instance.transforms,
        first_vertex(mesh_allocator, mesh_instance.mesh_asset_id()),
        mesh_instance.material_bindings_index().slot,
        None,
        skins.skin_index(main_entity),
        morphs.morph_descriptor_index(main_entity),
        None,
    ))
}

impl GetFullBatchData for FaceNormalPipeline {
    type BufferInputData = MeshInputUniform;

    fn get_index_and_compare_data(
        (mesh_instances, ..): &SystemParamItem<Self::Param>,
        main_entity: MainEntity,
    ) -> Option<(
        NonMaxU32,
        Option<(Self::BatchSetCompareData, Self::BatchCompareData)>,
    )> {
        let RenderMeshInstances::GpuBuilding(ref mesh_instances) = **mesh_instances else {
            return None;
        };
        let mesh_instance = mesh_instances.get(&main_entity)?;
        Some((
            NonMaxU32::new(mesh_instance.gpu_specific.current_uniform_index())?,
            mesh_instance
                .should_batch()
                .then_some((mesh_instance.mesh_asset_id(), ())),
        ))
    }

    fn get_binned_batch_data(
        param: &SystemParamItem<Self::Param>,
        main_entity: MainEntity,
    ) -> Option<Self::BufferData> {
        cpu_mesh_uniform(param, main_entity)
    }

    fn write_batch_indirect_parameters_metadata(
        indexed: bool,
        base_output_index: u32,
        batch_set_index: Option<NonMaxU32>,
        buffers: &mut UntypedPhaseIndirectParametersBuffers,
        offset: u32,
    ) {
        let metadata = IndirectParametersCpuMetadata {
            base_output_index,
            batch_set_index: batch_set_index.map_or(!0, u32::from),
        };
        if indexed {
            buffers.indexed.set(offset, metadata);
        } else {
            buffers.non_indexed.set(offset, metadata);
        }
    }

    fn get_binned_index(
        _param: &SystemParamItem<Self::Param>,
        _query_item: MainEntity,
    ) -> Option<NonMaxU32> {
        None
    }
}

/// A phase per active camera with [`FaceNormalPrepass`] while something reads the target
/// (a light with `DistanceFieldShadows`); others keep none: no draw, no texture.
#[allow(clippy::type_complexity, reason = "a Bevy system")]
fn extract_face_normal_phases(
    mut phases: ResMut<ViewSortedRenderPhases<FaceNormal3d>>,
    cameras: Extract<Query<(Entity, &Camera), (With<Camera3d>, With<FaceNormalPrepass>)>>,
    #[cfg(feature = "shadows")] readers: Extract<
        Query<(), With<crate::shadows::DistanceFieldShadows>>,
    >,
    mut live: Local<HashSet<RetainedViewEntity>>,
) {
    #[cfg(feature = "shadows")]
    let read = !readers.is_empty();
    #[cfg(not(feature = "shadows"))]
    let read = false;
    live.clear();
    for (main_entity, camera) in cameras.iter().filter(|_| read) {
        if !camera.is_active {
            continue;
        }
        let view = RetainedViewEntity::new(main_entity.into(), None, 0);
        phases.prepare_for_new_frame(view);
        live.insert(view);
    }
    phases.retain(|view, _| live.contains(view));
}

#[derive(Default, Deref, DerefMut, Resource)]
pub(super) struct PendingFaceNormalQueues(PendingQueues);

/// Whether the pass draws `mesh`: triangles (lines and points have no face).
fn drawn(mesh: &RenderMesh) -> bool {
    matches!(
        mesh.primitive_topology(),
        PrimitiveTopology::TriangleList | PrimitiveTopology::TriangleStrip
    )
}

#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn queue_face_normal_meshes(
    draw_functions: Res<DrawFunctions<FaceNormal3d>>,
    mut pipelines: ResMut<SpecializedMeshPipelines<FaceNormalPipeline>>,
    pipeline_cache: Res<PipelineCache>,
    pipeline: Option<Res<FaceNormalPipeline>>,
    render_meshes: Res<RenderAssets<RenderMesh>>,
    render_mesh_instances: Res<RenderMeshInstances>,
    batched_instance_buffers: Option<Res<BatchedInstanceBuffers<MeshUniform, MeshInputUniform>>>,
    mut phases: ResMut<ViewSortedRenderPhases<FaceNormal3d>>,
    views: Query<(&ExtractedView, &RenderVisibleEntities)>,
    view_key_cache: Res<ViewKeyCache>,
    dirty: Res<DirtySpecializations>,
    mut pending: ResMut<PendingFaceNormalQueues>,
    material_instances: Res<RenderMaterialInstances>,
    materials: Res<ErasedRenderAssets<PreparedMaterial>>,
) {
    let Some(pipeline) = pipeline else {
        return;
    };
    let draw = draw_functions.read().id::<DrawFaceNormal>();
    for (view, visible) in &views {
        let Some(phase) = phases.get_mut(&view.retained_view_entity) else {
            continue;
        };
        let Some(&view_key) = view_key_cache.get(&view.retained_view_entity) else {
            continue;
        };
        let Some(visible_meshes) = visible.get::<Mesh3d>() else {
            continue;
        };
        let view_pending = pending.prepare_for_new_frame(view.retained_view_entity);
        for &main_entity in dirty.iter_to_dequeue(view.retained_view_entity, visible_meshes) {
            phase.remove(Entity::PLACEHOLDER, main_entity);
        }
        for (render_entity, visible_entity) in dirty.iter_to_queue(
            view.retained_view_entity,
            visible_meshes,
            &view_pending.prev_frame,
        ) {
            let Some(instance) = render_mesh_instances.render_mesh_queue_data(*visible_entity)
            else {
                view_pending
                    .current_frame
                    .insert((*render_entity, *visible_entity));
                continue;
            };
            let Some(mesh) = render_meshes.get(instance.mesh_asset_id()) else {
                continue;
            };
            // Bevy's G-buffer leaves out what its forward phases blend (a goggle's
            // glass): so does this pass, or the pixels behind would fail the depth test.
            // A material not prepared yet is asked again next frame.
            let blended = match material_instances.instances.get(visible_entity) {
                Some(m) => match materials.get(m.asset_id) {
                    Some(m) => matches!(
                        m.properties.render_phase_type,
                        RenderPhaseType::Transmissive | RenderPhaseType::Transparent
                    ),
                    None => {
                        view_pending
                            .current_frame
                            .insert((*render_entity, *visible_entity));
                        continue;
                    }
                },
                None => false,
            };
            if blended || !drawn(mesh) {
                phase.remove(Entity::PLACEHOLDER, *visible_entity);
                continue;
            }
            // The mesh's own bits (topology, strip index format, morph targets) and its
            // lightmap choose the pipeline and the mesh bind group's layout, as in
            // Bevy's shadow phase.
            let mut key = view_key | MeshPipelineKey::from_bits_retain(mesh.key_bits.bits());
            if instance.shared.lightmap_slab_index().is_some() {
                key |= MeshPipelineKey::LIGHTMAPPED;
            }
            let id = match pipelines.specialize(&pipeline_cache, &pipeline, key, &mesh.layout) {
                Ok(id) => id,
                Err(err) => {
                    error!("Penumbra: face-normal pipeline: {err}");
                    continue;
                }
            };
            let center = pbr::get_mesh_instance_world_from_local(
                *visible_entity,
                instance.current_uniform_index,
                &render_mesh_instances,
                batched_instance_buffers.as_deref(),
            )
            .transform_point3(mesh.aabb_center);
            phase.add_retained(FaceNormal3d {
                sorting_info: TransparentSortingInfo3d::Sorted {
                    mesh_center: center,
                    depth_bias: 0.0,
                },
                distance: FloatOrd(0.0),
                entity: (Entity::PLACEHOLDER, *visible_entity),
                pipeline: id,
                draw_function: draw,
                batch_range: 0..1,
                extra_index: PhaseItemExtraIndex::None,
                indexed: mesh.indexed(),
            });
        }
    }
}

/// Gives every view with a face-normal phase its target and depth (Bevy's
/// `TextureCache`: reused while the size holds); takes them from views without one.
fn prepare_face_normal_textures(
    mut commands: Commands,
    device: Res<RenderDevice>,
    mut cache: ResMut<TextureCache>,
    phases: Res<ViewSortedRenderPhases<FaceNormal3d>>,
    views: Query<(
        Entity,
        &ExtractedCamera,
        &ExtractedView,
        Has<ViewFaceNormalTexture>,
    )>,
) {
    for (entity, camera, view, has_texture) in &views {
        let size = camera
            .physical_target_size
            .filter(|_| phases.get(&view.retained_view_entity).is_some());
        let Some(size) = size else {
            if has_texture {
                commands.entity(entity).remove::<ViewFaceNormalTexture>();
            }
            continue;
        };
        let size = Extent3d {
            width: size.x.max(1),
            height: size.y.max(1),
            depth_or_array_layers: 1,
        };
        let texture = |cache: &mut TextureCache, label, format, usage| {
            cache.get(
                &device,
                TextureDescriptor {
                    label: Some(label),
                    size,
                    mip_level_count: 1,
                    sample_count: 1,
                    dimension: TextureDimension::D2,
                    format,
                    usage: usage | TextureUsages::TEXTURE_BINDING | TextureUsages::COPY_SRC,
                    view_formats: &[],
                },
            )
        };
        let normal = texture(
            &mut cache,
            "penumbra_face_normal_texture",
            FACE_NORMAL_FORMAT,
            TextureUsages::RENDER_ATTACHMENT,
        );
        let depth = texture(
            &mut cache,
            "penumbra_face_normal_depth",
            FACE_DEPTH_FORMAT,
            TextureUsages::RENDER_ATTACHMENT,
        );
        commands
            .entity(entity)
            .insert(ViewFaceNormalTexture { normal, depth });
    }
}

/// Draws the view's face-normal phase into its target (cleared: w 0 is background).
fn face_normal_prepass(
    world: &World,
    view: ViewQuery<(
        &ExtractedCamera,
        &ExtractedView,
        &ViewFaceNormalTexture,
        Option<&MainPassResolutionOverride>,
    )>,
    phases: Res<ViewSortedRenderPhases<FaceNormal3d>>,
    mut ctx: RenderContext,
) {
    let view_entity = view.entity();
    let (camera, extracted_view, target, resolution_override) = view.into_inner();
    let Some(phase) = phases.get(&extracted_view.retained_view_entity) else {
        return;
    };
    let diagnostics = ctx.diagnostic_recorder();
    let diagnostics = diagnostics.as_deref();
    let time_span = diagnostics.time_span(ctx.command_encoder(), "penumbra_face_normals");
    let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
        label: Some("penumbra_face_normals"),
        color_attachments: &[Some(RenderPassColorAttachment {
            view: &target.normal.default_view,
            depth_slice: None,
            resolve_target: None,
            ops: Operations {
                load: LoadOp::Clear(Default::default()),
                store: StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(RenderPassDepthStencilAttachment {
            view: &target.depth.default_view,
            depth_ops: Some(Operations {
                load: LoadOp::Clear(0.0),
                store: StoreOp::Store,
            }),
            stencil_ops: None,
        }),
        timestamp_writes: None,
        occlusion_query_set: None,
        multiview_mask: None,
    });
    if let Some(viewport) =
        Viewport::from_viewport_and_override(camera.viewport.as_ref(), resolution_override)
    {
        pass.set_camera_viewport(&viewport);
    }
    if let Err(err) = phase.render(&mut pass, world, view_entity) {
        error!("Penumbra: face-normal pass: {err:?}");
    }
    drop(pass);
    time_span.end(ctx.command_encoder());
}
