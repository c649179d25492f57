//! Hair strips: a head with short hair and a beard under a key light, the camera
//! circling slowly. Some 5,000 strands of 2–4 segments (~33,000 triangles) are drawn as
//! camera-facing strips textured with an atlas of hair clumps; under 4× MSAA the alpha is
//! tested at every sample (Samaritan's short hair and beard), so the strands stay
//! anti-aliased and solid without sorting. They cast into the key light's shadow map
//! (the hair darkens the forehead and neck) and are lit with Kajiya-Kay highlights.
//!
//! ```text
//! cargo run --example hair                                  # a window (if a display exists)
//! cargo run --example hair -- --headless --frames 8 --out hair.png
//! cargo run --example hair -- --hair per-pixel              # one alpha test per pixel
//! cargo run --example hair -- --hair alpha-to-coverage      # or sample-shading, or off
//! ```
//!
//! Flags as for every example (`examples/common/cli.rs`). The 256×256 headless screenshot
//! is checked against `assets/reference/hair.png` by `tests/hair_example.rs`.

use bevy::light::{CascadeShadowConfigBuilder, GlobalAmbientLight};
use bevy::prelude::*;
use penumbra::prelude::*;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{HairMode, Options};
#[path = "common/character.rs"]
mod character;
use character::{HEAD_PARTS, SLOTS, hair_atlas, head_strands};

#[allow(dead_code, reason = "tests/hair_example.rs includes this file")]
fn main() -> std::process::ExitCode {
    cli::main("hair", add_scene, None)
}

/// Penumbra's plugins and this example's scene.
pub fn add_scene(app: &mut App) {
    app.add_plugins(PenumbraPlugins)
        .insert_resource(ClearColor(Color::srgb(0.02, 0.022, 0.03)))
        .insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.6, 0.7, 1.0),
            brightness: 120.0,
            ..default()
        })
        .add_systems(Startup, spawn_scene)
        .add_systems(Update, circle_camera);
}

/// Renders the example headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    cli::run_headless("hair", options, add_scene, None)
}

/// The head's centre.
const HEAD_AT: Vec3 = Vec3::new(0.0, 1.6, 0.0);

fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
    mut strands: ResMut<Assets<HairStrands>>,
    options: Option<Res<Options>>,
) {
    let skin = materials.add(StandardMaterial {
        base_color: Color::srgb(0.72, 0.5, 0.4),
        perceptual_roughness: 0.55,
        ..default()
    });
    let sphere = meshes.add(Sphere::new(1.0).mesh().uv(48, 32));
    // Head, nose, ears, neck and shoulders.
    let shoulders = (Vec3::new(0.0, -0.31, -0.02), Vec3::new(0.21, 0.08, 0.11));
    for (offset, scale) in HEAD_PARTS.into_iter().chain([shoulders]) {
        commands.spawn((
            Mesh3d(sphere.clone()),
            MeshMaterial3d(skin.clone()),
            Transform::from_translation(HEAD_AT + offset).with_scale(scale),
        ));
    }
    // A wall behind, for the shadows.
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::new(Vec3::Z, Vec2::splat(1.5)))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.35, 0.36, 0.4),
            perceptual_roughness: 0.9,
            ..default()
        })),
        Transform::from_xyz(0.0, 1.5, -0.45),
    ));
    let mode = options.as_ref().and_then(|o| o.hair);
    if mode != Some(HairMode::Off) {
        commands.spawn((
            Hair {
                strands: strands.add(HairStrands::new(head_strands())),
                atlas: Some(images.add(hair_atlas())),
                atlas_slots: SLOTS,
                root_color: Color::linear_rgb(0.018, 0.009, 0.005),
                tip_color: Color::linear_rgb(0.07, 0.04, 0.022),
                coverage: match mode {
                    Some(HairMode::SampleShading) => HairCoverage::SampleShading,
                    Some(HairMode::AlphaToCoverage) => HairCoverage::AlphaToCoverage,
                    Some(HairMode::PerPixel) => HairCoverage::PerPixel,
                    _ => HairCoverage::PerSample,
                },
                ..default()
            },
            Transform::from_translation(HEAD_AT),
        ));
    }
    // The key light, high on the camera's right; a cool fill on its left.
    commands.spawn((
        DirectionalLight {
            illuminance: 6000.0,
            shadow_maps_enabled: true,
            color: Color::srgb(1.0, 0.95, 0.88),
            ..default()
        },
        CascadeShadowConfigBuilder {
            num_cascades: 1,
            maximum_distance: 2.0,
            ..default()
        }
        .build(),
        Transform::default().looking_to(Vec3::new(-0.6, -0.65, -0.5), Vec3::Y),
    ));
    commands.spawn((
        PointLight {
            intensity: 20_000.0,
            color: Color::srgb(0.6, 0.7, 1.0),
            ..default()
        },
        Transform::from_xyz(-0.5, 1.7, 0.8),
    ));
    commands.spawn((Camera3d::default(), Msaa::Sample4, camera_transform(0)));
}

/// The camera `frame` frames in: circling the head slowly, a little above it.
fn camera_transform(frame: u32) -> Transform {
    let angle = 0.55 + 0.02 * frame as f32;
    let target = HEAD_AT + Vec3::new(0.0, -0.03, 0.0);
    Transform::from_translation(target + Vec3::new(angle.sin(), 0.25, angle.cos()) * 0.52)
        .looking_at(target, Vec3::Y)
}

/// Moves the camera a step per frame (frames, not seconds: headless captures repeat).
fn circle_camera(mut cameras: Query<&mut Transform, With<Camera3d>>, mut frame: Local<u32>) {
    *frame += 1;
    for mut transform in &mut cameras {
        *transform = camera_transform(*frame);
    }
}
