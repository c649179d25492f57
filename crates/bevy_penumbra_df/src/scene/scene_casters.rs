//! Tagging a whole scene: [`DistanceFieldSceneCasters`] on a glTF `WorldAssetRoot` (or any
//! entity) makes the meshes spawned under it distance-field casters.
//!
//! The rule is documented on [`DistanceFieldSceneCasters`].

use super::mesh_shape::{Bakes, decide, is_flat, is_ground, is_nearly_closed};
use super::{CasterMesh, DistanceFieldCaster};
use bevy::camera::primitives::MeshAabb;
use bevy::mesh::morph::MeshMorphWeights;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::mesh::{PrimitiveTopology, VertexAttributeValues};
use bevy::platform::collections::{HashMap, HashSet};
use bevy::prelude::*;

mod merge;

use merge::{MergedMeshes, merge_group, merged_caster_mesh, primitive_group};

/// What [`DistanceFieldSceneCasters`] does with skinned and morphing meshes.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SkinnedCasters {
    /// Not casters: a baked field would not follow the animation.
    Skip,
    /// Casters baked from the bind pose, placed at the mesh entity's transform: right
    /// for a statue, wrong once it moves.
    BindPose,
    /// Skinned meshes cast through capsules fitted to their joints, which follow the
    /// skeleton (default; [`SkinCapsuleFit`](super::SkinCapsuleFit),
    /// `penumbra_df_core::skin_capsules`). Morphing meshes without a skin are skipped.
    #[default]
    Capsules,
}

/// When [`DistanceFieldSceneCasters`] bakes a mesh two-sided (a shell around every
/// surface instead of a solid).
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SceneTwoSided {
    /// Never: every mesh is baked as a closed solid.
    Never,
    /// When the material is alpha-masked, or `double_sided` (or the mesh flat) and the
    /// mesh open — unless it is ground: open and facing up, baked solid below it
    /// (default; rule 5 of [`DistanceFieldSceneCasters`]).
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
/// 1. **Skinned or morphed** meshes (`SkinnedMesh`, `MeshMorphWeights`): skinned ones cast
///    through capsules fitted to their joints, following the skeleton (default); or
///    skipped, or cast from their bind pose ([`SkinnedCasters`]). A bind-pose SDF does
///    not follow the animation: right for a statue, wrong for a running fox. The
///    skinned primitives of one glTF mesh are fitted together, on the first
///    ([`SkinCapsules`](super::SkinCapsules)).
/// 2. **Not triangles** (lines, points) or no `Float32x3` positions: skipped.
/// 3. **Small**: the largest side of the mesh's world-space bounding box below
///    [`DistanceFieldSceneCasters::min_size`]: skipped (a pebble is not worth a trace).
/// 4. **Alpha-blended** `StandardMaterial`s (`Blend`, `Premultiplied`, `Add`,
///    `Multiply`) and **transmissive** ones (`specular_transmission` above 0: glass,
///    glTF's `KHR_materials_transmission`): skipped. Glass and smoke would cast solid
///    shadows (and Bevy draws both after the depth prepass and G-buffer, so the passes
///    shade what lies behind them).
/// 5. Otherwise a [`DistanceFieldCaster`] from the root's template
///    ([`DistanceFieldSceneCasters::caster`]), **two-sided** (a shell around the
///    surface) when the material is alpha-masked (`Mask`, `AlphaToCoverage`: foliage
///    cards), or `double_sided` or flat (a decal, a zero-thickness quad: a local box
///    a thousandth as thick as long) and the mesh is open: its boundary (edges one triangle
///    uses, after welding equal positions) is long for its area — an open index
///    (boundary over √area, `penumbra_sdf::openness`) above 1.5, where any flat sheet
///    scores at least 2√π ≈ 3.54 (a wall, a leaf, a terrain sheet) — per
///    [`SceneTwoSided`]. A closed or nearly closed double-sided mesh (a hose with a few
///    holes, 0.67) is baked solid: exporters mark most materials double-sided (Blender
///    does by default), and a shell about a voxel thick makes a solid box self-shadow
///    at grazing angles.
///    **Ground** first: an open mesh (double-sided or not) whose triangles, in world
///    space, face up with no overhang — at least half of its area's normal up, at most
///    1 % of it facing down (`penumbra_sdf::ground`: terrains and floors score 0.96–1,
///    everything else in the shared scenes 0.16 or more down, or upright) — bakes solid
///    below it ([`DistanceFieldCaster::ground`]), not as a shell: a shell about a bumpy
///    terrain shadows the terrain at grazing light.
///    Materials other than `StandardMaterial` count as opaque and single-sided.
///
/// **One field per glTF mesh.** Bevy spawns one entity per glTF primitive (one per
/// material); the casting primitives of one mesh under one node bake as a single field
/// over their union, placed on the first primitive's entity ([`CasterMesh`]: the union,
/// in its local space), as Unreal bakes a static mesh over all its sections. The sign
/// comes from the union's generalized winding number, so open pieces that close
/// together (a cake's crust, icing and cut faces) bake solid. Rule 5 is applied to the
/// union (masked or double-sided if any primitive is, open if the union is): a union
/// that would be a two-sided shell anyway (a room's open walls) stays in pieces, the
/// same shells in smaller volumes. The other primitives carry no caster
/// ([`SceneCasterCounts::merged`]). [`MergeDistanceFieldCasters`] on a node merges its
/// whole subtree the same way (a prop of several nodes).
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
    /// Skinned and morphing meshes. Default [`SkinnedCasters::Capsules`].
    pub skinned: SkinnedCasters,
    /// How capsules are fitted to skinned meshes ([`SkinnedCasters::Capsules`]).
    pub capsules: super::SkinCapsuleFit,
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
            skinned: SkinnedCasters::Capsules,
            capsules: super::SkinCapsuleFit::default(),
            min_size: 0.05,
            two_sided: SceneTwoSided::FromMaterial,
            masked_ao_transmission: super::FOLIAGE_AO_TRANSMISSION,
            caster: DistanceFieldCaster::default(),
        }
    }
}

