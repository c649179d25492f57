//! The distance-field scene: casters, the SDF atlas and the GPU object buffer.
//!
//! Unreal keeps every distance-field object on the GPU and sends only changes (Wright,
//! *Dynamic Occlusion with Signed Distance Fields*, SIGGRAPH 2015). Here the ECS is the
//! source of truth:
//!
//! - [`DistanceFieldCaster`] on an entity makes it a caster. Its distances come from the
//!   entity's `Mesh3d` (baked automatically on the async pool and cached, see
//!   [`crate::sdf_asset`]; instances of one mesh share one SDF), from an explicit
//!   [`SdfVolumeAsset`] handle, or from an analytic shape (sphere, box, capsule, plane).
//!   [`DistanceFieldSceneCasters`] on a glTF scene's root makes every mesh under it a
//!   caster, by a documented rule (skinned meshes cast through capsules fitted to their
//!   joints; small and alpha-blended meshes skipped; open double-sided and alpha-masked
//!   ones two-sided).
//! - Every SDF in use is placed once in a 3D `R16Float` **atlas** under a memory budget
//!   ([`DistanceFieldSceneSettings::atlas_budget_bytes`]); freed space is reused. When a
//!   volume does not fit, it is placed as sparse bricks at full resolution if they fit
//!   (a near-cube pool fits between volumes where a wide slab does not); else one
//!   warning is logged and the volume is halved in resolution (up to twice); if it still
//!   does not fit its casters are skipped until atlas space is freed (then tried again;
//!   a volume placed at reduced resolution stays so).
//!   Large volumes ([`DistanceFieldSceneSettings::sparse_min_bytes`]) are placed as
//!   sparse bricks: only the 8³ bricks near the surface, a coarse grid for the rest, and
//!   their entries in a brick table the passes bind beside the atlas
//!   (`penumbra_sdf::bricks`; ARCHITECTURE.md, "Sparse bricks").
//! - Every caster instance is one 128-byte record in the GPU **object buffer**
//!   (`penumbra_df_core::object`). The CPU keeps a mirror; change detection on
//!   `GlobalTransform`, `InheritedVisibility`, the caster and its SDF turns a frame's
//!   adds, removes and changes into slot writes, which a compute pass applies before the
//!   cameras render. A static scene uploads nothing; `k` changes upload `O(k)` bytes
//!   ([`DistanceFieldUploadStats`]).
//! - Views that consume the scene (today [`crate::debug_view::DistanceFieldDebugView`])
//!   cull the buffer on the GPU into a compact list with indirect dispatch arguments.
//!
//! **Skip what is not needed**: with no caster, no buffer or atlas exists, nothing is
//! uploaded and no pass runs.
//!
//! Conventions: Bevy's (right-handed, y up, metres). Records store positions relative
//! to 512 m tiles and shaders work camera-relative, so casters 10⁵ m from the origin
//! are as precise as near it. Non-uniform scale is safe: distances are scaled by the
//! transform's smallest singular value (conservative).
//!
//! Limits: a skinned mesh's capsules are rigid per joint (no bending within a joint, no
//! morph targets); its bind-pose SDF, if asked for, does not move with it; the atlas is never
//! defragmented and holds at most 1024 × 1024 × 4096 voxels (the records' coordinates);
//! casters are capped ([`DistanceFieldSceneSettings::max_casters`], and the device's
//! storage-binding limit: 2²⁰ at 128 MiB), the ones beyond it skipped with one warning
//! until slots free up.

mod bake_requests;
mod bricks;
mod cull;
mod heightfield;
mod mesh_shape;
mod placement;
mod query;
mod rebake;
mod rebake_render;
mod render;
mod scene_casters;
mod shading;
mod skin_capsules;
mod stretch;

use placement::{place_volume, release_volume};

use crate::sdf_asset::{SdfBakeFailed, SdfBaked, SdfVolumeAsset};
use crate::system_times::timed;
use bevy::ecs::entity::EntityHashMap;
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;
use bevy::render::RenderApp;
use penumbra_df_core::atlas::{AtlasAllocator, AtlasRegion};
use penumbra_df_core::object::{CasterShape, ObjectDesc, RECORD_BYTES, encode, flags};
use penumbra_df_core::table::{Deltas, ObjectTable};

