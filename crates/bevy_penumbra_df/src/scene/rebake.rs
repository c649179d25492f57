//! GPU re-bake of skinned meshes ([`DistanceFieldRebake`], opt-in per entity): a hero
//! character's own distance field, baked again from its posed triangles every
//! [`DistanceFieldRebake::interval`] frames.
//!
//! Each bake skins the mesh on the CPU (linear blend skinning as Bevy's vertex shader
//! does it, `penumbra_df_core::rebake::skinned_triangles`), centres a fixed cube of
//! `resolution³` samples on the posed bounds (`RebakeGrid`), and hands the triangles to
//! the render world, where `shaders/df/rebake.wgsl` computes every sample (exact
//! distance to the nearest triangle, signed by their winding number, so open seams keep
//! a sign) and copies the result into the cube's atlas region. The field is cast by a
//! companion caster entity ([`RebakedFrom`]) whose transform maps the cube's voxels to
//! the world: only its record and the cube change, the atlas placement never does.
//!
//! A pose that has not changed since the last bake (its joints' matrices and its mesh
//! the same) is not baked again: a character standing still costs nothing. Each bake
//! marks its cube dirty in the global field's clipmaps, so occlusion far away follows the
//! pose even while the cube stays where it was.
//!
//! Limits: the mesh's asset must keep its main-world data
//! (`RenderAssetUsages::MAIN_WORLD`); morph targets are not applied; the cube spans the
//! pose's longest side, so a character lying down or with arms spread gets coarser
//! voxels. Cost per bake: `resolution³ × triangles` point–triangle evaluations on the
//! GPU (the Fox, 576 triangles at 48³: 64 M) and an upload of 48 bytes per triangle.

use super::skin_capsules::append_skin;
use super::{CasterSource, DistanceFieldCaster};
use crate::sdf_asset::SdfVolumeAsset;
use bevy::ecs::lifecycle::HookContext;
use bevy::ecs::world::DeferredWorld;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use penumbra_df_core::rebake::{REBAKE_MARGIN, RebakeGrid, clamp_resolution, skinned_triangles};
use penumbra_sdf::SdfVolume;
use penumbra_sdf::volume::MAX_VOXEL_DISTANCE;
use std::sync::Arc;

/// Re-bakes a skinned mesh's distance field on the GPU from its pose (module docs).
/// Put it on the entity with the `SkinnedMesh`;
/// [`DistanceFieldSceneCasters`](super::DistanceFieldSceneCasters) then leaves that mesh
/// to it (no capsules, no bind-pose field), and decides it again by its rule when the
/// component is removed.
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone, Default)]
pub struct DistanceFieldRebake {
    /// Samples along each side of the cube, rounded to a multiple of 8 in 16–128.
    /// Default 48, the knee of the error–work front on the Fox (shadow error on shadowed
    /// pixels against rays on its skinned triangles, mean of four poses: 16 / 24 / 32 /
    /// 48 / 64 → 0.280 / 0.176 / 0.134 / 0.076 / 0.046; its capsules 0.187). Atlas
    /// memory `resolution³ × 2` bytes (216 KiB at 48); GPU work per bake
    /// `resolution³ × triangles`.
    pub resolution: u32,
    /// Frames from one bake to the next (1: every frame). Default 1. Between bakes the
    /// field and its placement stay as last baked.
    pub interval: u32,
    /// The field's caster settings (shadows, occlusion, hidden shadows, AO
    /// transmission); its `source`, `two_sided`, `ground` and `resolution_scale` are
    /// not used. Default: [`DistanceFieldCaster::default`].
    pub caster: DistanceFieldCaster,
}

impl Default for DistanceFieldRebake {
    fn default() -> Self {
        Self {
            resolution: 48,
            interval: 1,
            caster: DistanceFieldCaster::default(),
        }
    }
}

/// On a re-baked mesh: the caster entity of its field. Removing it or the mesh despawns
/// the caster.
#[derive(Component, Clone, Debug)]
#[component(on_discard = despawn_rebake_caster)]
pub struct RebakeCaster {
    caster: Entity,
    volume: Handle<SdfVolumeAsset>,
    resolution: u32,
    /// What the last bake was made from: the mesh and its joints' skinning matrices.
    baked: (AssetId<Mesh>, Vec<Mat4>),
}

impl RebakeCaster {
    /// The caster entity (with [`RebakedFrom`]).
    pub fn entity(&self) -> Entity {
        self.caster
    }
}

/// On the caster entity of a re-baked field: the mesh entity it is baked from.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(Component, Clone)]
pub struct RebakedFrom(pub Entity);

fn despawn_rebake_caster(mut world: DeferredWorld, context: HookContext) {
    let Some(caster) = world.get::<RebakeCaster>(context.entity).map(|c| c.caster) else {
        return;
    };
    world.commands().entity(caster).try_despawn();
}

