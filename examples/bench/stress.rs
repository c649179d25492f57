//! The benchmark's stress scene (part of `scenes.rs`).

use super::*;

/// The stress scene: a 40 × 25 field of 1,000 mesh casters (five shapes, scaled and
/// turned) on a glossy ground, a sun and seven point lights, 100 emissive signs that are
/// reflection billboards, a head of hair and a tessellated rock near the camera. The
/// hair, the rock and ten casters turn every frame, so the per-frame work of a game
/// (object deltas, hair visibility, re-tessellation) is measured, not a still frame's.
#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
pub(super) fn spawn_stress(
    mut commands: Commands,
    run: Res<Run>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
    strands: Option<ResMut<Assets<HairStrands>>>,
    mut camera: Single<&mut Transform, With<BenchCamera>>,
) {
    let penumbra = run.variant.penumbra_plugins();
    let df = run.variant.distance_fields();
    **camera = Transform::from_xyz(0.0, 7.0, 38.0).looking_at(Vec3::new(0.0, 0.5, 0.0), Vec3::Y);
    let hash = |i: u32, salt: u32| {
        let mut x = i.wrapping_mul(0x9E37_79B9) ^ salt.wrapping_mul(0x85EB_CA6B);
        x ^= x >> 15;
        x = x.wrapping_mul(0x2C1B_3C6D);
        x ^= x >> 12;
        (x & 0xFFFF) as f32 / 65536.0
    };
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::new(Vec3::Y, Vec2::new(50.0, 40.0)))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.3, 0.3, 0.32),
            perceptual_roughness: 0.25,
            ..default()
        })),
        Transform::default(),
    ));
    let shapes_: [Mesh; 5] = [
        Cuboid::new(1.0, 1.0, 1.0).into(),
        Sphere::new(0.5).mesh().uv(32, 16),
        Torus::new(0.25, 0.5).into(),
        Cylinder::new(0.3, 1.2).into(),
        Capsule3d::new(0.3, 0.6).into(),
    ];
    let shape_handles: Vec<Handle<Mesh>> = shapes_.into_iter().map(|m| meshes.add(m)).collect();
    let palette: Vec<Handle<StandardMaterial>> = (0..8)
        .map(|i| {
            materials.add(StandardMaterial {
                base_color: Color::hsl(i as f32 * 45.0, 0.5, 0.55),
                perceptual_roughness: 0.6,
                ..default()
            })
        })
        .collect();
    for i in 0..1_000u32 {
        let (col, row) = (i % 40, i / 40);
        let at = Vec3::new(
            -39.0 + 2.0 * col as f32 + 0.6 * (hash(i, 1) - 0.5),
            0.6,
            -24.0 + 2.0 * row as f32 + 0.6 * (hash(i, 2) - 0.5),
        );
        let mut object = commands.spawn((
            Mesh3d(shape_handles[(i % 5) as usize].clone()),
            MeshMaterial3d(palette[(i % 8) as usize].clone()),
            Transform::from_translation(at)
                .with_rotation(Quat::from_rotation_y(std::f32::consts::TAU * hash(i, 3)))
                .with_scale(Vec3::splat(0.7 + 0.6 * hash(i, 4))),
        ));
        if df {
            object.insert(DistanceFieldCaster::default());
        }
        // A row near the camera turns: the object buffer takes deltas every frame.
        if row == 24 && col % 4 == 0 {
            object.insert(Spin);
        }
    }
    commands.spawn((
        DirectionalLight {
            illuminance: 6_000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::default().looking_to(Vec3::new(-0.4, -1.0, -0.5), Vec3::Y),
    ));
    for i in 0..7 {
        let x = -30.0 + 10.0 * i as f32;
        commands.spawn((
            PointLight {
                color: Color::hsl(i as f32 * 50.0, 0.6, 0.7),
                intensity: 200_000.0,
                range: 14.0,
                radius: 0.1,
                shadow_maps_enabled: true,
                ..default()
            },
            Transform::from_xyz(x, 4.0, 4.0 * ((i % 3) as f32 - 1.0)),
        ));
    }
    // 100 signs along the back and the sides, one image size for the billboard array.
    let sign_images: Vec<Handle<Image>> = (0..4).map(|i| images.add(sign_image(i))).collect();
    let quad = meshes.add(Rectangle::new(2.0, 1.0));
    for i in 0..100u32 {
        let (at, facing) = if i < 60 {
            (Vec3::new(-44.0 + 1.5 * i as f32, 2.0, -27.0), Vec3::Z)
        } else {
            let side = if i < 80 { -1.0 } else { 1.0 };
            let k = (i - 60) % 20;
            (
                Vec3::new(side * 44.0, 2.0, -24.0 + 2.5 * k as f32),
                Vec3::X * -side,
            )
        };
        let glow = 4.0;
        let mut sign = commands.spawn((
            Mesh3d(quad.clone()),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::BLACK,
                emissive: LinearRgba::rgb(glow, glow * 0.5, glow * 0.8),
                ..default()
            })),
            Transform::from_translation(at).looking_to(-facing, Vec3::Y),
        ));
        if penumbra {
            sign.insert(ReflectionBillboard {
                image: sign_images[(i % 4) as usize].clone(),
                size: Vec2::new(2.0, 1.0),
                emissive: glow,
            });
        }
    }
    if let (true, Some(mut strands)) = (penumbra, strands) {
        let skin = materials.add(StandardMaterial {
            base_color: Color::srgb(0.72, 0.5, 0.4),
            perceptual_roughness: 0.55,
            ..default()
        });
        let head = Vec3::new(-1.0, 1.6, 30.0);
        commands.spawn((
            Mesh3d(meshes.add(Sphere::new(1.0).mesh().uv(48, 32))),
            MeshMaterial3d(skin),
            Transform::from_translation(head).with_scale(HEAD),
        ));
        commands.spawn((
            Hair {
                strands: strands.add(HairStrands::new(head_strands(HEAD))),
                ..default()
            },
            Transform::from_translation(head),
            Spin,
        ));
        commands.spawn((
            Mesh3d(meshes.add(shape_mesh(&shapes::rock(32, 8)))),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::srgb(0.62, 0.58, 0.52),
                perceptual_roughness: 0.85,
                ..default()
            })),
            Transform::from_xyz(2.5, 0.8, 28.0),
            Tessellated::default(),
            Spin,
        ));
    }
    commands.insert_resource(Framed {
        scale: 1.0,
        reach: 80.0,
    });
}