pub use cull::CulledObjects;
pub use heightfield::{
    DistanceFieldHeightfield, HeightfieldTerrain, SceneHeightfields, image_heights,
};
pub use query::{DistanceFieldQuery, SphereHit};
pub(crate) use rebake::RebakeJobs;
pub use rebake::{DistanceFieldRebake, DistanceFieldRebakeStats, RebakeCaster, RebakedFrom};
pub(crate) use render::apply_distance_field_deltas;
pub(crate) use render::no_heightfields;
pub use render::{
    DistanceFieldGpu, DistanceFieldPipelines, DistanceFieldRenderSystems, GpuHeightfields,
};
pub use scene_casters::{
    DistanceFieldSceneCaster, DistanceFieldSceneCasters, MergeDistanceFieldCasters,
    SceneCasterCounts, SceneTwoSided, SkinnedCasters,
};
pub use shading::{CasterShading, mesh_shading_apart};
pub use skin_capsules::{SkinCapsule, SkinCapsuleFit, SkinCapsules};
pub use stretch::{CasterStretch, STRETCH_MAX_RATIO, STRETCH_STEPS_PER_OCTAVE};

/// Adds distance-field casters, the atlas and the object buffer. Part of
/// `PenumbraPlugins`; needs [`crate::SdfAssetPlugin`] for mesh casters.
#[derive(Default)]
pub struct DistanceFieldScenePlugin;

/// Where a caster's distances come from.
#[derive(Reflect, Clone, Debug, PartialEq)]
pub enum CasterSource {
    /// The entity's `Mesh3d`, baked automatically (and cached) at
    /// 32 samples per mesh unit (at least 48 along its longest axis) ×
    /// [`DistanceFieldCaster::resolution_scale`].
    Mesh,
    /// A baked or loaded SDF.
    Sdf(Handle<SdfVolumeAsset>),
    /// A sphere of `radius` around the entity's origin (local units).
    Sphere {
        /// Radius, local units.
        radius: f32,
    },
    /// A box of `half_size` centred on the entity's origin (local units).
    Cuboid {
        /// Half extents, local units.
        half_size: Vec3,
    },
    /// A capsule along the local y axis (local units).
    Capsule {
        /// Radius.
        radius: f32,
        /// Half the length of the core segment.
        half_length: f32,
    },
    /// The entity's local `y = 0` plane, solid below (floors, walls).
    Plane,
}

/// The mesh a [`CasterSource::Mesh`] caster bakes when it is not the entity's `Mesh3d`:
/// an entity drawn through a generated mesh keeps its source here
/// (`bevy_penumbra_cinematic`'s tessellation inserts it). Without it, the caster bakes
/// its `Mesh3d`.
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone)]
pub struct CasterMesh(pub Handle<Mesh>);

/// Makes an entity a distance-field caster.
///
/// Cost: one 128-byte record on the GPU per instance, uploaded only when the instance
/// changes; one atlas placement per distinct SDF (50³ samples ≈ 250 KB); for mesh
/// casters, one bake per distinct mesh and settings, cached on disk.
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone, Default)]
#[require(Transform, Visibility)]
pub struct DistanceFieldCaster {
    /// Where distances come from. Default: [`CasterSource::Mesh`].
    pub source: CasterSource,
    /// Multiplier of the default bake resolution for mesh casters (Unreal's "distance
    /// field resolution scale"): 32 samples per mesh unit, and at least 48 along the
    /// mesh's longest axis so that a small prop is not a blob of a few voxels (a 0.7 m
    /// helmet: 1.7 cm voxels, 0.7 MiB for its 5 fields; 64 would lower the scene
    /// corpus's errors by at most 0.015 for twice the memory). Default 1. Atlas memory
    /// and bake time grow with its cube.
    pub resolution_scale: f32,
    /// Foliage and other open or single-sided surfaces (leaf cards, cloth): bake a shell
    /// around every surface, about a voxel thick (`SignMethod::TWO_SIDED`), instead of
    /// deciding inside from outside. The shell occludes like any solid. Default `false`.
    /// No run-time cost.
    pub two_sided: bool,
    /// Ground: an open sheet facing up everywhere (terrain, a floor, a road) bakes as the
    /// top of a solid (`SignMethod::SolidBelow`, `penumbra_sdf::ground`): inside below
    /// it along the world's +y as the caster stands (turning it re-bakes it), the field
    /// the distance to the sheet itself. A shell about a bumpy terrain shadows the
    /// terrain at grazing light; a winding number has no inside to find in an open
    /// sheet. Wins over `two_sided`. Default `false`; [`DistanceFieldSceneCasters`]
    /// sets it by its rule. No run-time cost.
    pub ground: bool,
    /// Shadows distance-field-shadowed lights (while visible, see
    /// [`DistanceFieldCaster::cast_hidden_shadow`]). Default `true`.
    pub casts_shadows: bool,
    /// Casts its shadow even while hidden (`Visibility::Hidden`): a shadow proxy, e.g. a
    /// simplified stand-in for a detailed mesh, or a shadow for an object the camera does
    /// not draw (Unreal's "Cast Hidden Shadow"). Default `false`: like Bevy's meshes, a
    /// hidden caster casts no shadow.
    pub cast_hidden_shadow: bool,
    /// Occludes distance-field ambient occlusion (`DistanceFieldAmbientOcclusion`).
    /// Default `true`.
    pub casts_occlusion: bool,
    /// The share of the sky light a cone keeps where this caster would close it, in
    /// distance-field ambient occlusion: 0 (default) is solid; foliage, whose cards the
    /// field fills in but whose alpha lets light through, wants about 0.5 (Unreal's
    /// softened occlusion of two-sided foliage; [`DistanceFieldCaster::foliage`]). A
    /// caster that leaves `v` of a cone open leaves `τ + (1 − τ) v`. Clamped to 0…1 (NaN
    /// counts as 0) with one warning, stored in 1/255 steps. Shadows ignore it. No run-time cost.
    pub ao_transmission: f32,
}

