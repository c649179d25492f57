//! Tagging a whole scene: [`DistanceFieldSceneCasters`] on a glTF `WorldAssetRoot` (or any
//! entity) makes the meshes spawned under it distance-field casters.
//!
//! The rule is documented on [`DistanceFieldSceneCasters`].

use super::DistanceFieldCaster;
use bevy::camera::primitives::MeshAabb;
use bevy::mesh::morph::MeshMorphWeights;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::mesh::{PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;

/// What [`DistanceFieldSceneCasters`] does with skinned and morphing meshes.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SkinnedCasters {
    /// Not casters (default): their SDF would not follow the animation.
    #[default]
    Skip,
    /// Casters baked from the bind pose, placed at the mesh entity's transform.
    BindPose,
}

/// When [`DistanceFieldSceneCasters`] bakes a mesh two-sided (a shell around every
/// surface instead of a solid).
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SceneTwoSided {
    /// Never: every mesh is baked as a closed solid.
    Never,
    /// When the material is alpha-masked, or `double_sided` and the mesh open (default).
    #[default]
    FromMaterial,
    /// Always: every mesh is baked as a shell.
    Always,
}

/// Makes every mesh spawned under this entity (typically a glTF `WorldAssetRoot`) a
/// [`DistanceFieldCaster`].
///
/// The rule, applied to every `Mesh3d` entity below the root (at any depth) when it
/// appears — the scene instanced, spawned later, or respawned by a hot reload — and to
/// all of them again when the root's settings change:
///
/// 1. **Skinned or morphed** meshes (`SkinnedMesh`, `MeshMorphWeights`): skipped, or cast
///    from their bind pose ([`SkinnedCasters`]). A bind-pose SDF does not follow the
///    animation: right for a statue, wrong for a running fox.
/// 2. **Not triangles** (lines, points) or no `Float32x3` positions: skipped.
/// 3. **Small**: the largest side of the mesh's world-space bounding box below
///    [`DistanceFieldSceneCasters::min_size`]: skipped (a pebble is not worth a trace).
/// 4. **Alpha-blended** `StandardMaterial`s (`Blend`, `Premultiplied`, `Add`,
///    `Multiply`): skipped. Glass and smoke would cast solid shadows.
/// 5. Otherwise a [`DistanceFieldCaster`] from the root's template
///    ([`DistanceFieldSceneCasters::caster`]), **two-sided** (a shell around the
///    surface) when the material is alpha-masked (`Mask`, `AlphaToCoverage`: foliage
///    cards), or `double_sided` and the mesh is open (some edge, after welding equal
///    positions, is not shared by exactly two triangles: a wall, a leaf, a terrain
///    sheet), per [`SceneTwoSided`]. A closed double-sided mesh is baked solid:
///    exporters mark most materials double-sided (Blender does by default), and a
///    shell about a voxel thick makes a solid box self-shadow at grazing angles.
///    Materials other than `StandardMaterial` count as opaque and single-sided.
///
/// A mesh entity that already has a `DistanceFieldCaster` of its own is left alone; the
/// casters it adds carry [`DistanceFieldSceneCaster`] and are removed when the
/// root's settings change (then re-added by the new rule) or the component is removed.
/// Instances of one mesh with the same settings share one bake (the bake cache keys on
/// mesh content and settings) and one atlas volume.
///
/// [`SceneCasterCounts`] on the root says what the rule did.
///
/// Cost: that of the casters it makes; the tagging itself runs once per new mesh entity
/// (and once per descendant when these settings change).
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone, Default)]
pub struct DistanceFieldSceneCasters {
    /// Skinned and morphing meshes. Default [`SkinnedCasters::Skip`].
    pub skinned: SkinnedCasters,
    /// Meshes whose world-space bounding box's largest side is below this many metres
    /// are skipped. Default 0.05 m. 0 keeps every mesh.
    pub min_size: f32,
    /// When a mesh is baked two-sided. Default [`SceneTwoSided::FromMaterial`].
    pub two_sided: SceneTwoSided,
    /// [`DistanceFieldCaster::ao_transmission`] of meshes with alpha-masked materials
    /// (foliage cards: the field fills the cards in, the alpha lets light through).
    /// Default [`super::FOLIAGE_AO_TRANSMISSION`] (0.5); 0 makes them solid.
    pub masked_ao_transmission: f32,
    /// The casters' options (`resolution_scale`, `casts_shadows`, …); `source` and
    /// `two_sided` are set per mesh. Default: `DistanceFieldCaster::default()`.
    pub caster: DistanceFieldCaster,
}

