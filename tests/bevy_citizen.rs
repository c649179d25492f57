//! Penumbra is opt-in: adding `PenumbraPlugins` changes nothing for cameras without a
//! Penumbra component, and a distance-field-shadowed light keeps its shadow map exactly
//! while something Bevy lights needs it.
//!
//! - Bit-identical renders with and without the plugins, for a forward camera (Bevy's
//!   default render method) and a deferred camera (the app's own deferred switch), on a
//!   scene with opaque, alpha-masked and alpha-blended `StandardMaterial`s, casters, and
//!   a directional and a point light with `DistanceFieldShadows` and shadow maps.
//!   Before this was fixed the plugins made deferred the global default (the forward
//!   camera showed only the clear colour) and switched the lights' shadow maps off
//!   everywhere (the deferred camera lost its shadows).
//! - Shadow maps of DF-shadowed lights: off when only Penumbra cameras with deferred
//!   materials look; on with an alpha-blended material in a Penumbra camera's view, and
//!   on with a second camera without `PenumbraLighting`.
//! - Plugins check their prerequisites; public types are registered for reflection.

use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
use bevy::pbr::{DefaultOpaqueRendererMethod, ExtractedDirectionalLight, ExtractedPointLight};
use bevy::prelude::*;
use bevy::render::RenderApp;
use penumbra::df::shadows::ShadowMapConsumers;
use penumbra::prelude::*;
use penumbra_test::{CaptureFormat, HeadlessRender, KeptApp, Tolerance, gpu_or_skip};

const SIZE: u32 = 96;

/// What the scene contains besides its opaque deferred-or-forward objects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Extras {
    /// An alpha-masked quad.
    masked: bool,
    /// An alpha-blended sphere.
    blended: bool,
    /// The blended sphere marked `ReadsNoShadowMaps`.
    unlit: bool,
    /// A `DistanceFieldParticles` emitter (blended, unlit discs).
    particles: bool,
}

fn spawn_scene(
    extras: Extras,
) -> impl Fn(Commands, ResMut<Assets<Mesh>>, ResMut<Assets<StandardMaterial>>) {
    move |mut commands, mut meshes, mut materials| {
        let matte = materials.add(StandardMaterial {
            base_color: Color::srgb(0.7, 0.7, 0.65),
            perceptual_roughness: 0.9,
            ..default()
        });
        let red = materials.add(Color::srgb(0.8, 0.2, 0.15));
        commands.spawn((
            Mesh3d(meshes.add(Plane3d::default().mesh().size(8.0, 8.0))),
            MeshMaterial3d(matte),
            DistanceFieldCaster {
                source: CasterSource::Plane,
                ..default()
            },
        ));
        commands.spawn((
            Mesh3d(meshes.add(Cuboid::new(0.8, 0.8, 0.8))),
            MeshMaterial3d(red),
            DistanceFieldCaster {
                source: CasterSource::Cuboid {
                    half_size: Vec3::splat(0.4),
                },
                ..default()
            },
            Transform::from_xyz(-0.6, 0.4, 0.0),
        ));
        if extras.masked {
            let masked = materials.add(StandardMaterial {
                base_color: Color::srgba(0.2, 0.7, 0.3, 0.8),
                alpha_mode: AlphaMode::Mask(0.5),
                double_sided: true,
                cull_mode: None,
                ..default()
            });
            commands.spawn((
                Mesh3d(meshes.add(Rectangle::new(0.9, 0.9))),
                MeshMaterial3d(masked),
                Transform::from_xyz(0.9, 0.6, -0.4),
            ));
        }
        if extras.blended {
            let blended = materials.add(StandardMaterial {
                base_color: Color::srgba(0.2, 0.4, 0.9, 0.5),
                alpha_mode: AlphaMode::Blend,
                ..default()
            });
            let mut sphere = commands.spawn((
                Mesh3d(meshes.add(Sphere::new(0.35).mesh().uv(24, 12))),
                MeshMaterial3d(blended),
                Transform::from_xyz(0.7, 0.35, 0.8),
            ));
            if extras.unlit {
                sphere.insert(ReadsNoShadowMaps);
            }
        }
        if extras.particles {
            commands.spawn((
                DistanceFieldParticles {
                    rate: 2000.0,
                    ..default()
                },
                Transform::from_xyz(0.0, 1.0, 0.0),
            ));
        }
        commands.spawn((
            DirectionalLight {
                illuminance: 6000.0,
                shadow_maps_enabled: true,
                ..default()
            },
            DistanceFieldShadows::default(),
            Transform::from_xyz(2.0, 5.0, 3.0).looking_at(Vec3::ZERO, Vec3::Y),
        ));
        commands.spawn((
            PointLight {
                intensity: 200_000.0,
                range: 12.0,
                radius: 0.1,
                shadow_maps_enabled: true,
                ..default()
            },
            DistanceFieldShadows::default(),
            Transform::from_xyz(-2.0, 2.5, 1.5),
        ));
    }
}

