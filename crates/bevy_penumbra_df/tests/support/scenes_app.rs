//! A headless app of Bevy's default plugins with no GPU (no backend: main world only),
//! its assets read from `../shared/scenes`, with the SDF assets (no disk cache) and the
//! distance-field scene: the setting of the tests that load real glTF scenes and check
//! what the main world makes of them.

use bevy::mesh::VertexAttributeValues;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::prelude::*;
use bevy::render::RenderPlugin;
use bevy::render::settings::{RenderCreation, WgpuSettings};
use bevy_penumbra_df::{DistanceFieldScenePlugin, SdfAssetPlugin, SdfBakeCache};
use std::path::{Path, PathBuf};

/// `../shared/scenes`, or `None` after reporting `test` skipped.
pub fn scenes_dir(test: &str) -> Option<PathBuf> {
    let dir = penumbra_testkit::shared_dir(test, env!("CARGO_MANIFEST_DIR"), "scenes")?;
    Some(dir.canonicalize().expect("scenes dir"))
}

/// The app, reading assets from `dir`; finished and cleaned up.
pub fn scenes_app_at(dir: &Path) -> App {
    scenes_app_with(dir, |_| {})
}

/// [`scenes_app_at`] with more plugins, added by `more` before the app is finished.
pub fn scenes_app_with(dir: &Path, more: impl FnOnce(&mut App)) -> App {
    let mut app = App::new();
    app.add_plugins(
        DefaultPlugins
            .set(AssetPlugin {
                file_path: dir.to_string_lossy().into_owned(),
                ..default()
            })
            .set(RenderPlugin {
                render_creation: RenderCreation::from(WgpuSettings {
                    backends: None,
                    ..default()
                }),
                ..default()
            })
            .disable::<bevy::winit::WinitPlugin>(),
    )
    .insert_resource(SdfBakeCache::with_directory(None))
    .add_plugins((SdfAssetPlugin, DistanceFieldScenePlugin));
    more(&mut app);
    app.finish();
    app.cleanup();
    app
}

/// The app on `../shared/scenes`, or `None` after reporting `test` skipped.
#[allow(dead_code, reason = "not every test takes the default directory")]
pub fn scenes_app(test: &str) -> Option<App> {
    Some(scenes_app_at(&scenes_dir(test)?))
}

/// The mesh's vertices skinned as Bevy skins them (world space: linear blend of the
/// joints' transforms times their inverse binds), with each vertex's dominant joint.
#[allow(dead_code, reason = "not every test reads skins")]
pub fn skinned_vertices(app: &App, mesh_entity: Entity) -> Vec<(Vec3, Entity)> {
    let world = app.world();
    let skin = world.get::<SkinnedMesh>(mesh_entity).expect("skinned");
    let mesh = world
        .resource::<Assets<Mesh>>()
        .get(&world.get::<Mesh3d>(mesh_entity).expect("a mesh").0)
        .expect("mesh");
    let inverse = world
        .resource::<Assets<SkinnedMeshInverseBindposes>>()
        .get(&skin.inverse_bindposes)
        .expect("bindposes");
    let (
        Some(VertexAttributeValues::Float32x3(p)),
        Some(VertexAttributeValues::Uint16x4(j)),
        Some(VertexAttributeValues::Float32x4(w)),
    ) = (
        mesh.attribute(Mesh::ATTRIBUTE_POSITION),
        mesh.attribute(Mesh::ATTRIBUTE_JOINT_INDEX),
        mesh.attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT),
    )
    else {
        panic!("skin attributes")
    };
    let matrices: Vec<Mat4> = skin
        .joints
        .iter()
        .zip(inverse.iter())
        .map(|(joint, inv)| {
            world
                .get::<GlobalTransform>(*joint)
                .expect("a joint")
                .to_matrix()
                * *inv
        })
        .collect();
    p.iter()
        .zip(j)
        .zip(w)
        .map(|((p, j), w)| {
            let mut posed = Vec3::ZERO;
            let mut best = (0, f32::NEG_INFINITY);
            for k in 0..4 {
                let joint = usize::from(j[k]);
                posed += w[k] * matrices[joint].transform_point3(Vec3::from(*p));
                if w[k] > best.1 {
                    best = (joint, w[k]);
                }
            }
            (posed, skin.joints[best.0])
        })
        .collect()
}
