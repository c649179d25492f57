//! `BillboardReflectionsPlugin` in a Bevy app on lavapipe, end to end. The scene: a
//! wide floor (y = 0) seen from 1.2 m up; two billboards standing on it, facing the
//! camera (a striped sign with a transparent hole and a half-transparent band, and a
//! larger sign behind it, so reflections composite two layers), and a third facing
//! away (one-sided: never reflected). The billboards draw nothing themselves. Linear HDR
//! capture, no tonemapping.
//!
//! - Contract: the specular layer (debug view) against the CPU model
//!   (`penumbra_cinematic_core::reflections::pass::reflect_pixel`) on the floor's
//!   pixels, from the analytic floor (position, normal, view) — glossy and anisotropic.
//! - Opt-in: a camera without the component renders bit for bit as without the plugin;
//!   with the component, pixels whose reflection misses every billboard are unchanged.
//! - Skip: no billboard → no pass and no allocation; steady frames allocate nothing.

use bevy::asset::RenderAssetUsages;
use bevy::camera::Hdr;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::image::Image;
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;
use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
use bevy_penumbra_cinematic::{
    BillboardReflections, BillboardReflectionsPlugin, ReflectionBillboard, ReflectionDebugView,
};
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldScenePlugin, PenumbraGpuAllocations,
    PenumbraLighting, PenumbraLightingPlugin, SdfAssetPlugin,
};
use penumbra_cinematic_core::reflections::Billboard;
use penumbra_cinematic_core::reflections::pass::{
    GpuBillboard, ReflectionUniform, Surface, reflect_pixel_shadowed, upsample_half,
};
use penumbra_cinematic_core::reflections::texture::MipChain;
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_test::{CaptureFormat, HeadlessRender, KeptApp, gpu_or_skip};

const WIDTH: u32 = 128;
const HEIGHT: u32 = 96;
const EYE: Vec3 = Vec3::new(0.0, 1.2, 3.0);
const TARGET: Vec3 = Vec3::new(0.0, 0.2, -2.0);
/// A box standing on the floor in front of the reflections (its faces reflect too; its
/// silhouette is a depth edge for the half-resolution upsample).
const BOX_CENTER: Vec3 = Vec3::new(-0.2, 0.25, -0.9);
const BOX_HALF: f32 = 0.25;
/// A wall between the striped sign and the floor before it (a distance-field caster
/// when the setup asks for it): reflection shadows.
const WALL_CENTER: Vec3 = Vec3::new(-0.7, 0.3, -1.9);
const WALL_HALF: Vec3 = Vec3::new(0.5, 0.3, 0.05);
/// The floor's half size.
const FLOOR_HALF: f32 = 20.0;
/// The images' size.
const IMAGE: UVec2 = UVec2::new(16, 8);
/// cd/m² of a texel of 1 (small: the layer is compared unexposed in f16).
const EMISSIVE: f32 = 4.0;

#[derive(Clone, Copy, Debug)]
struct Setup {
    /// `BillboardReflectionsPlugin` in the app.
    plugin: bool,
    /// `BillboardReflections` on the camera (with this debug view).
    reflections: Option<ReflectionDebugView>,
    /// The billboards exist.
    billboards: bool,
    perceptual_roughness: f32,
    anisotropy: f32,
    half_resolution: bool,
    /// The wall (a distance-field caster: reflection shadows).
    wall: bool,
    /// Billboards added behind the scene's (timing).
    extra_billboards: u32,
    /// `BillboardReflections::max_layers`.
    max_layers: u32,
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
            extra_billboards: 0,
            max_layers: 3,
        }
    }
}

