//! Screen-space subsurface scattering: a head-like bust of skin under a warm point light,
//! a thin bar between them casting a distance-field shadow across the face. Where the
//! light ends — the shadow's edges, the terminator — the skin glows red as light
//! travelling under the surface comes out in the shade; the highlights stay sharp
//! (specular light is not scattered); the dark backdrop beside the silhouette gains
//! nothing.
//!
//! ```text
//! cargo run --example subsurface                          # a window (if a display exists)
//! cargo run --example subsurface -- --headless --frames 8 --out subsurface.png
//! cargo run --example subsurface -- --no-sss               # the same skin, unscattered
//! ```
//!
//! Flags as for every example (`examples/common/cli.rs`); `--no-sss` removes the
//! camera's `SubsurfaceScattering` (the skin is then lit as an ordinary
//! `StandardMaterial`). The 256×256 headless screenshot is checked against
//! `assets/reference/subsurface.png` by `tests/subsurface_example.rs`.
//!
//! A material scatters when its `deferred_lighting_pass_id` names a profile registered
//! in `SubsurfaceProfiles` (`SubsurfaceProfileId::apply`); the camera's
//! `SubsurfaceScattering` sets the quality.

use bevy::{light::GlobalAmbientLight, pbr::DefaultOpaqueRendererMethod, prelude::*};
use penumbra::cinematic::SubsurfaceProfileId;
use penumbra::prelude::*;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{Options, casters_ready};

#[allow(dead_code, reason = "tests/subsurface_example.rs includes this file")]
fn main() -> std::process::ExitCode {
    cli::main("subsurface", add_scene, Some(casters_ready))
}

/// Penumbra's plugins and this example's scene.
pub fn add_scene(app: &mut App) {
    app.add_plugins(PenumbraPlugins)
        // Penumbra's lighting pass shades deferred materials (Bevy's switch, app-wide).
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .insert_resource(ClearColor(Color::srgb(0.02, 0.02, 0.03)))
        .insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.5, 0.6, 0.8),
            brightness: 60.0,
            ..default()
        })
        .add_systems(Startup, spawn_scene);
}

/// Renders the example headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    cli::run_headless("subsurface", options, add_scene, Some(casters_ready))
}

/// Skin: red light travels furthest under the surface (Jimenez's and Unreal's default
/// skin profiles scatter red a few millimetres to a centimetre).
fn skin_profile() -> SubsurfaceProfile {
    SubsurfaceProfile {
        scatter_color: Color::srgb(0.95, 0.5, 0.35),
        radius: 0.006,
    }
}

fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut profiles: ResMut<SubsurfaceProfiles>,
    options: Option<Res<Options>>,
) {
    let skin: SubsurfaceProfileId = profiles.add(skin_profile()).expect("the first profile");
    let skin = materials.add(skin.apply(StandardMaterial {
        base_color: Color::srgb(0.85, 0.62, 0.52),
        perceptual_roughness: 0.45,
        reflectance: 0.35,
        ..default()
    }));
    let sphere = meshes.add(Sphere::new(1.0).mesh().uv(96, 48));
    // The bust: head, nose, ears, neck (ellipsoids: scaled unit spheres).
    let mut part = |translation: Vec3, scale: Vec3| {
        commands.spawn((
            Mesh3d(sphere.clone()),
            MeshMaterial3d(skin.clone()),
            Transform::from_translation(translation).with_scale(scale),
        ));
    };
    part(Vec3::new(0.0, 1.6, 0.0), Vec3::new(0.078, 0.108, 0.095));
    part(Vec3::new(0.0, 1.585, 0.093), Vec3::new(0.014, 0.026, 0.018));
    part(Vec3::new(0.078, 1.6, -0.005), Vec3::new(0.012, 0.03, 0.02));
    part(Vec3::new(-0.078, 1.6, -0.005), Vec3::new(0.012, 0.03, 0.02));
    part(Vec3::new(0.0, 1.45, -0.01), Vec3::new(0.05, 0.09, 0.05));
    // A dark backdrop: not scattering, right behind the silhouette.
    commands.spawn((
        Mesh3d(meshes.add(Rectangle::new(2.0, 2.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.08, 0.08, 0.1),
            perceptual_roughness: 0.9,
            ..default()
        })),
        Transform::from_xyz(0.0, 1.6, -0.25),
    ));
    // The bar whose distance-field shadow crosses the face.
    commands.spawn((
        Mesh3d(meshes.add(Capsule3d::new(0.01, 0.5))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.3, 0.3, 0.32),
            ..default()
        })),
        Transform::from_xyz(0.12, 1.6, 0.2).with_rotation(Quat::from_rotation_z(0.35)),
        DistanceFieldCaster {
            source: CasterSource::Capsule {
                radius: 0.01,
                half_length: 0.25,
            },
            ..default()
        },
    ));
    commands.spawn((
        PointLight {
            color: Color::srgb(1.0, 0.85, 0.7),
            intensity: 9_000.0,
            range: 4.0,
            radius: 0.01,
            ..default()
        },
        Transform::from_xyz(0.45, 1.7, 0.75),
        DistanceFieldShadows::default(),
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        PenumbraLighting,
        Msaa::Off,
        Projection::Perspective(PerspectiveProjection {
            fov: 0.5,
            ..default()
        }),
        Transform::from_xyz(0.2, 1.64, 0.55).looking_at(Vec3::new(-0.01, 1.58, 0.0), Vec3::Y),
    ));
    if !options.is_some_and(|o| o.no_sss) {
        camera.insert(SubsurfaceScattering::default());
    }
}