/// One bake this frame: the posed triangles' corners relative to the grid's origin
/// (three `vec4`s each) and the volume whose atlas region receives it.
#[derive(Clone, Debug)]
pub(crate) struct RebakeJob {
    pub(crate) volume: AssetId<SdfVolumeAsset>,
    pub(crate) grid: RebakeGrid,
    pub(crate) corners: Arc<Vec<[f32; 4]>>,
    /// The mesh entity (the render world pools its buffers by it).
    pub(crate) mesh: Entity,
    /// Counts the bakes of the app: a later job has a larger number.
    pub(crate) sequence: u64,
    /// The field goes into the global field (occludes, opaque to AO).
    pub(crate) composes: bool,
}

/// This frame's bakes, and every re-baked mesh alive (main world; extracted).
#[derive(Resource, Default, Clone, Debug)]
pub(crate) struct RebakeJobs {
    pub(crate) jobs: Vec<RebakeJob>,
    pub(crate) live: Vec<Entity>,
    sequence: u64,
}

impl RebakeJobs {
    /// The world boxes of this frame's bakes that go into the global field: their
    /// distances change though their records may not.
    pub(crate) fn dirty_boxes(&self) -> impl Iterator<Item = (Vec3, Vec3)> + '_ {
        self.jobs.iter().filter(|j| j.composes).map(|j| {
            let g = &j.grid;
            let far = g.origin + Vec3::splat(g.voxel_size * (g.resolution - 1) as f32);
            (g.origin, far)
        })
    }
}

/// This frame's re-bakes (main world): what [`DistanceFieldRebake`] costs.
#[derive(Resource, Reflect, Clone, Debug, Default, PartialEq, Eq)]
#[reflect(Resource, Clone, Default)]
pub struct DistanceFieldRebakeStats {
    /// Meshes with [`DistanceFieldRebake`].
    pub meshes: usize,
    /// Bakes handed to the GPU this frame.
    pub bakes: usize,
    /// Meshes due a bake this frame whose pose had not changed since their last: not
    /// baked again.
    pub still: usize,
    /// Triangles uploaded for this frame's bakes (48 bytes each); the GPU evaluates
    /// `resolution³` samples against each.
    pub triangles: usize,
}

/// The volume a re-baked field is placed with: the cube, in voxel units (the caster's
/// transform scales it), far everywhere until the first bake lands.
fn placeholder(resolution: u32) -> SdfVolumeAsset {
    let dims = UVec3::splat(resolution);
    SdfVolumeAsset {
        volume: SdfVolume {
            dims,
            origin: bevy::math::DVec3::ZERO,
            voxel_size: 1.0,
            data: vec![SdfVolume::quantize(MAX_VOXEL_DISTANCE); (resolution as usize).pow(3)],
            margin: REBAKE_MARGIN,
        },
    }
}

/// The transform of a caster whose volume is in voxels: voxel `(i, j, k)` at
/// `origin + voxel_size · (i, j, k)`.
fn grid_transform(grid: &RebakeGrid) -> Transform {
    Transform::from_translation(grid.origin).with_scale(Vec3::splat(grid.voxel_size))
}

type RebakeItem<'a> = (
    Entity,
    &'a DistanceFieldRebake,
    &'a Mesh3d,
    &'a SkinnedMesh,
    Option<&'a mut RebakeCaster>,
    &'a InheritedVisibility,
);

