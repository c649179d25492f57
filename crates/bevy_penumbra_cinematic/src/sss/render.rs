//! Render-world side of subsurface scattering: which views see a scattering material,
//! their pipelines (from Penumbra's lighting pipeline), textures, bind groups and draws.

use super::{ScatteringMaterial, SubsurfaceDebugView, SubsurfaceProfiles, SubsurfaceScattering};
use bevy::core_pipeline::deferred::copy_lighting_id::DeferredLightingIdDepthTexture;
use bevy::core_pipeline::prepass::ViewPrepassTextures;
use bevy::core_pipeline::schedule::Core3d;
use bevy::pbr::{MeshPipelineKey, MeshViewBindGroup, ViewKeyCache};
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::render::diagnostic::RecordDiagnostics;
use bevy::render::render_resource::binding_types::{
    texture_2d, texture_2d_multisampled, uniform_buffer_sized,
};
use bevy::render::render_resource::encase::UniformBuffer as EncaseBuffer;
use bevy::render::render_resource::{
    BindGroup, BindGroupEntries, BindGroupLayoutDescriptor, BindGroupLayoutEntries, Buffer,
    BufferUsages, CachedRenderPipelineId, ColorTargetState, ColorWrites, CompareFunction, Extent3d,
    LoadOp, MultisampleState, Operations, PipelineCache, RenderPassColorAttachment,
    RenderPassDepthStencilAttachment, RenderPassDescriptor, RenderPipelineDescriptor, ShaderStages,
    ShaderType, StoreOp, TextureDescriptor, TextureDimension, TextureFormat, TextureSampleType,
    TextureUsages, TextureViewId,
};
use bevy::render::renderer::{RenderContext, RenderDevice, RenderQueue, ViewQuery};
use bevy::render::sync_component::{SyncComponent, SyncComponentPlugin};
use bevy::render::sync_world::{MainEntity, RenderEntity};
use bevy::render::texture::{CachedTexture, TextureCache};
use bevy::render::view::{ExtractedView, RenderVisibleEntities, ViewTarget};
use bevy::render::{Extract, ExtractSchedule, Render, RenderStartup, RenderSystems};
use bevy::shader::ShaderDefVal;
use bevy_penumbra_df::lighting::{
    DeferredMsaaTextures, MsaaShadedLightingIds, PenumbraLightingBindGroup,
    PenumbraLightingPipeline, PenumbraLightingSystems, PenumbraLightingView,
    set_lighting_bind_groups, unresolved_color_attachment, visible_meshes,
};
use bevy_penumbra_df::system_times::timed;
use bevy_penumbra_df::{PenumbraGpuAllocations, PenumbraLighting, PenumbraShaderLibrary};
use penumbra_cinematic_core::sss::{FIRST_LIGHTING_ID, SubsurfaceUniform};

/// The split lighting pass's targets (HDR light before post-processing).
const SPLIT_FORMAT: TextureFormat = TextureFormat::Rgba16Float;

/// Main world: the meshes whose material `M` names a subsurface profile (empty while no
/// profile is registered).
#[derive(Resource)]
pub(super) struct ScatteringMeshes<M = StandardMaterial> {
    meshes: HashSet<Entity>,
    /// Meshes the last run examined: all on a full scan, else the changed handles' and
    /// the meshes of materials with an asset event.
    examined: usize,
    material: std::marker::PhantomData<fn() -> M>,
}

impl<M> Default for ScatteringMeshes<M> {
    fn default() -> Self {
        Self {
            meshes: HashSet::new(),
            examined: 0,
            material: std::marker::PhantomData,
        }
    }
}

impl<M> ScatteringMeshes<M> {
    /// The meshes, sorted (for tests).
    #[cfg(test)]
    pub(super) fn sorted(&self) -> Vec<Entity> {
        let mut v: Vec<Entity> = self.meshes.iter().copied().collect();
        v.sort();
        v
    }

