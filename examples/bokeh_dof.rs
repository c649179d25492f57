//! Scatter bokeh depth of field on Bevy's own depth-of-field scene (a circuit board,
//! `../shared/scenes/DepthOfFieldExample.glb`): the camera, focus and aperture of Bevy's
//! `depth_of_field` example (focused at 7 m, f/0.125, the background at 14 m), with
//! Penumbra's [`BokehDepthOfField`] — each out-of-focus pixel a hexagonal sprite — or,
//! for comparison, Bevy's `DepthOfField` in either of its modes.
//!
//! ```text
//! cargo run --example bokeh_dof                          # a window (if a display exists)
//! cargo run --example bokeh_dof -- --headless --frames 4 --out bokeh_dof.png
//! cargo run --example bokeh_dof -- --headless --dof bevy-bokeh   # Bevy's gather bokeh
//! ```
//!
//! Flags as for every example (`examples/common/cli.rs`); `--dof penumbra|circle|
//! bevy-bokeh|bevy-gaussian|off` picks Penumbra's scatter bokeh with the hexagonal
//! aperture (the default) or a circular one, Bevy's `DepthOfField` in bokeh or Gaussian
//! mode, or none; `--assets DIR` the folder holding the scene (default
//! `../shared/scenes` beside the checkout). The scene is still, so a headless capture is
//! the same on every machine; its 256×256 screenshot is checked against
//! `assets/reference/bokeh_dof.png` by `tests/bokeh_dof_example.rs`.

use bevy::camera::Hdr;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::post_process::dof::{DepthOfField, DepthOfFieldMode};
use bevy::prelude::*;
use bevy::world_serialization::{WorldAsset, WorldAssetRoot};
use penumbra::prelude::*;
use std::path::PathBuf;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{DofMode, Options};

/// The scene, in the asset folder.
pub const SCENE: &str = "DepthOfFieldExample.glb";

#[allow(dead_code, reason = "tests/bokeh_dof_example.rs includes this file")]
fn main() -> std::process::ExitCode {
    cli::main_with_assets("bokeh_dof", add_scene, Some(scene_ready), scenes_dir())
}

/// `../shared/scenes` beside the checkout.
pub fn scenes_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/scenes")
}

/// The lens of Bevy's `depth_of_field` example.
const FOCAL_DISTANCE: f32 = 7.0;
const F_STOPS: f32 = 1.0 / 8.0;
const MAX_DEPTH: f32 = 14.0;

/// The scene's root (its handle tells when it has loaded).
#[derive(Resource)]
struct SceneHandle(Handle<WorldAsset>);

/// Penumbra's plugins and this example's scene.
pub fn add_scene(app: &mut App) {
    app.add_plugins(PenumbraPlugins)
        .add_systems(Startup, spawn_scene)
        .add_systems(Update, enable_shadow_maps);
}

/// Renders the example headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    let mut options = options.clone();
    options.assets.get_or_insert_with(scenes_dir);
    cli::run_headless("bokeh_dof", &options, add_scene, Some(scene_ready))
}

/// The camera's depth of field for `mode`.
pub fn depth_of_field(mode: DofMode) -> (Option<BokehDepthOfField>, Option<DepthOfField>) {
    let penumbra = |aperture| BokehDepthOfField {
        focal_distance: FOCAL_DISTANCE,
        aperture_f_stops: F_STOPS,
        max_depth: MAX_DEPTH,
        aperture,
        ..default()
    };
    let bevy = |mode| DepthOfField {
        mode,
        focal_distance: FOCAL_DISTANCE,
        aperture_f_stops: F_STOPS,
        max_depth: MAX_DEPTH,
        ..default()
    };
    match mode {
        DofMode::Penumbra => (Some(penumbra(BokehAperture::Hexagon)), None),
        DofMode::PenumbraCircle => (Some(penumbra(BokehAperture::Circle)), None),
        DofMode::BevyBokeh => (None, Some(bevy(DepthOfFieldMode::Bokeh))),
        DofMode::BevyGaussian => (None, Some(bevy(DepthOfFieldMode::Gaussian))),
        DofMode::Off => (None, None),
    }
}

fn spawn_scene(mut commands: Commands, assets: Res<AssetServer>, options: Option<Res<Options>>) {
    let mode = options.and_then(|o| o.dof).unwrap_or(DofMode::Penumbra);
    let mut camera = commands.spawn((
        Camera3d::default(),
        Hdr,
        Transform::from_xyz(0.0, 4.5, 8.25).looking_at(Vec3::ZERO, Vec3::Y),
        Tonemapping::TonyMcMapface,
    ));
    match depth_of_field(mode) {
        (Some(bokeh), _) => {
            camera.insert(bokeh);
        }
        (_, Some(bevy)) => {
            camera.insert(bevy);
        }
        _ => {}
    }
    let scene = assets.load(GltfAssetLabel::Scene(0).from_asset(SCENE));
    commands.spawn(WorldAssetRoot(scene.clone()));
    commands.insert_resource(SceneHandle(scene));
}

/// The scene's sun casts shadow maps (as in Bevy's example).
fn enable_shadow_maps(mut lights: Query<&mut DirectionalLight, Changed<DirectionalLight>>) {
    for mut light in &mut lights {
        light.shadow_maps_enabled = true;
    }
}

/// Whether the scene has loaded and spawned its meshes (headless captures count frames
/// from then).
pub fn scene_ready(world: &mut World) -> bool {
    let Some(handle) = world.get_resource::<SceneHandle>().map(|h| h.0.clone()) else {
        return false;
    };
    let server = world.resource::<AssetServer>();
    if matches!(
        server.get_recursive_dependency_load_state(&handle),
        Some(bevy::asset::RecursiveDependencyLoadState::Failed(_))
    ) {
        error!("bokeh_dof: {SCENE} failed to load (see --assets)");
        return true;
    }
    let loaded = server.is_loaded_with_dependencies(&handle);
    loaded && world.query::<&Mesh3d>().iter(world).next().is_some()
}