fn camera_transform() -> Transform {
    Transform::from_xyz(1.0, 2.5, 4.5).looking_at(Vec3::new(0.0, 0.3, 0.0), Vec3::Y)
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum UserCamera {
    /// Bevy's defaults: forward materials, MSAA 4×.
    Forward,
    /// The app made deferred the default and gave the camera a deferred prepass.
    Deferred,
}

/// The user's scene and camera (no Penumbra component on it), with or without Penumbra.
fn render_user_scene(camera: UserCamera, penumbra: bool) -> Vec<u8> {
    let harness = HeadlessRender::new(SIZE, SIZE)
        .format(CaptureFormat::LinearF16)
        .frames(8);
    let mut app = harness.app();
    if penumbra {
        app.add_plugins(PenumbraPlugins);
    }
    if camera == UserCamera::Deferred {
        app.insert_resource(DefaultOpaqueRendererMethod::deferred());
    }
    let extras = Extras {
        masked: true,
        blended: true,
        unlit: false,
        particles: false,
    };
    app.add_systems(Startup, spawn_scene(extras));
    app.add_systems(Startup, move |mut commands: Commands| {
        let mut entity = commands.spawn((Camera3d::default(), camera_transform()));
        if camera == UserCamera::Deferred {
            entity.insert((DeferredPrepass, DepthPrepass, Msaa::Off));
        }
    });
    harness.run(app).expect("renders").bytes
}

fn assert_identical(name: &str, camera: UserCamera) {
    let without = render_user_scene(camera, false);
    let with = render_user_scene(camera, true);
    let to_image = |bytes: &[u8]| {
        penumbra_test::Capture {
            width: SIZE,
            height: SIZE,
            format: CaptureFormat::LinearF16,
            bytes: bytes.to_vec(),
            frame_times: Vec::new(),
        }
        .to_rgba8()
    };
    penumbra_test::assert_not_blank(&to_image(&without));
    let differing = with
        .chunks_exact(8)
        .zip(without.chunks_exact(8))
        .filter(|(a, b)| a != b)
        .count();
    if differing > 0 {
        // Writes actual/expected/diff PNGs (panics if the 8-bit images differ too).
        penumbra_test::assert_images_match(
            name,
            &to_image(&with),
            &to_image(&without),
            &Tolerance::EXACT,
        );
        panic!("{name}: {differing} pixels differ in their f16 values");
    }
}

#[test]
fn forward_camera_renders_as_without_penumbra() {
    if !gpu_or_skip("forward_camera_renders_as_without_penumbra") {
        return;
    }
    assert_identical("citizen_forward", UserCamera::Forward);
}

#[test]
fn deferred_camera_renders_as_without_penumbra() {
    if !gpu_or_skip("deferred_camera_renders_as_without_penumbra") {
        return;
    }
    assert_identical("citizen_deferred", UserCamera::Deferred);
}

/// Renders a Penumbra camera (plus, optionally, a plain one) and returns the app.
fn render_penumbra(extras: Extras, second_camera: bool) -> KeptApp {
    let harness = HeadlessRender::new(64, 64).frames(4).without_pipelining();
    let mut app = harness.app();
    app.add_plugins(PenumbraPlugins)
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .add_systems(Startup, spawn_scene(extras));
    app.add_systems(Startup, move |mut commands: Commands| {
        commands.spawn((Camera3d::default(), PenumbraLighting, camera_transform()));
        if second_camera {
            commands.spawn((
                Camera3d::default(),
                Camera {
                    order: 1,
                    ..default()
                },
                Transform::from_xyz(0.0, 6.0, 0.1).looking_at(Vec3::ZERO, Vec3::Y),
            ));
        }
    });
    harness.run_keeping_app(app).expect("renders").1
}

/// Whether the render world's DF-shadowed lights render shadow maps (all agree).
fn shadow_maps_enabled(app: &mut KeptApp) -> bool {
    let world = app.sub_app_mut(RenderApp).world_mut();
    let mut enabled: Vec<bool> = world
        .query_filtered::<&ExtractedDirectionalLight, With<DistanceFieldShadows>>()
        .iter(world)
        .map(|l| l.shadow_maps_enabled)
        .collect();
    enabled.extend(
        world
            .query_filtered::<&ExtractedPointLight, With<DistanceFieldShadows>>()
            .iter(world)
            .map(|l| l.shadow_maps_enabled),
    );
    assert_eq!(enabled.len(), 2, "both lights are extracted");
    assert!(
        enabled.iter().all(|e| *e == enabled[0]),
        "lights disagree: {enabled:?}"
    );
    assert_eq!(
        world.resource::<ShadowMapConsumers>().forward_lit,
        enabled[0]
    );
    enabled[0]
}

#[test]
fn shadow_maps_are_skipped_when_no_one_reads_them() {
    if !gpu_or_skip("shadow_maps_are_skipped_when_no_one_reads_them") {
        return;
    }
    // Opaque deferred and alpha-masked deferred materials: all shaded by Penumbra.
    let extras = Extras {
        masked: true,
        blended: false,
        unlit: false,
        particles: false,
    };
    let mut app = render_penumbra(extras, false);
    assert!(!shadow_maps_enabled(&mut app));
}

#[test]
fn shadow_maps_are_kept_for_blended_materials() {
    if !gpu_or_skip("shadow_maps_are_kept_for_blended_materials") {
        return;
    }
    let extras = Extras {
        masked: false,
        blended: true,
        unlit: false,
        particles: false,
    };
    let mut app = render_penumbra(extras, false);
    assert!(shadow_maps_enabled(&mut app));
}

/// Blended meshes that read no shadow map — marked ones, Penumbra's particles — keep
/// none alive.
#[test]
fn shadow_maps_are_skipped_for_unlit_blended_meshes() {
    if !gpu_or_skip("shadow_maps_are_skipped_for_unlit_blended_meshes") {
        return;
    }
    let extras = Extras {
        masked: false,
        blended: true,
        unlit: true,
        particles: true,
    };
    let mut app = render_penumbra(extras, false);
    assert!(!shadow_maps_enabled(&mut app));
}

#[test]
fn shadow_maps_are_kept_for_other_cameras() {
    if !gpu_or_skip("shadow_maps_are_kept_for_other_cameras") {
        return;
    }
    let extras = Extras {
        masked: false,
        blended: false,
        unlit: false,
        particles: false,
    };
    let mut app = render_penumbra(extras, true);
    assert!(shadow_maps_enabled(&mut app));
}

/// A `PenumbraLighting` camera while materials render forward by default fails at
/// startup, naming the fix.
#[test]
#[should_panic(expected = "DefaultOpaqueRendererMethod::deferred()")]
fn penumbra_camera_without_deferred_materials_fails_loudly() {
    if !gpu_or_skip("penumbra_camera_without_deferred_materials_fails_loudly") {
        panic!("skipped: DefaultOpaqueRendererMethod::deferred()");
    }
    let harness = HeadlessRender::new(32, 32).frames(1).without_pipelining();
    let mut app = harness.app();
    app.add_plugins(PenumbraPlugins);
    app.add_systems(Startup, |mut commands: Commands| {
        commands.spawn((Camera3d::default(), PenumbraLighting));
    });
    let _ = harness.run(app);
}

/// Plugins added without their prerequisites panic in `build`, naming the missing one.
#[test]
#[should_panic(expected = "DistanceFieldDebugPlugin needs DistanceFieldScenePlugin")]
fn debug_view_without_scene_plugin_names_it() {
    App::new()
        .add_plugins(MinimalPlugins)
        .add_plugins(penumbra::df::DistanceFieldDebugPlugin);
}

#[test]
#[should_panic(expected = "DistanceFieldShadowsPlugin needs DistanceFieldScenePlugin")]
fn shadows_without_scene_plugin_names_it() {
    App::new()
        .add_plugins(MinimalPlugins)
        .add_plugins(penumbra::df::DistanceFieldShadowsPlugin);
}

#[test]
#[should_panic(expected = "SdfAssetPlugin needs AssetPlugin")]
fn sdf_assets_without_asset_plugin_names_it() {
    App::new()
        .add_plugins(MinimalPlugins)
        .add_plugins(SdfAssetPlugin);
}

/// Every public component and resource is registered for reflection, with its
/// `ReflectComponent` / `ReflectResource` data (editors and inspectors need both).
#[test]
fn public_types_are_reflect_registered() {
    use bevy::ecs::reflect::{AppTypeRegistry, ReflectComponent, ReflectResource};
    use penumbra::df;
    use std::any::TypeId;
    if !gpu_or_skip("public_types_are_reflect_registered") {
        return;
    }
    let app = {
        let mut app = HeadlessRender::new(8, 8).app();
        app.add_plugins(PenumbraPlugins);
        app
    };
    let registry = app.world().resource::<AppTypeRegistry>().read();
    let components: [(TypeId, &str); 11] = [
        (TypeId::of::<DistanceFieldCaster>(), "DistanceFieldCaster"),
        (TypeId::of::<BokehDepthOfField>(), "BokehDepthOfField"),
        (
            TypeId::of::<DistanceFieldDebugView>(),
            "DistanceFieldDebugView",
        ),
        (TypeId::of::<DistanceFieldShadows>(), "DistanceFieldShadows"),
        (TypeId::of::<PenumbraLighting>(), "PenumbraLighting"),
        (TypeId::of::<SdfBakeRequest>(), "SdfBakeRequest"),
        (TypeId::of::<SdfBakeTask>(), "SdfBakeTask"),
        (TypeId::of::<SdfBaked>(), "SdfBaked"),
        (TypeId::of::<df::SdfBakeWaiting>(), "SdfBakeWaiting"),
        (TypeId::of::<SdfBakeFailed>(), "SdfBakeFailed"),
        (
            TypeId::of::<df::lighting::PenumbraLightingView>(),
            "PenumbraLightingView",
        ),
    ];
    let resources: [(TypeId, &str); 8] = [
        (TypeId::of::<DistanceFieldScene>(), "DistanceFieldScene"),
        (
            TypeId::of::<DistanceFieldSceneSettings>(),
            "DistanceFieldSceneSettings",
        ),
        (
            TypeId::of::<DistanceFieldUploadStats>(),
            "DistanceFieldUploadStats",
        ),
        (TypeId::of::<df::SdfBakeCache>(), "SdfBakeCache"),
        (TypeId::of::<df::SdfBakeStats>(), "SdfBakeStats"),
        (
            TypeId::of::<df::PenumbraGpuAllocations>(),
            "PenumbraGpuAllocations",
        ),
        (
            TypeId::of::<df::PenumbraShaderLibrary>(),
            "PenumbraShaderLibrary",
        ),
        (TypeId::of::<ShadowMapConsumers>(), "ShadowMapConsumers"),
    ];
    let mut missing = Vec::new();
    for (id, name) in components {
        if registry.get_type_data::<ReflectComponent>(id).is_none() {
            missing.push(name);
        }
    }
    for (id, name) in resources {
        if registry.get_type_data::<ReflectResource>(id).is_none() {
            missing.push(name);
        }
    }
    assert!(missing.is_empty(), "not reflect-registered: {missing:?}");
}
