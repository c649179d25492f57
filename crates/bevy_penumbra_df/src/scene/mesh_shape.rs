//! What [`DistanceFieldSceneCasters`](super::DistanceFieldSceneCasters)' rule reads from a
//! mesh's shape: closed or open, flat, ground; and what it bakes from that
//! ([`decide`], rule 5 of its docs).

use super::SceneTwoSided;
use bevy::mesh::{PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;

/// How the rule bakes a caster.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Bakes {
    /// A solid, signed by the winding number.
    Solid,
    /// A two-sided shell about every surface.
    TwoSided,
    /// Ground: solid below an open sheet facing up (`penumbra_sdf::ground`).
    Ground,
}

/// Rule 5: masked → shell; open and ground → ground; open and double-sided or flat →
/// shell; else solid (per `setting`). `closed` and `ground` are asked only when needed.
pub(super) fn decide(
    setting: SceneTwoSided,
    masked: bool,
    double_sided: bool,
    flat: bool,
    closed: impl FnOnce() -> bool,
    ground: impl FnOnce() -> bool,
) -> Bakes {
    match setting {
        SceneTwoSided::Never => return Bakes::Solid,
        SceneTwoSided::Always => return Bakes::TwoSided,
        SceneTwoSided::FromMaterial => {}
    }
    if masked {
        Bakes::TwoSided
    } else if closed() {
        Bakes::Solid
    } else if ground() {
        Bakes::Ground
    } else if double_sided || flat {
        Bakes::TwoSided
    } else {
        Bakes::Solid
    }
}

/// The positions and triangle indices of a triangle-list mesh with `Float32x3`
/// positions (every index in range); `None` otherwise.
fn triangles(mesh: &Mesh) -> Option<(Vec<Vec3>, Vec<u32>)> {
    let (PrimitiveTopology::TriangleList, Ok(VertexAttributeValues::Float32x3(positions))) = (
        mesh.primitive_topology(),
        mesh.try_attribute(Mesh::ATTRIBUTE_POSITION),
    ) else {
        return None;
    };
    let positions: Vec<Vec3> = positions.iter().map(|p| Vec3::from(*p)).collect();
    let indices: Vec<u32> = match mesh.indices() {
        Some(list) => list.iter().map(|i| i as u32).collect(),
        None => (0..positions.len() as u32).collect(),
    };
    Some((positions, indices))
}

/// Whether a triangle-list mesh is closed or nearly so: its open index (boundary length
/// over √area, `penumbra_sdf::openness`) is at most
/// [`NEARLY_CLOSED_OPEN_INDEX`](penumbra_sdf::openness::NEARLY_CLOSED_OPEN_INDEX). Strips
/// and meshes without `Float32x3` positions count as open.
pub(super) fn is_nearly_closed(mesh: &Mesh) -> bool {
    triangles(mesh).is_some_and(|(positions, indices)| {
        penumbra_sdf::openness::open_index(&positions, &indices)
            <= penumbra_sdf::openness::NEARLY_CLOSED_OPEN_INDEX
    })
}

/// A flat piece (a decal, a zero-thickness quad): its local box is at most a thousandth
/// as thick as it is long. Baked solid, an open flat piece has no inside for its sign to
/// find; it bakes as a two-sided shell whatever its material (unless it is ground).
pub(super) fn is_flat(half_extents: Vec3) -> bool {
    half_extents.min_element() <= 1e-3 * half_extents.max_element()
}

/// Whether a mesh placed by `transform` is ground: its triangles, in world space, face
/// +y as `penumbra_sdf::ground::is_ground` asks (at least half up, at most 1 % down).
/// A mirroring transform (negative determinant) turns the triangles' winding, not their
/// faces: it is measured against −y. Strips and meshes without `Float32x3` positions are
/// not ground.
pub(super) fn is_ground(mesh: &Mesh, transform: &GlobalTransform) -> bool {
    triangles(mesh).is_some_and(|(positions, indices)| {
        let affine = transform.affine();
        let world: Vec<Vec3> = positions
            .iter()
            .map(|&p| affine.transform_point3(p))
            .collect();
        let up = Vec3::Y * affine.matrix3.determinant().signum();
        penumbra_sdf::ground::is_ground(penumbra_sdf::ground::facing(&world, &indices, up))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_meshes_are_told_from_open_ones() {
        // Bevy's primitives duplicate positions per face (normals): welding finds the
        // shared edges.
        assert!(is_nearly_closed(&Cuboid::default().into()));
        assert!(is_nearly_closed(&Sphere::new(1.0).mesh().uv(16, 8)));
        assert!(is_nearly_closed(&Torus::new(0.3, 0.6).into()));
        assert!(!is_nearly_closed(&Plane3d::default().mesh().build()));
        assert!(!is_nearly_closed(
            &Cylinder::new(0.5, 1.0).mesh().without_caps().build()
        ));
        // A box missing one face (two triangles) is open: a lidless crate.
        let mut open: Mesh = Cuboid::default().into();
        if let Some(bevy::mesh::Indices::U32(i)) = open.indices_mut() {
            i.truncate(i.len() - 6);
        }
        assert!(!is_nearly_closed(&open));
        // A sphere missing one small triangle is nearly closed (a baked solid signs it).
        let mut holed = Sphere::new(1.0).mesh().ico(3).unwrap();
        if let Some(bevy::mesh::Indices::U32(i)) = holed.indices_mut() {
            i.truncate(i.len() - 3);
        }
        assert!(is_nearly_closed(&holed));
    }

    /// The rule's order: masked before closed, closed before ground, ground before the
    /// double-sided or flat shell; `Never` and `Always` whatever the shape.
    #[test]
    fn the_rule_decides_in_order() {
        let d = |setting, masked, double_sided, flat, closed, ground| {
            decide(setting, masked, double_sided, flat, || closed, || ground)
        };
        let from = SceneTwoSided::FromMaterial;
        assert_eq!(d(from, true, false, false, true, true), Bakes::TwoSided);
        assert_eq!(d(from, false, true, true, true, true), Bakes::Solid);
        assert_eq!(d(from, false, false, false, false, true), Bakes::Ground);
        assert_eq!(d(from, false, true, false, false, false), Bakes::TwoSided);
        assert_eq!(d(from, false, false, true, false, false), Bakes::TwoSided);
        assert_eq!(d(from, false, false, false, false, false), Bakes::Solid);
        assert_eq!(
            d(SceneTwoSided::Never, true, true, true, false, true),
            Bakes::Solid
        );
        assert_eq!(
            d(SceneTwoSided::Always, false, false, false, true, true),
            Bakes::TwoSided
        );
    }

    /// A floor is ground; turned over (a ceiling) or upright it is not; mirrored it still
    /// is (the winding turns, not the face).
    #[test]
    fn floors_are_ground_and_ceilings_are_not() {
        let floor: Mesh = Plane3d::default().mesh().build();
        let at = |t: Transform| GlobalTransform::from(t);
        assert!(is_ground(&floor, &at(Transform::default())));
        assert!(is_ground(
            &floor,
            &at(Transform::from_scale(Vec3::new(-1.0, 1.0, 1.0)))
        ));
        assert!(!is_ground(
            &floor,
            &at(Transform::from_rotation(Quat::from_rotation_x(3.0)))
        ));
        assert!(!is_ground(
            &floor,
            &at(Transform::from_rotation(Quat::from_rotation_x(1.57)))
        ));
        assert!(!is_ground(
            &Cuboid::default().into(),
            &at(Transform::default())
        ));
    }
}
