//! Strands to the strip mesh the material draws: two vertices per point (sides −1 and
//! +1, at the same centre-line position: the vertex shader moves them apart facing the
//! camera), two triangles per segment, and the joints of the strand's root when the
//! hair is bound to a skin.

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology, VertexAttributeValues};
use bevy::prelude::*;
use penumbra_cinematic_core::hair::strands::Strand;

use super::material::{ATTRIBUTE_HAIR_STRIP, ATTRIBUTE_HAIR_TANGENT};

/// The joints (indices, weights) of each strand, when bound to a skin.
pub type StrandJoints = Vec<([u16; 4], [f32; 4])>;

/// The strip mesh of `strands` (all drawable: see `check_strands`); `None` when there
/// is nothing to draw.
pub fn strip_mesh(strands: &[Strand], joints: Option<&StrandJoints>) -> Option<Mesh> {
    let points: usize = strands.iter().map(|s| s.points.len()).sum();
    if points == 0 {
        return None;
    }
    let mut positions = Vec::with_capacity(2 * points);
    let mut tangents = Vec::with_capacity(2 * points);
    let mut strips = Vec::with_capacity(2 * points);
    let mut joint_indices = Vec::new();
    let mut joint_weights = Vec::new();
    let mut indices = Vec::with_capacity(6 * points);
    for (s, strand) in strands.iter().enumerate() {
        let p = &strand.points;
        let base = positions.len() as u32;
        // Arc length along the strand: u from 0 at the root to 1 at the tip.
        let mut lengths = vec![0.0f32; p.len()];
        for i in 1..p.len() {
            lengths[i] = lengths[i - 1] + p[i].distance(p[i - 1]);
        }
        let total = lengths[p.len() - 1].max(f32::MIN_POSITIVE);
        for i in 0..p.len() {
            let (before, after) = (p[i.saturating_sub(1)], p[(i + 1).min(p.len() - 1)]);
            let tangent = (after - before).normalize_or(Vec3::Y);
            for side in [-1.0f32, 1.0] {
                positions.push(p[i].to_array());
                tangents.push(tangent.to_array());
                strips.push([side, lengths[i] / total, strand.width, strand.slot as f32]);
                if let Some(joints) = joints {
                    let (j, w) = joints
                        .get(s)
                        .copied()
                        .unwrap_or(([0; 4], [1.0, 0.0, 0.0, 0.0]));
                    joint_indices.push(j);
                    joint_weights.push(w);
                }
            }
            if i + 1 < p.len() {
                let k = base + 2 * i as u32;
                indices.extend([k, k + 1, k + 2, k + 1, k + 3, k + 2]);
            }
        }
    }
    let mut mesh = Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::RENDER_WORLD,
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
    .with_inserted_attribute(ATTRIBUTE_HAIR_TANGENT, tangents)
    .with_inserted_attribute(ATTRIBUTE_HAIR_STRIP, strips)
    .with_inserted_indices(Indices::U32(indices));
    if joints.is_some() {
        mesh.insert_attribute(
            Mesh::ATTRIBUTE_JOINT_INDEX,
            VertexAttributeValues::Uint16x4(joint_indices),
        );
        mesh.insert_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, joint_weights);
    }
    Some(mesh)
}

