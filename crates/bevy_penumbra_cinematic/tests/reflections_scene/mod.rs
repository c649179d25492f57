//! The scene of the billboard reflection plugin tests (`reflections_plugin.rs`,
//! `reflections_culling.rs`): a wide floor (y = 0) seen from 1.2 m up; two billboards
//! standing on it, facing the camera (a striped sign with a transparent hole and a
//! half-transparent band, and a larger sign behind it, so reflections composite two
//! layers), and a third facing away (one-sided: never reflected); a box on the floor,
//! optionally a wall (a distance-field caster) and more billboards. The billboards draw
//! nothing themselves. Linear HDR capture, no tonemapping. The CPU model of the layer
//! from the scene's analytic G-buffer.

#![allow(dead_code, reason = "each test file uses part of the scene")]

use bevy::asset::RenderAssetUsages;
use bevy::camera::Hdr;
use bevy::camera::visibility::RenderLayers;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::image::Image;
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy_penumbra_cinematic::{
    BillboardReflections, BillboardReflectionsPlugin, ReflectionBillboard, ReflectionDebugView,
};
use bevy_penumbra_df::{
    CasterSource, DeferredMsaa, DistanceFieldCaster, DistanceFieldScenePlugin,
    DistanceFieldSceneSettings, PenumbraLighting, PenumbraLightingPlugin, SdfAssetPlugin,
    SdfVolumeAsset,
};
use penumbra_cinematic_core::reflections::Billboard;
use penumbra_cinematic_core::reflections::pass::{
    GpuBillboard, ReflectionUniform, ShadowCasters, Surface, reflect_pixel_shadowed,
};
use penumbra_cinematic_core::reflections::texture::MipChain;
use penumbra_reference::analytic_volume;
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_test::{CaptureFormat, HeadlessRender, KeptApp};

pub const WIDTH: u32 = 128;
pub const HEIGHT: u32 = 96;
pub const EYE: Vec3 = Vec3::new(0.0, 1.2, 3.0);
pub const TARGET: Vec3 = Vec3::new(0.0, 0.2, -2.0);
/// A box standing on the floor in front of the reflections (its faces reflect too; its
/// silhouette is a depth edge for the half-resolution upsample).
pub const BOX_CENTER: Vec3 = Vec3::new(-0.2, 0.25, -0.9);
pub const BOX_HALF: f32 = 0.25;
/// A wall between the striped sign and the floor before it (a distance-field caster
/// when the setup asks for it): reflection shadows.
pub const WALL_CENTER: Vec3 = Vec3::new(-0.7, 0.3, -1.9);
pub const WALL_HALF: Vec3 = Vec3::new(0.5, 0.3, 0.05);
/// With the wall, a board 2 cm behind the striped sign (a caster too): it must hide
/// nothing (it lies behind the sign's plane).
pub const BOARD_CENTER: Vec3 = Vec3::new(-0.5, 0.9, -2.57);
pub const BOARD_HALF: Vec3 = Vec3::new(0.9, 0.6, 0.05);
/// The floor's half size.
pub const FLOOR_HALF: f32 = 20.0;
/// The images' size.
pub const IMAGE: UVec2 = UVec2::new(16, 8);
/// cd/m² of a texel of 1 (small: the layer is compared unexposed in f16).
pub const EMISSIVE: f32 = 4.0;

#[derive(Clone, Copy, Debug)]
pub struct Setup {
    /// `BillboardReflectionsPlugin` in the app.
    pub plugin: bool,
    /// `BillboardReflections` on the camera (with this debug view).
    pub reflections: Option<ReflectionDebugView>,
    /// The billboards exist.
    pub billboards: bool,
    pub perceptual_roughness: f32,
    pub anisotropy: f32,
    pub half_resolution: bool,
    /// The wall (a distance-field caster: reflection shadows).
    pub wall: bool,
    /// With the wall: the wall as a volume of its exact distances,
    /// placed as sparse bricks (`true`) or dense, instead of an analytic cuboid.
    pub wall_volume: Option<bool>,
    /// Billboards added behind the scene's (timing).
    pub extra_billboards: u32,
    /// `BillboardReflections::max_layers`.
    pub max_layers: u32,
    /// `BillboardReflections::tile_culling`.
    pub tile_culling: bool,
    /// Spawn the billboards in reverse order (other entities, other list order, other
    /// texture array layers).
    pub reversed: bool,
    /// The scene's billboards' render layer (0: no `RenderLayers`, Bevy's default).
    pub billboard_layer: usize,
    /// The camera renders layers 0 and 1 (otherwise Bevy's default, 0).
    pub camera_sees_layer_1: bool,
    /// `DeferredMsaa` on the camera (otherwise `Msaa::Off`).
    pub msaa: bool,
    /// Small sphere casters (no mesh) in a lattice between the floor and the signs
    /// ([`crowd`]): more than a tile's caster list holds.
    pub crowd: u32,
}