    /// Meshes the last run examined (for tests).
    #[cfg(test)]
    pub(super) fn examined(&self) -> usize {
        self.examined
    }
}

/// Whether a material names a subsurface profile.
fn scatters<M: ScatteringMaterial>(materials: &Assets<M>, material: &MeshMaterial3d<M>) -> bool {
    materials
        .get(&material.0)
        .is_some_and(|m| m.lighting_pass_id() >= FIRST_LIGHTING_ID)
}

/// The meshes of material `M` by material, and each one's, while
/// [`find_scattering_meshes`] is active: a material's asset event finds its meshes.
pub(super) struct MeshesByMaterial<M: Asset> {
    material_of: HashMap<Entity, AssetId<M>>,
    meshes_of: HashMap<AssetId<M>, HashSet<Entity>>,
}

impl<M: Asset> Default for MeshesByMaterial<M> {
    fn default() -> Self {
        Self {
            material_of: HashMap::default(),
            meshes_of: HashMap::default(),
        }
    }
}

impl<M: Asset> MeshesByMaterial<M> {
    /// `entity`'s material is now `material`.
    fn set(&mut self, entity: Entity, material: AssetId<M>) {
        match self.material_of.insert(entity, material) {
            Some(old) if old == material => return,
            Some(old) => self.unlink(entity, old),
            None => {}
        }
        self.meshes_of.entry(material).or_default().insert(entity);
    }

    /// `entity` has no material (any more).
    fn remove(&mut self, entity: Entity) {
        if let Some(old) = self.material_of.remove(&entity) {
            self.unlink(entity, old);
        }
    }

    fn unlink(&mut self, entity: Entity, material: AssetId<M>) {
        if let Some(meshes) = self.meshes_of.get_mut(&material) {
            meshes.remove(&entity);
            if meshes.is_empty() {
                self.meshes_of.remove(&material);
            }
        }
    }
}

/// Keeps the set of meshes with a scattering material `M`, while a profile exists and a
/// Penumbra camera could shade it: a full scan when that starts, else only the meshes
/// whose material handle changed or went away, and the meshes of a material with an
/// asset event (its lighting id may have changed), found by an index of the meshes by
/// material kept meanwhile.
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
pub(super) fn find_scattering_meshes<M: ScatteringMaterial>(
    profiles: Res<SubsurfaceProfiles>,
    cameras: Query<(), With<PenumbraLighting>>,
    materials: Res<Assets<M>>,
    mut material_events: MessageReader<AssetEvent<M>>,
    meshes: Query<(Entity, &MeshMaterial3d<M>)>,
    changed: Query<(Entity, &MeshMaterial3d<M>), Changed<MeshMaterial3d<M>>>,
    mut removed: RemovedComponents<MeshMaterial3d<M>>,
    mut found: ResMut<ScatteringMeshes<M>>,
    // `Some` while active.
    mut index: Local<Option<MeshesByMaterial<M>>>,
) {
    if profiles.is_empty() || cameras.is_empty() {
        material_events.clear();
        removed.clear();
        *index = None;
        found.bypass_change_detection().examined = 0;
        if !found.meshes.is_empty() {
            found.meshes.clear();
        }
        return;
    }
    let found_mut = found.bypass_change_detection();
    let set = &mut found_mut.meshes;
    let mut modified = false;
    if let Some(index) = index.as_mut() {
        for entity in removed.read() {
            index.remove(entity);
            modified |= set.remove(&entity);
        }
        // New handles, then the meshes of the materials with an event.
        let mut examine = HashSet::new();
        for (entity, material) in &changed {
            index.set(entity, material.id());
            examine.insert(entity);
        }
        for event in material_events.read() {
            let (AssetEvent::Added { id }
            | AssetEvent::Modified { id }
            | AssetEvent::Removed { id }
            | AssetEvent::Unused { id }
            | AssetEvent::LoadedWithDependencies { id }) = event;
            if let Some(meshes) = index.meshes_of.get(id) {
                examine.extend(meshes.iter().copied());
            }
        }
        found_mut.examined = examine.len();
        for (entity, material) in meshes.iter_many(&examine) {
            modified |= if scatters(&materials, material) {
                set.insert(entity)
            } else {
                set.remove(&entity)
            };
        }
    } else {
        material_events.clear();
        removed.clear();
        let mut fresh = MeshesByMaterial::default();
        let mut now = HashSet::new();
        for (entity, material) in &meshes {
            fresh.set(entity, material.id());
            if scatters(&materials, material) {
                now.insert(entity);
            }
        }
        found_mut.examined = fresh.material_of.len();
        *index = Some(fresh);
        if now != *set {
            *set = now;
            modified = true;
        }
    }
    if modified {
        found.set_changed();
    }
}