/// The stress scene's head: an ellipsoid's semi-axes, metres.
const HEAD: Vec3 = Vec3::new(0.078, 0.105, 0.092);

/// 9,000 short strands (4 segments, 4–6 cm) over the head's upper two thirds, combed
/// back and down: as many points as the hair example's head.
fn head_strands(head: Vec3) -> Vec<Strand> {
    let n = 9_000u32;
    (0..n)
        .filter_map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            if y < -0.3 {
                return None;
            }
            let r = (1.0 - y * y).max(0.0).sqrt();
            let phi = i as f32 * 2.399_963;
            let d = Vec3::new(r * phi.cos(), y, r * phi.sin());
            let normal = (d / head).normalize();
            let comb = Vec3::new(0.0, -0.8, -0.6).normalize();
            let along = (comb - normal * normal.dot(comb)).normalize_or(comb);
            let length = 0.04 + 0.02 * ((i * 7919) % 100) as f32 / 100.0;
            let root = d * head;
            let points = (0..=4)
                .map(|k| {
                    let s = k as f32 / 4.0;
                    root + (normal * 0.3 + along).normalize() * length * s + normal * 0.002 * s
                })
                .collect();
            Some(Strand {
                points,
                width: 0.0015,
                slot: i % 4,
            })
        })
        .collect()
}

/// A 64 × 32 sign: bars of one of four colours.
fn sign_image(i: u32) -> Image {
    use bevy::asset::RenderAssetUsages;
    use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
    let colour = [
        [255, 60, 90],
        [60, 200, 255],
        [255, 200, 60],
        [120, 255, 120],
    ][i as usize % 4];
    let mut data = Vec::with_capacity(64 * 32 * 4);
    for y in 0..32 {
        for x in 0..64 {
            let on = (x / 8 + y / 8 + i).is_multiple_of(2);
            let c = if on { colour } else { [20, 20, 24] };
            data.extend([c[0], c[1], c[2], 255]);
        }
    }
    Image::new(
        Extent3d {
            width: 64,
            height: 32,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba8UnormSrgb,
        RenderAssetUsages::default(),
    )
}