/// [`DistanceFieldCaster::ao_transmission`] of [`DistanceFieldCaster::foliage`] and of
/// alpha-masked scene meshes ([`DistanceFieldSceneCasters::masked_ao_transmission`]):
/// leaf cards are about half leaf, half hole.
pub const FOLIAGE_AO_TRANSMISSION: f32 = 0.5;

impl DistanceFieldCaster {
    /// A mesh caster for foliage and other open, leaky surfaces: two-sided, letting
    /// [`FOLIAGE_AO_TRANSMISSION`] of the sky through in ambient occlusion.
    pub fn foliage() -> Self {
        Self {
            two_sided: true,
            ao_transmission: FOLIAGE_AO_TRANSMISSION,
            ..Self::default()
        }
    }
}

impl Default for DistanceFieldCaster {
    fn default() -> Self {
        Self {
            source: CasterSource::Mesh,
            resolution_scale: 1.0,
            two_sided: false,
            ground: false,
            casts_shadows: true,
            cast_hidden_shadow: false,
            casts_occlusion: true,
            ao_transmission: 0.0,
        }
    }
}

/// Scene-wide settings (a resource; change before the first caster appears).
#[derive(Resource, Reflect, Clone, Debug)]
#[reflect(Resource, Clone, Default)]
pub struct DistanceFieldSceneSettings {
    /// Memory for the SDF atlas, bytes. Default 64 MiB (a 256×256×512 `R16Float`
    /// texture: about 260 volumes of 50³). Capped by the device's 3D texture size and
    /// by the records' atlas coordinates (1024 × 1024 × 4096 voxels).
    pub atlas_budget_bytes: u64,
    /// Most casters in the object buffer. Default 2²⁰ (1,048,576: 128 MiB of records).
    /// Also capped by the device's `max_storage_buffer_binding_size` (128 MiB on many
    /// devices) and `max_buffer_size`, 128 bytes per caster. Casters beyond the cap are
    /// skipped — those that arrive when it is full, in entity order; casters already in
    /// the buffer are never evicted — with one warning, and join as slots free up.
    pub max_casters: u32,
    /// Volumes whose dense grid holds at least this many bytes are placed as sparse
    /// bricks (`penumbra_sdf::bricks`: only the 8³ bricks within 4 voxels of the
    /// surface) when that at least halves them, and any volume that finds no free box
    /// dense (before it is downsampled). Default 1 MiB (a 80³ grid); `u64::MAX` keeps
    /// every volume dense. Cost: one pass over the grid when it is placed, and a
    /// table read per distance sample of a bricked volume.
    pub sparse_min_bytes: u64,
}

impl Default for DistanceFieldSceneSettings {
    fn default() -> Self {
        Self {
            atlas_budget_bytes: 64 << 20,
            max_casters: 1 << 20,
            sparse_min_bytes: 1 << 20,
        }
    }
}