/// On a node under a [`DistanceFieldSceneCasters`] root (or on the root): every mesh in
/// its subtree bakes as one distance field over their union — a prop of several nodes
/// (a lamp of base, arm and shade) as Unreal bakes one static mesh — when the union bakes
/// solid (rule 5 of [`DistanceFieldSceneCasters`] on the union; a union that would be a
/// two-sided shell stays in pieces). The union is taken at the nodes' transforms when it
/// is decided: for static props (a part that moves later keeps its old place in the
/// field). Inserting it re-decides the subtree's meshes, so it can be added once a glTF
/// scene has spawned.
#[derive(Component, Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
#[reflect(Component, Clone, Default)]
pub struct MergeDistanceFieldCasters;

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
    /// Of those, solid although their material is double-sided: closed or nearly closed
    /// (open index ≤ 1.5, see rule 5 of [`DistanceFieldSceneCasters`]).
    pub solid_double_sided: u32,
    /// Of those, ground: open sheets facing up, baked solid below them (rule 5).
    pub ground: u32,
    /// Of those, shaded apart from their faces (smooth vertex normals or a normal map:
    /// [`CasterShading`](super::CasterShading)), counted once their SDF has arrived.
    pub shaded_apart: u32,
    /// Skipped: skinned or morphing (with [`SkinnedCasters::Skip`]), or morphing without
    /// a skin (with [`SkinnedCasters::Capsules`]).
    pub skinned: u32,
    /// Skinned meshes cast through fitted capsules ([`SkinnedCasters::Capsules`]; the
    /// primitives of one glTF mesh count once).
    pub capsule_meshes: u32,
    /// The capsule casters made for them, counted once fitted.
    pub capsules: u32,
    /// Skipped: below [`DistanceFieldSceneCasters::min_size`].
    pub small: u32,
    /// Skipped: alpha-blended or transmissive material.
    pub blended: u32,
    /// Skipped: not triangles, or no usable positions.
    pub unsupported: u32,
    /// Left alone: the entity has its own `DistanceFieldCaster`, or its field is
    /// re-baked ([`DistanceFieldRebake`](super::DistanceFieldRebake)).
    pub own: u32,
    /// Primitives baked into a sibling's field: the primitives of one glTF mesh are one
    /// caster (counted once in `casters`, on its first primitive).
    pub merged: u32,
}