impl Default for Setup {
    fn default() -> Self {
        Setup {
            plugin: true,
            reflections: Some(ReflectionDebugView::Layer),
            billboards: true,
            perceptual_roughness: 0.2,
            anisotropy: 0.0,
            half_resolution: false,
            wall: false,
            wall_volume: None,
            extra_billboards: 0,
            max_layers: 3,
            tile_culling: true,
            reversed: false,
            billboard_layer: 0,
            camera_sees_layer_1: false,
            msaa: false,
            crowd: 0,
        }
    }
}

/// The billboards: transform, size, image (straight-alpha linear texels, `IMAGE`).
pub fn billboards() -> Vec<(Transform, Vec2, Vec<Vec4>)> {
    let stripes: Vec<Vec4> = (0..IMAGE.x * IMAGE.y)
        .map(|i| {
            let (x, y) = (i % IMAGE.x, i / IMAGE.x);
            let colour = [
                Vec3::new(1.0, 0.2, 0.1),
                Vec3::new(0.1, 0.9, 0.3),
                Vec3::new(0.2, 0.3, 1.0),
            ][(x / 3 % 3) as usize];
            let alpha = if (6..10).contains(&x) && (2..6).contains(&y) {
                0.0 // a hole
            } else if y == 7 {
                0.5 // a half-transparent band along the bottom
            } else {
                1.0
            };
            colour.extend(alpha)
        })
        .collect();
    let glow: Vec<Vec4> = (0..IMAGE.x * IMAGE.y)
        .map(|i| {
            let (x, y) = (i % IMAGE.x, i / IMAGE.x);
            let v = 0.3 + 0.7 * ((x + 2 * y) % 5) as f32 / 4.0;
            Vec4::new(v, v * 0.8, 0.2, 1.0)
        })
        .collect();
    vec![
        (
            Transform::from_xyz(-0.5, 0.9, -2.5),
            Vec2::new(1.6, 1.0),
            stripes,
        ),
        (
            Transform::from_xyz(0.5, 1.2, -4.5),
            Vec2::new(3.0, 1.8),
            glow.clone(),
        ),
        // Facing away from the camera: reflects nothing toward it.
        (
            Transform::from_xyz(0.0, 0.8, -1.5)
                .with_rotation(Quat::from_rotation_y(std::f32::consts::PI)),
            Vec2::new(2.0, 1.0),
            glow,
        ),
    ]
}