/// What the scene uploaded, for profiling and tests.
#[derive(Resource, Reflect, Clone, Debug, Default, PartialEq)]
#[reflect(Resource, Clone, Default)]
pub struct DistanceFieldUploadStats {
    /// Object-buffer bytes uploaded this frame (slot writes).
    pub frame_object_bytes: usize,
    /// Records written this frame.
    pub frame_records: usize,
    /// Atlas bytes uploaded this frame (new SDF placements; with a bricked volume's, the
    /// whole brick table).
    pub frame_atlas_bytes: usize,
    /// Object-buffer and atlas bytes uploaded since startup.
    pub total_bytes: u64,
    /// Live casters in the object buffer.
    pub objects: usize,
    /// Slots of the object buffer (live and free).
    pub slots: u32,
    /// Atlas texture size, bytes (0 until the first SDF caster).
    pub atlas_bytes: u64,
    /// Atlas bytes holding SDFs.
    pub atlas_used_bytes: u64,
    /// Distinct SDFs in the atlas.
    pub atlas_volumes: usize,
    /// SDFs placed at reduced resolution because the atlas was full (since startup).
    pub atlas_downsampled: usize,
    /// SDFs in the atlas as sparse bricks
    /// ([`DistanceFieldSceneSettings::sparse_min_bytes`]).
    pub atlas_bricked: usize,
    /// Bytes of the brick table: a header and one entry per brick of every bricked
    /// volume placed (freed ranges included, reused first).
    pub brick_table_bytes: u64,
    /// SDFs whose casters are skipped: they fit nowhere, even at quarter resolution
    /// (tried again when atlas space is freed).
    pub atlas_skipped: usize,
    /// Casters skipped because the object buffer is at its cap
    /// ([`DistanceFieldSceneSettings::max_casters`] or the device's limit).
    pub over_cap: usize,
}

/// One SDF placed in the atlas.
#[derive(Clone, Debug)]
struct PlacedVolume {
    /// The dense volume, or the pool of a bricked one.
    region: AtlasRegion,
    /// The dense grid's samples along each axis.
    dims: UVec3,
    /// A bricked volume's range of the brick table and its coarse grid's region.
    table: Option<(std::ops::Range<u32>, AtlasRegion)>,
    local_origin: Vec3,
    voxel_size: f32,
    /// `SdfVolume::margin`, voxels.
    margin: f32,
    users: u32,
}

/// A volume to copy into the atlas this frame: `f16` bits, x fastest.
#[derive(Clone, Debug)]
pub(crate) struct AtlasUpload {
    pub(crate) region: AtlasRegion,
    pub(crate) data: Vec<u16>,
}

/// The main-world state: the CPU mirror of the GPU scene. Reflected as an opaque
/// resource (its state is read through the methods below).
#[derive(Resource, Reflect, Default)]
#[reflect(Resource)]
pub struct DistanceFieldScene {
    #[reflect(ignore)]
    table: ObjectTable,
    #[reflect(ignore)]
    atlas: Option<AtlasAllocator>,
    #[reflect(ignore)]
    volumes: HashMap<AssetId<SdfVolumeAsset>, PlacedVolume>,
    /// Volumes that could not be placed (warned once), until atlas space is freed.
    #[reflect(ignore)]
    unplaceable: HashSet<AssetId<SdfVolumeAsset>>,
    /// Casters skipped because their volume could not be placed: retried when atlas
    /// space is freed.
    #[reflect(ignore)]
    unplaced_casters: HashSet<Entity>,
    /// Atlas space was freed since the last retry.
    #[reflect(ignore)]
    atlas_freed: bool,
    /// The atlas could not be created (budget below the minimum): not retried.
    #[reflect(ignore)]
    atlas_failed: bool,
    /// Casters skipped because the object buffer is full: retried as slots free up.
    #[reflect(ignore)]
    over_cap: HashSet<Entity>,
    /// The cap has been reported once.
    #[reflect(ignore)]
    warned_cap: bool,
    /// The device's cap on records (storage-binding and buffer size / 128 bytes).
    #[reflect(ignore)]
    device_max_objects: u32,
    /// Which volume each caster uses.
    #[reflect(ignore)]
    caster_volume: EntityHashMap<AssetId<SdfVolumeAsset>>,
    /// Casters waiting for their SDF (not yet loaded, baked or placed).
    #[reflect(ignore)]
    waiting: HashSet<Entity>,
    #[reflect(ignore)]
    uploads: Vec<AtlasUpload>,
    /// The brick table of volumes placed as bricks.
    #[reflect(ignore)]
    brick_table: bricks::BrickTable,
    /// Volumes placed as bricks.
    #[reflect(ignore)]
    bricked: usize,
    max_texture_3d: u32,
    /// The atlas has been reported full once (later overflows are only counted).
    #[reflect(ignore)]
    warned_full: bool,
    /// Casters whose transform or shape was reported unusable (once each).
    #[reflect(ignore)]
    warned_casters: HashSet<Entity>,
    /// Casters whose `ao_transmission` was reported out of range (once each).
    #[reflect(ignore)]
    warned_transmission: HashSet<Entity>,
    #[reflect(ignore)]
    downsampled: usize,
}