impl SceneCasterCounts {
    /// Counts a caster's kind (not `casters` itself).
    fn count(&mut self, bakes: Bakes, double_sided: bool) {
        self.two_sided += u32::from(bakes == Bakes::TwoSided);
        self.ground += u32::from(bakes == Bakes::Ground);
        self.solid_double_sided += u32::from(double_sided && bakes == Bakes::Solid);
    }
}

/// Why a mesh is or is not a caster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Verdict {
    Caster {
        /// What it bakes as.
        bakes: Bakes,
        /// Alpha-masked material (foliage).
        masked: bool,
        /// The material is double-sided.
        double_sided: bool,
    },
    Skinned,
    /// Cast through capsules fitted to its skin.
    Capsules,
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
        Has<super::DistanceFieldRebake>,
    ),
>;

fn verdict(
    settings: &DistanceFieldSceneCasters,
    mesh: Option<&Mesh>,
    transform: &GlobalTransform,
    material: Option<Option<&StandardMaterial>>,
    (skinned, morphed): (bool, bool),
    closed: impl FnOnce(&Mesh) -> bool,
) -> Verdict {
    match settings.skinned {
        SkinnedCasters::Capsules if skinned => return Verdict::Capsules,
        SkinnedCasters::Skip | SkinnedCasters::Capsules if skinned || morphed => {
            return Verdict::Skinned;
        }
        _ => {}
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
        // Glass: Bevy draws a transmissive material after the opaque passes, as a blended
        // one; neither casts.
        Some(Some(m)) if m.specular_transmission > 0.0 => return Verdict::Blended,
        Some(Some(m)) => match m.alpha_mode {
            AlphaMode::Blend | AlphaMode::Premultiplied | AlphaMode::Add | AlphaMode::Multiply => {
                return Verdict::Blended;
            }
            AlphaMode::Mask(_) | AlphaMode::AlphaToCoverage => (m.double_sided, true),
            AlphaMode::Opaque => (m.double_sided, false),
        },
        None => (false, false),
    };
    let bakes = decide(
        settings.two_sided,
        masked,
        double_sided,
        is_flat(half),
        || closed(mesh),
        || is_ground(mesh, transform),
    );
    Verdict::Caster {
        bakes,
        masked,
        double_sided,
    }
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
    mut mesh_assets: Option<ResMut<Assets<Mesh>>>,
    // Absent in apps without PBR (e.g. headless logic tests): no material, opaque.
    materials: Option<Res<Assets<StandardMaterial>>>,
    mut waiting: Local<Vec<Entity>>,
    mut closed_meshes: Local<HashMap<AssetId<Mesh>, bool>>,
    drawn_through: Query<(), (With<CasterMesh>, Without<SceneMergedMesh>)>,
    mut merges: Local<MergedMeshes>,
    merge_nodes: Query<(Entity, Ref<MergeDistanceFieldCasters>)>,
    skins: Query<&SkinnedMesh>,
    rebake_added: Query<Entity, Added<super::DistanceFieldRebake>>,
    mut rebake_removed: RemovedComponents<super::DistanceFieldRebake>,
) {
    // A mesh that gained or lost a re-bake is decided again: its capsules or bind-pose
    // field give way to the re-baked field, and come back when the re-bake goes.
    let rebake_changed: Vec<Entity> = rebake_added.iter().chain(rebake_removed.read()).collect();
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
    // A new merge marker re-decides its subtree.
    for (node, marker) in &merge_nodes {
        if marker.is_added()
            && let Some(root) = scene_root(node, &parents, &roots)
        {
            todo.extend(
                std::iter::once(node)
                    .chain(children.iter_descendants(node))
                    .filter(|&e| meshes.contains(e))
                    .map(|e| (e, root)),
            );
        }
    }
    let candidates = new_meshes
        .iter()
        .chain(std::mem::take(&mut *waiting))
        .chain(rebake_changed);
    for entity in candidates {
        if let Some(root) = scene_root(entity, &parents, &roots)
            && !roots.get(root).is_ok_and(|(_, s)| s.is_changed())
        {
            todo.push((entity, root));
        }
    }
    let mut decided: HashSet<Entity> = HashSet::default();
    for (entity, root) in todo {
        if decided.contains(&entity) {
            continue;
        }
        let Ok((_, settings)) = roots.get(root) else {
            continue;
        };
        let settings: &DistanceFieldSceneCasters = &settings;
        // The primitives of one glTF mesh, or the meshes under a merge marker, are
        // decided together.
        let group = merge_group(
            entity,
            root,
            &merge_nodes,
            &meshes,
            &parents,
            &children,
            &drawn_through,
        )
        .unwrap_or_else(|| primitive_group(entity, &meshes, &parents, &children, &drawn_through));
        decided.extend(group.iter().copied());
        let mut judged = Vec::with_capacity(group.len());
        for &member in &group {
            let Ok((mesh, transform, material, skinned, morphed, caster, tag, rebaked)) =
                meshes.get(member)
            else {
                continue;
            };
            let verdict = if rebaked || (caster.is_some() && tag.is_none()) {
                None // re-baked, or its own caster: left alone
            } else {
                let material = material
                    .zip(materials.as_deref())
                    .map(|(m, all)| all.get(&m.0));
                let closed = |m: &Mesh| {
                    *closed_meshes
                        .entry(mesh.id())
                        .or_insert_with(|| is_nearly_closed(m))
                };
                Some(verdict(
                    settings,
                    mesh_assets.as_deref().and_then(|a| a.get(&mesh.0)),
                    transform,
                    material,
                    (skinned, morphed),
                    closed,
                ))
            };
            judged.push((member, verdict, tag.is_some()));
        }
        if judged.iter().any(|(_, v, _)| *v == Some(Verdict::Wait)) {
            waiting.extend(judged.iter().map(|j| j.0));
            continue;
        }
        let casting: Vec<Entity> = judged
            .iter()
            .filter(|(_, v, _)| matches!(v, Some(Verdict::Caster { .. })))
            .map(|j| j.0)
            .collect();
        // The union's material flags: masked or double-sided if any primitive is.
        let (masked, double_sided) =
            judged
                .iter()
                .fold((false, false), |(m, d), (_, v, _)| match v {
                    Some(Verdict::Caster {
                        masked,
                        double_sided,
                        ..
                    }) => (m || *masked, d || *double_sided),
                    _ => (m, d),
                });
        // Two or more casting primitives: one field over their union, on the first, when
        // the union bakes solid (its sign is what merging fixes). A union that would be a
        // two-sided shell anyway (a room's open walls) stays in pieces: the same shells,
        // in smaller volumes than one around the whole.
        let merged = (casting.len() > 1)
            .then(|| {
                let assets = mesh_assets.as_deref_mut()?;
                let handle = merged_caster_mesh(&casting, &meshes, assets, &mut merges)?;
                let closed = *closed_meshes
                    .entry(handle.id())
                    .or_insert_with(|| assets.get(&handle).is_some_and(is_nearly_closed));
                let union = assets.get(&handle)?;
                let flat = union
                    .compute_aabb()
                    .is_some_and(|b| is_flat(Vec3::from(b.half_extents)));
                let lead = meshes.get(casting[0]).ok()?.1;
                let bakes = decide(
                    settings.two_sided,
                    masked,
                    double_sided,
                    flat,
                    || closed,
                    || is_ground(union, lead),
                );
                (bakes != Bakes::TwoSided).then_some((handle, bakes))
            })
            .flatten();
        let lead = casting.first().copied();
        // Skinned primitives cast through capsules fitted over all of them that share a
        // skeleton, on the first of each skeleton.
        let mut skeletons: Vec<Vec<Entity>> = Vec::new();
        let skeleton = |e: Entity| {
            skins
                .get(e)
                .ok()
                .map(|s| (&s.joints, s.inverse_bindposes.id()))
        };
        for (e, _, _) in judged
            .iter()
            .filter(|(_, v, _)| *v == Some(Verdict::Capsules))
        {
            match skeletons
                .iter_mut()
                .find(|g| skeleton(g[0]) == skeleton(*e))
            {
                Some(group) => group.push(*e),
                None => skeletons.push(vec![*e]),
            }
        }
        for (member, verdict, tagged) in judged {
            let mut tally = SceneCasterCounts::default();
            // Its `CasterMesh`, if any, is the rule's (a union), not another plugin's.
            let ours = !drawn_through.contains(member);
            let mut commands = commands.entity(member);
            // Capsules already made are made again (the settings may have changed).
            commands.remove::<(
                super::SkinCapsules,
                super::skin_capsules::SkinCapsuleRequest,
            )>();
            match verdict {
                None => {
                    tally.own = 1;
                    // Re-baked now: the rule's field of it goes.
                    if tagged {
                        untag(&mut commands, ours);
                    }
                }
                Some(Verdict::Caster {
                    bakes,
                    masked,
                    double_sided,
                }) if merged.is_none() => {
                    tally.casters = 1;
                    tally.count(bakes, double_sided);
                    if ours {
                        commands.remove::<(CasterMesh, SceneMergedMesh)>();
                    }
                    commands.insert(scene_caster(settings, bakes, masked, root));
                }
                Some(Verdict::Caster { .. }) if Some(member) == lead => {
                    let (handle, bakes) = merged.as_ref().expect("merged");
                    tally.casters = 1;
                    tally.count(*bakes, double_sided);
                    commands.insert((
                        scene_caster(settings, *bakes, masked, root),
                        CasterMesh(handle.clone()),
                        SceneMergedMesh,
                    ));
                }
                Some(Verdict::Caster { .. }) => {
                    tally.merged = 1;
                    untag(&mut commands, ours);
                }
                Some(Verdict::Capsules) => {
                    if tagged {
                        untag(&mut commands, ours);
                    }
                    if let Some(group) = skeletons.iter().find(|g| g[0] == member) {
                        tally.capsule_meshes = 1;
                        commands.insert(super::skin_capsules::SkinCapsuleRequest {
                            root,
                            meshes: group.clone(),
                        });
                    }
                }
                Some(skipped) => {
                    match skipped {
                        Verdict::Skinned => tally.skinned = 1,
                        Verdict::Small => tally.small = 1,
                        Verdict::Blended => tally.blended = 1,
                        _ => tally.unsupported = 1,
                    }
                    if tagged {
                        untag(&mut commands, ours);
                    }
                }
            }
            commands.insert(SceneMeshVerdict {
                root,
                counts: tally,
            });
        }
    }
}