impl Default for DistanceFieldSceneCasters {
    fn default() -> Self {
        Self {
            skinned: SkinnedCasters::Skip,
            min_size: 0.05,
            two_sided: SceneTwoSided::FromMaterial,
            masked_ao_transmission: super::FOLIAGE_AO_TRANSMISSION,
            caster: DistanceFieldCaster::default(),
        }
    }
}

/// Marks a caster added by [`DistanceFieldSceneCasters`]; the root it came from.
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(Component, Clone)]
pub struct DistanceFieldSceneCaster(pub Entity);

/// What [`DistanceFieldSceneCasters`] did under a root (inserted on the root; counts of
/// mesh entities).
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Clone, Default)]
pub struct SceneCasterCounts {
    /// Casters added.
    pub casters: u32,
    /// Of those, two-sided.
    pub two_sided: u32,
    /// Skipped: skinned or morphing (with [`SkinnedCasters::Skip`]).
    pub skinned: u32,
    /// Skipped: below [`DistanceFieldSceneCasters::min_size`].
    pub small: u32,
    /// Skipped: alpha-blended material.
    pub blended: u32,
    /// Skipped: not triangles, or no usable positions.
    pub unsupported: u32,
    /// Left alone: the entity has its own `DistanceFieldCaster`.
    pub own: u32,
}

/// Why a mesh is or is not a caster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Verdict {
    Caster {
        two_sided: bool,
        /// Alpha-masked material (foliage).
        masked: bool,
    },
    Skinned,
    Small,
    Blended,
    Unsupported,
    /// Its mesh or material is not loaded yet: decide later.
    Wait,
}

/// The mesh entities a pass looks at.
type MeshQuery<'w, 's> = Query<
    'w,
    's,
    (
        &'static Mesh3d,
        &'static GlobalTransform,
        Option<&'static MeshMaterial3d<StandardMaterial>>,
        Has<SkinnedMesh>,
        Has<MeshMorphWeights>,
        Option<&'static DistanceFieldCaster>,
        Option<&'static DistanceFieldSceneCaster>,
    ),
>;

/// Whether a triangle-list mesh is closed: after welding equal positions, every edge
/// is shared by exactly two triangles. Strips and meshes without `Float32x3` positions
/// count as open.
pub(super) fn is_closed(mesh: &Mesh) -> bool {
    use bevy::platform::collections::HashMap;
    let (PrimitiveTopology::TriangleList, Ok(VertexAttributeValues::Float32x3(positions))) = (
        mesh.primitive_topology(),
        mesh.try_attribute(Mesh::ATTRIBUTE_POSITION),
    ) else {
        return false;
    };
    // Weld on a grid of 10⁻⁵ of the mesh's size: seams whose positions differ by
    // rounding (sin 0 against sin 2π) are one vertex.
    let (lo, hi) = positions
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), p| {
            (lo.min(Vec3::from(*p)), hi.max(Vec3::from(*p)))
        });
    let cell = ((hi - lo).max_element() * 1e-5).max(f32::MIN_POSITIVE);
    let mut welded: HashMap<[i64; 3], u32> = HashMap::default();
    let ids: Vec<u32> = positions
        .iter()
        .map(|p| {
            let key = p.map(|c| (c / cell).round() as i64);
            let next = welded.len() as u32;
            *welded.entry(key).or_insert(next)
        })
        .collect();
    let indices: Vec<u32> = match mesh.indices() {
        Some(list) => list.iter().filter_map(|v| ids.get(v).copied()).collect(),
        None => ids.clone(),
    };
    let expected = mesh.indices().map_or(ids.len(), |i| i.len());
    if indices.len() != expected || expected < 12 || !expected.is_multiple_of(3) {
        return false;
    }
    let mut edges: HashMap<(u32, u32), u32> = HashMap::default();
    for t in indices.chunks_exact(3) {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if a == b {
                continue;
            }
            *edges.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    edges.values().all(|&n| n == 2)
}