/// Each strand's root takes the joints of the nearest vertex of `skin` (a skinned mesh
/// with positions, joint indices and weights in the hair's space); `None` when `skin`
/// lacks them (or they are in the render world only).
pub fn joints_from_skin(strands: &[Strand], skin: &Mesh) -> Option<StrandJoints> {
    // Once this succeeds every attribute is readable.
    let Ok(Some(VertexAttributeValues::Float32x3(positions))) =
        skin.try_attribute_option(Mesh::ATTRIBUTE_POSITION)
    else {
        return None;
    };
    let Some(VertexAttributeValues::Uint16x4(indices)) =
        skin.attribute(Mesh::ATTRIBUTE_JOINT_INDEX)
    else {
        return None;
    };
    let Some(VertexAttributeValues::Float32x4(weights)) =
        skin.attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT)
    else {
        return None;
    };
    if positions.is_empty() || positions.len() != indices.len() || indices.len() != weights.len() {
        return None;
    }
    Some(
        strands
            .iter()
            .map(|strand| {
                // A strand without points (dropped before drawing) binds as one at the
                // origin would.
                let root = strand.points.first().copied().unwrap_or(Vec3::ZERO);
                let nearest = positions
                    .iter()
                    .enumerate()
                    .min_by(|(_, a), (_, b)| {
                        Vec3::from_array(**a)
                            .distance_squared(root)
                            .total_cmp(&Vec3::from_array(**b).distance_squared(root))
                    })
                    .map_or(0, |(i, _)| i);
                (indices[nearest], weights[nearest])
            })
            .collect(),
    )
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

    #[test]
    fn a_skin_in_the_render_world_only_gives_no_joints() {
        let skin = extracted(Sphere::new(1.0).mesh().uv(8, 4));
        assert!(joints_from_skin(&[], &skin).is_none());
    }

    #[test]
    fn a_strip_has_two_vertices_per_point_and_two_triangles_per_segment() {
        let strands = vec![
            Strand {
                points: vec![Vec3::ZERO, Vec3::Y, Vec3::new(0.0, 3.0, 0.0)],
                width: 0.01,
                slot: 2,
            },
            Strand {
                points: vec![Vec3::X, Vec3::new(1.0, 0.0, 1.0)],
                width: 0.02,
                slot: 0,
            },
        ];
        let mesh = strip_mesh(&strands, None).unwrap();
        assert_eq!(mesh.count_vertices(), 10);
        assert_eq!(mesh.indices().unwrap().len(), 6 * 3);
        let Some(VertexAttributeValues::Float32x4(strip)) = mesh.attribute(ATTRIBUTE_HAIR_STRIP)
        else {
            panic!("no strip attribute");
        };
        // u by arc length: the middle point of the first strand is a third of the way.
        assert_eq!(strip[2], [-1.0, 1.0 / 3.0, 0.01, 2.0]);
        assert_eq!(strip[5], [1.0, 1.0, 0.01, 2.0]);
        assert_eq!(strip[9], [1.0, 1.0, 0.02, 0.0]);
        assert!(strip_mesh(&[], None).is_none());
    }

    /// A strand without points (a `.hair` line `strand 0.01 0`) binds without a panic
    /// (it indexed its first point, #47); the others take their nearest vertex's joints.
    #[test]
    fn a_strand_without_points_binds_without_a_panic() {
        let mut skin = Mesh::new(
            PrimitiveTopology::TriangleList,
            RenderAssetUsages::default(),
        );
        skin.insert_attribute(
            Mesh::ATTRIBUTE_POSITION,
            vec![[0.0f32, 0.0, 0.0], [0.0, 2.0, 0.0]],
        );
        skin.insert_attribute(
            Mesh::ATTRIBUTE_JOINT_INDEX,
            VertexAttributeValues::Uint16x4(vec![[1, 0, 0, 0], [2, 0, 0, 0]]),
        );
        skin.insert_attribute(
            Mesh::ATTRIBUTE_JOINT_WEIGHT,
            vec![[1.0f32, 0.0, 0.0, 0.0]; 2],
        );
        let strands = [
            Strand {
                points: vec![],
                width: 0.01,
                slot: 0,
            },
            Strand {
                points: vec![Vec3::new(0.0, 1.9, 0.0), Vec3::new(0.0, 1.8, 0.1)],
                width: 0.01,
                slot: 0,
            },
        ];
        let joints = joints_from_skin(&strands, &skin).expect("a skin");
        assert_eq!(joints.len(), 2);
        assert_eq!(joints[1].0, [2, 0, 0, 0]);
    }
}