impl DistanceFieldScene {
    /// Where `volume` is in the atlas, if placed (re-baked fields are written there).
    pub(crate) fn volume_region(&self, volume: AssetId<SdfVolumeAsset>) -> Option<AtlasRegion> {
        // Bricked volumes are never re-baked (they have a surface; placeholders do not).
        self.volumes
            .get(&volume)
            .filter(|p| p.table.is_none())
            .map(|p| p.region)
    }

    /// Live casters.
    pub fn len(&self) -> usize {
        self.table.len()
    }

    /// Whether there is no live caster.
    pub fn is_empty(&self) -> bool {
        self.table.is_empty()
    }

    /// The CPU mirror of the object buffer, by slot.
    pub fn records(&self) -> &[penumbra_df_core::object::ObjectRecord] {
        self.table.records()
    }

    /// The buffer slot of a caster.
    pub fn slot(&self, entity: Entity) -> Option<u32> {
        self.table.slot(entity.to_bits())
    }

    /// Atlas size in voxels, once created.
    pub fn atlas_size(&self) -> Option<UVec3> {
        self.atlas.as_ref().map(AtlasAllocator::size)
    }
}

/// This frame's changes, handed to the render world.
#[derive(Resource, Clone, Default)]
pub(crate) struct DistanceFieldFrame {
    pub(crate) deltas: Deltas,
    pub(crate) uploads: Vec<AtlasUpload>,
    pub(crate) atlas_size: Option<UVec3>,
    /// The whole brick table, when it changed this frame.
    pub(crate) brick_table: Option<std::sync::Arc<[u32]>>,
}

/// System sets of the scene's main-world work, in `PostUpdate` after transform
/// propagation and visibility.
#[derive(SystemSet, Clone, Debug, PartialEq, Eq, Hash)]
pub enum DistanceFieldSystems {
    /// Casters for the meshes under [`DistanceFieldSceneCasters`] roots.
    TagSceneCasters,
    /// Bake requests for mesh casters.
    RequestBakes,
    /// Atlas placement and object records.
    UpdateObjects,
}

