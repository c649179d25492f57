//! Penumbra's showcase: the room later features light — thin walls with a window, a
//! half ceiling, a few meshes, a sun, a point light and a spot light — with
//! distance-field soft shadows from all three lights and distance-field ambient
//! occlusion of the sky light. `--plain` renders it as plain Bevy would (shadow maps, no
//! AO): the README shows the two side by side.
//!
//! ```text
//! cargo run --example showcase                          # a window (if a display exists)
//! cargo run --example showcase -- --headless --frames 30 --out showcase.png
//! ```
//!
//! Flags: `--headless` (render into an image, no window; the default when neither
//! `DISPLAY` nor `WAYLAND_DISPLAY` is set), `--frames N` (frames before the capture;
//! in a window, exit after N frames), `--out PATH` (PNG to write; headless default
//! `showcase.png`), `--size WxH` (default 256x256 headless, 1280x720 windowed),
//! `--plain` (without Penumbra's effects), `--ao-view ao|bent|tiles` (a DFAO debug view).
//!
//! The scene is built in code (no asset files), so it runs on a fresh clone; its
//! 256×256 headless screenshot is checked against `assets/reference/showcase.png` by
//! `tests/showcase.rs`.

use bevy::{
    camera::{Exposure, ShadowLodOrigin},
    light::GlobalAmbientLight,
    pbr::DefaultOpaqueRendererMethod,
    prelude::*,
};
use penumbra::prelude::*;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{Options, casters_ready_in_phase};

#[allow(
    dead_code,
    reason = "tests/showcase.rs includes this file for its scene"
)]
fn main() -> std::process::ExitCode {
    cli::main("showcase", add_scene, Some(casters_ready_in_phase))
}

/// Penumbra's plugins, the showcase scene and its distance-field effects.
fn add_scene(app: &mut App) {
    // Penumbra's lighting pass shades deferred materials (Bevy's switch, app-wide).
    app.add_plugins((PenumbraPlugins, ShowcaseScenePlugin))
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .add_systems(Startup, add_penumbra_effects.after(spawn_scene));
}

/// Renders the showcase headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    cli::run_headless("showcase", options, add_scene, Some(casters_ready_in_phase))
}

/// What an object of the room casts as a distance-field caster (the scene viewer tags
/// the room its own way, so the room keeps this aside).
#[derive(Component, Clone)]
pub struct ShowcaseCaster(pub CasterSource);

/// The showcase's distance-field effects: every object a caster (analytic shapes where
/// they exist, baked meshes otherwise), soft shadows from every light, and DFAO on the
/// camera with a 3 m reach (the room is 8 m across).
#[allow(clippy::type_complexity, reason = "a Bevy system")]
fn add_penumbra_effects(
    mut commands: Commands,
    casters: Query<(Entity, &ShowcaseCaster)>,
    lights: Query<Entity, Or<(With<DirectionalLight>, With<PointLight>, With<SpotLight>)>>,
    cameras: Query<Entity, With<PenumbraLighting>>,
) {
    for (entity, ShowcaseCaster(source)) in &casters {
        commands.entity(entity).insert(DistanceFieldCaster {
            source: source.clone(),
            ..default()
        });
    }
    for light in &lights {
        commands
            .entity(light)
            .insert(DistanceFieldShadows::default());
    }
    for camera in &cameras {
        commands
            .entity(camera)
            .insert(DistanceFieldAmbientOcclusion {
                max_occlusion_distance: 3.0,
                ..default()
            });
    }
}

/// Spawns the showcase room.
pub struct ShowcaseScenePlugin;

impl Plugin for ShowcaseScenePlugin {
    fn build(&self, app: &mut App) {
        app.insert_resource(ClearColor(Color::srgb(0.55, 0.7, 0.9)))
            .insert_resource(GlobalAmbientLight {
                color: Color::srgb(0.7, 0.8, 1.0),
                brightness: 120.0,
                ..default()
            })
            .add_systems(Startup, spawn_scene);
    }
}