pub fn image_of(texels: &[Vec4]) -> Image {
    let data: Vec<u8> = texels
        .iter()
        .flat_map(|t| t.to_array())
        .flat_map(f32::to_le_bytes)
        .collect();
    Image::new(
        Extent3d {
            width: IMAGE.x,
            height: IMAGE.y,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        TextureFormat::Rgba32Float,
        RenderAssetUsages::default(),
    )
}

#[allow(clippy::type_complexity, reason = "a Bevy system's parameters")]
#[expect(clippy::type_complexity, reason = "a startup system's resources")]
pub fn scene(
    setup: Setup,
) -> impl Fn(
    Commands,
    ResMut<Assets<Mesh>>,
    ResMut<Assets<StandardMaterial>>,
    ResMut<Assets<Image>>,
    ResMut<Assets<SdfVolumeAsset>>,
) {
    move |mut commands, mut meshes, mut materials, mut images, mut sdfs| {
        commands.spawn((
            Mesh3d(
                meshes.add(
                    Plane3d::default()
                        .mesh()
                        .size(2.0 * FLOOR_HALF, 2.0 * FLOOR_HALF),
                ),
            ),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::linear_rgb(0.1, 0.1, 0.1),
                perceptual_roughness: setup.perceptual_roughness,
                ..default()
            })),
        ));
        commands.spawn((
            Mesh3d(meshes.add(Cuboid::from_length(2.0 * BOX_HALF))),
            MeshMaterial3d(materials.add(StandardMaterial {
                base_color: Color::linear_rgb(0.1, 0.1, 0.1),
                perceptual_roughness: setup.perceptual_roughness,
                ..default()
            })),
            Transform::from_translation(BOX_CENTER),
        ));
        if setup.wall {
            for (center, half) in [(WALL_CENTER, WALL_HALF), (BOARD_CENTER, BOARD_HALF)] {
                commands.spawn((
                    Mesh3d(meshes.add(Cuboid::from_size(2.0 * half))),
                    MeshMaterial3d(materials.add(StandardMaterial {
                        base_color: Color::linear_rgb(0.1, 0.1, 0.1),
                        perceptual_roughness: setup.perceptual_roughness,
                        ..default()
                    })),
                    Transform::from_translation(center),
                    DistanceFieldCaster {
                        source: match setup.wall_volume {
                            Some(_) if center == WALL_CENTER => {
                                CasterSource::Sdf(sdfs.add(SdfVolumeAsset {
                                    // Most of its 8³ bricks far from the surface.
                                    volume: analytic_volume::cuboid(half, 0.5, 0.02),
                                }))
                            }
                            _ => CasterSource::Cuboid { half_size: half },
                        },
                        ..default()
                    },
                ));
            }
        }
        for center in crowd(setup.crowd) {
            commands.spawn((
                Transform::from_translation(center),
                DistanceFieldCaster {
                    source: CasterSource::Sphere {
                        radius: CROWD_RADIUS,
                    },
                    ..default()
                },
            ));
        }
        if setup.billboards {
            let mut handles = Vec::new();
            let mut list = billboards();
            if setup.reversed {
                list.reverse();
            }
            for (transform, size, texels) in list {
                let image = images.add(image_of(&texels));
                handles.push(image.clone());
                let mut billboard = commands.spawn((
                    ReflectionBillboard {
                        image,
                        size,
                        emissive: EMISSIVE,
                    },
                    transform,
                ));
                if setup.billboard_layer != 0 {
                    billboard.insert(RenderLayers::layer(setup.billboard_layer));
                }
            }
            if setup.reversed {
                handles.reverse(); // the same images for the signs below
            }
            // More signs behind, facing the camera (a deterministic scatter).
            for k in 0..setup.extra_billboards {
                let h = |m: u32| ((k.wrapping_mul(m).wrapping_add(0x9e37)) % 1000) as f32 / 1000.0;
                commands.spawn((
                    ReflectionBillboard {
                        image: handles[(k % 2) as usize].clone(),
                        size: Vec2::new(0.6, 0.4),
                        emissive: EMISSIVE,
                    },
                    Transform::from_xyz(
                        -6.0 + 12.0 * h(7919),
                        0.4 + 2.5 * h(104_729),
                        -3.0 - 12.0 * h(1_299_709),
                    ),
                ));
            }
        }
        commands.spawn((
            DirectionalLight {
                illuminance: 50.0,
                ..default()
            },
            Transform::default().looking_to(Vec3::new(0.2, -1.0, -0.4), Vec3::Y),
        ));
        let mut camera = commands.spawn((
            Camera3d::default(),
            Hdr,
            Tonemapping::None,
            PenumbraLighting,
            Msaa::Off,
            // Exposure 1/1.2: the floor's light and its reflections near 1.
            bevy::camera::Exposure { ev100: 0.0 },
            Transform::from_translation(EYE).looking_at(TARGET, Vec3::Y),
        ));
        if setup.camera_sees_layer_1 {
            camera.insert(RenderLayers::from_layers(&[0, 1]));
        }
        if setup.msaa {
            camera.insert((DeferredMsaa::default(), Msaa::Sample4));
        }
        if let Some(debug_view) = setup.reflections {
            camera.insert(BillboardReflections {
                debug_view,
                anisotropy: setup.anisotropy,
                half_resolution: setup.half_resolution,
                max_layers: setup.max_layers,
                tile_culling: setup.tile_culling,
                ..default()
            });
        }
    }
}

pub fn render(setup: Setup) -> (Vec<[f32; 4]>, KeptApp) {
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(5);
    let (capture, app) = render_with(setup, &harness);
    (capture.to_linear(), app)
}