/// The caster a scene root's rule makes.
fn scene_caster(
    settings: &DistanceFieldSceneCasters,
    bakes: Bakes,
    masked: bool,
    root: Entity,
) -> (DistanceFieldCaster, DistanceFieldSceneCaster) {
    let ao_transmission = if masked {
        settings.masked_ao_transmission
    } else {
        settings.caster.ao_transmission
    };
    (
        DistanceFieldCaster {
            source: super::CasterSource::Mesh,
            two_sided: bakes == Bakes::TwoSided,
            ground: bakes == Bakes::Ground,
            ao_transmission,
            ..settings.caster.clone()
        },
        DistanceFieldSceneCaster(root),
    )
}

/// Removes what the rule added to a mesh entity: the caster, and the union's
/// [`CasterMesh`] when it is the rule's (`ours`; another plugin's, e.g. tessellation's,
/// stays).
fn untag(commands: &mut EntityCommands, ours: bool) {
    commands.remove::<(DistanceFieldCaster, DistanceFieldSceneCaster)>();
    if ours {
        commands.remove::<(CasterMesh, SceneMergedMesh)>();
    }
}

/// Marks a caster whose [`CasterMesh`] the scene rule made (the union of its glTF mesh's
/// primitives): removed with the caster.
#[derive(Component, Clone, Copy, Debug)]
pub(super) struct SceneMergedMesh;