/// Render world: the scattering meshes (per material type) and the profiles' uniform
/// data.
#[derive(Resource, Default)]
pub(super) struct SubsurfaceScene {
    meshes: HashMap<std::any::TypeId, HashSet<MainEntity>>,
    uniform: SubsurfaceUniform,
}

impl SubsurfaceScene {
    /// Whether a view shows a mesh with a scattering material.
    fn seen_by(&self, visible: Option<&RenderVisibleEntities>) -> bool {
        self.meshes.values().any(|m| !m.is_empty())
            && visible.is_some_and(|v| {
                visible_meshes(v).any(|e| self.meshes.values().any(|m| m.contains(&e)))
            })
    }
}

/// A scattering camera's settings in the render world.
#[derive(Component, Clone, Debug)]
pub struct ExtractedSubsurface {
    samples: u32,
    temporal: bool,
    debug_view: SubsurfaceDebugView,
}

impl SyncComponent for SubsurfaceScattering {
    type Target = (ExtractedSubsurface, ViewSubsurfaceBindGroup);
}

pub(super) fn sync_plugin() -> SyncComponentPlugin<SubsurfaceScattering> {
    SyncComponentPlugin::default()
}

/// What a Penumbra view draws for scattering pixels this frame (absent: it sees none).
#[derive(Component)]
#[allow(clippy::large_enum_variant, reason = "one per view")]
pub enum ViewSubsurface {
    /// Split lighting, then the scatter draw.
    Scatter {
        split: CachedRenderPipelineId,
        scatter: CachedRenderPipelineId,
        rest: CachedTexture,
        diffuse: CachedTexture,
        /// A deferred MSAA view: both draws run once per pixel after the lighting pass,
        /// and the scatter replaces the scattering samples' shading.
        msaa: bool,
    },
    /// No `SubsurfaceScattering`: Penumbra's lighting, unscattered.
    Plain(CachedRenderPipelineId),
}

/// A scattering view's uniform and group 2 (remade when a bound texture changes).
#[derive(Component)]
pub struct ViewSubsurfaceBindGroup {
    uniform: Buffer,
    group: Option<(BindGroup, [TextureViewId; 4])>,
}

/// Which draw a pipeline is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
enum Draw {
    Split,
    Scatter,
    Plain,
}

/// The scatter draw's group 2 and shader, and the pipelines queued per view key.
#[derive(Resource)]
struct SubsurfacePipelines {
    layout: BindGroupLayoutDescriptor,
    /// The scatter draw's group 2 on deferred MSAA views: the lighting ids and G-buffer
    /// per sample instead of the single-sample ids.
    msaa_layout: BindGroupLayoutDescriptor,
    scatter_shader: Handle<Shader>,
    queued: HashMap<(MeshPipelineKey, Draw), CachedRenderPipelineId>,
}