impl Plugin for DistanceFieldScenePlugin {
    fn build(&self, app: &mut App) {
        crate::shader_library::register_shader_library(app);
        crate::require_plugin::<crate::SdfAssetPlugin>(
            app,
            "DistanceFieldScenePlugin",
            "SdfAssetPlugin",
        );
        app.register_type::<DistanceFieldCaster>()
            .register_type::<CasterMesh>()
            .register_type::<CasterStretch>()
            .register_type::<DistanceFieldHeightfield>()
            .register_type::<DistanceFieldScene>()
            .register_type::<DistanceFieldSceneSettings>()
            .register_type::<DistanceFieldUploadStats>()
            .register_type::<DistanceFieldSceneCasters>()
            .register_type::<DistanceFieldSceneCaster>()
            .register_type::<MergeDistanceFieldCasters>()
            .register_type::<SceneCasterCounts>()
            .register_type::<CasterShading>()
            .register_type::<SkinCapsule>()
            .register_type::<DistanceFieldRebake>()
            .register_type::<RebakedFrom>()
            .register_type::<DistanceFieldRebakeStats>()
            .init_resource::<RebakeJobs>()
            .init_resource::<DistanceFieldRebakeStats>()
            .init_resource::<DistanceFieldSceneSettings>()
            .init_resource::<DistanceFieldUploadStats>()
            .init_resource::<DistanceFieldScene>()
            .init_resource::<DistanceFieldFrame>()
            .init_resource::<SceneHeightfields>()
            .configure_sets(
                PostUpdate,
                (
                    DistanceFieldSystems::TagSceneCasters,
                    DistanceFieldSystems::RequestBakes,
                    DistanceFieldSystems::UpdateObjects,
                )
                    .chain()
                    .after(TransformSystems::Propagate)
                    .after(bevy::camera::visibility::VisibilitySystems::VisibilityPropagate),
            )
            .add_systems(
                PostUpdate,
                (
                    (
                        timed(scene_casters::untag_removed_roots),
                        timed(scene_casters::tag_scene_casters),
                        timed(skin_capsules::fit_skin_capsule_casters)
                            .run_if(skin_capsules::skin_assets_exist),
                        timed(skin_capsules::sync_skin_capsule_visibility),
                        timed(rebake::drop_rebake_casters),
                        timed(rebake::rebake_skinned_meshes)
                            .run_if(skin_capsules::skin_assets_exist),
                        timed(scene_casters::count_scene_casters),
                    )
                        .chain()
                        .in_set(DistanceFieldSystems::TagSceneCasters)
                        .after(bevy::mesh::mark_3d_meshes_as_changed_if_their_assets_changed),
                    timed(bake_requests::request_caster_bakes)
                        .in_set(DistanceFieldSystems::RequestBakes)
                        .after(bevy::mesh::mark_3d_meshes_as_changed_if_their_assets_changed),
                    (
                        timed(remove_distance_field_casters),
                        timed(shading::detect_caster_shading),
                        timed(update_distance_field_casters),
                        timed(finish_frame),
                    )
                        .chain()
                        .in_set(DistanceFieldSystems::UpdateObjects),
                    // Apps without images (no `ImagePlugin`) have no terrain to build.
                    (
                        timed(heightfield::build_heightfields)
                            .run_if(resource_exists::<Assets<Image>>),
                        timed(heightfield::collect_heightfields),
                    )
                        .chain()
                        .in_set(DistanceFieldSystems::UpdateObjects),
                ),
            );
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app);
            rebake_render::build(render_app);
        }
    }

    fn finish(&self, app: &mut App) {
        let limits = app
            .world()
            .get_resource::<bevy::render::renderer::RenderDevice>()
            .map(|d| d.limits());
        let mut scene = app.world_mut().resource_mut::<DistanceFieldScene>();
        scene.max_texture_3d = limits.as_ref().map_or(2048, |l| l.max_texture_dimension_3d);
        // Without a device (no renderer) nothing is uploaded; keep the documented cap.
        scene.device_max_objects = limits.as_ref().map_or(1 << 20, |l| {
            let bytes = l.max_storage_buffer_binding_size.min(l.max_buffer_size);
            (bytes / RECORD_BYTES as u64).min(u64::from(u32::MAX)) as u32
        });
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::finish(render_app);
            rebake_render::finish(render_app);
        }
    }
}

/// Takes a caster out of the object buffer; casters waiting for a slot may take it.
fn remove_record(scene: &mut DistanceFieldScene, entity: Entity) {
    if scene.table.remove(entity.to_bits()) && !scene.over_cap.is_empty() {
        // Retried at the casters' next update (this frame's, when a caster was removed
        // before it), in entity order.
        let waiting: Vec<Entity> = scene.over_cap.drain().collect();
        scene.waiting.extend(waiting);
    }
}

fn remove_distance_field_casters(
    mut removed: RemovedComponents<DistanceFieldCaster>,
    casters: Query<(), With<DistanceFieldCaster>>,
    mut scene: ResMut<DistanceFieldScene>,
) {
    for entity in removed.read() {
        if casters.contains(entity) {
            continue; // removed and re-added this frame: updated below
        }
        remove_record(&mut scene, entity);
        scene.waiting.remove(&entity);
        scene.warned_casters.remove(&entity);
        scene.warned_transmission.remove(&entity);
        scene.unplaced_casters.remove(&entity);
        scene.over_cap.remove(&entity);
        release_volume(&mut scene, entity);
    }
}

