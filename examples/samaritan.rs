//! Penumbra's flagship scene, after Epic's *Samaritan* (2011): every Penumbra feature on
//! one camera. A man in a coat stands at night on a cobbled square at the end of a wet
//! street; the camera frames him close, the street behind out of focus.
//!
//! - **Deferred shading with 4× MSAA** (`DeferredMsaa`): every feature below on the same
//!   multisampled `PenumbraLighting` camera.
//! - **Distance-field soft shadows** from the moon (directional), the street lamp over
//!   him (spot) and a shop window's glow (point); the buildings, the kiosk and the lamp
//!   post are analytic distance-field casters; the man's body is a **skinned character**
//!   (one mesh on a swaying skeleton, `examples/common/skinned_body.rs`) cast by capsules
//!   fitted to its joints that follow it every frame, his head by a sphere.
//! - **Distance-field AO** with its temporal filter, traced through the camera's
//!   **global distance field** beyond 1 m.
//! - **Subsurface scattering** on his skin (a skin profile), **hair and beard strips**
//!   alpha-tested per MSAA sample.
//! - **Billboard reflections**: neon signs on the buildings streak across the wet
//!   asphalt, cut by the kiosk's **reflection shadow**.
//! - **Scatter bokeh depth of field** focused on his face: the signs and the lamps far
//!   down the street open into hexagons.
//! - **Compute tessellation**: the square's cobbles are a flat patch cut to ~10-pixel
//!   triangles on the GPU and displaced by a height map of stones.
//! - **Particles colliding with the distance fields**: rain bouncing off the ground,
//!   the man and the kiosk.
//!
//! ```text
//! cargo run --release --example samaritan                     # a window (if a display exists)
//! cargo run --example samaritan -- --headless --frames 8 --out samaritan.png
//! cargo run --example samaritan -- --headless --size 1280x720 --out samaritan.png
//! ```
//!
//! Keys (windowed; the state is shown in the title): every example's `Space`
//! (distance-field shadows; off: Bevy's shadow maps), `H`, `D`, `A` (DFAO) and `V`
//! (`examples/common/controls.rs`), and `1` subsurface scattering, `2` hair, `3`
//! billboard reflections, `4` bokeh, `5` tessellation, `6` rain, `M` deferred MSAA (off:
//! no AA).
//! Flags as for every example (`examples/common/cli.rs`); `--plain` removes the
//! distance-field shadows and DFAO. The 256×256 headless screenshot is checked against
//! `assets/reference/samaritan.png` by `tests/samaritan_example.rs`; the README's first
//! picture is its 1280×720 render (`--frames 6`, saved as `assets/readme/samaritan.jpg`).
//!
//! Built in code (no asset files), so it runs on a fresh clone. The man's coat is a
//! skinned mesh of merged capsules, his head ellipsoids: the scene shows the effects
//! together, and a skinned character among them, not a character pipeline.

use bevy::asset::RenderAssetUsages;
use bevy::camera::{Exposure, Hdr, ShadowLodOrigin};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::GlobalAmbientLight;
use bevy::mesh::skinning::SkinnedMeshInverseBindposes;
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use penumbra::cinematic::SubsurfaceProfileId;
use penumbra::prelude::*;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{Options, casters_ready};
#[path = "common/character.rs"]
mod character;
use character::{HEAD_PARTS, SLOTS, hair_atlas, head_strands};
#[path = "common/skinned_body.rs"]
mod skinned_body;
#[path = "common/street.rs"]
mod street;
use street::{building, sign, sign_image};

#[allow(dead_code, reason = "tests/samaritan_example.rs includes this file")]
fn main() -> std::process::ExitCode {
    cli::main("samaritan", add_scene, Some(casters_ready))
}

/// Penumbra's plugins, the scene and its key toggles. Without a window, time advances
/// 1/30 s a frame (the rain falls the same in every capture, whatever the machine's
/// speed).
pub fn add_scene(app: &mut App) {
    app.add_plugins((PenumbraPlugins, SamaritanScenePlugin));
    if !app.is_plugin_added::<bevy::winit::WinitPlugin>() {
        app.insert_resource(bevy::time::TimeUpdateStrategy::ManualDuration(
            std::time::Duration::from_secs_f64(1.0 / 30.0),
        ));
    }
}

/// Renders the example headless into `options.out` (a PNG).
pub fn run_headless(options: &Options) -> Result<(), String> {
    cli::run_headless("samaritan", options, add_scene, Some(casters_ready))
}