pub(super) fn build(render_app: &mut SubApp) {
    render_app
        // Deferred MSAA cameras, where no scattering pass runs, shade the profiles'
        // materials as ordinary ones.
        .insert_resource(MsaaShadedLightingIds {
            from: u32::from(FIRST_LIGHTING_ID),
        })
        .init_resource::<SubsurfaceScene>()
        .add_systems(RenderStartup, init_subsurface_pipelines)
        .add_systems(
            ExtractSchedule,
            (
                timed(extract_subsurface_profiles),
                timed(extract_subsurface_cameras),
            ),
        )
        .add_systems(
            Render,
            (
                timed(prepare_subsurface_views).in_set(RenderSystems::PrepareResources),
                timed(prepare_subsurface_bind_groups).in_set(RenderSystems::PrepareBindGroups),
            ),
        )
        .add_systems(
            Core3d,
            (
                timed(subsurface_scattering).in_set(PenumbraLightingSystems::Shading),
                // Deferred MSAA: after the lighting pass, whose shading of the scattering
                // samples the scatter replaces; before the forward opaque pass.
                timed(subsurface_scattering_msaa)
                    .after(PenumbraLightingSystems::Lighting)
                    .before(bevy::core_pipeline::core_3d::main_opaque_pass_3d)
                    .in_set(bevy::core_pipeline::Core3dSystems::MainPass),
            ),
        );
}

pub(super) fn finish(_render_app: &mut SubApp) {}

fn init_subsurface_pipelines(mut commands: Commands, library: Option<Res<PenumbraShaderLibrary>>) {
    let Some(library) = library else {
        warn!("Penumbra: the shader library is not registered; no subsurface scattering");
        return;
    };
    let float = || texture_2d(TextureSampleType::Float { filterable: false });
    let layout = BindGroupLayoutDescriptor::new(
        "penumbra_sss_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::VERTEX_FRAGMENT,
            (
                uniform_buffer_sized(false, Some(SubsurfaceUniform::min_size())),
                float(),
                float(),
                texture_2d(TextureSampleType::Uint),
            ),
        ),
    );
    let msaa_layout = BindGroupLayoutDescriptor::new(
        "penumbra_sss_msaa_layout",
        &BindGroupLayoutEntries::sequential(
            ShaderStages::VERTEX_FRAGMENT,
            (
                uniform_buffer_sized(false, Some(SubsurfaceUniform::min_size())),
                float(),
                float(),
                texture_2d_multisampled(TextureSampleType::Uint),
                texture_2d_multisampled(TextureSampleType::Uint),
            ),
        ),
    );
    commands.insert_resource(SubsurfacePipelines {
        layout,
        msaa_layout,
        scatter_shader: library.handle("sss/scatter.wgsl"),
        queued: HashMap::default(),
    });
}

/// The scattering meshes of material `M` (when they changed).
pub(super) fn extract_scattering_meshes<M: ScatteringMaterial>(
    mut scene: ResMut<SubsurfaceScene>,
    meshes: Extract<Res<ScatteringMeshes<M>>>,
) {
    if meshes.is_changed() {
        scene.meshes.insert(
            std::any::TypeId::of::<M>(),
            meshes.meshes.iter().map(|&e| MainEntity::from(e)).collect(),
        );
    }
}

fn extract_subsurface_profiles(
    mut scene: ResMut<SubsurfaceScene>,
    profiles: Extract<Res<SubsurfaceProfiles>>,
) {
    if profiles.is_changed() {
        let resolved: Vec<Vec4> = profiles
            .iter()
            .map(|(_, p)| p.resolve().0.d.extend(0.0))
            .collect();
        for (k, slot) in scene.uniform.profiles.iter_mut().enumerate() {
            *slot = resolved.get(k).copied().unwrap_or(Vec4::ZERO);
        }
    }
}

fn extract_subsurface_cameras(
    mut commands: Commands,
    cameras: Extract<Query<(RenderEntity, &SubsurfaceScattering)>>,
) {
    for (entity, settings) in &cameras {
        if let Ok(mut render) = commands.get_entity(entity) {
            render.insert(ExtractedSubsurface {
                samples: settings.resolve().0,
                temporal: settings.temporal,
                debug_view: settings.debug_view,
            });
        }
    }
}

