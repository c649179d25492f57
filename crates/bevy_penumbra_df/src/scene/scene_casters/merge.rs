//! Which meshes bake as one field: the primitives of one glTF mesh, or every mesh under a
//! [`MergeDistanceFieldCasters`] node, and their union as one mesh asset.

use super::{CasterMesh, MergeDistanceFieldCasters, MeshQuery, SceneMergedMesh, gltf_mesh_of};
use bevy::asset::RenderAssetUsages;
use bevy::mesh::{PrimitiveTopology, VertexAttributeValues};
use bevy::platform::collections::HashMap;
use bevy::prelude::*;

/// `entity` and its siblings that are primitives of the same glTF mesh (children of one
/// node, meshes `MeshN/PrimitiveM` of one file and one `N`), in the node's child order;
/// `[entity]` for any other mesh entity. A primitive drawn through another mesh (its own
/// `CasterMesh`, e.g. tessellated) is decided alone.
pub(super) fn primitive_group(
    entity: Entity,
    meshes: &MeshQuery,
    parents: &Query<&ChildOf>,
    children: &Query<&Children>,
    drawn_through: &Query<(), (With<CasterMesh>, Without<SceneMergedMesh>)>,
) -> Vec<Entity> {
    let key = |e: Entity| {
        let (mesh, ..) = meshes.get(e).ok()?;
        if drawn_through.contains(e) {
            return None;
        }
        gltf_mesh_of(mesh.0.path())
    };
    let (Some(own), Ok(parent)) = (key(entity), parents.get(entity)) else {
        return vec![entity];
    };
    let Ok(siblings) = children.get(parent.parent()) else {
        return vec![entity];
    };
    let group: Vec<Entity> = siblings
        .iter()
        .filter(|&e| key(e).as_ref() == Some(&own))
        .collect();
    if group.contains(&entity) {
        group
    } else {
        vec![entity]
    }
}

/// The meshes under `entity`'s nearest [`MergeDistanceFieldCasters`] (itself or an
/// ancestor up to the scene `root`), in hierarchy order; `None` without one. Meshes
/// drawn through another mesh (their own `CasterMesh`) are left out, decided alone.
pub(super) fn merge_group(
    entity: Entity,
    root: Entity,
    merge_nodes: &Query<(Entity, Ref<MergeDistanceFieldCasters>)>,
    meshes: &MeshQuery,
    parents: &Query<&ChildOf>,
    children: &Query<&Children>,
    drawn_through: &Query<(), (With<CasterMesh>, Without<SceneMergedMesh>)>,
) -> Option<Vec<Entity>> {
    if drawn_through.contains(entity) {
        return None;
    }
    let mut up = std::iter::once(entity).chain(parents.iter_ancestors(entity));
    let node = up
        .by_ref()
        .take_while(|&e| e != root)
        .chain(std::iter::once(root))
        .find(|&e| merge_nodes.contains(e))?;
    Some(
        std::iter::once(node)
            .chain(children.iter_descendants(node))
            .filter(|&e| meshes.contains(e) && !drawn_through.contains(e))
            .collect(),
    )
}

/// Merged meshes by their primitives (mesh and position relative to the first): the
/// instances of a glTF mesh share one union, so one bake and one atlas volume. Ids, not
/// handles: a union no caster holds any more is freed, and made again when needed.
#[derive(Default)]
pub(in crate::scene) struct MergedMeshes(HashMap<Vec<MergedPart>, AssetId<Mesh>>);

/// A primitive of a union: its mesh and its transform relative to the first's (the
/// affine matrix's bits).
type MergedPart = (AssetId<Mesh>, [u32; 12]);

/// The union of `casting`'s meshes in the first one's local space (positions and
/// triangles, and normals when every member has them: what a bake and the shading rule
/// read), a main-world mesh asset; `None` when a member is
/// not a triangle list with `Float32x3` positions (each is then decided alone).
pub(super) fn merged_caster_mesh(
    casting: &[Entity],
    meshes: &MeshQuery,
    assets: &mut Assets<Mesh>,
    merges: &mut MergedMeshes,
) -> Option<Handle<Mesh>> {
    let (_, lead_transform, ..) = meshes.get(casting[0]).ok()?;
    let local_from_world = lead_transform.affine().inverse();
    let mut key = Vec::with_capacity(casting.len());
    let mut relatives = Vec::with_capacity(casting.len());
    for &e in casting {
        let (mesh, transform, ..) = meshes.get(e).ok()?;
        let relative = local_from_world * transform.affine();
        let bits = relative.to_cols_array().map(f32::to_bits);
        key.push((mesh.id(), bits));
        relatives.push((mesh.id(), relative));
    }
    if let Some(handle) = merges
        .0
        .get(&key)
        .and_then(|&id| assets.get_strong_handle(id))
    {
        return Some(handle);
    }
    let mut positions: Vec<[f32; 3]> = Vec::new();
    // The members' normals, while every member has them: the union's shading
    // (`CasterShading`) is its members'.
    let mut normals: Option<Vec<[f32; 3]>> = Some(Vec::new());
    let mut indices: Vec<u32> = Vec::new();
    for (id, relative) in relatives {
        let mesh = assets.get(id)?;
        let (PrimitiveTopology::TriangleList, Ok(VertexAttributeValues::Float32x3(p))) = (
            mesh.primitive_topology(),
            mesh.try_attribute(Mesh::ATTRIBUTE_POSITION),
        ) else {
            return None;
        };
        let base = u32::try_from(positions.len()).ok()?;
        positions.extend(
            p.iter()
                .map(|v| relative.transform_point3(Vec3::from(*v)).to_array()),
        );
        normals = normals.and_then(|mut out| match mesh.attribute(Mesh::ATTRIBUTE_NORMAL) {
            Some(VertexAttributeValues::Float32x3(n)) if n.len() == p.len() => {
                let normal_matrix = relative.matrix3.inverse().transpose();
                out.extend(n.iter().map(|v| {
                    (normal_matrix * Vec3A::from(*v))
                        .normalize_or_zero()
                        .to_array()
                }));
                Some(out)
            }
            _ => None,
        });
        match mesh.indices() {
            Some(list) => indices.extend(list.iter().map(|i| base + i as u32)),
            None => indices.extend(base..base + p.len() as u32),
        }
    }
    let mut union = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::MAIN_WORLD,
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
    .with_inserted_indices(bevy::mesh::Indices::U32(indices));
    if let Some(normals) = normals {
        union.insert_attribute(Mesh::ATTRIBUTE_NORMAL, normals);
    }
    let handle = assets.add(union);
    merges.0.insert(key, handle.id());
    Some(handle)
}
