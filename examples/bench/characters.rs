//! The characters scene (#48's cost): `--characters N` Foxes (`Fox.glb`, scaled to
//! about 1.2 m) walking in place on a ground in a square grid 2 m apart, under a sun.
//! Each plays the glTF's walk (animation 1) from its own phase: the joints' local
//! transforms are sampled once by `penumbra_reference::posed_gltf` at 24 times over
//! the walk's 0.708 s and cycled, so every frame poses every Fox anew (as an animated crowd does) at
//! no cost the measurement would count.
//!
//! Variants: `bevy` (shadow maps), `bevy-no-shadows`, `penumbra-skip` (Penumbra's
//! shadows and DFAO with the Foxes not cast: `SkinnedCasters::Skip`),
//! `penumbra-bind-pose` (each Fox cast by one field baked in its bind pose, once:
//! `SkinnedCasters::BindPose`), `penumbra` (each Fox cast by capsules fitted to its
//! joints, the default of `DistanceFieldSceneCasters`) and `penumbra-rebake` (each
//! Fox's own field re-baked on the GPU from its pose every frame, `DistanceFieldRebake`
//! at its defaults). The report gives per variant the records uploaded and the
//! re-bakes per frame beside the passes' GPU times.

use super::scenes::{BenchCamera, Framed, Run, Variant};
use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use penumbra::prelude::*;
use penumbra_reference::posed_gltf::{NodePose, Pose, node_poses};
use std::path::Path;

/// The Fox's file under the scenes folder.
pub const FILE: &str = "Fox.glb";
/// Fox.glb is in centimetres (about 120 long).
const SCALE: f32 = 0.01;
/// Metres between neighbours.
const SPACING: f32 = 2.0;
/// The walk's samples over one cycle of it.
const KEYS: usize = 24;
/// The length of the Fox's walk (animation 1, "Walk"), seconds.
const WALK_SECONDS: f32 = 0.708;

/// The walk's node transforms at each key (by glTF node index).
#[derive(Resource)]
struct Walk(Vec<Vec<NodePose>>);

/// A Fox's root, its phase (keys), and once its nodes exist, the entity of each glTF
/// node (by index; `None` for one not found).
#[derive(Component)]
struct Fox {
    phase: usize,
    nodes: Option<Vec<Option<Entity>>>,
}

/// Adds the scene: the Foxes, their ground, the camera's place and the sun. `Err` when
/// the Fox's walk cannot be read.
pub fn add(app: &mut App, run: &Run, scenes_dir: &Path) -> Result<(), String> {
    let keys = (0..KEYS)
        .map(|k| {
            node_poses(
                &scenes_dir.join(FILE),
                Pose {
                    animation: 1,
                    time: k as f32 * WALK_SECONDS / KEYS as f32,
                },
            )
        })
        .collect::<Result<Vec<_>, _>>()?;
    app.insert_resource(Walk(keys))
        .add_systems(PostStartup, spawn_characters)
        .add_systems(Update, (find_nodes, walk).chain());
    if run.variant == Variant::PenumbraRebake {
        app.add_systems(Update, rebake_skinned_meshes);
    }
    Ok(())
}

/// The grid's side for `n` characters.
fn side(n: u32) -> u32 {
    (f64::from(n).sqrt().ceil() as u32).max(1)
}