impl SubsurfacePipelines {
    /// The pipeline of one draw for a view key, queued on first use.
    fn get(
        &mut self,
        cache: &PipelineCache,
        lighting: &PenumbraLightingPipeline,
        key: MeshPipelineKey,
        draw: Draw,
    ) -> CachedRenderPipelineId {
        *self.queued.entry((key, draw)).or_insert_with(|| {
            let layout = if key.msaa_samples() > 1 {
                &self.msaa_layout
            } else {
                &self.layout
            };
            cache.queue_render_pipeline(descriptor(
                lighting,
                key,
                draw,
                layout,
                &self.scatter_shader,
            ))
        })
    }
}

/// Penumbra's lighting pipeline turned to the scattering ids (`Less` against the
/// lighting-id depth: ids from `FIRST_LIGHTING_ID` up) and to one draw.
fn descriptor(
    lighting: &PenumbraLightingPipeline,
    key: MeshPipelineKey,
    draw: Draw,
    layout: &BindGroupLayoutDescriptor,
    scatter_shader: &Handle<Shader>,
) -> RenderPipelineDescriptor {
    // A multisampled key is a deferred MSAA view's: its draws run per pixel after the
    // lighting pass (`subsurface_scattering_msaa`).
    let msaa = key.msaa_samples() > 1;
    let mut desc = if msaa {
        lighting.msaa_view_descriptor(key)
    } else {
        lighting.view_descriptor(key)
    };
    let ids_from = ShaderDefVal::UInt(
        "PENUMBRA_LIGHTING_IDS_FROM".into(),
        u32::from(FIRST_LIGHTING_ID),
    );
    desc.vertex.shader_defs.push(ids_from.clone());
    if let Some(depth) = desc.depth_stencil.as_mut() {
        depth.depth_compare = Some(CompareFunction::Less);
    }
    let fragment = desc.fragment.as_mut().expect("the lighting pass has one");
    fragment.shader_defs.push(ids_from);
    match draw {
        Draw::Plain => desc.label = Some("penumbra_sss_plain_pipeline".into()),
        Draw::Split => {
            desc.label = Some("penumbra_sss_split_pipeline".into());
            fragment.shader_defs.push("PENUMBRA_SPLIT_DIFFUSE".into());
            fragment.entry_point = Some(
                if msaa {
                    "split_diffuse_msaa"
                } else {
                    "split_diffuse"
                }
                .into(),
            );
            let target = Some(ColorTargetState {
                format: SPLIT_FORMAT,
                blend: None,
                write_mask: ColorWrites::ALL,
            });
            fragment.targets = vec![target.clone(), target];
        }
        Draw::Scatter => {
            desc.label = Some("penumbra_sss_scatter_pipeline".into());
            fragment.shader = scatter_shader.clone();
            fragment.entry_point = Some(if msaa { "scatter_msaa" } else { "scatter" }.into());
            desc.vertex.shader = scatter_shader.clone();
            desc.layout[2] = layout.clone();
            if msaa {
                // Into the multisampled target, the scattering samples only.
                fragment.shader_defs.push("PENUMBRA_SSS_MSAA".into());
                desc.vertex.shader_defs.push("PENUMBRA_SSS_MSAA".into());
                desc.multisample = MultisampleState {
                    count: key.msaa_samples(),
                    ..default()
                };
            }
        }
    }
    desc
}