pub fn render_with(setup: Setup, harness: &HeadlessRender) -> (penumbra_test::Capture, KeptApp) {
    let mut app = harness.app();
    app.add_plugins((
        SdfAssetPlugin,
        DistanceFieldScenePlugin,
        PenumbraLightingPlugin::default(),
    ));
    if setup.plugin {
        app.add_plugins(BillboardReflectionsPlugin);
    }
    app.insert_resource(DefaultOpaqueRendererMethod::deferred())
        .insert_resource(GlobalAmbientLight {
            brightness: 20.0,
            ..default()
        })
        .insert_resource(DistanceFieldSceneSettings {
            sparse_min_bytes: if setup.wall_volume == Some(true) {
                0
            } else {
                u64::MAX
            },
            ..default()
        })
        .add_systems(Startup, scene(setup));
    harness.run_keeping_app(app).expect("renders")
}

pub fn test_camera() -> PerspectiveCamera {
    PerspectiveCamera::looking_at(
        EYE,
        TARGET,
        PerspectiveProjection::default().fov,
        WIDTH,
        HEIGHT,
    )
}

/// The crowd's spheres' radius, metres.
pub const CROWD_RADIUS: f32 = 0.02;

/// `n` sphere casters' centres in a lattice filling the space between the floor and the
/// signs (x in ±2 m, y 0.1–1.3 m, z −4.3 to −0.5 m), where every reflecting tile's rays
/// pass: many within reach of each tile, few near each ray.
pub fn crowd(n: u32) -> Vec<Vec3> {
    let (nx, ny) = (16, 5);
    let layers = n.div_ceil(nx * ny).max(1);
    (0..n)
        .map(|i| {
            let (x, y, z) = (i % nx, i / nx % ny, i / (nx * ny));
            Vec3::new(
                -2.0 + 4.0 * (x as f32 + 0.5) / nx as f32,
                0.1 + 1.2 * (y as f32 + 0.5) / ny as f32,
                -4.3 + 3.8 * (z as f32 + 0.5) / layers as f32,
            )
        })
        .collect()
}

/// The boxes in the scene (centre, half size): the box, and the wall when asked for.
pub fn boxes(wall: bool) -> Vec<(Vec3, Vec3)> {
    let mut v = vec![(BOX_CENTER, Vec3::splat(BOX_HALF))];
    if wall {
        v.push((WALL_CENTER, WALL_HALF));
        v.push((BOARD_CENTER, BOARD_HALF));
    }
    v
}

/// What pixel `p` sees, analytically: a box or the floor (position, unit normal, view
/// depth, the unit ray), or `None` for the sky.
pub fn analytic_surface(p: IVec2, wall: bool) -> Option<(Vec3, Vec3, f32, Vec3)> {
    let ray = test_camera().ray(p.x as f32 + 0.5, p.y as f32 + 0.5);
    let forward = (TARGET - EYE).normalize();
    let inv = ray.dir.recip();
    // The nearest box (slabs), else the floor.
    let mut hit: Option<(f32, Vec3)> = None;
    for (center, half) in boxes(wall) {
        let lo = (center - half - ray.origin) * inv;
        let hi = (center + half - ray.origin) * inv;
        let (near, far) = (lo.min(hi), lo.max(hi));
        let t = near.max_element();
        if t <= far.min_element() && t > 0.0 && hit.is_none_or(|(h, _)| t < h) {
            let axis = near.max_position();
            let mut n = Vec3::ZERO;
            n[axis] = -ray.dir[axis].signum();
            hit = Some((t, n));
        }
    }
    let hit = hit.or_else(|| {
        let t = -ray.origin.y / ray.dir.y;
        let q = ray.at(t);
        (ray.dir.y < 0.0 && q.x.abs() <= FLOOR_HALF && q.z.abs() <= FLOOR_HALF)
            .then_some((t, Vec3::Y))
    });
    hit.map(|(t, n)| (ray.at(t), n, -t * ray.dir.dot(forward), ray.dir))
}

/// The wall's and the board's exact distance (the casters' cuboids), metres.
/// The wall's (0) or the board's (1) distance at `p`.
pub fn caster_distance(i: usize, p: Vec3) -> f32 {
    let (center, half) = [(WALL_CENTER, WALL_HALF), (BOARD_CENTER, BOARD_HALF)][i];
    let q = (p - center).abs() - half;
    q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
}

