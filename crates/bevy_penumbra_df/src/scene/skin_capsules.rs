//! Skinned meshes cast through capsules fitted to their joints
//! ([`SkinnedCasters::Capsules`](super::SkinnedCasters::Capsules), the default of
//! [`DistanceFieldSceneCasters`]), as Unreal's capsule shadows.
//!
//! The fit (`penumbra_df_core::skin_capsules`) is made once per mesh and skin and cached;
//! each capsule is an analytic [`DistanceFieldCaster`] spawned as a child of its joint,
//! so transform propagation carries it with the skeleton and the object buffer uploads
//! only the records of capsules whose joints moved (a still character uploads nothing).
//! Capsules appear the frame after their fit (visibility and transforms propagate first).

use super::{CasterSource, DistanceFieldCaster, DistanceFieldSceneCasters};
use bevy::ecs::lifecycle::HookContext;
use bevy::ecs::world::DeferredWorld;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{PrimitiveTopology, VertexAttributeValues};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;
use penumbra_df_core::skin_capsules::{
    CapsuleFitSettings, FittedCapsule, SkinInput, fit_skin_capsules,
};
use std::sync::Arc;

/// How [`SkinnedCasters::Capsules`](super::SkinnedCasters::Capsules) fits capsules to a
/// skinned mesh's joints (`penumbra_df_core::skin_capsules` has the method).
///
/// Cost: one capsule record per kept joint and per piece fitted apart (the Fox: 31
/// capsules on 20 of its 24 joints), uploaded
/// when its joint moves; each capsule is an object the shadow and DFAO passes trace
/// analytically (no atlas memory). The fit runs once per mesh and skin, on the main
/// thread, so that the capsules appear on a frame that does not depend on thread
/// timing (deterministic captures): fitted to the volume the joints skin (a grid of
/// about 96 cells along the mesh), the Fox takes 43–55 ms with `penumbra_df_core`
/// optimised (opt-level 3); a mesh without triangles falls back to the vertex fit
/// (under a millisecond).
#[derive(Reflect, Clone, Copy, Debug, PartialEq)]
pub struct SkinCapsuleFit {
    /// The vertex fit only (a mesh whose triangles enclose nothing; a triangle mesh is
    /// fitted to its volume and ignores it): the fraction of a joint's vertices its
    /// capsule holds, in (0, 1]. Default 0.6 (the least shadow error on the Fox by the
    /// vertex fit, over 0.3–0.9). Larger covers fur tufts and ears with fatter capsules
    /// that shadow too much; smaller leaves a limb's edges out.
    pub coverage: f32,
    /// The vertex fit only: joints dominating fewer vertices get no capsule (the volume
    /// fit keeps a joint that owns 8 cells of the mesh's grid). Default 16.
    pub min_vertices: u32,
    /// Capsules thinner than this fraction of the mesh's thickest one are dropped
    /// (fingers, a tail's tip). Default 0.15.
    pub min_radius: f32,
}

impl Default for SkinCapsuleFit {
    fn default() -> Self {
        let d = CapsuleFitSettings::default();
        Self {
            coverage: d.coverage,
            min_vertices: d.min_vertices as u32,
            min_radius: d.min_radius,
        }
    }
}

impl From<SkinCapsuleFit> for CapsuleFitSettings {
    fn from(s: SkinCapsuleFit) -> Self {
        Self {
            coverage: s.coverage,
            min_vertices: s.min_vertices as usize,
            min_radius: s.min_radius,
        }
    }
}

/// On a skinned mesh entity cast through capsules: the capsule entities (children of
/// its joints). Removing or replacing it, or despawning the mesh, despawns them.
#[derive(Component, Clone, Debug, Default)]
#[component(on_discard = despawn_capsules)]
pub struct SkinCapsules(pub(super) Vec<Entity>);

impl SkinCapsules {
    /// The capsule entities, each with a [`SkinCapsule`].
    pub fn entities(&self) -> &[Entity] {
        &self.0
    }
}

/// On a capsule caster made for a skinned mesh: the mesh entity and the joint it
/// follows (its parent).
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(Component, Clone)]
pub struct SkinCapsule {
    /// The skinned mesh entity whose [`SkinCapsules`] lists it.
    pub mesh: Entity,
    /// The joint entity.
    pub joint: Entity,
}

fn despawn_capsules(mut world: DeferredWorld, context: HookContext) {
    let Some(capsules) = world.get::<SkinCapsules>(context.entity) else {
        return;
    };
    let capsules = capsules.0.clone();
    let mut commands = world.commands();
    for capsule in capsules {
        commands.entity(capsule).try_despawn();
    }
}

