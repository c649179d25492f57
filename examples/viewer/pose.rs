//! `--animation N --time T`: the scene held in a pose of its glTF animation. The nodes'
//! local transforms are sampled by `penumbra_reference::posed_gltf` (the sampler the
//! ray-traced truth poses its triangles with) and set on the scene's node entities by
//! name (Bevy's: the node's, or `GltfNode{index}` for an unnamed one), once the scene
//! has spawned; skinned meshes then follow their joints as in any Bevy app. A node whose
//! name an earlier node took keeps its rest transform.

use super::{ViewerArgs, ViewerError, ViewerScene};
use bevy::prelude::*;
use penumbra_reference::posed_gltf::{Pose, node_poses};

/// Sets the pose once the scene's nodes exist (then never again).
pub fn pose_scene(
    args: Res<ViewerArgs>,
    root: Single<Entity, With<ViewerScene>>,
    children: Query<&Children>,
    mut nodes: Query<(&Name, &mut Transform), Without<Mesh3d>>,
    mut error: ResMut<ViewerError>,
    mut done: Local<bool>,
) {
    let (Some(animation), Some(path)) = (args.0.animation, args.0.scene.as_ref()) else {
        return;
    };
    if *done || error.0.is_some() {
        return;
    }
    let descendants: Vec<Entity> = children.iter_descendants(*root).collect();
    if !descendants.iter().any(|&e| nodes.contains(e)) {
        return; // not spawned yet
    }
    *done = true;
    let pose = Pose {
        animation,
        time: args.0.time.unwrap_or(0.0),
    };
    let poses = match node_poses(path, pose) {
        Ok(p) => p,
        Err(e) => {
            error.0 = Some(format!("--animation {animation}: {e}"));
            return;
        }
    };
    let mut posed = 0;
    let mut seen = std::collections::HashSet::new();
    for (index, node) in poses.iter().enumerate() {
        let name = node
            .name
            .clone()
            .unwrap_or_else(|| format!("GltfNode{index}"));
        if !seen.insert(name.clone()) {
            continue;
        }
        if let Some(&entity) = descendants
            .iter()
            .find(|&&e| nodes.get(e).is_ok_and(|(n, _)| n.as_str() == name))
            && let Ok((_, mut transform)) = nodes.get_mut(entity)
        {
            *transform = Transform {
                translation: node.translation,
                rotation: node.rotation,
                scale: node.scale,
            };
            posed += 1;
        }
    }
    info!(
        "viewer: posed {posed} of {} nodes (animation {animation} at {} s)",
        poses.len(),
        pose.time
    );
}