/// Per Penumbra view: whether it sees a scattering material, and then its draw's
/// pipelines and (scattering views) this frame's split-lighting textures.
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
fn prepare_subsurface_views(
    mut commands: Commands,
    views: Query<(
        Entity,
        &ExtractedView,
        &PenumbraLightingView,
        &ViewTarget,
        Option<&RenderVisibleEntities>,
        Has<ExtractedSubsurface>,
        Has<ViewSubsurface>,
    )>,
    scene: Res<SubsurfaceScene>,
    view_key_cache: Res<ViewKeyCache>,
    lighting: Option<Res<PenumbraLightingPipeline>>,
    pipelines: Option<ResMut<SubsurfacePipelines>>,
    pipeline_cache: Res<PipelineCache>,
    mut texture_cache: ResMut<TextureCache>,
    device: Res<RenderDevice>,
) {
    let (Some(lighting), Some(mut pipelines)) = (lighting, pipelines) else {
        return;
    };
    for (entity, view, lighting_view, target, visible, scatters, drawn) in &views {
        let key = view_key_cache.get(&view.retained_view_entity);
        let msaa = lighting_view.msaa.is_some();
        // Deferred MSAA views without the component: the lighting pass shades the
        // scattering materials (`MsaaShadedLightingIds`).
        let (Some(key), true, true) = (key, scatters || !msaa, scene.seen_by(visible)) else {
            if drawn {
                commands.entity(entity).remove::<ViewSubsurface>();
            }
            continue;
        };
        let mut pipeline = |draw| pipelines.get(&pipeline_cache, &lighting, *key, draw);
        let draw = if scatters {
            let size = target.main_texture().size();
            let mut texture = |label| {
                texture_cache.get(
                    &device,
                    TextureDescriptor {
                        label: Some(label),
                        size: Extent3d {
                            depth_or_array_layers: 1,
                            ..size
                        },
                        mip_level_count: 1,
                        sample_count: 1,
                        dimension: TextureDimension::D2,
                        format: SPLIT_FORMAT,
                        usage: TextureUsages::RENDER_ATTACHMENT | TextureUsages::TEXTURE_BINDING,
                        view_formats: &[],
                    },
                )
            };
            ViewSubsurface::Scatter {
                split: pipeline(Draw::Split),
                scatter: pipeline(Draw::Scatter),
                rest: texture("penumbra_sss_rest_light"),
                diffuse: texture("penumbra_sss_diffuse_irradiance"),
                msaa,
            }
        } else {
            ViewSubsurface::Plain(pipeline(Draw::Plain))
        };
        commands.entity(entity).insert(draw);
    }
}