/// The glTF file and mesh index of a primitive's mesh (`MeshN/PrimitiveM` label), or
/// `None` for a mesh not loaded from glTF.
pub(super) fn gltf_mesh_of(path: Option<&bevy::asset::AssetPath>) -> Option<(String, usize)> {
    let path = path?;
    let label = path.label()?;
    let rest = label.strip_prefix("Mesh")?;
    let (mesh, primitive) = rest.split_once("/Primitive")?;
    primitive.parse::<usize>().ok()?;
    Some((path.without_label().to_string(), mesh.parse().ok()?))
}

/// Recomputes [`SceneCasterCounts`] on every root when a verdict was made or a judged
/// mesh despawned (a respawned or hot-reloaded scene), from the meshes under it.
#[allow(clippy::too_many_arguments, reason = "a system's queries")]
pub(super) fn count_scene_casters(
    mut commands: Commands,
    changed: Query<(), Changed<SceneMeshVerdict>>,
    shading_changed: Query<(), (Changed<super::CasterShading>, With<SceneMeshVerdict>)>,
    mut removed: RemovedComponents<SceneMeshVerdict>,
    roots: Query<(Entity, Option<&SceneCasterCounts>), With<DistanceFieldSceneCasters>>,
    added_roots: Query<(), Added<DistanceFieldSceneCasters>>,
    children: Query<&Children>,
    verdicts: Query<(
        &SceneMeshVerdict,
        Option<&super::CasterShading>,
        Option<&super::SkinCapsules>,
    )>,
    capsules_changed: Query<(), (Changed<super::SkinCapsules>, With<SceneMeshVerdict>)>,
) {
    let removed = removed.read().count() > 0;
    if changed.is_empty()
        && shading_changed.is_empty()
        && capsules_changed.is_empty()
        && !removed
        && added_roots.is_empty()
    {
        return;
    }
    for (root, counts) in &roots {
        let mut sum = SceneCasterCounts::default();
        for (v, shading, capsules) in std::iter::once(root)
            .chain(children.iter_descendants(root))
            .filter_map(|e| verdicts.get(e).ok())
        {
            add_counts(&mut sum, &v.counts);
            sum.shaded_apart += u32::from(v.counts.casters > 0 && shading.is_some_and(|s| s.apart));
            sum.capsules += capsules.map_or(0, |c| c.0.len() as u32);
        }
        if counts != Some(&sum) {
            commands.entity(root).insert(sum);
        }
    }
}