fn verdict(
    settings: &DistanceFieldSceneCasters,
    mesh: Option<&Mesh>,
    transform: &GlobalTransform,
    material: Option<Option<&StandardMaterial>>,
    animated: bool,
    closed: impl FnOnce(&Mesh) -> bool,
) -> Verdict {
    if animated && settings.skinned == SkinnedCasters::Skip {
        return Verdict::Skinned;
    }
    let Some(mesh) = mesh else {
        return Verdict::Wait;
    };
    let triangles = matches!(
        mesh.primitive_topology(),
        PrimitiveTopology::TriangleList | PrimitiveTopology::TriangleStrip
    );
    let positions = matches!(
        mesh.try_attribute(Mesh::ATTRIBUTE_POSITION),
        Ok(VertexAttributeValues::Float32x3(_))
    );
    let Some(aabb) = mesh.compute_aabb().filter(|_| triangles && positions) else {
        return Verdict::Unsupported;
    };
    // The world-space box of the local box (its 8 corners).
    let half = Vec3::from(aabb.half_extents);
    let affine = transform.affine();
    let extent = (Mat3::from(affine.matrix3).abs() * half) * 2.0;
    let size = extent.max_element();
    if !size.is_finite() || size < settings.min_size {
        return Verdict::Small;
    }
    let (double_sided, masked) = match material {
        // A material component whose asset is not loaded yet.
        Some(None) => return Verdict::Wait,
        Some(Some(m)) => match m.alpha_mode {
            AlphaMode::Blend | AlphaMode::Premultiplied | AlphaMode::Add | AlphaMode::Multiply => {
                return Verdict::Blended;
            }
            AlphaMode::Mask(_) | AlphaMode::AlphaToCoverage => (m.double_sided, true),
            AlphaMode::Opaque => (m.double_sided, false),
        },
        None => (false, false),
    };
    let two_sided = match settings.two_sided {
        SceneTwoSided::Never => false,
        SceneTwoSided::FromMaterial => masked || double_sided && !closed(mesh),
        SceneTwoSided::Always => true,
    };
    Verdict::Caster { two_sided, masked }
}

/// The nearest ancestor (or the entity itself) with [`DistanceFieldSceneCasters`].
fn scene_root(
    entity: Entity,
    parents: &Query<&ChildOf>,
    roots: &Query<(Entity, Ref<DistanceFieldSceneCasters>)>,
) -> Option<Entity> {
    std::iter::once(entity)
        .chain(parents.iter_ancestors(entity))
        .find(|&e| roots.contains(e))
}

/// What the rule decided for a mesh entity (kept on it, so that the root's counts are
/// recomputed from the meshes that exist: a respawned scene does not count twice).
#[derive(Component, Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct SceneMeshVerdict {
    root: Entity,
    counts: SceneCasterCounts,
}

/// Tags new mesh entities under a [`DistanceFieldSceneCasters`] root, and all of a
/// root's meshes again when its settings change.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
pub(super) fn tag_scene_casters(
    mut commands: Commands,
    roots: Query<(Entity, Ref<DistanceFieldSceneCasters>)>,
    new_meshes: Query<Entity, Added<Mesh3d>>,
    meshes: MeshQuery,
    parents: Query<&ChildOf>,
    children: Query<&Children>,
    mesh_assets: Option<Res<Assets<Mesh>>>,
    // Absent in apps without PBR (e.g. headless logic tests): no material, opaque.
    materials: Option<Res<Assets<StandardMaterial>>>,
    mut waiting: Local<Vec<Entity>>,
    mut closed_meshes: Local<bevy::platform::collections::HashMap<AssetId<Mesh>, bool>>,
) {
    // No root: nothing to tag (and no ancestor walk for every new mesh).
    if roots.is_empty() {
        waiting.clear();
        return;
    }
    // (mesh entity, root) pairs to decide this frame.
    let mut todo: Vec<(Entity, Entity)> = Vec::new();
    for (root, settings) in &roots {
        if settings.is_changed() {
            todo.extend(
                std::iter::once(root)
                    .chain(children.iter_descendants(root))
                    .filter(|&e| meshes.contains(e))
                    .map(|e| (e, root)),
            );
        }
    }
    let candidates = new_meshes.iter().chain(std::mem::take(&mut *waiting));
    for entity in candidates {
        if let Some(root) = scene_root(entity, &parents, &roots)
            && !roots.get(root).is_ok_and(|(_, s)| s.is_changed())
        {
            todo.push((entity, root));
        }
    }
    for (entity, root) in todo {
        let (Ok((mesh, transform, material, skinned, morphed, caster, tag)), Ok((_, settings))) =
            (meshes.get(entity), roots.get(root))
        else {
            continue;
        };
        let mut tally = SceneCasterCounts::default();
        if caster.is_some() && tag.is_none() {
            tally.own = 1;
        } else {
            let material = material
                .zip(materials.as_deref())
                .map(|(m, all)| all.get(&m.0));
            let closed = |m: &Mesh| {
                *closed_meshes
                    .entry(mesh.id())
                    .or_insert_with(|| is_closed(m))
            };
            match verdict(
                &settings,
                mesh_assets.as_deref().and_then(|a| a.get(&mesh.0)),
                transform,
                material,
                skinned || morphed,
                closed,
            ) {
                Verdict::Wait => {
                    waiting.push(entity);
                    continue;
                }
                Verdict::Caster { two_sided, masked } => {
                    tally.casters = 1;
                    tally.two_sided = u32::from(two_sided);
                    let ao_transmission = if masked {
                        settings.masked_ao_transmission
                    } else {
                        settings.caster.ao_transmission
                    };
                    commands.entity(entity).insert((
                        DistanceFieldCaster {
                            source: super::CasterSource::Mesh,
                            two_sided,
                            ao_transmission,
                            ..settings.caster.clone()
                        },
                        DistanceFieldSceneCaster(root),
                    ));
                }
                skipped => {
                    match skipped {
                        Verdict::Skinned => tally.skinned = 1,
                        Verdict::Small => tally.small = 1,
                        Verdict::Blended => tally.blended = 1,
                        _ => tally.unsupported = 1,
                    }
                    if tag.is_some() {
                        commands
                            .entity(entity)
                            .remove::<(DistanceFieldCaster, DistanceFieldSceneCaster)>();
                    }
                }
            }
        }
        commands.entity(entity).insert(SceneMeshVerdict {
            root,
            counts: tally,
        });
    }
}