/// The scene, its toggles and title (Penumbra's plugins are the app's to add).
pub struct SamaritanScenePlugin;

impl Plugin for SamaritanScenePlugin {
    fn build(&self, app: &mut App) {
        // Penumbra's lighting pass shades deferred materials (Bevy's switch, app-wide).
        app.insert_resource(DefaultOpaqueRendererMethod::deferred())
            .insert_resource(ClearColor(Color::srgb(0.004, 0.005, 0.01)))
            .insert_resource(GlobalAmbientLight {
                color: Color::srgb(0.45, 0.55, 0.8),
                brightness: 25.0,
                ..default()
            })
            .add_systems(Startup, spawn_scene)
            .add_systems(Update, (toggle_features, show_features).chain())
            .add_systems(Update, skinned_body::move_body);
    }
}

/// The camera's exposure (a night street).
const EV100: f32 = 6.0;
/// The centre of the man's head (the hair's origin).
const HEAD_AT: Vec3 = Vec3::new(0.0, 1.62, 0.0);
/// The camera: in front of him and to his left, at eye height.
const EYE: Vec3 = Vec3::new(0.6, 1.7, 2.0);
/// What it looks at: down the street beside him (he stands right of the centre).
const LOOK_AT: Vec3 = Vec3::new(-0.45, 1.12, -1.0);
/// The cobbles' height map: stones in running bond (rows offset by half a stone), each
/// a rounded dome with a little tilt, mortar joints at 0.
fn cobble_map() -> Image {
    const SIZE: u32 = 256;
    const ROWS: u32 = 16;
    const COLUMNS: u32 = 11;
    let hash = |a: u32, b: u32| {
        let mut h = a.wrapping_mul(0x9e37_79b9) ^ b.wrapping_mul(0x85eb_ca6b);
        h ^= h >> 15;
        h = h.wrapping_mul(0x2c1b_3c6d);
        (h >> 8) as f32 / (1u32 << 24) as f32
    };
    let mut data = Vec::with_capacity((SIZE * SIZE) as usize);
    for y in 0..SIZE {
        for x in 0..SIZE {
            let v = (y as f32 + 0.5) / SIZE as f32 * ROWS as f32;
            let row = v.floor() as u32;
            let shift = if row % 2 == 1 { 0.5 } else { 0.0 };
            let u = (x as f32 + 0.5) / SIZE as f32 * COLUMNS as f32 + shift;
            let column = u.floor() as u32 % COLUMNS;
            // Position in the stone, -1..1 each way; the joints 8 % of a stone wide.
            let (su, sv) = (2.0 * u.fract() - 1.0, 2.0 * v.fract() - 1.0);
            let edge = su.abs().max(sv.abs());
            let dome = (1.0 - su * su * 0.6 - sv * sv * 0.6).max(0.0).sqrt();
            let tilt = 0.15 * (hash(row, column) - 0.5) * su + 0.1 * hash(column, row) * sv;
            let height = if edge > 0.92 {
                0.0
            } else {
                ((0.55 + 0.35 * hash(row * 31 + column, 7)) * dome + tilt).clamp(0.0, 1.0)
            };
            data.push((height * 255.0).round() as u8);
        }
    }
    Image::new(
        Extent3d {
            width: SIZE,
            height: SIZE,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::R8Unorm,
        RenderAssetUsages::default(),
    )
}

/// A capsule that is drawn and casts (the lamp post).
fn capsule(
    radius: f32,
    length: f32,
    transform: Transform,
    material: Handle<StandardMaterial>,
    meshes: &mut Assets<Mesh>,
) -> impl Bundle {
    (
        Mesh3d(meshes.add(Capsule3d::new(radius, length))),
        MeshMaterial3d(material),
        transform,
        DistanceFieldCaster {
            source: CasterSource::Capsule {
                radius,
                half_length: length * 0.5,
            },
            ..default()
        },
    )
}

#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn spawn_scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
    mut strands: ResMut<Assets<HairStrands>>,
    mut profiles: ResMut<SubsurfaceProfiles>,
    mut bindposes: ResMut<Assets<SkinnedMeshInverseBindposes>>,
) {
    let mut material = |color: Color, roughness: f32| {
        materials.add(StandardMaterial {
            base_color: color,
            perceptual_roughness: roughness,
            ..default()
        })
    };
    let asphalt = material(Color::srgb(0.03, 0.03, 0.035), 0.1);
    let stone = material(Color::srgb(0.32, 0.3, 0.28), 0.4);
    let facade = material(Color::srgb(0.07, 0.065, 0.07), 0.8);
    let coat = material(Color::srgb(0.06, 0.07, 0.09), 0.7);
    let iron = material(Color::srgb(0.05, 0.05, 0.05), 0.4);

    // The street: wet asphalt from the square to the far end, where the building
    // across it closes the view. The ground occludes (DFAO) and stops the rain.
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(14.0, 56.0))),
        MeshMaterial3d(asphalt),
        Transform::from_xyz(0.0, 0.0, -32.0),
        DistanceFieldCaster {
            source: CasterSource::Plane,
            casts_shadows: false,
            ..default()
        },
    ));
    // The square: a flat 8 × 6 m patch, tessellated on the GPU and displaced up to 4 cm
    // by the cobbles' height map (wet stones: fairly smooth).
    let cobbles = images.add(cobble_map());
    commands.spawn((
        Mesh3d(
            meshes.add(
                Plane3d::default()
                    .mesh()
                    .size(8.0, 6.0)
                    .subdivisions(3)
                    .build(),
            ),
        ),
        MeshMaterial3d(stone),
        Transform::from_xyz(0.0, 0.0, -1.0),
        Tessellated {
            pixels_per_triangle: 10.0,
            max_level: 5,
            displacement: Some(cobbles),
            displacement_scale: 0.04,
            displacement_midlevel: 0.0,
            mode: TessellationMode::Flat,
            ..default()
        },
    ));
    // Buildings along both sides, one across the far end; the kiosk between the far
    // sign and the square.
    for (size, at) in [
        (Vec3::new(4.0, 9.0, 14.0), Vec3::new(-6.5, 4.5, -9.0)),
        (Vec3::new(4.0, 12.0, 16.0), Vec3::new(-6.5, 6.0, -25.0)),
        (Vec3::new(4.0, 8.0, 12.0), Vec3::new(6.5, 4.0, -8.0)),
        (Vec3::new(4.0, 11.0, 20.0), Vec3::new(6.5, 5.5, -24.0)),
        (Vec3::new(18.0, 14.0, 4.0), Vec3::new(0.0, 7.0, -42.0)),
        (Vec3::new(1.6, 2.2, 1.6), Vec3::new(-1.4, 1.1, -15.0)),
    ] {
        commands.spawn(building(size, at, facade.clone(), &mut meshes));
    }
    // The neon signs: (colour, bars, size, position, rotation, luminance cd/m²). Each
    // reflects (`ReflectionBillboard`) and is shown by an emissive quad of its image.
    let exposure = Exposure { ev100: EV100 }.exposure();
    let quarter = std::f32::consts::FRAC_PI_2;
    for (colour, bars, size, at, rotation, luminance) in [
        (
            [255, 40, 160],
            3,
            Vec2::new(3.2, 1.6),
            Vec3::new(-4.45, 3.6, -8.0),
            Quat::from_rotation_y(quarter),
            600.0,
        ),
        (
            [40, 200, 255],
            4,
            Vec2::new(3.6, 1.8),
            Vec3::new(4.45, 3.4, -13.0),
            Quat::from_rotation_y(-quarter),
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
    ] {
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
    skinned_body::spawn_body(&mut commands, &mut meshes, &mut bindposes, coat.clone());
    spawn_man(
        &mut commands,
        &mut meshes,
        &mut materials,
        &mut images,
        &mut strands,
        &mut profiles,
        coat,
    );
    // The street lamp: a post in front of him on his right, its lamp over his face.
    commands.spawn(capsule(
        0.06,
        3.8,
        Transform::from_xyz(-1.25, 1.95, 0.75),
        iron,
        &mut meshes,
    ));
    commands.spawn((
        SpotLight {
            color: Color::srgb(1.0, 0.82, 0.6),
            intensity: 60_000.0, // lumens
            range: 14.0,
            radius: 0.08,
            outer_angle: 0.75,
            inner_angle: 0.45,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(-1.0, 3.8, 0.7).looking_at(Vec3::new(0.0, 1.0, -0.2), Vec3::Y),
        DistanceFieldShadows::default(),
    ));
    // A shop window's warm glow on his left.
    commands.spawn((
        PointLight {
            color: Color::srgb(1.0, 0.6, 0.35),
            intensity: 10_000.0,
            range: 10.0,
            radius: 0.3,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(2.2, 1.7, 0.4),
        DistanceFieldShadows::default(),
    ));
    // The moon, high behind him.
    commands.spawn((
        DirectionalLight {
            color: Color::srgb(0.6, 0.7, 1.0),
            illuminance: 60.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::default().looking_to(Vec3::new(0.35, -0.8, 0.5), Vec3::Y),
        DistanceFieldShadows {
            angular_diameter: 1.5f32.to_radians(),
            ..default()
        },
    ));
    // Rain over the square and the street near it, bouncing off the distance fields.
    commands.spawn((
        DistanceFieldParticles {
            capacity: 4096,
            rate: 1500.0,
            spawn_half_extents: Vec3::new(3.5, 0.2, 3.5),
            velocity: Vec3::new(0.4, -6.0, 0.0),
            velocity_jitter: 0.4,
            radius: 0.006,
            restitution: 0.25,
            friction: 0.3,
            color: Color::srgb(0.6, 0.7, 0.85),
            // Fixed, so the reference image does not move with the app's entity count
            // (this is the id the emitter had when the reference was made).
            seed: Some(4_294_967_051),
            ..default()
        },
        Transform::from_xyz(0.0, 4.0, -1.5),
    ));
    let focus = EYE.distance(HEAD_AT);
    commands.spawn((
        Camera3d::default(),
        Hdr,
        Tonemapping::TonyMcMapface,
        PenumbraLighting,
        DeferredMsaa::default(),
        Exposure { ev100: EV100 },
        Projection::Perspective(PerspectiveProjection {
            fov: 0.62,
            ..default()
        }),
        Transform::from_translation(EYE).looking_at(LOOK_AT, Vec3::Y),
        DistanceFieldAmbientOcclusion {
            max_occlusion_distance: 2.5,
            ..default()
        },
        GlobalDistanceField::default(),
        SubsurfaceScattering::default(),
        BillboardReflections {
            anisotropy: 0.5,
            ..default()
        },
        BokehDepthOfField {
            focal_distance: focus,
            aperture_f_stops: 1.0 / 3.0,
            max_depth: 60.0,
            aperture: BokehAperture::Hexagon,
            ..default()
        },
        // The tessellation's level of detail follows this camera, and so do Bevy's
        // point and spot shadow maps (with `--plain`).
        TessellationCamera,
        ShadowLodOrigin,
    ));
}

/// Skin: red light travels furthest under the surface.
fn skin_profile() -> SubsurfaceProfile {
    SubsurfaceProfile {
        scatter_color: Color::srgb(0.95, 0.5, 0.35),
        radius: 0.006,
    }
}

/// The man above his skinned body (`skinned_body`): shoulders (the coat), neck and head
/// (ellipsoids of skin; the head also a sphere caster), his hair and beard.
fn spawn_man(
    commands: &mut Commands,
    meshes: &mut Assets<Mesh>,
    materials: &mut Assets<StandardMaterial>,
    images: &mut Assets<Image>,
    strands: &mut Assets<HairStrands>,
    profiles: &mut SubsurfaceProfiles,
    coat: Handle<StandardMaterial>,
) {
    let skin: SubsurfaceProfileId = profiles.add(skin_profile()).expect("the first profile");
    let skin = materials.add(skin.apply(StandardMaterial {
        base_color: Color::srgb(0.8, 0.58, 0.48),
        perceptual_roughness: 0.5,
        reflectance: 0.35,
        ..default()
    }));
    let sphere = meshes.add(Sphere::new(1.0).mesh().uv(48, 32));
    // Shoulders (the coat), neck, head, nose and ears.
    commands.spawn((
        Mesh3d(sphere.clone()),
        MeshMaterial3d(coat),
        Transform::from_translation(HEAD_AT + Vec3::new(0.0, -0.33, -0.02))
            .with_scale(Vec3::new(0.23, 0.09, 0.13)),
    ));
    for (offset, scale) in HEAD_PARTS {
        commands.spawn((
            Mesh3d(sphere.clone()),
            MeshMaterial3d(skin.clone()),
            Transform::from_translation(HEAD_AT + offset).with_scale(scale),
        ));
    }
    // The head's shadow and occlusion: a sphere caster (no mesh bake needed).
    commands.spawn((
        Transform::from_translation(HEAD_AT),
        Visibility::Hidden,
        DistanceFieldCaster {
            source: CasterSource::Sphere { radius: 0.095 },
            cast_hidden_shadow: true,
            ..default()
        },
    ));
    commands.spawn((
        Hair {
            strands: strands.add(HairStrands::new(head_strands())),
            atlas: Some(images.add(hair_atlas())),
            atlas_slots: SLOTS,
            root_color: Color::linear_rgb(0.018, 0.009, 0.005),
            tip_color: Color::linear_rgb(0.07, 0.04, 0.022),
            ..default()
        },
        Transform::from_translation(HEAD_AT),
    ));
}

/// A feature's component while it is toggled off.
#[derive(Component, Clone)]
struct Stashed<T: Component + Clone>(T);

/// Removes `T` from every entity that has it (keeping it aside), or puts it back.
fn toggle<T: Component + Clone>(world: &mut World) {
    let on: Vec<(Entity, T)> = world
        .query::<(Entity, &T)>()
        .iter(world)
        .map(|(e, t)| (e, t.clone()))
        .collect();
    if on.is_empty() {
        let off: Vec<(Entity, T)> = world
            .query::<(Entity, &Stashed<T>)>()
            .iter(world)
            .map(|(e, s)| (e, s.0.clone()))
            .collect();
        for (entity, value) in off {
            world
                .entity_mut(entity)
                .remove::<Stashed<T>>()
                .insert(value);
        }
    } else {
        for (entity, value) in on {
            world
                .entity_mut(entity)
                .remove::<T>()
                .insert(Stashed(value));
        }
    }
}

/// Whether any entity has `T` (the feature is on).
fn is_on<T: Component>(world: &mut World) -> bool {
    world
        .query_filtered::<(), With<T>>()
        .iter(world)
        .next()
        .is_some()
}

/// A key, the feature's name, its toggle and whether it is on.
type Toggle = (
    KeyCode,
    &'static str,
    fn(&mut World),
    fn(&mut World) -> bool,
);

/// The keys and what they toggle (distance-field shadows and DFAO: `Space` and `A`, as
/// in every example).
const KEYS: [Toggle; 6] = [
    (
        KeyCode::Digit1,
        "SSS",
        toggle::<SubsurfaceScattering>,
        is_on::<SubsurfaceScattering>,
    ),
    (KeyCode::Digit2, "hair", toggle::<Hair>, is_on::<Hair>),
    (
        KeyCode::Digit3,
        "reflections",
        toggle::<BillboardReflections>,
        is_on::<BillboardReflections>,
    ),
    (
        KeyCode::Digit4,
        "bokeh",
        toggle::<BokehDepthOfField>,
        is_on::<BokehDepthOfField>,
    ),
    (
        KeyCode::Digit5,
        "tessellation",
        toggle::<Tessellated>,
        is_on::<Tessellated>,
    ),
    (
        KeyCode::Digit6,
        "rain",
        toggle::<DistanceFieldParticles>,
        is_on::<DistanceFieldParticles>,
    ),
];

/// `1`–`6` toggle the features, `M` deferred MSAA (windowed runs: no keyboard headless).
fn toggle_features(world: &mut World) {
    let Some(keys) = world.get_resource::<ButtonInput<KeyCode>>() else {
        return;
    };
    let pressed: Vec<fn(&mut World)> = KEYS
        .iter()
        .filter(|(key, ..)| keys.just_pressed(*key))
        .map(|(_, _, toggle, _)| *toggle)
        .collect();
    let msaa = keys.just_pressed(KeyCode::KeyM);
    for toggle in pressed {
        toggle(world);
    }
    if msaa {
        let mut cameras = world.query_filtered::<&mut Msaa, With<PenumbraLighting>>();
        for mut m in cameras.iter_mut(world) {
            *m = if *m == Msaa::Off {
                Msaa::Sample4
            } else {
                Msaa::Off
            };
        }
    }
}

/// The features' state in the window title, after the part every example's controls
/// write there (`controls.rs`, which rewrites it when its toggles change).
fn show_features(world: &mut World) {
    let mut state = String::new();
    for (key, name, _, on) in KEYS {
        let digit = format!("{key:?}").replace("Digit", "");
        state += &format!(
            "[{digit}] {name}: {} · ",
            if on(world) { "on" } else { "off" }
        );
    }
    let msaa = world
        .query_filtered::<&Msaa, With<PenumbraLighting>>()
        .iter(world)
        .next()
        .is_some_and(|m| *m != Msaa::Off);
    state += &format!("[M] MSAA: {}", if msaa { "4×" } else { "off" });
    let mut windows = world.query::<&mut Window>();
    for mut window in windows.iter_mut(world) {
        let base = window
            .title
            .split(" | ")
            .next()
            .unwrap_or_default()
            .to_string();
        let title = format!("{base} | {state}");
        if window.title != title {
            window.title = title;
        }
    }
}
