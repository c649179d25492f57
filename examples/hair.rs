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

use bevy::asset::RenderAssetUsages;
use bevy::light::{CascadeShadowConfigBuilder, GlobalAmbientLight};
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use penumbra::cinematic::hair::Strand;
use penumbra::prelude::*;

#[path = "common/cli.rs"]
mod cli;
pub use cli::{HairMode, Options};

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

/// The head's semi-axes, metres (an ellipsoid).
const HEAD: Vec3 = Vec3::new(0.078, 0.105, 0.092);
/// The head's centre.
const HEAD_AT: Vec3 = Vec3::new(0.0, 1.6, 0.0);
/// Columns of the atlas.
const SLOTS: u32 = 4;

/// A deterministic value in [0, 1) for `(i, salt)`.
fn hash(i: u32, salt: u32) -> f32 {
    let mut h = i.wrapping_mul(0x9e37_79b9) ^ salt.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 15;
    h = h.wrapping_mul(0x2c1b_3c6d);
    h ^= h >> 12;
    (h >> 8) as f32 / (1u32 << 24) as f32
}

/// Direction `i` of `n` spread evenly over the sphere (a Fibonacci lattice).
fn lattice(i: u32, n: u32) -> Vec3 {
    let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
    let r = (1.0 - y * y).max(0.0).sqrt();
    let phi = i as f32 * 2.399_963;
    Vec3::new(r * phi.cos(), y, r * phi.sin())
}

/// Grows a strand from the head's surface in direction `d` (unit, from the centre):
/// it leaves the skin at a low angle and lies along `comb` (projected onto the scalp),
/// `segments` steps of `length / segments`, kept at least 2 mm off the skin.
fn grow(
    d: Vec3,
    length: f32,
    segments: u32,
    comb: Vec3,
    lift: f32,
    width: f32,
    slot: u32,
) -> Strand {
    let root = d * HEAD * 0.985;
    let normal = (d / HEAD).normalize();
    let along = (comb - normal * normal.dot(comb)).normalize_or(comb);
    let mut points = vec![root];
    let mut dir = (normal * lift + along).normalize();
    let mut p = root;
    for _ in 0..segments {
        p += dir * (length / segments as f32);
        let r = (p / HEAD).length();
        let floor = 1.0 + 0.002 / HEAD.min_element();
        if r < floor {
            p *= floor / r;
        }
        points.push(p);
        dir = (dir + comb * 0.4).normalize();
    }
    Strand {
        points,
        width,
        slot,
    }
}

/// Short hair over the scalp and a beard over the jaw, head-centred metres.
pub fn head_strands() -> Vec<Strand> {
    let mut strands = Vec::new();
    let n = 9000;
    for i in 0..n {
        let d = lattice(i, n);
        let slot = (hash(i, 7) * SLOTS as f32) as u32;
        // Scalp: the crown, and the back and sides down to the nape, above the ears.
        let scalp = d.y > 0.42 || (d.z < 0.2 && d.y > -0.25 + 0.5 * d.z.max(0.0));
        // Beard: the jaw and chin, below the cheekbones.
        let beard = d.z > 0.3 && d.y < -0.2 && d.y > -0.92 && d.x.abs() < 0.9;
        if scalp {
            let length = 0.035 + 0.02 * hash(i, 1);
            let comb = Vec3::new(0.3 * (hash(i, 2) - 0.5), -0.8, -0.6).normalize();
            strands.push(grow(d, length, 4, comb, 0.5, 0.0016, slot));
        } else if beard && hash(i, 3) < 0.8 {
            let length = 0.012 + 0.008 * hash(i, 4);
            let comb = Vec3::new(0.2 * (hash(i, 5) - 0.5), -1.0, 0.15).normalize();
            strands.push(grow(d, length, 2, comb, 0.8, 0.0013, slot));
        }
    }
    strands
}

/// The hair atlas: `SLOTS` columns of 16 × 64 texels, each a clump of three or four
/// hairs (alpha: narrow profiles across, thinning towards the tip), tinted slightly.
fn hair_atlas() -> Image {
    let (w, h) = (16 * SLOTS, 64);
    let mut data = Vec::with_capacity((w * h * 4) as usize);
    for y in 0..h {
        let u = (y as f32 + 0.5) / h as f32;
        for x in 0..w {
            let slot = x / 16;
            let v = ((x % 16) as f32 + 0.5) / 16.0;
            let hairs: &[f32] = match slot {
                0 => &[0.2, 0.45, 0.75],
                1 => &[0.15, 0.38, 0.6, 0.85],
                2 => &[0.25, 0.5, 0.8],
                _ => &[0.12, 0.35, 0.62, 0.88],
            };
            // Each hair's half-width across the strip thins to a third at the tip.
            let half = 0.11 * (1.0 - 0.66 * u);
            let alpha = hairs
                .iter()
                .map(|c| (1.0 - ((v - c) / half).powi(2)).max(0.0))
                .fold(0.0f32, f32::max);
            let tint = 0.85 + 0.15 * hash(slot, 11);
            let t = |c: f32| (c * tint * 255.0) as u8;
            data.extend([t(1.0), t(0.95), t(0.9), (alpha.sqrt() * 255.0) as u8]);
        }
    }
    Image::new(
        Extent3d {
            width: w,
            height: h,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba8Unorm,
        RenderAssetUsages::default(),
    )
}

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
    for (at, scale) in [
        (HEAD_AT, HEAD),
        (
            HEAD_AT + Vec3::new(0.0, -0.01, 0.092),
            Vec3::new(0.014, 0.026, 0.018),
        ),
        (
            HEAD_AT + Vec3::new(0.079, 0.0, -0.005),
            Vec3::new(0.01, 0.028, 0.017),
        ),
        (
            HEAD_AT + Vec3::new(-0.079, 0.0, -0.005),
            Vec3::new(0.01, 0.028, 0.017),
        ),
        (
            HEAD_AT + Vec3::new(0.0, -0.16, -0.015),
            Vec3::new(0.052, 0.09, 0.052),
        ),
        (
            HEAD_AT + Vec3::new(0.0, -0.31, -0.02),
            Vec3::new(0.21, 0.08, 0.11),
        ),
    ] {
        commands.spawn((
            Mesh3d(sphere.clone()),
            MeshMaterial3d(skin.clone()),
            Transform::from_translation(at).with_scale(scale),
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