/// Recomputes [`SceneCasterCounts`] on every root when a verdict was made or a judged
/// mesh despawned (a respawned or hot-reloaded scene), from the meshes under it.
pub(super) fn count_scene_casters(
    mut commands: Commands,
    changed: Query<(), Changed<SceneMeshVerdict>>,
    mut removed: RemovedComponents<SceneMeshVerdict>,
    roots: Query<(Entity, Option<&SceneCasterCounts>), With<DistanceFieldSceneCasters>>,
    added_roots: Query<(), Added<DistanceFieldSceneCasters>>,
    children: Query<&Children>,
    verdicts: Query<&SceneMeshVerdict>,
) {
    let removed = removed.read().count() > 0;
    if changed.is_empty() && !removed && added_roots.is_empty() {
        return;
    }
    for (root, counts) in &roots {
        let mut sum = SceneCasterCounts::default();
        for v in std::iter::once(root)
            .chain(children.iter_descendants(root))
            .filter_map(|e| verdicts.get(e).ok())
        {
            add_counts(&mut sum, &v.counts);
        }
        if counts != Some(&sum) {
            commands.entity(root).insert(sum);
        }
    }
}

fn add_counts(c: &mut SceneCasterCounts, t: &SceneCasterCounts) {
    c.casters += t.casters;
    c.two_sided += t.two_sided;
    c.skinned += t.skinned;
    c.small += t.small;
    c.blended += t.blended;
    c.unsupported += t.unsupported;
    c.own += t.own;
}

/// Removing [`DistanceFieldSceneCasters`] removes the casters it added.
pub(super) fn untag_removed_roots(
    mut commands: Commands,
    mut removed: RemovedComponents<DistanceFieldSceneCasters>,
    tagged: Query<(Entity, &DistanceFieldSceneCaster)>,
    judged: Query<(Entity, &SceneMeshVerdict)>,
) {
    let removed: Vec<Entity> = removed.read().collect();
    if removed.is_empty() {
        return;
    }
    for (entity, tag) in &tagged {
        if removed.contains(&tag.0) {
            commands
                .entity(entity)
                .remove::<(DistanceFieldCaster, DistanceFieldSceneCaster)>();
        }
    }
    // Verdicts under a root that is no longer one are stale.
    for (entity, verdict) in &judged {
        if removed.contains(&verdict.root) {
            commands.entity(entity).remove::<SceneMeshVerdict>();
        }
    }
    for root in removed {
        if let Ok(mut e) = commands.get_entity(root) {
            e.remove::<SceneCasterCounts>();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::is_closed;
    use bevy::prelude::*;

    #[test]
    fn closed_meshes_are_told_from_open_ones() {
        // Bevy's primitives duplicate positions per face (normals): welding finds the
        // shared edges.
        assert!(is_closed(&Cuboid::default().into()));
        assert!(is_closed(&Sphere::new(1.0).mesh().uv(16, 8)));
        assert!(is_closed(&Torus::new(0.3, 0.6).into()));
        assert!(!is_closed(&Plane3d::default().mesh().build()));
        assert!(!is_closed(
            &Cylinder::new(0.5, 1.0).mesh().without_caps().build()
        ));
        // A box missing one face (two triangles) is open.
        let mut open: Mesh = Cuboid::default().into();
        if let Some(bevy::mesh::Indices::U32(i)) = open.indices_mut() {
            i.truncate(i.len() - 6);
        }
        assert!(!is_closed(&open));
    }
}