/// The billboards: transform, size, image (straight-alpha linear texels, `IMAGE`).
fn billboards() -> Vec<(Transform, Vec2, Vec<Vec4>)> {
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

fn image_of(texels: &[Vec4]) -> Image {
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
fn scene(
    setup: Setup,
) -> impl Fn(Commands, ResMut<Assets<Mesh>>, ResMut<Assets<StandardMaterial>>, ResMut<Assets<Image>>)
{
    move |mut commands, mut meshes, mut materials, mut images| {
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
            commands.spawn((
                Mesh3d(meshes.add(Cuboid::from_size(2.0 * WALL_HALF))),
                MeshMaterial3d(materials.add(StandardMaterial {
                    base_color: Color::linear_rgb(0.1, 0.1, 0.1),
                    perceptual_roughness: setup.perceptual_roughness,
                    ..default()
                })),
                Transform::from_translation(WALL_CENTER),
                DistanceFieldCaster {
                    source: CasterSource::Cuboid {
                        half_size: WALL_HALF,
                    },
                    ..default()
                },
            ));
        }
        if setup.billboards {
            let mut handles = Vec::new();
            for (transform, size, texels) in billboards() {
                let image = images.add(image_of(&texels));
                handles.push(image.clone());
                commands.spawn((
                    ReflectionBillboard {
                        image,
                        size,
                        emissive: EMISSIVE,
                    },
                    transform,
                ));
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
        if let Some(debug_view) = setup.reflections {
            camera.insert(BillboardReflections {
                debug_view,
                anisotropy: setup.anisotropy,
                half_resolution: setup.half_resolution,
                max_layers: setup.max_layers,
                ..default()
            });
        }
    }
}

fn render(setup: Setup) -> (Vec<[f32; 4]>, KeptApp) {
    let harness = HeadlessRender::new(WIDTH, HEIGHT)
        .format(CaptureFormat::LinearF16)
        .frames(5);
    let (capture, app) = render_with(setup, &harness);
    (capture.to_linear(), app)
}

fn render_with(setup: Setup, harness: &HeadlessRender) -> (penumbra_test::Capture, KeptApp) {
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
        .add_systems(Startup, scene(setup));
    harness.run_keeping_app(app).expect("renders")
}

fn test_camera() -> PerspectiveCamera {
    PerspectiveCamera::looking_at(
        EYE,
        TARGET,
        PerspectiveProjection::default().fov,
        WIDTH,
        HEIGHT,
    )
}

/// The boxes in the scene (centre, half size): the box, and the wall when asked for.
fn boxes(wall: bool) -> Vec<(Vec3, Vec3)> {
    let mut v = vec![(BOX_CENTER, Vec3::splat(BOX_HALF))];
    if wall {
        v.push((WALL_CENTER, WALL_HALF));
    }
    v
}

/// What pixel `p` sees, analytically: a box or the floor (position, unit normal, view
/// depth, the unit ray), or `None` for the sky.
fn analytic_surface(p: IVec2, wall: bool) -> Option<(Vec3, Vec3, f32, Vec3)> {
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

/// The wall's exact distance (the distance-field caster's cuboid), metres.
fn wall_distance(p: Vec3) -> f32 {
    let q = (p - WALL_CENTER).abs() - WALL_HALF;
    q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
}

/// The layer the model predicts at every pixel (the floor's analytic G-buffer; `None`
/// where the pixel sees the sky).
fn model(setup: Setup) -> Vec<Option<Vec4>> {
    model_with(setup, setup.wall)
}

/// [`model`], with or without reflection shadows.
fn model_with(setup: Setup, shadows: bool) -> Vec<Option<Vec4>> {
    let mut gpu = Vec::new();
    let mut images = Vec::new();
    for (transform, size, texels) in billboards() {
        let quad = Billboard::from_transform(transform.to_matrix(), size).unwrap();
        gpu.push(GpuBillboard {
            center: quad.center,
            layer: images.len() as u32,
            half_x: quad.half_x,
            emissive: EMISSIVE,
            half_y: quad.half_y,
            reserved: 0,
        });
        images.push(MipChain::from_straight_alpha(IMAGE.x, IMAGE.y, &texels));
    }
    let mut settings =
        ReflectionUniform::new(gpu.len() as u32, IMAGE, images[0].levels.len() as u32);
    settings.anisotropy = setup.anisotropy;
    if shadows {
        settings.shadow_steps = 32;
        settings.object_count = 1;
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
                wall_distance,
            ))
        })
        .collect()
}

fn save(name: &str, image: &[[f32; 4]]) {
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
fn compare(gpu: &[[f32; 4]], model: &[Option<Vec4>]) -> (f32, f32, usize, usize) {
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

#[test]
fn the_layer_matches_the_model() {
    if !gpu_or_skip("the_layer_matches_the_model") {
        return;
    }
    for setup in [
        Setup::default(),
        Setup {
            perceptual_roughness: 0.5,
            ..default()
        },
        Setup {
            anisotropy: 0.8,
            ..default()
        },
        Setup {
            wall: true,
            ..default()
        },
    ] {
        let (gpu, _app) = render(setup);
        let model = model(setup);
        let name = format!(
            "reflections_layer_r{}_a{}{}",
            setup.perceptual_roughness,
            setup.anisotropy,
            if setup.wall { "_wall" } else { "" }
        );
        save(&name, &gpu);
        let model_image: Vec<[f32; 4]> = model
            .iter()
            .map(|m| m.unwrap_or(Vec4::ZERO).to_array())
            .collect();
        save(&format!("{name}_model"), &model_image);
        let (mean, worst, n, lit) = compare(&gpu, &model);
        println!(
            "{setup:?}: {n} floor pixels, {lit} reflecting; |GPU − model| mean {mean:.2e}, worst {worst:.2e}"
        );
        assert!(lit > 800, "{lit} pixels reflect a billboard");
        if setup.wall {
            // The wall shadows a good part of the striped sign's reflection.
            let unshadowed = model_with(setup, false);
            let shadowed = model
                .iter()
                .zip(&unshadowed)
                .filter(|(s, u)| match (s, u) {
                    (Some(s), Some(u)) => u.x > 0.2 * EMISSIVE && s.x < 0.5 * u.x,
                    _ => false,
                })
                .count();
            println!("  {shadowed} pixels lose more than half their reflection to the wall");
            assert!(shadowed > 100, "{shadowed} shadowed pixels");
        }
        assert!(mean < 2e-3 && worst < 0.05, "mean {mean}, worst {worst}");
    }
}

/// Bevy's `F_AB` (the polynomial: Penumbra's lighting pass does not bind the DFG LUT).
fn f_ab(perceptual_roughness: f32, n_dot_v: f32) -> Vec2 {
    let c0 = Vec4::new(-1.0, -0.0275, -0.572, 0.022);
    let c1 = Vec4::new(1.0, 0.0425, 1.04, -0.04);
    let r = perceptual_roughness * c0 + c1;
    let a004 = (r.x * r.x).min((-9.28 * n_dot_v).exp2()) * r.x + r.y;
    (Vec2::new(-1.04, 1.04) * a004 + Vec2::new(r.z, r.w)).max(Vec2::splat(0.00005))
}

/// The lighting pass adds the layer as specular under Bevy's environment BRDF: the
/// shaded floor minus the floor without the component is `exposure · FssEss · layer`
/// (no environment map: nothing to cover); pixels reflecting nothing are bit for bit
/// unchanged; and without the component the plugin changes nothing.
#[test]
fn the_layer_is_added_as_specular_only_where_it_reflects() {
    if !gpu_or_skip("the_layer_is_added_as_specular_only_where_it_reflects") {
        return;
    }
    let setup = Setup::default();
    let (without_plugin, app) = render(Setup {
        plugin: false,
        reflections: None,
        ..setup
    });
    drop(app);
    let (plain, app) = render(Setup {
        reflections: None,
        ..setup
    });
    drop(app);
    assert_eq!(
        plain, without_plugin,
        "a camera without the component changed"
    );
    let (layer, app) = render(setup);
    drop(app);
    let (shaded, _app) = render(Setup {
        reflections: Some(ReflectionDebugView::None),
        ..setup
    });
    save("reflections_shaded", &shaded);
    let exposure = 1.0 / 1.2;
    // Reflectance 0.5: F0 = 0.04; its pre-baked specular occlusion is 1.
    let f0 = 0.04;
    let (mut worst, mut checked, mut untouched) = (0.0f32, 0, 0);
    for i in 0..(WIDTH * HEIGHT) as usize {
        let (l, s, p) = (Vec4::from_array(layer[i]), shaded[i], plain[i]);
        if l == Vec4::ZERO {
            // Sky pixels show the clear colour in the debug view; floor pixels
            // reflecting nothing must be untouched.
            assert_eq!(s, p, "pixel {i} reflects nothing but changed");
            untouched += 1;
            continue;
        }
        if l.truncate().min_element() < 0.2 {
            continue; // too faint to compare through f16
        }
        let pixel = IVec2::new((i as u32 % WIDTH) as i32, (i as u32 / WIDTH) as i32);
        let Some((_, normal, _, dir)) = analytic_surface(pixel, false) else {
            continue;
        };
        let n_dot_v = (-dir.dot(normal)).max(1e-4);
        let ab = f_ab(setup.perceptual_roughness, n_dot_v);
        let brdf = f0 * ab.x + ab.y;
        for c in 0..3 {
            let want = exposure * brdf * l[c];
            let got = s[c] - p[c];
            // Less two f16 steps of the shaded values (the capture's rounding).
            let step = (2.0f32).powi(s[c].max(p[c]).log2().floor() as i32 - 10);
            let e = ((got - want).abs() - 2.0 * step).max(0.0) / want;
            worst = worst.max(e);
        }
        checked += 1;
    }
    println!(
        "added specular: {checked} pixels checked, worst relative error {worst:.4}; {untouched} untouched"
    );
    assert!(
        checked > 500 && untouched > 3000,
        "{checked} checked, {untouched} untouched"
    );
    // Beyond the capture's rounding, within the layer's own f16 rounding (0.1 %): a
    // layer added without the BRDF (10× here), or with the metallic F0, fails.
    assert!(worst < 0.01, "worst relative error {worst}");
}

/// Half resolution: each texel shades the top-left pixel of its 2 × 2 block, so those
/// pixels equal the full-resolution layer bit for bit; the others are interpolated
/// within the depth bounds, close to the full-resolution layer on average.
#[test]
fn half_resolution_upsamples_the_full_trace() {
    if !gpu_or_skip("half_resolution_upsamples_the_full_trace") {
        return;
    }
    let (full, app) = render(Setup::default());
    drop(app);
    let (half, _app) = render(Setup {
        half_resolution: true,
        ..default()
    });
    save("reflections_layer_half", &half);
    let (mut differ_even, mut sum_diff, mut sum_full) = (0, 0.0f32, 0.0f32);
    for y in 0..HEIGHT {
        for x in 0..WIDTH {
            let i = (y * WIDTH + x) as usize;
            let (f, h) = (Vec4::from_array(full[i]), Vec4::from_array(half[i]));
            if x % 2 == 0 && y % 2 == 0 && f != h {
                differ_even += 1;
            }
            sum_diff += (f - h).truncate().abs().element_sum();
            sum_full += f.truncate().abs().element_sum();
        }
    }
    let relative = sum_diff / sum_full;
    // Every pixel against the model of the upsample, from the GPU's own texels (the
    // even pixels) and the scene's analytic view depth.
    let view_z = |p: IVec2| analytic_surface(p, false).map_or(f32::NEG_INFINITY, |s| s.2);
    let texel = |t: IVec2| Vec4::from_array(half[(2 * t.y * WIDTH as i32 + 2 * t.x) as usize]);
    let half_size = IVec2::new(WIDTH as i32 / 2, HEIGHT as i32 / 2);
    let mut worst = 0.0f32;
    for y in 0..HEIGHT as i32 {
        for x in 0..WIDTH as i32 {
            let z = view_z(IVec2::new(x, y));
            if z == f32::NEG_INFINITY {
                continue; // no lighting pass there
            }
            let want = upsample_half(texel, view_z, half_size, IVec2::new(x, y), z);
            let got = Vec4::from_array(half[(y * WIDTH as i32 + x) as usize]);
            worst = worst.max(
                ((got - want) / Vec4::new(EMISSIVE, EMISSIVE, EMISSIVE, 1.0))
                    .abs()
                    .max_element(),
            );
        }
    }
    println!("half resolution: upsample against its model: worst {worst:.2e}");
    assert!(
        worst < 2e-3,
        "the upsample differs from its model by {worst}"
    );
    println!(
        "half resolution: {differ_even} even pixels differ; mean |half − full| / mean |full| {relative:.4}"
    );
    assert_eq!(
        differ_even, 0,
        "the traced pixels differ from the full-resolution trace"
    );
    assert!(
        relative < 0.1,
        "the upsampled layer is far from the full one: {relative}"
    );
}

/// No billboard: the camera's image and GPU allocations equal those without the
/// component; with billboards, steady frames allocate nothing.
#[test]
fn nothing_to_reflect_costs_nothing() {
    if !gpu_or_skip("nothing_to_reflect_costs_nothing") {
        return;
    }
    let empty = Setup {
        billboards: false,
        ..default()
    };
    let (without, app) = render(Setup {
        reflections: None,
        ..empty
    });
    let counts_without = app.world().resource::<PenumbraGpuAllocations>().counts();
    drop(app);
    let (with, app) = render(Setup {
        reflections: Some(ReflectionDebugView::None),
        ..empty
    });
    assert_eq!(without, with, "the image changed");
    assert_eq!(
        app.world().resource::<PenumbraGpuAllocations>().counts(),
        counts_without,
        "GPU resources created with nothing to reflect"
    );
    drop(app);
    let (_, mut app) = render(Setup {
        reflections: Some(ReflectionDebugView::None),
        ..default()
    });
    let allocations = app.world().resource::<PenumbraGpuAllocations>().clone();
    let before = allocations.counts();
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(allocations.counts(), before, "steady frames allocated");
}

/// Lavapipe's frame time against the billboard count and the settings (a measurement):
/// 384 × 288, the median of 10 frames after 4, 3 runs. `cargo test -p
/// bevy_penumbra_cinematic --test reflections_plugin reflections_against_time --
/// --ignored --nocapture`
#[test]
#[ignore = "a measurement (~2 min)"]
fn reflections_against_time() {
    if !gpu_or_skip("reflections_against_time") {
        return;
    }
    let harness = HeadlessRender::new(384, 288).frames(14);
    let median = |setup| {
        let (capture, _) = render_with(setup, &harness);
        let mut ms: Vec<f64> = capture.frame_times[4..]
            .iter()
            .map(|t| t.as_secs_f64() * 1e3)
            .collect();
        ms.sort_by(f64::total_cmp);
        ms[ms.len() / 2]
    };
    let shaded = Setup {
        reflections: Some(ReflectionDebugView::None),
        ..default()
    };
    for run in 0..3 {
        let mut line = format!(
            "run {run}: no component {:.1} ms",
            median(Setup {
                reflections: None,
                ..shaded
            })
        );
        for (name, setup) in [
            ("3 billboards", shaded),
            (
                "1 layer",
                Setup {
                    max_layers: 1,
                    ..shaded
                },
            ),
            (
                "half res",
                Setup {
                    half_resolution: true,
                    ..shaded
                },
            ),
            (
                "wall + shadows",
                Setup {
                    wall: true,
                    ..shaded
                },
            ),
            (
                "10",
                Setup {
                    extra_billboards: 8,
                    ..shaded
                },
            ),
            (
                "100",
                Setup {
                    extra_billboards: 98,
                    ..shaded
                },
            ),
            (
                "1000",
                Setup {
                    extra_billboards: 998,
                    ..shaded
                },
            ),
            (
                "1000 half res",
                Setup {
                    extra_billboards: 998,
                    half_resolution: true,
                    ..shaded
                },
            ),
        ] {
            line += &format!(", {name}: {:.1}", median(setup));
        }
        println!("{line}");
    }
}