fn spawn_characters(
    mut commands: Commands,
    run: Res<Run>,
    assets: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut camera: Single<&mut Transform, With<BenchCamera>>,
) {
    let n = run.characters;
    let side = side(n);
    let half = 0.5 * (side - 1) as f32 * SPACING;
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(FILE));
    for i in 0..n {
        let at = Vec3::new(
            (i % side) as f32 * SPACING - half,
            0.0,
            (i / side) as f32 * SPACING - half,
        );
        let mut fox = commands.spawn((
            Fox {
                phase: (i as usize * 7) % KEYS,
                nodes: None,
            },
            Transform::from_translation(at)
                .with_rotation(Quat::from_rotation_y(0.3 * i as f32))
                .with_scale(Vec3::splat(SCALE)),
            Visibility::default(),
            WorldAssetRoot(scene.clone()),
        ));
        if run.variant.distance_fields() {
            fox.insert(DistanceFieldSceneCasters {
                skinned: match run.variant {
                    Variant::PenumbraSkip => SkinnedCasters::Skip,
                    Variant::PenumbraBindPose => SkinnedCasters::BindPose,
                    _ => SkinnedCasters::Capsules,
                },
                ..default()
            });
        }
    }
    let extent = half + SPACING;
    let mut ground = commands.spawn((
        Mesh3d(meshes.add(Plane3d::new(Vec3::Y, Vec2::splat(extent)))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.55, 0.55, 0.5),
            perceptual_roughness: 0.9,
            ..default()
        })),
        Transform::default(),
    ));
    if run.variant.distance_fields() {
        ground.insert(DistanceFieldCaster {
            source: CasterSource::Plane,
            ..default()
        });
    }
    commands.spawn(super::scenes::sun());
    commands.insert_resource(GlobalAmbientLight {
        color: Color::srgb(0.7, 0.8, 1.0),
        brightness: 120.0,
        ..default()
    });
    let radius = extent * std::f32::consts::SQRT_2;
    let distance = radius / (PerspectiveProjection::default().fov * 0.5).sin();
    **camera = Transform::from_translation(Vec3::new(0.0, 0.6, 1.0).normalize() * distance)
        .looking_at(Vec3::ZERO, Vec3::Y);
    commands.insert_resource(Framed {
        scale: (radius / 10.0).max(1.0),
        reach: distance + 2.0 * radius,
    });
}

/// Once a Fox's scene has spawned: its glTF nodes' entities, by the node's name (as
/// the viewer's `--animation` finds them).
fn find_nodes(
    walk: Res<Walk>,
    mut foxes: Query<(Entity, &mut Fox)>,
    children: Query<&Children>,
    names: Query<&Name, Without<Mesh3d>>,
) {
    for (root, mut fox) in &mut foxes {
        if fox.nodes.is_some() {
            continue;
        }
        let named: Vec<(Entity, &Name)> = children
            .iter_descendants(root)
            .filter_map(|e| Some((e, names.get(e).ok()?)))
            .collect();
        if named.is_empty() {
            continue; // not spawned yet
        }
        let nodes = walk.0[0]
            .iter()
            .enumerate()
            .map(|(index, node)| {
                let name = node
                    .name
                    .clone()
                    .unwrap_or_else(|| format!("GltfNode{index}"));
                named
                    .iter()
                    .find(|(_, n)| n.as_str() == name)
                    .map(|(e, _)| *e)
            })
            .collect();
        fox.nodes = Some(nodes);
    }
}

/// Every Fox one key further along its walk.
fn walk(
    walk: Res<Walk>,
    mut foxes: Query<&mut Fox>,
    mut transforms: Query<&mut Transform, Without<Fox>>,
    mut frame: Local<usize>,
) {
    *frame += 1;
    for fox in &mut foxes {
        let Some(nodes) = &fox.nodes else {
            continue;
        };
        let key = &walk.0[(*frame + fox.phase) % KEYS];
        for (node, entity) in key.iter().zip(nodes) {
            if let Some(mut t) = entity.and_then(|e| transforms.get_mut(e).ok()) {
                *t = Transform {
                    translation: node.translation,
                    rotation: node.rotation,
                    scale: node.scale,
                };
            }
        }
    }
}

/// `penumbra-rebake`: each skinned mesh re-baked from its pose.
fn rebake_skinned_meshes(
    mut commands: Commands,
    meshes: Query<Entity, (With<SkinnedMesh>, Without<DistanceFieldRebake>)>,
) {
    for mesh in &meshes {
        commands.entity(mesh).insert(DistanceFieldRebake::default());
    }
}
