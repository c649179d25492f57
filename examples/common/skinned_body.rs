//! The flagship's man below the neck as a skinned character: legs, body and arms in a
//! coat are one mesh (capsules merged, each vertex bound to its limb's joint) on a
//! skeleton of six joints (hips, spine, two legs, two arms) that sways and swings a
//! little every frame. `DistanceFieldSceneCasters` on its root makes its distance-field
//! shadows and occlusion: capsules fitted to the joints' vertices that follow the
//! skeleton (#48), as any skinned glTF character gets them. The motion counts frames,
//! not seconds, so a headless capture is the same pose on every machine.

use bevy::asset::RenderAssetUsages;
use bevy::diagnostic::FrameCount;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use penumbra::prelude::DistanceFieldSceneCasters;

/// A joint of the body, its bind-pose local transform and how it moves.
#[derive(Component, Clone, Copy)]
pub struct BodyJoint {
    bind: Transform,
    motion: Motion,
}

/// How a joint moves, in frames.
#[derive(Clone, Copy)]
enum Motion {
    Still,
    /// Turns about local z (a sway), radians at its peak.
    Sway(f32),
    /// Turns about local x (a swing), radians at its peak, in phase or against.
    Swing(f32),
}

/// The skeleton: each joint's parent, bind position in the world and motion.
const JOINTS: [(Option<usize>, Vec3, Motion); 6] = [
    (None, Vec3::new(0.0, 0.8, 0.0), Motion::Still),
    (Some(0), Vec3::new(0.0, 1.02, -0.01), Motion::Sway(0.03)),
    (Some(0), Vec3::new(-0.1, 0.8, 0.0), Motion::Swing(0.12)),
    (Some(0), Vec3::new(0.1, 0.8, 0.0), Motion::Swing(-0.12)),
    (Some(1), Vec3::new(-0.25, 1.28, 0.0), Motion::Swing(-0.2)),
    (Some(1), Vec3::new(0.25, 1.28, 0.0), Motion::Swing(0.2)),
];

/// The coat's parts: radius, length, placement (bind pose, world) and joint.
fn parts() -> [(f32, f32, Transform, u16); 5] {
    let arm = |side: f32| {
        Transform::from_xyz(side * 0.25, 1.0, 0.0).with_rotation(Quat::from_rotation_z(side * 0.12))
    };
    [
        (0.075, 0.7, Transform::from_xyz(-0.1, 0.43, 0.0), 2),
        (0.075, 0.7, Transform::from_xyz(0.1, 0.43, 0.0), 3),
        (
            0.19,
            0.42,
            Transform::from_xyz(0.0, 1.02, -0.01).with_scale(Vec3::new(1.0, 1.0, 0.72)),
            1,
        ),
        (0.055, 0.55, arm(-1.0), 4),
        (0.055, 0.55, arm(1.0), 5),
    ]
}

/// One mesh of the coat's capsules in the bind pose, each vertex bound to its part's
/// joint. Kept in the main world too: the capsule fit reads its vertices.
fn coat_mesh() -> Mesh {
    let (mut positions, mut normals, mut uvs) = (Vec::new(), Vec::new(), Vec::new());
    let (mut joints, mut weights, mut indices) = (Vec::new(), Vec::new(), Vec::new());
    for (radius, length, place, joint) in parts() {
        let part = Capsule3d::new(radius, length).mesh().rings(4).build();
        let base = positions.len() as u32;
        let matrix = place.to_matrix();
        let normal_matrix = matrix.inverse().transpose();
        if let Some(VertexAttributeValues::Float32x3(p)) = part.attribute(Mesh::ATTRIBUTE_POSITION)
        {
            positions.extend(
                p.iter()
                    .map(|p| matrix.transform_point3(Vec3::from(*p)).to_array()),
            );
            joints.extend(std::iter::repeat_n([joint, 0, 0, 0], p.len()));
            weights.extend(std::iter::repeat_n([1.0f32, 0.0, 0.0, 0.0], p.len()));
        }
        if let Some(VertexAttributeValues::Float32x3(n)) = part.attribute(Mesh::ATTRIBUTE_NORMAL) {
            normals.extend(n.iter().map(|n| {
                normal_matrix
                    .transform_vector3(Vec3::from(*n))
                    .normalize_or_zero()
                    .to_array()
            }));
        }
        if let Some(VertexAttributeValues::Float32x2(uv)) = part.attribute(Mesh::ATTRIBUTE_UV_0) {
            uvs.extend_from_slice(uv);
        }
        if let Some(i) = part.indices() {
            indices.extend(i.iter().map(|i| base + i as u32));
        }
    }
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
    .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, uvs)
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_JOINT_INDEX,
        VertexAttributeValues::Uint16x4(joints),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights)
    .with_inserted_indices(Indices::U32(indices))
}

/// Spawns the body: its root (cast by `DistanceFieldSceneCasters`), the skeleton and the
/// skinned coat.
pub fn spawn_body(
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    bindposes: &mut Assets<SkinnedMeshInverseBindposes>,
    coat: Handle<StandardMaterial>,
) -> Entity {
    let root = commands
        .spawn((
            Name::new("the man's body"),
            Transform::default(),
            Visibility::default(),
            DistanceFieldSceneCasters::default(),
        ))
        .id();
    let mut entities: Vec<Entity> = Vec::with_capacity(JOINTS.len());
    for (parent, at, motion) in JOINTS {
        let parent_at = parent.map_or(Vec3::ZERO, |p| JOINTS[p].1);
        let bind = Transform::from_translation(at - parent_at);
        let joint = commands
            .spawn((bind, Visibility::default(), BodyJoint { bind, motion }))
            .id();
        commands
            .entity(joint)
            .insert(ChildOf(parent.map_or(root, |p| entities[p])));
        entities.push(joint);
    }
    let inverse: Vec<Mat4> = JOINTS
        .iter()
        .map(|(_, at, _)| Mat4::from_translation(-*at))
        .collect();
    commands.spawn((
        Mesh3d(meshes.add(coat_mesh())),
        MeshMaterial3d(coat),
        SkinnedMesh {
            inverse_bindposes: bindposes.add(SkinnedMeshInverseBindposes::from(inverse)),
            joints: entities,
        },
        Transform::default(),
        ChildOf(root),
    ));
    root
}

/// The body's idle motion: the spine sways, legs and arms swing a little, one cycle
/// every 48 frames.
pub fn move_body(frame: Res<FrameCount>, mut joints: Query<(&BodyJoint, &mut Transform)>) {
    let phase = (frame.0 % 48) as f32 / 48.0 * std::f32::consts::TAU;
    for (joint, mut transform) in &mut joints {
        let turn = match joint.motion {
            Motion::Still => Quat::IDENTITY,
            Motion::Sway(peak) => Quat::from_rotation_z(peak * phase.sin()),
            Motion::Swing(peak) => Quat::from_rotation_x(peak * phase.sin()),
        };
        *transform = joint.bind.with_rotation(joint.bind.rotation * turn);
    }
}