/// Writes each scattering view's uniform; remakes its group 2 when a texture changed.
#[allow(
    clippy::too_many_arguments,
    clippy::type_complexity,
    reason = "a Bevy system"
)]
fn prepare_subsurface_bind_groups(
    mut views: Query<(
        &ViewSubsurface,
        &ExtractedSubsurface,
        &ViewPrepassTextures,
        Option<&DeferredMsaaTextures>,
        &mut ViewSubsurfaceBindGroup,
    )>,
    mut fresh: Query<
        (Entity, Has<ViewSubsurface>),
        (With<ExtractedSubsurface>, Without<ViewSubsurfaceBindGroup>),
    >,
    mut commands: Commands,
    scene: Res<SubsurfaceScene>,
    pipelines: Option<Res<SubsurfacePipelines>>,
    pipeline_cache: Res<PipelineCache>,
    frame: Res<bevy::diagnostic::FrameCount>,
    allocations: Res<PenumbraGpuAllocations>,
    device: Res<RenderDevice>,
    queue: Res<RenderQueue>,
) {
    let Some(pipelines) = pipelines else {
        return;
    };
    // A new scattering view's uniform buffer (its first frame draws from the next).
    for (entity, sees) in &mut fresh {
        if sees {
            commands.entity(entity).insert(ViewSubsurfaceBindGroup {
                uniform: allocations.sized_buffer(
                    &device,
                    "penumbra_sss_uniform",
                    SubsurfaceUniform::min_size().get(),
                    BufferUsages::UNIFORM | BufferUsages::COPY_DST,
                ),
                group: None,
            });
        }
    }
    for (draw, settings, prepass, msaa_textures, mut group) in &mut views {
        let ViewSubsurface::Scatter {
            rest,
            diffuse,
            msaa,
            ..
        } = draw
        else {
            continue;
        };
        // The lighting ids (and, multisampled, the G-buffer words) the scatter reads.
        let (ids_view, gbuffer_view) = match (msaa, msaa_textures) {
            (true, Some(m)) => (&m.lighting_id_view, Some(&m.gbuffer_view)),
            (false, _) => match &prepass.deferred_lighting_pass_id {
                Some(ids) => (&ids.texture.default_view, None),
                None => continue,
            },
            (true, None) => continue,
        };
        let uniform = SubsurfaceUniform {
            samples: settings.samples,
            frame: if settings.temporal { frame.0 } else { 0 },
            debug_view: match settings.debug_view {
                SubsurfaceDebugView::None => 0,
                SubsurfaceDebugView::Irradiance => 1,
                SubsurfaceDebugView::Scattered => 2,
            },
            ..scene.uniform
        };
        let mut bytes = EncaseBuffer::new(Vec::new());
        bytes
            .write(&uniform)
            .expect("the subsurface uniform encodes");
        queue.write_buffer(&group.uniform, 0, bytes.as_ref());
        let key = [
            rest.default_view.id(),
            diffuse.default_view.id(),
            ids_view.id(),
            gbuffer_view.unwrap_or(ids_view).id(),
        ];
        if group.group.as_ref().map(|(_, k)| k) != Some(&key) {
            let bind_group = match gbuffer_view {
                None => allocations.bind_group(
                    &device,
                    "penumbra_sss_bind_group",
                    &pipeline_cache.get_bind_group_layout(&pipelines.layout),
                    &BindGroupEntries::sequential((
                        group.uniform.as_entire_binding(),
                        &rest.default_view,
                        &diffuse.default_view,
                        ids_view,
                    )),
                ),
                Some(gbuffer_view) => allocations.bind_group(
                    &device,
                    "penumbra_sss_msaa_bind_group",
                    &pipeline_cache.get_bind_group_layout(&pipelines.msaa_layout),
                    &BindGroupEntries::sequential((
                        group.uniform.as_entire_binding(),
                        &rest.default_view,
                        &diffuse.default_view,
                        ids_view,
                        gbuffer_view,
                    )),
                ),
            };
            group.group = Some((bind_group, key));
        }
    }
}

/// The scattering pixels' draws, before Penumbra's lighting pass (which discards the
/// lighting-id depth it tests against): split lighting into the two textures, then the
/// scatter draw into the view's target — or, on a view without the component,
/// Penumbra's lighting of those pixels. Deferred MSAA views: [`subsurface_scattering_msaa`].
#[allow(clippy::type_complexity, reason = "a Bevy system")]
pub fn subsurface_scattering(
    view: ViewQuery<(
        &ViewSubsurface,
        &MeshViewBindGroup,
        &ViewTarget,
        &DeferredLightingIdDepthTexture,
        &PenumbraLightingBindGroup,
        Option<&ViewSubsurfaceBindGroup>,
    )>,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (draw, mesh_view, target, ids, lighting, group) = view.into_inner();
    let Some(lighting_group) = lighting.bind_group() else {
        return;
    };
    let depth = RenderPassDepthStencilAttachment {
        view: &ids.texture.default_view,
        depth_ops: Some(Operations {
            load: LoadOp::Load,
            store: StoreOp::Store,
        }),
        stencil_ops: None,
    };
    match draw {
        ViewSubsurface::Plain(id) => {
            let Some(pipeline) = pipeline_cache.get_render_pipeline(*id) else {
                return;
            };
            let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
                label: Some("penumbra_sss_plain"),
                color_attachments: &[Some(unresolved_color_attachment(target))],
                depth_stencil_attachment: Some(depth),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_render_pipeline(pipeline);
            set_lighting_bind_groups(&mut pass, mesh_view, lighting_group);
            pass.draw(0..3, 0..1);
        }
        ViewSubsurface::Scatter { msaa: false, .. } => {
            let draws = ScatterDraws {
                draw,
                mesh_view,
                target,
                lighting_group,
                group,
            };
            draws.record(&pipeline_cache, &mut ctx, Some(depth));
        }
        ViewSubsurface::Scatter { msaa: true, .. } => {}
    }
}