/// Poses the re-baked meshes due this frame, spawns their casters on first sight, moves
/// each caster onto its new cube, and lists the bakes for the render world (none for a
/// pose unchanged since its last bake). Runs after
/// transform propagation (the joints are where they are drawn) and before the objects
/// are encoded (the caster's record follows in the same frame).
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
pub(super) fn rebake_skinned_meshes(
    mut commands: Commands,
    mut meshes: Query<RebakeItem>,
    joints: Query<&GlobalTransform, Without<RebakedFrom>>,
    casters: Query<(&Transform, &Visibility), With<RebakedFrom>>,
    mesh_assets: Res<Assets<Mesh>>,
    bindposes: Res<Assets<SkinnedMeshInverseBindposes>>,
    mut volumes: ResMut<Assets<SdfVolumeAsset>>,
    mut jobs: ResMut<RebakeJobs>,
    mut stats: ResMut<DistanceFieldRebakeStats>,
    mut frame: Local<u64>,
    mut warned: Local<bevy::platform::collections::HashSet<Entity>>,
) {
    *frame += 1;
    jobs.jobs.clear();
    jobs.live.clear();
    *stats = DistanceFieldRebakeStats::default();
    for (entity, settings, mesh, skin, mut current, visible) in &mut meshes {
        jobs.live.push(entity);
        stats.meshes += 1;
        let resolution = clamp_resolution(settings.resolution);
        let interval = u64::from(settings.interval.max(1));
        let fresh = current.as_ref().is_none_or(|c| c.resolution != resolution);
        let shown = if visible.get() {
            Visibility::Inherited
        } else {
            Visibility::Hidden
        };
        if let Some(c) = current.as_ref()
            && !fresh
            && let Ok((_, v)) = casters.get(c.caster)
            && *v != shown
        {
            commands.entity(c.caster).insert(shown);
        }
        if !fresh && !(*frame + u64::from(entity.index_u32())).is_multiple_of(interval) {
            continue;
        }
        let (Some(asset), Some(inverse)) = (
            mesh_assets.get(&mesh.0),
            bindposes.get(&skin.inverse_bindposes),
        ) else {
            continue; // loading
        };
        let joint_from_bind: Vec<Mat4> = skin
            .joints
            .iter()
            .zip(inverse.iter())
            .map(|(&joint, inverse)| {
                joints
                    .get(joint)
                    .map_or(Mat4::NAN, |g| g.to_matrix() * *inverse)
            })
            .collect();
        if !fresh
            && let Some(c) = current.as_ref()
            && c.baked.0 == mesh.id()
            && c.baked.1 == joint_from_bind
        {
            stats.still += 1;
            continue; // the pose of its last bake: that field stands
        }
        let (mut positions, mut joint_indices, mut weights) = (Vec::new(), Vec::new(), Vec::new());
        if let Err(reason) = append_skin(asset, &mut positions, &mut joint_indices, &mut weights) {
            if warned.insert(entity) {
                warn!(
                    "Penumbra: skinned mesh {entity} is not re-baked: {reason}. Keep its \
                     asset in the main world (RenderAssetUsages::MAIN_WORLD)."
                );
            }
            continue;
        }
        let indices: Vec<u32> = match asset.indices() {
            Some(i) => i.iter().map(|i| i as u32).collect(),
            None => (0..positions.len() as u32).collect(),
        };
        let triangles = skinned_triangles(
            &positions,
            &indices,
            &joint_indices,
            &weights,
            &joint_from_bind,
        );
        let Some(grid) =
            bounds(&triangles).and_then(|(lo, hi)| RebakeGrid::around(lo, hi, resolution))
        else {
            continue; // nothing posable: the last bake stays
        };
        let corners: Vec<[f32; 4]> = triangles
            .iter()
            .flatten()
            .map(|v| (*v - grid.origin).extend(0.0).to_array())
            .collect();
        let transform = grid_transform(&grid);
        let volume = match current.as_deref_mut() {
            Some(c) if !fresh => {
                // Placed through commands, applied before the records are encoded this
                // frame (transforms have propagated already); a cube that stays keeps
                // its record, nothing is uploaded for it.
                if let Ok((t, _)) = casters.get(c.caster)
                    && *t != transform
                {
                    commands
                        .entity(c.caster)
                        .insert((transform, GlobalTransform::from(transform)));
                }
                c.baked = (mesh.id(), joint_from_bind);
                c.volume.id()
            }
            _ => {
                let volume = volumes.add(placeholder(resolution));
                let caster = commands
                    .spawn((
                        Name::new("penumbra re-baked field"),
                        DistanceFieldCaster {
                            source: CasterSource::Sdf(volume.clone()),
                            two_sided: false,
                            ground: false,
                            resolution_scale: 1.0,
                            ..settings.caster.clone()
                        },
                        transform,
                        GlobalTransform::from(transform),
                        shown,
                        RebakedFrom(entity),
                    ))
                    .id();
                let id = volume.id();
                // Replacing an earlier caster (a new resolution) despawns it.
                commands.entity(entity).insert(RebakeCaster {
                    caster,
                    volume,
                    resolution,
                    baked: (mesh.id(), joint_from_bind),
                });
                id
            }
        };
        jobs.sequence += 1;
        stats.bakes += 1;
        stats.triangles += triangles.len();
        let caster = &settings.caster;
        let sequence = jobs.sequence;
        jobs.jobs.push(RebakeJob {
            volume,
            grid,
            corners: Arc::new(corners),
            mesh: entity,
            sequence,
            composes: caster.casts_occlusion
                && (caster.ao_transmission.is_nan() || caster.ao_transmission <= 0.0),
        });
    }
}

/// The posed triangles' bounds (their corners are finite).
fn bounds(triangles: &[[Vec3; 3]]) -> Option<(Vec3, Vec3)> {
    let mut corners = triangles.iter().flatten();
    let first = *corners.next()?;
    Some(corners.fold((first, first), |(lo, hi), v| (lo.min(*v), hi.max(*v))))
}

/// A mesh that lost its [`DistanceFieldRebake`] lets its caster go (its capsules or
/// bind-pose field, gone while it was re-baked, come back by the scene's rule:
/// `tag_scene_casters` decides it again).
pub(super) fn drop_rebake_casters(
    mut commands: Commands,
    orphans: Query<Entity, (With<RebakeCaster>, Without<DistanceFieldRebake>)>,
) {
    for entity in &orphans {
        commands.entity(entity).remove::<RebakeCaster>();
    }
}