/// Asks for capsules for a skinned mesh entity (the first of its glTF mesh's skinned
/// primitives; `meshes` are all of them, fitted together).
#[derive(Component, Clone, Debug)]
pub(super) struct SkinCapsuleRequest {
    pub(super) root: Entity,
    pub(super) meshes: Vec<Entity>,
}

/// Fits by the meshes, their skin and the settings: instances share a fit.
type FitKey = (
    Vec<AssetId<Mesh>>,
    AssetId<SkinnedMeshInverseBindposes>,
    [u32; 3],
);

/// The skinned vertices of `mesh` appended to the arrays; `Err` with the reason when
/// the mesh has no usable skinning attributes.
pub(super) fn append_skin(
    mesh: &Mesh,
    positions: &mut Vec<Vec3>,
    joints: &mut Vec<[u16; 4]>,
    weights: &mut Vec<[f32; 4]>,
) -> Result<(), &'static str> {
    // Render-world-only meshes have given their data away.
    let Ok(Some(VertexAttributeValues::Float32x3(p))) =
        mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION)
    else {
        return Err("no Float32x3 positions in the main world");
    };
    let Ok(Some(VertexAttributeValues::Uint16x4(j))) =
        mesh.try_attribute_option(Mesh::ATTRIBUTE_JOINT_INDEX)
    else {
        return Err("no Uint16x4 joint indices");
    };
    let Ok(Some(VertexAttributeValues::Float32x4(w))) =
        mesh.try_attribute_option(Mesh::ATTRIBUTE_JOINT_WEIGHT)
    else {
        return Err("no Float32x4 joint weights");
    };
    if p.len() != j.len() || p.len() != w.len() {
        return Err("attributes of different lengths");
    }
    positions.extend(p.iter().map(|v| Vec3::from(*v)));
    joints.extend_from_slice(j);
    weights.extend_from_slice(w);
    Ok(())
}

/// The triangles of `mesh` (a triangle list; none for another topology) appended with
/// its vertex indices offset by `first`; triangles reaching past `end` are left out.
fn append_triangles(mesh: &Mesh, first: u32, end: u32, triangles: &mut Vec<[u32; 3]>) {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return;
    }
    let count = end - first;
    let indices: Vec<u32> = match mesh.indices() {
        Some(i) => i.iter().map(|i| i as u32).collect(),
        None => (0..count).collect(),
    };
    triangles.extend(
        indices
            .chunks_exact(3)
            .filter(|t| t.iter().all(|&i| i < count))
            .map(|t| [t[0] + first, t[1] + first, t[2] + first]),
    );
}

