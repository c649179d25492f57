//! Distance-field ambient occlusion: a colonnade, a corner of walls, a stack of crates and
//! a ring under a bright sky, with `DistanceFieldAmbientOcclusion` on the camera. Watch
//! the sky light fade under the lintel, between the pillars, in the corner and beneath
//! the ball rolling across the ground — medium-range occlusion that screen-space AO
//! cannot see (the lintel's top is off screen; nothing vanishes at the frame's edge).
//!
//! ```text
//! cargo run --example dfao                          # a window (if a display exists)
//! cargo run --example dfao -- --headless --frames 40 --out dfao.png
//! cargo run --example dfao -- --headless --ao-view ao --out ao.png   # the AO alone
//! cargo run --example dfao -- --headless --plain --out plain.png     # without DFAO
//! ```
//!
//! Flags as for every example (`examples/common/cli.rs`); `--ao-view ao|bent|tiles`
//! shows a debug view (the AO, the bent normal, objects per tile), `--plain` leaves
//! Penumbra's effects out, `--casters N` scatters N more small casters over the ground
//! (how the passes' cost grows with objects: the figures in CHANGELOG.md). In a window, `A` turns DFAO off and on and `V` cycles its
//! debug views. The animation advances per frame, so a headless capture is the same on
//! every machine; its 256×256 screenshot after 40 frames is checked against
//! `assets/reference/dfao.png` by `tests/dfao_example.rs`.
//!
//! With `--global-field` the camera also has a `GlobalDistanceField` (the cones' far
//! part goes through it) and a fountain of `DistanceFieldParticles` bounces off the
//! casters through it.
//!
//! Occlusion comes only from `DistanceFieldCaster`s: here analytic shapes, the ground
//! (a `Plane` caster: objects standing on it darken at their feet) and a torus mesh (its
//! SDF baked in the background on first use). The sky is `GlobalAmbientLight`, which
//! DFAO occludes like Unreal's sky light; the sun is direct light with distance-field
//! shadows, which DFAO leaves alone.

use bevy::diagnostic::FrameCount;
use bevy::{light::GlobalAmbientLight, pbr::DefaultOpaqueRendererMethod, prelude::*};
use penumbra::prelude::*;

#[path = "common/cli.rs"]
mod cli;
pub use cli::Options;

#[allow(dead_code, reason = "tests/dfao_example.rs includes this file")]
fn main() -> std::process::ExitCode {
    cli::main("dfao", add_scene, Some(rolling))
}

/// Penumbra's plugins and this example's scene.
pub fn add_scene(app: &mut App) {
    let no_plugin = app
        .world()
        .get_resource::<Options>()
        .is_some_and(|o| o.no_dfao == Some(cli::NoDfao::Plugin));
    if no_plugin {
        app.add_plugins(
            PenumbraPlugins
                .build()
                .disable::<penumbra::df::DistanceFieldAmbientOcclusionPlugin>(),
        );
    } else {
        app.add_plugins(PenumbraPlugins);
    }
    app
        // Penumbra's lighting pass shades deferred materials (Bevy's switch, app-wide).
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .insert_resource(ClearColor(Color::srgb(0.55, 0.7, 0.9)))
        // A bright sky: the light DFAO occludes.
        .insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.75, 0.85, 1.0),
            brightness: 1600.0,
            ..default()
        })
        .init_resource::<RollStart>()
        .add_systems(Startup, spawn_scene)
        .add_systems(Update, roll_ball);
}

/// Renders the example headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    cli::run_headless("dfao", options, add_scene, Some(rolling))
}

/// The frame the ball started rolling on: the first with every caster placed
/// (`cli::casters_ready`) and a multiple of 4, so that a capture a given number of
/// frames later always sees the same one of DFAO's four jitter positions, however long
/// the torus's bake took.
#[derive(Resource, Default)]
struct RollStart(Option<u32>);

/// Whether the ball is rolling: headless captures count frames from it.
pub fn rolling(world: &mut World) -> bool {
    world.resource::<RollStart>().0.is_some()
}

/// The ball that rolls across the ground.
#[derive(Component)]
struct Rolling;

/// A box caster with its mesh.
fn crate_bundle(
    meshes: &mut Assets<Mesh>,
    material: &Handle<StandardMaterial>,
    size: Vec3,
    transform: Transform,
) -> impl Bundle {
    (
        Mesh3d(meshes.add(Cuboid::from_size(size))),
        MeshMaterial3d(material.clone()),
        transform,
        DistanceFieldCaster {
            source: CasterSource::Cuboid {
                half_size: size / 2.0,
            },
            ..default()
        },
    )
}

fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    options: Option<Res<Options>>,
) {
    let extra = options.as_ref().and_then(|o| o.casters).unwrap_or(0);
    let mut material = |color: Color, roughness: f32| {
        materials.add(StandardMaterial {
            base_color: color,
            perceptual_roughness: roughness,
            ..default()
        })
    };
    let ground = material(Color::srgb(0.7, 0.68, 0.64), 0.9);
    let stone = material(Color::srgb(0.8, 0.78, 0.74), 0.8);
    let wood = material(Color::srgb(0.6, 0.42, 0.26), 0.7);
    let red = material(Color::srgb(0.75, 0.15, 0.1), 0.5);
    let gold = material(Color::srgb(0.85, 0.65, 0.3), 0.4);

    // The ground occludes too: things standing on it darken at their feet.
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(24.0, 24.0))),
        MeshMaterial3d(ground),
        DistanceFieldCaster {
            source: CasterSource::Plane,
            ..default()
        },
    ));
    // A colonnade: four pillars under a lintel.
    for i in 0..4 {
        let x = -2.4 + 1.2 * i as f32;
        commands.spawn(crate_bundle(
            &mut meshes,
            &stone,
            Vec3::new(0.35, 2.2, 0.35),
            Transform::from_xyz(x, 1.1, -2.0),
        ));
    }
    commands.spawn(crate_bundle(
        &mut meshes,
        &stone,
        Vec3::new(4.4, 0.4, 0.9),
        Transform::from_xyz(-0.6, 2.4, -2.0),
    ));
    // A corner of two walls, with crates stacked in it.
    commands.spawn(crate_bundle(
        &mut meshes,
        &stone,
        Vec3::new(0.2, 2.0, 3.0),
        Transform::from_xyz(2.6, 1.0, -1.2),
    ));
    commands.spawn(crate_bundle(
        &mut meshes,
        &stone,
        Vec3::new(2.4, 2.0, 0.2),
        Transform::from_xyz(1.5, 1.0, -2.6),
    ));
    for (size, at, turn) in [
        (0.7, Vec3::new(2.05, 0.35, -2.05), 0.1),
        (0.6, Vec3::new(1.25, 0.3, -2.1), -0.2),
        (0.5, Vec3::new(2.1, 0.95, -2.0), 0.35),
    ] {
        commands.spawn(crate_bundle(
            &mut meshes,
            &wood,
            Vec3::splat(size),
            Transform::from_translation(at).with_rotation(Quat::from_rotation_y(turn)),
        ));
    }
    // `--casters N`: small blocks on a jittered grid over a 20 m square.
    let side = (extra as f32).sqrt().ceil().max(1.0) as u32;
    let block = meshes.add(Cuboid::from_size(Vec3::splat(0.3)));
    for i in 0..extra {
        let (gx, gz) = (i % side, i / side);
        let h = (i.wrapping_mul(2_654_435_761) >> 8) as f32 / 16_777_216.0;
        let cell = 20.0 / side as f32;
        let at = Vec3::new(
            -10.0 + (gx as f32 + 0.25 + 0.5 * h) * cell,
            0.15,
            -10.0 + (gz as f32 + 0.75 - 0.5 * h) * cell,
        );
        commands.spawn((
            Mesh3d(block.clone()),
            MeshMaterial3d(wood.clone()),
            Transform::from_translation(at).with_rotation(Quat::from_rotation_y(6.0 * h)),
            DistanceFieldCaster {
                source: CasterSource::Cuboid {
                    half_size: Vec3::splat(0.15),
                },
                ..default()
            },
        ));
    }
    // A mesh caster lying on the ground: baked to an SDF in the background.
    commands.spawn((
        Mesh3d(meshes.add(Torus::new(0.2, 0.55))),
        MeshMaterial3d(gold),
        Transform::from_xyz(-1.4, 0.18, 0.9),
        DistanceFieldCaster::default(),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.45).mesh().uv(48, 24))),
        MeshMaterial3d(red),
        Transform::from_xyz(0.0, 0.45, 0.5),
        DistanceFieldCaster {
            source: CasterSource::Sphere { radius: 0.45 },
            ..default()
        },
        Rolling,
    ));
    commands.spawn((
        // Shadow maps stay enabled for the `--plain` comparison; with distance-field
        // shadows and nothing else in view, Penumbra skips them.
        DirectionalLight {
            illuminance: 1_800.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(-2.0, 4.0, 1.5).looking_at(Vec3::ZERO, Vec3::Y),
        DistanceFieldShadows {
            angular_diameter: 2f32.to_radians(),
            ..default()
        },
    ));
    if options.as_ref().is_some_and(|o| o.global_field) {
        // With the global field: a fountain of sparks bouncing off the ball, the torus
        // and the ground through it (`DistanceFieldParticles`).
        commands.spawn((
            DistanceFieldParticles {
                rate: 400.0,
                spawn_half_extents: Vec3::splat(0.05),
                velocity: Vec3::new(-0.6, 3.0, 0.2),
                velocity_jitter: 1.2,
                radius: 0.025,
                restitution: 0.5,
                color: Color::srgb(1.0, 0.8, 0.4),
                ..default()
            },
            Transform::from_xyz(0.3, 1.4, 0.5),
        ));
    }
    commands.spawn((
        Camera3d::default(),
        PenumbraLighting,
        Msaa::Off,
        // Medium range: a few metres (Unreal's default is 10 m, for larger scenes).
        DistanceFieldAmbientOcclusion {
            max_occlusion_distance: 3.0,
            ..default()
        },
        Transform::from_xyz(1.2, 3.4, 5.8).looking_at(Vec3::new(0.0, 0.7, -0.8), Vec3::Y),
    ));
}

/// Per-frame animation (frame-counted from [`RollStart`]: deterministic captures): the
/// ball rolls to and fro in front of the colonnade.
fn roll_ball(
    frames: Res<FrameCount>,
    mut start: ResMut<RollStart>,
    casters: Query<Entity, With<DistanceFieldCaster>>,
    scene: Res<DistanceFieldScene>,
    mut ball: Query<&mut Transform, With<Rolling>>,
) {
    let placed = || !casters.is_empty() && casters.iter().all(|e| scene.slot(e).is_some());
    if start.0.is_none() && frames.0.is_multiple_of(4) && placed() {
        start.0 = Some(frames.0);
    }
    let t = start.0.map_or(0.0, |s| (frames.0 - s) as f32 / 30.0);
    for mut transform in &mut ball {
        let x = 1.6 * (0.8 * t).sin();
        transform.translation = Vec3::new(x, 0.45, 0.2 - 0.3 * (0.8 * t).cos());
        transform.rotation = Quat::from_rotation_z(-x / 0.45);
    }
}