/// The scattering pixels' draws on a deferred MSAA view, after Penumbra's lighting
/// pass: split lighting once per pixel, then the scatter draw into the samples that hold
/// a scattering material (their unscattered shading replaced).
#[allow(clippy::type_complexity, reason = "a Bevy system")]
pub fn subsurface_scattering_msaa(
    view: ViewQuery<
        (
            &ViewSubsurface,
            &MeshViewBindGroup,
            &ViewTarget,
            &PenumbraLightingBindGroup,
            Option<&ViewSubsurfaceBindGroup>,
        ),
        With<DeferredMsaaTextures>,
    >,
    pipeline_cache: Res<PipelineCache>,
    mut ctx: RenderContext,
) {
    let (draw, mesh_view, target, lighting, group) = view.into_inner();
    let (ViewSubsurface::Scatter { msaa: true, .. }, Some(lighting_group)) =
        (draw, lighting.bind_group())
    else {
        return;
    };
    let draws = ScatterDraws {
        draw,
        mesh_view,
        target,
        lighting_group,
        group,
    };
    draws.record(&pipeline_cache, &mut ctx, None);
}

/// What the split lighting and scatter draws of one view bind.
struct ScatterDraws<'a> {
    draw: &'a ViewSubsurface,
    mesh_view: &'a MeshViewBindGroup,
    target: &'a ViewTarget,
    lighting_group: &'a BindGroup,
    group: Option<&'a ViewSubsurfaceBindGroup>,
}

impl ScatterDraws<'_> {
    /// Records split lighting into the two textures, then the scatter into the view's
    /// target; both depth-tested against `depth` (the lighting ids) when given.
    fn record(
        &self,
        pipeline_cache: &PipelineCache,
        ctx: &mut RenderContext,
        depth: Option<RenderPassDepthStencilAttachment<'_>>,
    ) {
        let ViewSubsurface::Scatter {
            split,
            scatter,
            rest,
            diffuse,
            ..
        } = self.draw
        else {
            return;
        };
        let (Some(split), Some(scatter), Some((group, _))) = (
            pipeline_cache.get_render_pipeline(*split),
            pipeline_cache.get_render_pipeline(*scatter),
            self.group.and_then(|g| g.group.as_ref()),
        ) else {
            return; // compiling, or the first frame
        };
        let diagnostics = ctx.diagnostic_recorder();
        let diagnostics = diagnostics.as_deref();
        let time_span =
            diagnostics.time_span(ctx.command_encoder(), "penumbra_subsurface_scattering");
        let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
            label: Some("penumbra_sss_split"),
            color_attachments: &[cleared(rest), cleared(diffuse)],
            depth_stencil_attachment: depth.clone(),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_render_pipeline(split);
        set_lighting_bind_groups(&mut pass, self.mesh_view, self.lighting_group);
        pass.draw(0..3, 0..1);
        drop(pass);
        let mut pass = ctx.begin_tracked_render_pass(RenderPassDescriptor {
            label: Some("penumbra_sss_scatter"),
            color_attachments: &[Some(unresolved_color_attachment(self.target))],
            depth_stencil_attachment: depth,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_render_pipeline(scatter);
        pass.set_bind_group(0, &self.mesh_view.main, &self.mesh_view.main_offsets);
        pass.set_bind_group(1, &self.mesh_view.binding_array, &[]);
        pass.set_bind_group(2, group, &[]);
        pass.draw(0..3, 0..1);
        drop(pass);
        time_span.end(ctx.command_encoder());
    }
}

/// A colour attachment cleared to 0 and stored.
fn cleared(texture: &CachedTexture) -> Option<RenderPassColorAttachment<'_>> {
    Some(RenderPassColorAttachment {
        view: &texture.default_view,
        depth_slice: None,
        resolve_target: None,
        ops: Operations {
            load: LoadOp::Clear(default()),
            store: StoreOp::Store,
        },
    })
}