/// The shape a caster's record gets now, placing its SDF in the atlas if needed (and
/// letting go of a volume it no longer uses); `None`: not in the scene this frame
/// (waiting for its SDF, or its SDF fits nowhere).
fn caster_shape(
    scene: &mut DistanceFieldScene,
    settings: &DistanceFieldSceneSettings,
    sdfs: &Assets<SdfVolumeAsset>,
    entity: Entity,
    caster: &DistanceFieldCaster,
    baked: Option<&SdfBaked>,
    bake_failed: bool,
) -> Option<CasterShape> {
    let volume_handle = match &caster.source {
        CasterSource::Mesh => baked.map(|b| b.0.id()),
        CasterSource::Sdf(handle) => Some(handle.id()),
        _ => None,
    };
    // The volume this caster used before, released after placing the new one so an
    // unchanged volume is not freed and re-uploaded.
    let previous = scene.caster_volume.get(&entity).copied();
    if volume_handle.is_none() && previous.is_some() {
        release_volume(scene, entity);
    }
    let volume_shape = |placed: &PlacedVolume| match &placed.table {
        Some((table, _)) => CasterShape::BrickedVolume {
            table_offset: table.start,
            dims: placed.dims,
            local_origin: placed.local_origin,
            voxel_size: placed.voxel_size,
            margin: placed.margin,
        },
        None => CasterShape::Volume {
            region: placed.region,
            local_origin: placed.local_origin,
            voxel_size: placed.voxel_size,
            margin: placed.margin,
        },
    };
    match (&caster.source, volume_handle) {
        (CasterSource::Sphere { radius }, _) => Some(CasterShape::Sphere { radius: *radius }),
        (CasterSource::Cuboid { half_size }, _) => Some(CasterShape::Cuboid {
            half_extents: *half_size,
        }),
        (
            CasterSource::Capsule {
                radius,
                half_length,
            },
            _,
        ) => Some(CasterShape::Capsule {
            radius: *radius,
            half_length: *half_length,
        }),
        (CasterSource::Plane, _) => Some(CasterShape::Plane),
        (_, Some(id)) if previous == Some(id) => Some(volume_shape(&scene.volumes[&id])),
        (_, Some(id)) => {
            let Some(asset) = sdfs.get(id) else {
                scene.waiting.insert(entity); // not loaded yet
                return None;
            };
            let placed = place_volume(scene, settings, id, asset);
            // Whether or not the new volume found room, the old one is let go.
            release_volume(scene, entity);
            match placed {
                Some(placed) => {
                    scene.caster_volume.insert(entity, id);
                    Some(volume_shape(&placed))
                }
                None => {
                    scene.unplaced_casters.insert(entity);
                    None
                }
            }
        }
        (_, None) => {
            // Bake pending (a failed bake is retried when its request changes, which
            // brings the caster back through `SdfBaked`).
            if !bake_failed {
                scene.waiting.insert(entity);
            }
            None
        }
    }
}

/// The record flags of a caster.
fn caster_flags(caster: &DistanceFieldCaster, visible: bool, shading_apart: bool) -> u32 {
    let mut f = 0;
    for (on, bit) in [
        (visible, flags::VISIBLE),
        (shading_apart, flags::SHADING_APART),
        (caster.casts_shadows, flags::CASTS_SHADOWS),
        (caster.casts_occlusion, flags::CASTS_OCCLUSION),
        (caster.two_sided, flags::TWO_SIDED),
        (caster.cast_hidden_shadow, flags::CAST_HIDDEN_SHADOW),
    ] {
        if on {
            f |= bit;
        }
    }
    f | flags::ao_transmission_bits(caster.ao_transmission)
}