/// The room: an 8 m × 8 m floor, 10 cm thick walls (back, and left with a window), a
/// ceiling over the back half, five objects, a sun through the window and the open
/// half, a warm point light and a spot light.
pub fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let mut material = |color: Color, roughness: f32, metallic: f32| {
        materials.add(StandardMaterial {
            base_color: color,
            perceptual_roughness: roughness,
            metallic,
            ..default()
        })
    };
    let plaster = material(Color::srgb(0.82, 0.8, 0.76), 0.9, 0.0);
    let floor = material(Color::srgb(0.45, 0.38, 0.3), 0.7, 0.0);
    let red = material(Color::srgb(0.75, 0.12, 0.08), 0.5, 0.0);
    let blue = material(Color::srgb(0.1, 0.25, 0.7), 0.35, 0.0);
    let gold = material(Color::srgb(0.9, 0.7, 0.3), 0.3, 1.0);
    let green = material(Color::srgb(0.2, 0.55, 0.25), 0.6, 0.0);
    let white = material(Color::srgb(0.9, 0.9, 0.9), 0.4, 0.0);

    let mut slab = |size: Vec3, at: Vec3, mat: &Handle<StandardMaterial>| {
        commands.spawn((
            Mesh3d(meshes.add(Cuboid::from_size(size))),
            MeshMaterial3d(mat.clone()),
            Transform::from_translation(at),
            // Baked: as analytic cuboids these 10 cm slabs leak grainy sunlight
            // into their shadows (a known distance-field shadow defect, CHANGELOG).
            ShowcaseCaster(CasterSource::Mesh),
        ));
    };
    const T: f32 = 0.1; // wall thickness
    slab(
        Vec3::new(8.0, T, 8.0),
        Vec3::new(0.0, -T / 2.0, 0.0),
        &floor,
    );
    slab(
        Vec3::new(8.0, 4.0, T),
        Vec3::new(0.0, 2.0, -4.0 - T / 2.0),
        &plaster,
    );
    // Left wall (x = -4) with a 2 m × 1.6 m window from z = -2.5 to -0.5, y = 1 to 2.6.
    let lx = -4.0 - T / 2.0;
    slab(Vec3::new(T, 4.0, 1.5), Vec3::new(lx, 2.0, -3.25), &plaster);
    slab(Vec3::new(T, 4.0, 4.5), Vec3::new(lx, 2.0, 1.75), &plaster);
    slab(Vec3::new(T, 1.0, 2.0), Vec3::new(lx, 0.5, -1.5), &plaster);
    slab(Vec3::new(T, 1.4, 2.0), Vec3::new(lx, 3.3, -1.5), &plaster);
    // Ceiling over the back half.
    slab(
        Vec3::new(8.2, T, 4.0),
        Vec3::new(0.0, 4.0 + T / 2.0, -2.0),
        &plaster,
    );

    let mut object =
        |mesh: Mesh, mat: &Handle<StandardMaterial>, transform: Transform, source: CasterSource| {
            commands.spawn((
                Mesh3d(meshes.add(mesh)),
                MeshMaterial3d(mat.clone()),
                transform,
                ShowcaseCaster(source),
            ));
        };
    object(
        Sphere::new(0.7).mesh().uv(48, 24),
        &red,
        Transform::from_xyz(-1.2, 0.7, -0.6),
        CasterSource::Sphere { radius: 0.7 },
    );
    object(
        Cuboid::new(1.0, 1.0, 1.0).into(),
        &blue,
        Transform::from_xyz(1.4, 0.5, -1.6).with_rotation(Quat::from_rotation_y(0.6)),
        CasterSource::Cuboid {
            half_size: Vec3::splat(0.5),
        },
    );
    object(
        Torus::new(0.3, 0.6).into(),
        &gold,
        Transform::from_xyz(0.6, 0.3, 1.2).with_rotation(Quat::from_rotation_x(0.25)),
        CasterSource::Mesh,
    );
    object(
        Cylinder::new(0.25, 3.0).into(),
        &white,
        Transform::from_xyz(-2.6, 1.5, -3.0),
        CasterSource::Mesh,
    );
    object(
        Capsule3d::new(0.3, 0.8).into(),
        &green,
        Transform::from_xyz(2.4, 0.7, 0.6),
        CasterSource::Capsule {
            radius: 0.3,
            half_length: 0.4,
        },
    );

    commands.spawn((
        DirectionalLight {
            illuminance: 8_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(-3.0, 2.5, 1.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        PointLight {
            color: Color::srgb(1.0, 0.75, 0.5),
            intensity: 120_000.0, // lumens
            range: 12.0,
            radius: 0.1,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(2.0, 3.2, -3.0),
    ));
    commands.spawn((
        SpotLight {
            color: Color::srgb(0.8, 0.9, 1.0),
            intensity: 300_000.0, // lumens
            range: 15.0,
            radius: 0.05,
            outer_angle: 0.45,
            inner_angle: 0.3,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(3.5, 3.8, 3.0).looking_at(Vec3::new(0.6, 0.0, 0.6), Vec3::Y),
    ));
    commands.spawn((
        Camera3d::default(),
        // Penumbra's lighting pass (deferred: no MSAA).
        PenumbraLighting,
        Msaa::Off,
        Exposure::default(),
        // Point/spot shadow LOD is measured from here, windowed or headless.
        ShadowLodOrigin,
        Transform::from_xyz(3.2, 2.6, 6.8).looking_at(Vec3::new(-0.3, 1.1, -1.0), Vec3::Y),
    ));
}