/// Fits and spawns the capsules of the skinned meshes that asked for them, once their
/// mesh and skin assets are loaded. Runs where both asset types exist
/// ([`skin_assets_exist`]).
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
pub(super) fn fit_skin_capsule_casters(
    mut commands: Commands,
    requests: Query<(Entity, &SkinCapsuleRequest), Without<SkinCapsules>>,
    skins: Query<(&Mesh3d, &SkinnedMesh)>,
    roots: Query<&DistanceFieldSceneCasters>,
    mesh_assets: Res<Assets<Mesh>>,
    bindposes: Res<Assets<SkinnedMeshInverseBindposes>>,
    parents: Query<&ChildOf>,
    visibility: Query<&InheritedVisibility>,
    mut fits: Local<HashMap<FitKey, Arc<Vec<FittedCapsule>>>>,
    mut mesh_events: MessageReader<AssetEvent<Mesh>>,
    mut skin_events: MessageReader<AssetEvent<SkinnedMeshInverseBindposes>>,
) {
    // A reloaded mesh or skin is fitted again.
    let stale = changed_assets(&mut mesh_events);
    let stale_skins = changed_assets(&mut skin_events);
    if !stale.is_empty() || !stale_skins.is_empty() {
        fits.retain(|(meshes, skin, _), _| {
            !stale_skins.contains(skin) && !meshes.iter().any(|m| stale.contains(m))
        });
    }
    for (entity, request) in &requests {
        let Ok(settings) = roots.get(request.root) else {
            continue;
        };
        let Ok((_, lead)) = skins.get(entity) else {
            commands.entity(entity).insert(SkinCapsules::default());
            continue;
        };
        // The primitives skinned to the same skeleton fit together.
        let members: Vec<&Mesh3d> = request
            .meshes
            .iter()
            .filter_map(|&m| skins.get(m).ok())
            .filter(|(_, s)| {
                s.joints == lead.joints && s.inverse_bindposes == lead.inverse_bindposes
            })
            .map(|(mesh, _)| mesh)
            .collect();
        let Some(inverse) = bindposes.get(&lead.inverse_bindposes) else {
            continue; // not loaded yet
        };
        let fit = CapsuleFitSettings::from(settings.capsules);
        let key: FitKey = (
            members.iter().map(|m| m.id()).collect(),
            lead.inverse_bindposes.id(),
            [
                fit.coverage.to_bits(),
                fit.min_vertices as u32,
                fit.min_radius.to_bits(),
            ],
        );
        let capsules = if let Some(found) = fits.get(&key) {
            found.clone()
        } else {
            let Some(meshes) = members
                .iter()
                .map(|m| mesh_assets.get(&m.0))
                .collect::<Option<Vec<&Mesh>>>()
            else {
                continue; // not loaded yet
            };
            let (mut positions, mut joints, mut weights) = (Vec::new(), Vec::new(), Vec::new());
            let mut triangles = Vec::new();
            if let Some(reason) = meshes.iter().find_map(|m| {
                let first = positions.len() as u32;
                let appended = append_skin(m, &mut positions, &mut joints, &mut weights);
                append_triangles(m, first, positions.len() as u32, &mut triangles);
                appended.err()
            }) {
                warn!(
                    "Penumbra: skinned mesh {entity} casts no capsule shadow: {reason}. \
                     Keep its asset in the main world (RenderAssetUsages::MAIN_WORLD)."
                );
                commands.entity(entity).insert(SkinCapsules::default());
                continue;
            }
            let joint_parents: Vec<Option<usize>> = lead
                .joints
                .iter()
                .map(|&joint| {
                    let parent = parents.get(joint).ok()?.parent();
                    lead.joints.iter().position(|&j| j == parent)
                })
                .collect();
            let fitted = Arc::new(fit_skin_capsules(
                &SkinInput {
                    positions: &positions,
                    joints: &joints,
                    weights: &weights,
                    inverse_bindposes: inverse,
                    parents: &joint_parents,
                    triangles: &triangles,
                },
                &fit,
            ));
            fits.insert(key, fitted.clone());
            fitted
        };
        // A hidden mesh's capsules are hidden from the start.
        let shown = if visibility.get(entity).is_ok_and(|v| !v.get()) {
            Visibility::Hidden
        } else {
            Visibility::Inherited
        };
        let mut spawned = Vec::with_capacity(capsules.len());
        for capsule in capsules.iter() {
            let Some(&joint) = lead.joints.get(capsule.joint) else {
                continue;
            };
            let local = Transform::from_translation(capsule.center)
                .with_rotation(Quat::from_rotation_arc(Vec3::Y, capsule.axis));
            let id = commands
                .spawn((
                    Name::new("penumbra skin capsule"),
                    DistanceFieldCaster {
                        source: CasterSource::Capsule {
                            radius: capsule.radius,
                            half_length: capsule.half_length,
                        },
                        two_sided: false,
                        ground: false,
                        ..settings.caster.clone()
                    },
                    local,
                    shown,
                    SkinCapsule {
                        mesh: entity,
                        joint,
                    },
                    ChildOf(joint),
                ))
                .id();
            spawned.push(id);
        }
        commands.entity(entity).insert(SkinCapsules(spawned));
    }
}

/// A hidden skinned mesh hides its capsules (they hang from its joints, not from it).
#[allow(clippy::type_complexity, reason = "a Bevy query")]
pub(super) fn sync_skin_capsule_visibility(
    meshes: Query<
        (&SkinCapsules, &InheritedVisibility),
        Or<(Changed<InheritedVisibility>, Changed<SkinCapsules>)>,
    >,
    mut capsules: Query<&mut Visibility, With<SkinCapsule>>,
) {
    for (list, visible) in &meshes {
        let want = if visible.get() {
            Visibility::Inherited
        } else {
            Visibility::Hidden
        };
        for &capsule in &list.0 {
            if let Ok(mut v) = capsules.get_mut(capsule) {
                v.set_if_neq(want);
            }
        }
    }
}

/// The assets modified or removed since the last read.
fn changed_assets<A: Asset>(events: &mut MessageReader<AssetEvent<A>>) -> Vec<AssetId<A>> {
    events
        .read()
        .filter_map(|e| match e {
            AssetEvent::Modified { id } | AssetEvent::Removed { id } => Some(*id),
            _ => None,
        })
        .collect()
}

/// Whether the app has meshes and skins (headless logic apps may have neither).
pub(super) fn skin_assets_exist(
    meshes: Option<Res<Assets<Mesh>>>,
    skins: Option<Res<Assets<SkinnedMeshInverseBindposes>>>,
) -> bool {
    meshes.is_some() && skins.is_some()
}