fn add_counts(c: &mut SceneCasterCounts, t: &SceneCasterCounts) {
    c.casters += t.casters;
    c.two_sided += t.two_sided;
    c.solid_double_sided += t.solid_double_sided;
    c.ground += t.ground;
    c.shaded_apart += t.shaded_apart;
    c.skinned += t.skinned;
    c.capsule_meshes += t.capsule_meshes;
    c.capsules += t.capsules;
    c.small += t.small;
    c.blended += t.blended;
    c.unsupported += t.unsupported;
    c.own += t.own;
    c.merged += t.merged;
}

/// Removing [`DistanceFieldSceneCasters`] removes the casters it added.
pub(super) fn untag_removed_roots(
    mut commands: Commands,
    mut removed: RemovedComponents<DistanceFieldSceneCasters>,
    tagged: Query<(Entity, &DistanceFieldSceneCaster, Has<SceneMergedMesh>)>,
    judged: Query<(Entity, &SceneMeshVerdict)>,
) {
    let removed: Vec<Entity> = removed.read().collect();
    if removed.is_empty() {
        return;
    }
    for (entity, tag, merged) in &tagged {
        if removed.contains(&tag.0) {
            let mut e = commands.entity(entity);
            e.remove::<(DistanceFieldCaster, DistanceFieldSceneCaster)>();
            if merged {
                e.remove::<(CasterMesh, SceneMergedMesh)>();
            }
        }
    }
    // Verdicts under a root that is no longer one are stale, and its capsules go.
    for (entity, verdict) in &judged {
        if removed.contains(&verdict.root) {
            commands.entity(entity).remove::<(
                SceneMeshVerdict,
                super::SkinCapsules,
                super::skin_capsules::SkinCapsuleRequest,
            )>();
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
    use super::gltf_mesh_of;
    use bevy::asset::AssetPath;

    #[test]
    fn primitives_are_grouped_by_file_and_mesh() {
        let of = |p: &str| gltf_mesh_of(Some(&AssetPath::parse(p)));
        assert_eq!(
            of("scenes/cake.glb#Mesh3/Primitive1"),
            Some(("scenes/cake.glb".into(), 3))
        );
        assert_eq!(
            of("cake.glb#Mesh3/Primitive0"),
            Some(("cake.glb".into(), 3))
        );
        assert_eq!(of("cake.glb#Mesh12/Primitive7").map(|k| k.1), Some(12));
        for other in [
            "cake.glb",
            "cake.glb#Mesh3",
            "cake.glb#Material0",
            "cake.glb#Mesh3/MorphTargets",
            "cake.glb#MeshX/Primitive0",
        ] {
            assert_eq!(of(other), None, "{other}");
        }
        assert_eq!(gltf_mesh_of(None), None);
    }
}
