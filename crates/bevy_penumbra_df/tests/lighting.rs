//! Penumbra's lighting pass reproduces Bevy's own deferred lighting: the same scene —
//! a directional light with cascaded shadow maps, a shadowed point light, a shadowed
//! spot light, ambient light, emissive, metallic and clearcoat materials — rendered
//! with Bevy's deferred pass and with Penumbra's gives a bit-identical image (HDR,
//! linear f16 values compared). A second scene adds an environment map, distance fog
//! and SSAO.

use bevy::camera::Hdr;
use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::GlobalAmbientLight;
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::prelude::*;
use bevy_penumbra_df::{PenumbraLighting, PenumbraLightingPlugin};
use penumbra_test::{CaptureFormat, HeadlessRender, gpu_or_skip, image};

const SIZE: u32 = 128;

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Lighting {
    Bevy,
    Penumbra,
}

fn scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let plane = meshes.add(Plane3d::default().mesh().size(12.0, 12.0));
    let sphere = meshes.add(Sphere::new(0.6).mesh().uv(48, 24));
    let cube = meshes.add(Cuboid::new(0.9, 0.9, 0.9));
    let matte = materials.add(StandardMaterial {
        base_color: Color::srgb(0.55, 0.6, 0.62),
        perceptual_roughness: 0.9,
        ..default()
    });
    let metal = materials.add(StandardMaterial {
        base_color: Color::srgb(0.9, 0.6, 0.3),
        metallic: 1.0,
        perceptual_roughness: 0.35,
        ..default()
    });
    let coated = materials.add(StandardMaterial {
        base_color: Color::srgb(0.2, 0.3, 0.8),
        perceptual_roughness: 0.6,
        clearcoat: 0.8,
        clearcoat_perceptual_roughness: 0.2,
        ..default()
    });
    let glowing = materials.add(StandardMaterial {
        base_color: Color::srgb(0.3, 0.3, 0.3),
        emissive: LinearRgba::rgb(2000.0, 600.0, 100.0),
        ..default()
    });
    commands.spawn((Mesh3d(plane), MeshMaterial3d(matte)));
    commands.spawn((
        Mesh3d(sphere.clone()),
        MeshMaterial3d(metal),
        Transform::from_xyz(-1.2, 0.6, 0.0),
    ));
    commands.spawn((
        Mesh3d(cube),
        MeshMaterial3d(coated),
        Transform::from_xyz(1.0, 0.45, -0.4).with_rotation(Quat::from_rotation_y(0.5)),
    ));
    commands.spawn((
        Mesh3d(sphere),
        MeshMaterial3d(glowing),
        Transform::from_xyz(0.2, 0.3, 1.2).with_scale(Vec3::splat(0.4)),
    ));
    commands.spawn((
        DirectionalLight {
            illuminance: 4000.0,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(3.0, 6.0, 2.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    commands.spawn((
        PointLight {
            intensity: 300_000.0,
            range: 20.0,
            color: Color::srgb(1.0, 0.8, 0.6),
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(-2.5, 2.5, 1.5),
    ));
    commands.spawn((
        SpotLight {
            intensity: 600_000.0,
            range: 20.0,
            color: Color::srgb(0.6, 0.8, 1.0),
            outer_angle: 0.6,
            inner_angle: 0.4,
            shadow_maps_enabled: true,
            ..default()
        },
        Transform::from_xyz(2.5, 3.5, 2.5).looking_at(Vec3::new(0.5, 0.0, 0.0), Vec3::Y),
    ));
}

/// `extras`: an environment map light, distance fog and SSAO on the camera.
fn render(lighting: Lighting, extras: bool) -> Vec<[f32; 4]> {
    let harness = HeadlessRender::new(SIZE, SIZE)
        .format(CaptureFormat::LinearF16)
        // Spot-light shadow maps were missing in some runs after 4 frames; 8 is stable.
        .frames(8);
    let mut app = harness.app();
    app.insert_resource(GlobalAmbientLight {
        color: Color::srgb(0.7, 0.8, 1.0),
        brightness: 400.0,
        ..default()
    });
    match lighting {
        Lighting::Bevy => {
            app.insert_resource(DefaultOpaqueRendererMethod::deferred());
        }
        Lighting::Penumbra => {
            app.add_plugins(PenumbraLightingPlugin::default())
                .insert_resource(DefaultOpaqueRendererMethod::deferred());
        }
    }
    // One spawn order (entity ids order Bevy's lights) for both renders.
    let camera = move |mut commands: Commands, mut images: ResMut<Assets<Image>>| {
        let mut camera = commands.spawn((
            Camera3d::default(),
            Hdr,
            Tonemapping::None,
            Msaa::Off,
            Transform::from_xyz(1.5, 3.0, 5.5).looking_at(Vec3::new(0.0, 0.4, 0.0), Vec3::Y),
        ));
        match lighting {
            Lighting::Bevy => camera.insert((DeferredPrepass, DepthPrepass)),
            Lighting::Penumbra => camera.insert(PenumbraLighting),
        };
        if extras {
            let mut environment = EnvironmentMapLight::hemispherical_gradient(
                &mut images,
                Color::srgb(0.4, 0.6, 1.0),
                Color::srgb(0.8, 0.8, 0.7),
                Color::srgb(0.3, 0.25, 0.2),
            );
            environment.intensity = 600.0;
            camera.insert((
                environment,
                DistanceFog {
                    color: Color::srgb(0.5, 0.55, 0.6),
                    falloff: FogFalloff::Linear {
                        start: 4.0,
                        end: 14.0,
                    },
                    ..default()
                },
                bevy::pbr::ScreenSpaceAmbientOcclusion::default(),
            ));
        }
    };
    app.add_systems(Startup, (scene, camera).chain());
    harness.run(app).expect("renders").to_linear()
}

/// Per-pixel absolute difference of the RGB channels relative to the brighter pixel's
/// largest channel (so bright emissive and dark shadowed pixels weigh alike).
fn relative_differences(a: &[[f32; 4]], b: &[[f32; 4]]) -> Vec<f32> {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            let scale = x[..3]
                .iter()
                .chain(&y[..3])
                .fold(1e-3f32, |m, v| m.max(v.abs()));
            (0..3).map(|c| (x[c] - y[c]).abs()).fold(0.0, f32::max) / scale
        })
        .collect()
}

#[test]
fn penumbra_lighting_matches_bevy_deferred_lighting() {
    compare("penumbra_lighting_matches_bevy_deferred_lighting", false);
}

#[test]
fn with_environment_map_fog_and_ssao_too() {
    compare("with_environment_map_fog_and_ssao_too", true);
}

fn compare(name: &str, extras: bool) {
    if !gpu_or_skip(name) {
        return;
    }
    let bevy = render(Lighting::Bevy, extras);
    let penumbra = render(Lighting::Penumbra, extras);
    let lit = bevy
        .iter()
        .filter(|p| p[..3].iter().any(|&v| v > 1e-4))
        .count();
    assert!(
        lit > bevy.len() / 2,
        "Bevy's image is mostly black: {lit} lit pixels"
    );
    let mut d = relative_differences(&bevy, &penumbra);
    d.sort_by(f32::total_cmp);
    let mean = d.iter().sum::<f32>() / d.len() as f32;
    let p99 = d[d.len() * 99 / 100];
    let max = d[d.len() - 1];
    println!(
        "{name}: Penumbra vs Bevy deferred, relative difference: mean {mean:.2e}, p99 {p99:.2e}, \
         max {max:.2e}"
    );
    // Bit-identical, as documented: the same shading functions on the same inputs in
    // the same order. Any difference (a term left out, a different BRDF path) fails.
    if max != 0.0 {
        for (label, pixels) in [("bevy", &bevy), ("penumbra", &penumbra)] {
            let path = penumbra_test::output_dir().join(format!("{name}_{label}.png"));
            let _ = std::fs::create_dir_all(path.parent().expect("has a parent"));
            to_png(pixels).save(&path).expect("write PNG");
            eprintln!("wrote {}", path.display());
        }
        panic!("{name}: mean {mean}, p99 {p99}, max {max}");
    }
}

/// Reinhard-mapped sRGB preview of a linear image (for failure reports).
fn to_png(pixels: &[[f32; 4]]) -> image::RgbaImage {
    let encode = |v: f32| {
        let c = (v / (1.0 + v)).clamp(0.0, 1.0);
        (255.0 * c.powf(1.0 / 2.2) + 0.5) as u8
    };
    image::RgbaImage::from_fn(SIZE, SIZE, |x, y| {
        let p = pixels[(y * SIZE + x) as usize];
        image::Rgba([encode(p[0]), encode(p[1]), encode(p[2]), 255])
    })
}

/// A `PenumbraLighting` camera with `DeferredMsaa` keeps its MSAA: Bevy would switch it
/// off on a deferred camera; Penumbra's deferred MSAA serves it (Bevy's deferred pass is
/// skipped), and the image is rendered. One without `DeferredMsaa` but with Bevy's
/// default `Msaa::Sample4` renders without MSAA, as before (the opt-in is explicit).
#[test]
fn msaa_is_served_to_deferred_msaa_cameras_only() {
    use bevy::render::RenderApp;
    use bevy_penumbra_df::lighting::DeferredMsaa;
    if !gpu_or_skip("msaa_is_served_to_deferred_msaa_cameras_only") {
        return;
    }
    for opt_in in [true, false] {
        let harness = HeadlessRender::new(64, 64).without_pipelining().frames(3);
        let mut app = harness.app();
        app.add_plugins(PenumbraLightingPlugin::default())
            .insert_resource(DefaultOpaqueRendererMethod::deferred());
        app.add_systems(Startup, scene);
        app.add_systems(Startup, move |mut commands: Commands| {
            let mut camera = commands.spawn((
                Camera3d::default(),
                PenumbraLighting,
                Msaa::Sample4,
                Transform::from_xyz(1.5, 3.0, 5.5).looking_at(Vec3::ZERO, Vec3::Y),
            ));
            if opt_in {
                camera.insert(DeferredMsaa::default());
            }
        });
        let (capture, mut app) = harness.run_keeping_app(app).expect("renders");
        penumbra_test::assert_not_blank(&capture.to_rgba8());
        let msaa: Vec<Msaa> = app
            .world_mut()
            .query_filtered::<&Msaa, With<PenumbraLighting>>()
            .iter(app.world())
            .copied()
            .collect();
        let expected = if opt_in { Msaa::Sample4 } else { Msaa::Off };
        assert_eq!(msaa, [expected]);
        let render_world = app.sub_app_mut(RenderApp).world_mut();
        let served: Vec<bool> = render_world
            .query_filtered::<&bevy_penumbra_df::lighting::PenumbraLightingView, (
                With<bevy::pbr::deferred::SkipDeferredLighting>,
                With<bevy::render::view::ExtractedView>,
            )>()
            .iter(render_world)
            .map(|v| v.msaa.is_some())
            .collect();
        assert_eq!(
            served,
            [opt_in],
            "the camera is served, with MSAA: {opt_in}"
        );
    }
}

/// Only cameras with `PenumbraLighting` are served by Penumbra's lighting pass: Bevy's
/// component extraction queries every render-synced entity unless filtered, and before
/// the filter the lights and any other camera got the marker (and
/// `SkipDeferredLighting`, which turns Bevy's deferred lighting off).
#[test]
fn only_penumbra_cameras_get_the_lighting_marker() {
    if !gpu_or_skip("only_penumbra_cameras_get_the_lighting_marker") {
        return;
    }
    use bevy::render::RenderApp;
    use bevy::render::sync_world::MainEntity;
    use bevy_penumbra_df::lighting::PenumbraLightingView;
    let render = HeadlessRender::new(32, 32).frames(2).without_pipelining();
    let mut app = render.app();
    app.add_plugins(PenumbraLightingPlugin::default())
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .add_systems(Startup, scene);
    let penumbra = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            PenumbraLighting,
            Msaa::Off,
            Transform::from_xyz(0.0, 2.0, 6.0).looking_at(Vec3::ZERO, Vec3::Y),
        ))
        .id();
    // A second, plain deferred camera.
    app.world_mut().spawn((
        Camera3d::default(),
        Camera {
            order: 1,
            ..default()
        },
        DeferredPrepass,
        DepthPrepass,
        Msaa::Off,
        Transform::from_xyz(4.0, 2.0, 0.0).looking_at(Vec3::ZERO, Vec3::Y),
    ));
    let (_, mut app) = render.run_keeping_app(app).unwrap();
    let world = app.sub_app_mut(RenderApp).world_mut();
    let marked: Vec<Entity> = world
        .query_filtered::<&MainEntity, With<PenumbraLightingView>>()
        .iter(world)
        .map(|m| m.id())
        .collect();
    let skipping = world
        .query_filtered::<(), With<bevy::pbr::deferred::SkipDeferredLighting>>()
        .iter(world)
        .count();
    assert_eq!(marked, vec![penumbra], "marked render entities");
    assert_eq!(skipping, 1, "entities skipping Bevy's deferred lighting");
}
