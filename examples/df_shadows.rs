//! Distance-field soft shadows: a sun and a point light with `DistanceFieldShadows`,
//! casters moving through them. Watch the contact hardening — the pillar's and the
//! torus's shadows are sharp where they touch the ground and soften with distance —
//! and the moving sphere's penumbra widening as it rises.
//!
//! ```text
//! cargo run --example df_shadows                          # a window (if a display exists)
//! cargo run --example df_shadows -- --headless --frames 40 --out df_shadows.png
//! ```
//!
//! Flags as for every example (`examples/common/cli.rs`): `--headless`, `--frames N`,
//! `--out PATH`, `--size WxH`; `--lights N` (1..=8) keeps the sun (1) and the lamp (2)
//! and adds small lamps around the scene (`--lights 4`: the figures in CHANGELOG.md). The animation advances per frame (not per second), so a
//! headless capture is the same on every machine; its 256×256 screenshot after 40 frames
//! is checked against `assets/reference/df_shadows.png` by `tests/df_shadows_example.rs`.
//!
//! Only `DistanceFieldCaster`s cast distance-field shadows: here the torus is a mesh
//! (its SDF is baked in the background on first use, then cached), the others are
//! analytic shapes. The ground receives shadows without being a caster.

use bevy::{light::GlobalAmbientLight, pbr::DefaultOpaqueRendererMethod, prelude::*};
use penumbra::prelude::*;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{Options, casters_ready};

#[allow(dead_code, reason = "tests/df_shadows_example.rs includes this file")]
fn main() -> std::process::ExitCode {
    cli::main("df_shadows", add_scene, Some(casters_ready))
}

/// Penumbra's plugins and this example's scene.
pub fn add_scene(app: &mut App) {
    app.add_plugins(PenumbraPlugins)
        // Penumbra's lighting pass shades deferred materials (Bevy's switch, app-wide).
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .insert_resource(ClearColor(Color::srgb(0.5, 0.65, 0.85)))
        .insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.6, 0.7, 1.0),
            brightness: 150.0,
            ..default()
        })
        .add_systems(Startup, spawn_scene)
        .add_systems(Update, animate);
}

/// Renders the example headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    cli::run_headless("df_shadows", options, add_scene, Some(casters_ready))
}

/// What the animation moves.
#[derive(Component, Clone, Copy)]
enum Animated {
    /// The sphere: orbits and bobs.
    Orbiting,
    /// The sun: turns.
    Sun,
    /// The point light: sways.
    Lamp,
}

fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    options: Option<Res<Options>>,
) {
    let lights = options.as_ref().and_then(|o| o.lights).unwrap_or(2);
    let glass = options.is_some_and(|o| o.glass);
    let mut material = |color: Color, roughness: f32| {
        materials.add(StandardMaterial {
            base_color: color,
            perceptual_roughness: roughness,
            ..default()
        })
    };
    let ground = material(Color::srgb(0.62, 0.6, 0.56), 0.9);
    let stone = material(Color::srgb(0.75, 0.72, 0.68), 0.6);
    let red = material(Color::srgb(0.75, 0.15, 0.1), 0.5);
    let gold = material(Color::srgb(0.85, 0.65, 0.3), 0.4);
    let blue = material(Color::srgb(0.15, 0.3, 0.75), 0.4);

    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(16.0, 16.0))),
        MeshMaterial3d(ground),
    ));
    if glass {
        // Alpha-blended: lit by Bevy's forward pass with the lights' shadow maps, which
        // Penumbra therefore keeps rendering (see `--glass` in examples/common/cli.rs).
        let glass = materials.add(StandardMaterial {
            base_color: Color::srgba(0.6, 0.8, 0.9, 0.35),
            alpha_mode: AlphaMode::Blend,
            perceptual_roughness: 0.1,
            ..default()
        });
        commands.spawn((
            Mesh3d(meshes.add(Cuboid::new(1.2, 0.9, 0.05))),
            MeshMaterial3d(glass),
            Transform::from_xyz(-0.4, 0.45, 1.3),
        ));
    }
    // A tall pillar: its shadow hardens toward its foot.
    commands.spawn((
        Mesh3d(meshes.add(Capsule3d::new(0.15, 2.7))),
        MeshMaterial3d(stone.clone()),
        Transform::from_xyz(-1.6, 1.5, -1.2),
        DistanceFieldCaster {
            source: CasterSource::Capsule {
                radius: 0.15,
                half_length: 1.35,
            },
            ..default()
        },
    ));
    // A mesh caster: baked to an SDF in the background.
    commands.spawn((
        Mesh3d(meshes.add(Torus::new(0.25, 0.6))),
        MeshMaterial3d(gold),
        Transform::from_xyz(0.9, 0.62, 0.2).with_rotation(Quat::from_rotation_x(1.2)),
        DistanceFieldCaster::default(),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Cuboid::new(0.8, 0.8, 0.8))),
        MeshMaterial3d(blue),
        Transform::from_xyz(1.8, 0.4, -1.6).with_rotation(Quat::from_rotation_y(0.7)),
        DistanceFieldCaster {
            source: CasterSource::Cuboid {
                half_size: Vec3::splat(0.4),
            },
            ..default()
        },
    ));
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.35).mesh().uv(48, 24))),
        MeshMaterial3d(red),
        Transform::from_xyz(0.0, 1.0, 0.0),
        DistanceFieldCaster {
            source: CasterSource::Sphere { radius: 0.35 },
            ..default()
        },
        Animated::Orbiting,
    ));
    commands.spawn((
        // Shadow maps stay enabled for whatever Penumbra does not shade (`--glass`); with
        // nothing of the kind in view, Penumbra skips them.
        DirectionalLight {
            illuminance: 6_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::default(),
        DistanceFieldShadows {
            angular_diameter: 3f32.to_radians(),
            ..default()
        },
        Animated::Sun,
    ));
    if lights >= 2 {
        commands.spawn((
            PointLight {
                color: Color::srgb(1.0, 0.75, 0.5),
                intensity: 150_000.0,
                range: 12.0,
                radius: 0.15,
                shadow_maps_enabled: true,
                ..default()
            },
            Transform::from_xyz(0.0, 2.2, 1.5),
            DistanceFieldShadows::default(),
            Animated::Lamp,
        ));
    }
    // `--lights N`: small lamps on a circle around the scene.
    for i in 2..lights {
        let a = i as f32 * 1.9;
        commands.spawn((
            PointLight {
                color: Color::srgb(0.6, 0.8, 1.0),
                intensity: 40_000.0,
                range: 5.0,
                radius: 0.05,
                ..default()
            },
            Transform::from_xyz(2.6 * a.cos(), 1.4, 2.6 * a.sin()),
            DistanceFieldShadows::default(),
        ));
    }
    commands.spawn((
        Camera3d::default(),
        PenumbraLighting,
        Msaa::Off,
        Transform::from_xyz(2.2, 3.6, 5.4).looking_at(Vec3::new(0.0, 0.4, -0.4), Vec3::Y),
    ));
}

/// Per-frame animation (frame-counted: deterministic captures): the sphere orbits and
/// bobs, the sun turns, the lamp sways.
fn animate(
    mut frame: Local<u32>,
    casters: Query<Entity, With<DistanceFieldCaster>>,
    scene: Res<DistanceFieldScene>,
    mut animated: Query<(&Animated, &mut Transform)>,
) {
    if *frame > 0 && casters.iter().any(|e| scene.slot(e).is_none()) {
        return; // wait for the torus's bake (the first frame places everything)
    }
    let t = *frame as f32 / 30.0;
    *frame += 1;
    for (what, mut transform) in &mut animated {
        match what {
            Animated::Orbiting => {
                transform.translation = Vec3::new(
                    1.1 * (0.9 * t).cos() - 0.3,
                    1.0 + 0.6 * (1.3 * t).sin(),
                    1.1 * (0.9 * t).sin() - 0.2,
                );
            }
            Animated::Sun => {
                let azimuth = 0.6 + 0.25 * t;
                let to_sun = Vec3::new(azimuth.cos() * 0.75, 0.62, azimuth.sin() * 0.75);
                *transform = Transform::from_translation(to_sun).looking_at(Vec3::ZERO, Vec3::Y);
            }
            Animated::Lamp => {
                transform.translation = Vec3::new(0.8 * (0.7 * t).sin(), 2.2, 1.5);
            }
        }
    }
}