/// The wall and the board as the reflection shadows' casters (bounding spheres as the
/// GPU's: a box's half diagonal).
pub fn casters() -> ShadowCasters<'static, fn(usize, Vec3) -> f32> {
    static SPHERES: std::sync::OnceLock<[Option<(Vec3, f32)>; 2]> = std::sync::OnceLock::new();
    ShadowCasters {
        spheres: SPHERES.get_or_init(|| {
            [
                Some((WALL_CENTER, WALL_HALF.length())),
                Some((BOARD_CENTER, BOARD_HALF.length())),
            ]
        }),
        distance: caster_distance,
    }
}

/// The scene's billboards as the pass lists them (layer `i`: the `i`-th image).
pub fn model_billboards() -> Vec<GpuBillboard> {
    billboards()
        .into_iter()
        .enumerate()
        .map(|(i, (transform, size, _))| {
            let quad = Billboard::from_transform(transform.to_matrix(), size).unwrap();
            GpuBillboard {
                center: quad.center,
                layer: i as u32,
                half_x: quad.half_x,
                emissive: EMISSIVE,
                half_y: quad.half_y,
                layers: u32::MAX,
            }
        })
        .collect()
}

/// The layer the model predicts at every pixel (the floor's analytic G-buffer; `None`
/// where the pixel sees the sky).
pub fn model(setup: Setup) -> Vec<Option<Vec4>> {
    model_with(setup, setup.wall)
}

/// [`model`], with or without reflection shadows.
pub fn model_with(setup: Setup, shadows: bool) -> Vec<Option<Vec4>> {
    let gpu = model_billboards();
    let images: Vec<MipChain> = billboards()
        .into_iter()
        .map(|(_, _, texels)| MipChain::from_straight_alpha(IMAGE.x, IMAGE.y, &texels))
        .collect();
    let mut settings =
        ReflectionUniform::new(gpu.len() as u32, IMAGE, images[0].levels.len() as u32);
    settings.anisotropy = setup.anisotropy;
    if shadows {
        settings.shadow_steps = 32;
        settings.object_count = 2;
    }
    (0..WIDTH * HEIGHT)
        .map(|i| {
            let pixel = IVec2::new((i % WIDTH) as i32, (i / WIDTH) as i32);
            let (position, normal, _, dir) = analytic_surface(pixel, setup.wall)?;
            // Pixels on the silhouette's edge may see either surface: skipped.
            let edge = [IVec2::X, IVec2::NEG_X, IVec2::Y, IVec2::NEG_Y]
                .iter()
                .any(|o| analytic_surface(pixel + *o, setup.wall).map(|s| s.1) != Some(normal));
            if edge {
                return None;
            }
            let surface = Surface {
                position,
                normal,
                view: -dir,
                perceptual_roughness: setup.perceptual_roughness,
            };
            Some(reflect_pixel_shadowed(
                &surface,
                &gpu,
                &images,
                &settings,
                &casters(),
            ))
        })
        .collect()
}

pub fn save(name: &str, image: &[[f32; 4]]) {
    let dir = penumbra_test::output_dir();
    std::fs::create_dir_all(&dir).unwrap();
    let peak = image
        .iter()
        .map(|p| p[0].max(p[1]).max(p[2]))
        .fold(1e-6f32, f32::max);
    let bytes: Vec<u8> = image
        .iter()
        .flat_map(|p| {
            let e = |c: f32| ((c / peak).clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0) as u8;
            [e(p[0]), e(p[1]), e(p[2]), 255]
        })
        .collect();
    penumbra_test::image::RgbaImage::from_raw(WIDTH, HEIGHT, bytes)
        .unwrap()
        .save(dir.join(format!("{name}.png")))
        .unwrap();
}

/// Mean and worst absolute difference (radiance relative to `EMISSIVE`, and coverage)
/// over the floor's pixels, and the count reflecting something.
pub fn compare(gpu: &[[f32; 4]], model: &[Option<Vec4>]) -> (f32, f32, usize, usize) {
    let (mut sum, mut worst, mut n, mut lit) = (0.0f32, 0.0f32, 0usize, 0usize);
    for (g, m) in gpu.iter().zip(model) {
        let Some(m) = m else { continue };
        let g = Vec4::from_array(*g);
        let d = ((g - *m) * Vec4::new(1.0 / EMISSIVE, 1.0 / EMISSIVE, 1.0 / EMISSIVE, 1.0))
            .abs()
            .max_element();
        sum += d;
        worst = worst.max(d);
        n += 1;
        lit += usize::from(m.w > 0.01);
    }
    (sum / n.max(1) as f32, worst, n, lit)
}
