//! Deferred shading with 4× MSAA: a fence of thin posts and wires, a grille and a ball
//! against a bright sky, lit through Penumbra's deferred lighting pass with
//! distance-field shadows — and anti-aliased, which Bevy's deferred renderer cannot do.
//! Penumbra shades each pixel once where its four samples agree and each sample where
//! they do not (the wires' and posts' silhouettes, the ground's far edge).
//!
//! ```text
//! cargo run --example deferred_msaa                          # a window (if a display exists)
//! cargo run --example deferred_msaa -- --headless --frames 8 --out deferred_msaa.png
//! cargo run --example deferred_msaa -- --headless --msaa off   # the same without MSAA
//! cargo run --example deferred_msaa -- --headless --msaa edges # per-sample pixels in magenta
//! ```
//!
//! Flags as for every example (`examples/common/cli.rs`); `--msaa off|4|every|edges`
//! picks `Msaa::Off`, deferred 4× (the default), every sample shaded (the reference the
//! classifier is measured against) or the per-sample mask's debug view
//! (`DeferredMsaa::show_edges`). The scene is still, so a headless capture is the same
//! on every machine; its 256×256 screenshots with and without MSAA are checked against
//! `assets/reference/deferred_msaa.png` and `deferred_msaa_off.png` by
//! `tests/deferred_msaa_example.rs`. Accuracy and cost against 16× supersampling and
//! Bevy's forward MSAA: `crates/bevy_penumbra_df/tests/deferred_msaa.rs`.

use bevy::{light::GlobalAmbientLight, pbr::DefaultOpaqueRendererMethod, prelude::*};
use penumbra::prelude::*;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{MsaaMode, Options, casters_ready};

#[allow(
    dead_code,
    reason = "tests/deferred_msaa_example.rs includes this file"
)]
fn main() -> std::process::ExitCode {
    cli::main("deferred_msaa", add_scene, Some(casters_ready))
}

/// Penumbra's plugins and this example's scene.
pub fn add_scene(app: &mut App) {
    app.add_plugins(PenumbraPlugins)
        // Penumbra's lighting pass shades deferred materials (Bevy's switch, app-wide).
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .insert_resource(ClearColor(Color::srgb(0.85, 0.9, 1.0)))
        .insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.7, 0.8, 1.0),
            brightness: 300.0,
            ..default()
        })
        .add_systems(Startup, spawn_scene);
}

/// Renders the example headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    cli::run_headless("deferred_msaa", options, add_scene, Some(casters_ready))
}

fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    options: Option<Res<Options>>,
) {
    let mut material = |color: Color, roughness: f32| {
        materials.add(StandardMaterial {
            base_color: color,
            perceptual_roughness: roughness,
            ..default()
        })
    };
    let ground = material(Color::srgb(0.55, 0.52, 0.45), 0.9);
    let dark = material(Color::srgb(0.06, 0.06, 0.07), 0.5);
    let wood = material(Color::srgb(0.45, 0.3, 0.18), 0.8);
    let red = material(Color::srgb(0.75, 0.15, 0.1), 0.4);

    // A ground tilted away: its far edge meets the sky.
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(14.0, 10.0))),
        MeshMaterial3d(ground),
        Transform::from_xyz(0.0, 0.0, -2.0).with_rotation(Quat::from_rotation_x(0.12)),
    ));
    // Fence posts (distance-field casters) and three sagging wires between them.
    let post = meshes.add(Cuboid::new(0.08, 1.6, 0.08));
    for i in 0..5 {
        let x = -2.4 + 1.2 * i as f32;
        commands.spawn((
            Mesh3d(post.clone()),
            MeshMaterial3d(wood.clone()),
            Transform::from_xyz(x, 0.8, -0.6),
            DistanceFieldCaster {
                source: CasterSource::Cuboid {
                    half_size: Vec3::new(0.04, 0.8, 0.04),
                },
                ..default()
            },
        ));
    }
    let wire = meshes.add(Cuboid::new(4.8, 0.012, 0.012));
    for (i, y) in [0.8, 1.1, 1.4].into_iter().enumerate() {
        commands.spawn((
            Mesh3d(wire.clone()),
            MeshMaterial3d(dark.clone()),
            Transform::from_xyz(0.0, y, -0.6).with_rotation(Quat::from_rotation_z(0.02 * i as f32)),
        ));
    }
    // A grille of thin bars.
    let bar = meshes.add(Cuboid::new(0.025, 0.9, 0.025));
    for i in 0..10 {
        commands.spawn((
            Mesh3d(bar.clone()),
            MeshMaterial3d(dark.clone()),
            Transform::from_xyz(-1.9 + 0.1 * i as f32, 0.45, 0.6),
        ));
    }
    // A ball casting a soft distance-field shadow.
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.45).mesh().uv(64, 32))),
        MeshMaterial3d(red),
        Transform::from_xyz(1.3, 0.45, 0.4),
        DistanceFieldCaster {
            source: CasterSource::Sphere { radius: 0.45 },
            ..default()
        },
    ));
    commands.spawn((
        DirectionalLight {
            illuminance: 6000.0,
            ..default()
        },
        DistanceFieldShadows::default(),
        Transform::default().looking_to(Vec3::new(-0.4, -1.0, -0.5), Vec3::Y),
    ));
    let mode = options.and_then(|o| o.msaa).unwrap_or(MsaaMode::Classified);
    let mut camera = commands.spawn((
        Camera3d::default(),
        PenumbraLighting,
        Transform::from_xyz(0.3, 1.3, 4.2).looking_at(Vec3::new(0.0, 0.9, 0.0), Vec3::Y),
    ));
    match mode {
        MsaaMode::Off => camera.insert(Msaa::Off),
        MsaaMode::Classified => camera.insert(DeferredMsaa::default()),
        MsaaMode::EverySample => camera.insert(DeferredMsaa {
            shading: DeferredMsaaShading::EverySample,
            ..default()
        }),
        MsaaMode::Edges => camera.insert(DeferredMsaa {
            show_edges: true,
            ..default()
        }),
    };
}
