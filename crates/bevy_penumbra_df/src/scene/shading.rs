//! Whether a mesh caster is shaded apart from its faces: smooth vertex normals (a sphere,
//! a terrain, a character) or a `StandardMaterial` normal map, rather than its triangles'
//! own normals (a box, a low-poly prop). Its records carry
//! [`flags::SHADING_APART`](penumbra_df_core::object::flags::SHADING_APART): where a
//! receiver's G-buffer normal hides a light, the shadow pass lets the caster field's own
//! normal decide whether the triangles face it (`penumbra_df_core::shadow::
//! FIELD_NORMAL_MIN_FACING_SHADED`), which a flat-shaded caster's G-buffer already says.
//!
//! Decided once per mesh caster when its SDF arrives (the mesh is loaded then) or its
//! mesh or material handle changes, in one pass over the triangles
//! ([`shading_apart_from_faces`]); a material asset edited in place (a normal map added
//! later) is not looked at again. A glTF mesh merged into one caster is judged by its
//! union, which carries its primitives' normals, and by the material of the entity the
//! caster sits on (the other primitives' normal maps are not looked at).

use super::{CasterMesh, CasterSource, DistanceFieldCaster};
use crate::sdf_asset::SdfBaked;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use penumbra_df_core::shadow::shading_apart_from_faces;

/// A mesh caster's shading, as the scene found it (inserted by the plugin; read-only).
#[derive(Component, Reflect, Clone, Copy, Debug, PartialEq, Eq)]
#[reflect(Component, Clone)]
pub struct CasterShading {
    /// Its shading normals are not its faces' (smooth vertex normals or a normal map).
    pub apart: bool,
}

/// Whether `mesh` (a triangle list with normals) is shaded apart from its faces; `false`
/// when its data is in the render world only.
pub fn mesh_shading_apart(mesh: &Mesh) -> bool {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return false;
    }
    // Once the positions are readable, the normals and indices are too.
    let (
        Ok(Some(VertexAttributeValues::Float32x3(positions))),
        Some(VertexAttributeValues::Float32x3(normals)),
    ) = (
        mesh.try_attribute_option(Mesh::ATTRIBUTE_POSITION),
        mesh.try_attribute_option(Mesh::ATTRIBUTE_NORMAL)
            .ok()
            .flatten(),
    )
    else {
        return false;
    };
    let positions: Vec<Vec3> = positions.iter().map(|p| Vec3::from_array(*p)).collect();
    let normals: Vec<Vec3> = normals.iter().map(|n| Vec3::from_array(*n)).collect();
    let triangles = |indices: &mut dyn Iterator<Item = u32>| {
        let mut out = Vec::new();
        while let (Some(a), Some(b), Some(c)) = (indices.next(), indices.next(), indices.next()) {
            out.push([a, b, c]);
        }
        out
    };
    let triangles = match mesh.indices() {
        Some(Indices::U16(i)) => triangles(&mut i.iter().map(|&i| u32::from(i))),
        Some(Indices::U32(i)) => triangles(&mut i.iter().copied()),
        None => triangles(&mut (0..positions.len() as u32)),
    };
    shading_apart_from_faces(&positions, &normals, triangles)
}

/// Decides [`CasterShading`] for mesh casters whose SDF arrived or whose mesh or material
/// changed (before their records are encoded).
#[allow(clippy::type_complexity)]
pub(super) fn detect_caster_shading(
    mut commands: Commands,
    meshes: Option<Res<Assets<Mesh>>>,
    materials: Option<Res<Assets<StandardMaterial>>>,
    casters: Query<
        (
            Entity,
            &DistanceFieldCaster,
            Option<&Mesh3d>,
            Option<&CasterMesh>,
            Option<&MeshMaterial3d<StandardMaterial>>,
            Option<&CasterShading>,
        ),
        Or<(
            Changed<SdfBaked>,
            Changed<Mesh3d>,
            Changed<CasterMesh>,
            Changed<MeshMaterial3d<StandardMaterial>>,
        )>,
    >,
) {
    let Some(meshes) = meshes else {
        return;
    };
    for (entity, caster, mesh, source, material, old) in &casters {
        if caster.source != CasterSource::Mesh {
            continue;
        }
        let Some(handle) = source.map(|s| &s.0).or(mesh.map(|m| &m.0)) else {
            continue;
        };
        let Some(mesh) = meshes.get(handle) else {
            continue;
        };
        let normal_map = material
            .and_then(|m| materials.as_ref()?.get(&m.0))
            .is_some_and(|m| m.normal_map_texture.is_some());
        let shading = CasterShading {
            apart: normal_map || mesh_shading_apart(mesh),
        };
        if old != Some(&shading) {
            commands.entity(entity).insert(shading);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mesh as the main world keeps it after extraction when its asset usage lacks
    /// `MAIN_WORLD`: every CPU read of it is an error (or a panic, through the plain
    /// accessors).
    fn extracted(mut mesh: Mesh) -> Mesh {
        mesh.take_gpu_data().expect("a fresh mesh has its data");
        mesh
    }

    /// A render-world-only mesh (a caster whose data went to the GPU) is not read: not
    /// apart, and no panic.
    #[test]
    fn a_mesh_in_the_render_world_only_is_not_apart() {
        assert!(!mesh_shading_apart(&extracted(
            Sphere::new(1.0).mesh().uv(16, 8)
        )));
    }

    /// Bevy's sphere is smooth, its cuboid flat; a cuboid whose normals were smoothed
    /// (every corner the mean of its faces) is apart.
    #[test]
    fn smooth_meshes_are_apart_and_flat_ones_are_not() {
        assert!(mesh_shading_apart(&Sphere::new(1.0).mesh().uv(16, 8)));
        assert!(!mesh_shading_apart(
            &Cuboid::new(1.0, 2.0, 3.0).mesh().build()
        ));
        assert!(!mesh_shading_apart(&Plane3d::default().mesh().build()));
        let mut smoothed = Cuboid::new(1.0, 1.0, 1.0).mesh().build();
        let Some(VertexAttributeValues::Float32x3(positions)) =
            smoothed.attribute(Mesh::ATTRIBUTE_POSITION)
        else {
            panic!("positions");
        };
        let normals: Vec<[f32; 3]> = positions
            .iter()
            .map(|p| Vec3::from_array(*p).normalize().to_array())
            .collect();
        smoothed.insert_attribute(Mesh::ATTRIBUTE_NORMAL, normals);
        assert!(mesh_shading_apart(&smoothed));
    }
}
