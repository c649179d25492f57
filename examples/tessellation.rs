//! Compute tessellation: a cobbled rock under a low sun. The 768-triangle rock (a UV
//! seam down its side, a hard edge and a second UV chart at its rim) is cut to ~12-pixel
//! edges on the GPU every frame the camera moves, smoothed as PN-AEN patches and
//! displaced by a 256² height map along the averaged normal — no cracks at the seam or
//! the rim — then drawn by `StandardMaterial`, shadows included.
//!
//! ```text
//! cargo run --example tessellation                                   # a window (if a display exists)
//! cargo run --example tessellation -- --headless --frames 6 --out tessellation.png
//! cargo run --example tessellation -- --tessellation flat            # or off, or wireframe
//! ```
//!
//! In a window: `T` cycles off / flat / PN-AEN, `W` toggles the wireframe view (Bevy's
//! `Wireframe` on the tessellated mesh, where the GPU supports line polygons). Flags as
//! for every example (`examples/common/cli.rs`). The 256×256 headless screenshots are
//! checked against `assets/reference/tessellation.png` and (`--tessellation wireframe`)
//! `assets/reference/tessellation_wireframe.png` by `tests/tessellation_example.rs`.

use bevy::asset::RenderAssetUsages;
use bevy::pbr::wireframe::{Wireframe, WireframePlugin};
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use penumbra::cinematic::tessellation::shape_mesh;
use penumbra::prelude::*;
use penumbra_cinematic_core::tessellation::shapes;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{Options, TessellationChoice};

#[allow(dead_code, reason = "tests/tessellation_example.rs includes this file")]
fn main() -> std::process::ExitCode {
    cli::main("tessellation", add_scene, None)
}

/// Penumbra's plugins and this example's scene.
pub fn add_scene(app: &mut App) {
    app.add_plugins((PenumbraPlugins, WireframePlugin::default()))
        .insert_resource(ClearColor(Color::srgb(0.45, 0.55, 0.7)))
        .add_systems(Startup, spawn_scene)
        .add_systems(Update, (toggle, orbit));
}

/// Renders the example headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    cli::run_headless("tessellation", options, add_scene, None)
}

/// The rock's settings for a choice (`None`: untessellated).
fn settings(choice: TessellationChoice, map: &Handle<Image>) -> Option<Tessellated> {
    let mode = match choice {
        TessellationChoice::Off => return None,
        TessellationChoice::Flat => TessellationMode::Flat,
        TessellationChoice::PnAen | TessellationChoice::Wireframe => TessellationMode::PnAen,
    };
    Some(Tessellated {
        pixels_per_triangle: 12.0,
        max_level: 5,
        displacement: Some(map.clone()),
        displacement_scale: 0.2,
        mode,
        ..default()
    })
}

#[derive(Resource)]
struct Scene {
    rock: Entity,
    map: Handle<Image>,
    choice: TessellationChoice,
}

fn height_image() -> Image {
    let size = 256;
    let bytes: Vec<u8> = shapes::height_map(size)
        .iter()
        .map(|h| (h * 255.0).round() as u8)
        .collect();
    Image::new(
        Extent3d {
            width: size,
            height: size,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        bytes,
        TextureFormat::R8Unorm,
        RenderAssetUsages::default(),
    )
}

fn spawn_scene(
    mut commands: Commands,
    options: Option<Res<Options>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut images: ResMut<Assets<Image>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let choice = options
        .and_then(|o| o.tessellation)
        .unwrap_or(TessellationChoice::PnAen);
    let map = images.add(height_image());
    let mut rock = commands.spawn((
        Mesh3d(meshes.add(shape_mesh(&shapes::rock(32, 8)))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.62, 0.58, 0.52),
            perceptual_roughness: 0.85,
            ..default()
        })),
        Transform::from_scale(Vec3::splat(1.2)),
    ));
    if let Some(t) = settings(choice, &map) {
        rock.insert(t);
    }
    if choice == TessellationChoice::Wireframe {
        rock.insert(Wireframe);
    }
    let rock = rock.id();
    commands.insert_resource(Scene { rock, map, choice });
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(8.0, 8.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.3, 0.34, 0.28),
            perceptual_roughness: 1.0,
            ..default()
        })),
        Transform::from_xyz(0.0, -0.02, 0.0),
    ));
    commands.spawn((
        DirectionalLight {
            illuminance: 12_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(-1.0, 0.8, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((Camera3d::default(), camera_transform(0), Msaa::Sample4));
}

fn camera_transform(frame: u32) -> Transform {
    let angle = 0.6 + frame as f32 * 0.01;
    Transform::from_xyz(3.6 * angle.cos(), 1.4, 3.6 * angle.sin())
        .looking_at(Vec3::new(0.0, 0.35, 0.0), Vec3::Y)
}

/// Moves the camera a step per frame (frames, not seconds: headless captures repeat).
fn orbit(mut cameras: Query<&mut Transform, With<Camera3d>>, mut frame: Local<u32>) {
    *frame += 1;
    for mut t in &mut cameras {
        *t = camera_transform(*frame);
    }
}

/// `T` cycles off / flat / PN-AEN; `W` toggles the wireframe.
fn toggle(
    keys: Option<Res<ButtonInput<KeyCode>>>,
    mut scene: ResMut<Scene>,
    mut commands: Commands,
    wireframes: Query<(), With<Wireframe>>,
) {
    let Some(keys) = keys else { return };
    if keys.just_pressed(KeyCode::KeyT) {
        scene.choice = match scene.choice {
            TessellationChoice::Off => TessellationChoice::Flat,
            TessellationChoice::Flat => TessellationChoice::PnAen,
            TessellationChoice::PnAen | TessellationChoice::Wireframe => TessellationChoice::Off,
        };
        info!("tessellation: {:?}", scene.choice);
        match settings(scene.choice, &scene.map) {
            Some(t) => commands.entity(scene.rock).insert(t),
            None => commands.entity(scene.rock).remove::<Tessellated>(),
        };
    }
    if keys.just_pressed(KeyCode::KeyW) {
        if wireframes.contains(scene.rock) {
            commands.entity(scene.rock).remove::<Wireframe>();
        } else {
            commands.entity(scene.rock).insert(Wireframe);
        }
    }
}