/// Re-encodes changed casters (and those whose SDF just arrived, changed or failed;
/// those waiting for atlas space or a slot when space or a slot was freed).
#[allow(clippy::type_complexity)]
fn update_distance_field_casters(
    mut scene: ResMut<DistanceFieldScene>,
    settings: Res<DistanceFieldSceneSettings>,
    sdfs: Res<Assets<SdfVolumeAsset>>,
    changed: Query<
        Entity,
        (
            With<DistanceFieldCaster>,
            Or<(
                Changed<GlobalTransform>,
                Changed<DistanceFieldCaster>,
                Changed<InheritedVisibility>,
                Changed<SdfBaked>,
                Added<SdfBakeFailed>,
                Changed<CasterShading>,
                Changed<CasterStretch>,
            )>,
        ),
    >,
    mut unbaked: RemovedComponents<SdfBaked>,
    casters: Query<(
        &DistanceFieldCaster,
        &GlobalTransform,
        Option<&InheritedVisibility>,
        Option<&SdfBaked>,
        Has<SdfBakeFailed>,
        Option<&CasterShading>,
        Option<&CasterStretch>,
    )>,
) {
    let scene = &mut *scene;
    let mut todo: Vec<Entity> = changed.iter().collect();
    todo.extend(unbaked.read());
    todo.extend(scene.waiting.drain());
    if std::mem::take(&mut scene.atlas_freed) && !scene.unplaced_casters.is_empty() {
        scene.unplaceable.clear();
        todo.extend(scene.unplaced_casters.drain());
    }
    todo.sort_unstable();
    todo.dedup();
    let cap = settings.max_casters.min(scene.device_max_objects) as usize;
    for entity in todo {
        let Ok((caster, transform, visibility, baked, bake_failed, shading, stretch)) =
            casters.get(entity)
        else {
            continue;
        };
        let Some(shape) = caster_shape(scene, &settings, &sdfs, entity, caster, baked, bake_failed)
        else {
            remove_record(scene, entity);
            continue;
        };
        if !(0.0..=1.0).contains(&caster.ao_transmission)
            && scene.warned_transmission.insert(entity)
        {
            warn!(
                "Penumbra: distance-field caster {entity}: ao_transmission = {} is not in \
                 [0, 1]; clamped (NaN: 0, solid). Reported once.",
                caster.ao_transmission
            );
        }
        let desc = ObjectDesc {
            world_from_local: stretch::world_from_field(&caster.source, transform, stretch),
            shape,
            flags: caster_flags(
                caster,
                visibility.is_none_or(|v| v.get()),
                shading.is_some_and(|s| s.apart),
            ),
        };
        let record = match encode(&desc) {
            Ok(record) => record,
            Err(e) => {
                if scene.warned_casters.insert(entity) {
                    warn!(
                        "Penumbra: distance-field caster {entity}: {e}; it is skipped while it \
                         stays so (reported once)"
                    );
                }
                remove_record(scene, entity);
                continue;
            }
        };
        if scene.table.slot(entity.to_bits()).is_none() && scene.table.len() >= cap {
            if !scene.warned_cap {
                scene.warned_cap = true;
                warn!(
                    "Penumbra: the distance-field object buffer is full ({cap} casters: \
                     DistanceFieldSceneSettings::max_casters or the device's storage-buffer \
                     limit); further casters are skipped until slots free up (counted in \
                     DistanceFieldUploadStats::over_cap). Reported once."
                );
            }
            scene.over_cap.insert(entity);
            continue;
        }
        scene.over_cap.remove(&entity);
        scene.table.upsert(entity.to_bits(), record);
    }
}

/// Moves the frame's deltas and atlas uploads out for extraction, and updates stats.
fn finish_frame(
    mut scene: ResMut<DistanceFieldScene>,
    mut frame: ResMut<DistanceFieldFrame>,
    mut stats: ResMut<DistanceFieldUploadStats>,
) {
    let deltas = scene.table.take_deltas();
    let uploads = std::mem::take(&mut scene.uploads);
    let brick_table = scene.brick_table.take_changed();
    // A bricked volume's placement also sends the whole brick table.
    let atlas_bytes: usize = uploads.iter().map(|u| u.data.len() * 2).sum::<usize>()
        + brick_table.as_ref().map_or(0, |t| 4 * t.len());
    stats.frame_object_bytes = deltas.bytes();
    stats.frame_records = deltas.writes.len();
    stats.frame_atlas_bytes = atlas_bytes;
    stats.total_bytes += (deltas.bytes() + atlas_bytes) as u64;
    stats.objects = scene.table.len();
    stats.slots = scene.table.slot_count();
    stats.atlas_bytes = scene.atlas.as_ref().map_or(0, AtlasAllocator::bytes);
    stats.atlas_used_bytes = scene.atlas.as_ref().map_or(0, AtlasAllocator::used_bytes);
    stats.atlas_volumes = scene.volumes.len();
    stats.atlas_downsampled = scene.downsampled;
    stats.atlas_bricked = scene.bricked;
    stats.brick_table_bytes = 4 * scene.brick_table.len() as u64;
    stats.atlas_skipped = scene.unplaceable.len();
    stats.over_cap = scene.over_cap.len();
    *frame = DistanceFieldFrame {
        deltas,
        uploads,
        atlas_size: scene.atlas_size(),
        brick_table,
    };
}
