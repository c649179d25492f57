//! Billboard reflections: a wet street at night. Lit signs hang on the buildings and
//! across the far end; the wet asphalt reflects them as long streaks toward the viewer
//! (the GGX lobe stretches toward grazing angles, and `anisotropy` stretches it more). A
//! low kiosk stands between the far sign and the near street: its distance-field
//! reflection shadow cuts the sign's streak where the kiosk hides it.
//!
//! ```text
//! cargo run --example reflections                          # a window (if a display exists)
//! cargo run --example reflections -- --headless --frames 8 --out reflections.png
//! cargo run --example reflections -- --no-reflections      # the street without them
//! ```
//!
//! Flags as for every example (`examples/common/cli.rs`); `--no-reflections` leaves
//! `BillboardReflections` off the camera. The 256×256 headless screenshot is checked
//! against `assets/reference/reflections.png` by `tests/reflections_example.rs`.
//!
//! Each sign is two things on one entity: a `ReflectionBillboard` (what reflects) and an
//! emissive `Rectangle` of the same size showing the same image (what the camera sees).
//! The buildings and the kiosk are `DistanceFieldCaster` cuboids: they occlude
//! reflections.

use bevy::camera::Exposure;
use bevy::{light::GlobalAmbientLight, pbr::DefaultOpaqueRendererMethod, prelude::*};
use penumbra::prelude::*;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{Options, casters_ready};
#[path = "common/street.rs"]
mod street;
use street::{building, sign, sign_image};

#[allow(dead_code, reason = "tests/reflections_example.rs includes this file")]
fn main() -> std::process::ExitCode {
    cli::main("reflections", add_scene, Some(casters_ready))
}

/// Penumbra's plugins and this example's scene.
pub fn add_scene(app: &mut App) {
    app.add_plugins(PenumbraPlugins)
        // Penumbra's lighting pass shades deferred materials (Bevy's switch, app-wide).
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .insert_resource(ClearColor(Color::srgb(0.005, 0.006, 0.012)))
        .insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.4, 0.5, 0.8),
            brightness: 30.0,
            ..default()
        })
        .add_systems(Startup, spawn_scene);
}

/// Renders the example headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    cli::run_headless("reflections", options, add_scene, Some(casters_ready))
}

/// The camera's exposure (a night street).
const EV100: f32 = 6.0;

fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
    options: Option<Res<Options>>,
) {
    // Wet asphalt: dark and smooth.
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(14.0, 60.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.03, 0.03, 0.035),
            perceptual_roughness: 0.12,
            ..default()
        })),
        Transform::from_xyz(0.0, 0.0, -22.0),
    ));
    let facade = materials.add(StandardMaterial {
        base_color: Color::srgb(0.06, 0.06, 0.07),
        perceptual_roughness: 0.8,
        ..default()
    });
    // Buildings along both sides, one across the far end.
    for (size, at) in [
        (Vec3::new(4.0, 9.0, 14.0), Vec3::new(-6.5, 4.5, -6.0)),
        (Vec3::new(4.0, 12.0, 16.0), Vec3::new(-6.5, 6.0, -24.0)),
        (Vec3::new(4.0, 8.0, 12.0), Vec3::new(6.5, 4.0, -5.0)),
        (Vec3::new(4.0, 11.0, 20.0), Vec3::new(6.5, 5.5, -23.0)),
        (Vec3::new(18.0, 14.0, 4.0), Vec3::new(0.0, 7.0, -42.0)),
        // The kiosk between the far sign and the near street.
        (Vec3::new(1.6, 2.2, 1.6), Vec3::new(-0.9, 1.1, -16.0)),
    ] {
        commands.spawn(building(size, at, facade.clone(), &mut meshes));
    }
    // The signs: (image colour, bars, size, position, rotation, luminance cd/m²).
    let signs = [
        (
            [255, 40, 160],
            3,
            Vec2::new(3.2, 1.6),
            Vec3::new(-4.45, 4.0, -9.0),
            Quat::from_rotation_y(std::f32::consts::FRAC_PI_2),
            600.0,
        ),
        (
            [40, 200, 255],
            4,
            Vec2::new(3.6, 1.8),
            Vec3::new(4.45, 3.6, -14.0),
            Quat::from_rotation_y(-std::f32::consts::FRAC_PI_2),
            600.0,
        ),
        (
            [255, 190, 40],
            5,
            Vec2::new(6.0, 3.0),
            Vec3::new(-0.5, 4.2, -39.9),
            Quat::IDENTITY,
            900.0,
        ),
    ];
    // Bevy's deferred G-buffer keeps emissive light unexposed (its lighting pass cannot
    // tell `emissive_exposure_weight`): the signs' meshes carry their exposed luminance.
    let exposure = Exposure { ev100: EV100 }.exposure();
    for (colour, bars, size, at, rotation, luminance) in signs {
        let image = images.add(sign_image(colour, bars));
        let transform = Transform::from_translation(at).with_rotation(rotation);
        commands.spawn(sign(
            image,
            size,
            luminance,
            exposure,
            transform,
            &mut meshes,
            &mut materials,
        ));
    }
    commands.spawn((
        DirectionalLight {
            color: Color::srgb(0.6, 0.7, 1.0),
            illuminance: 40.0,
            ..default()
        },
        Transform::default().looking_to(Vec3::new(0.3, -1.0, -0.4), Vec3::Y),
    ));
    let mut camera = commands.spawn((
        Camera3d::default(),
        PenumbraLighting,
        Msaa::Off,
        Exposure { ev100: EV100 },
        Transform::from_xyz(0.6, 1.7, 6.0).looking_at(Vec3::new(0.0, 1.4, -20.0), Vec3::Y),
    ));
    if !options.is_some_and(|o| o.no_reflections) {
        camera.insert(BillboardReflections {
            anisotropy: 0.5,
            ..default()
        });
    }
}
