//! End to end on lavapipe: a light with `DistanceFieldShadows`, seen by a
//! `PenumbraLighting` camera, is dimmed by exactly the visibility the CPU model
//! (`penumbra_reference::shadow_mask::pixel_visibility`) computes for the plugin's own
//! object records.
//!
//! With no other light, no ambient light and no emissive, a pixel's radiance is linear
//! in the light's visibility: `v = shadowed / unshadowed` (the same scene rendered with
//! the light's shadows off). Measured on ground pixels, whose world position is exact
//! (the ray's hit on the plane), away from the objects' silhouettes.

use bevy::camera::Hdr;
use bevy::core_pipeline::tonemapping::Tonemapping;
use bevy::light::GlobalAmbientLight;
use bevy::prelude::*;
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldScene, DistanceFieldScenePlugin,
    DistanceFieldSceneSettings, DistanceFieldShadows, DistanceFieldShadowsPlugin,
    DistanceFieldUploadStats, PenumbraLighting, PenumbraLightingPlugin, SdfAssetPlugin,
    SdfVolumeAsset,
};
use penumbra_df_core::cull::CameraOrigin;
use penumbra_df_core::shadow::{ShadowLight, ShadowLightKind};
use penumbra_reference::analytic_volume;
use penumbra_reference::camera::PerspectiveCamera;
use penumbra_reference::df::{Atlas, object_distance};
use penumbra_reference::shadow_mask::pixel_visibility;
use penumbra_test::{CaptureFormat, HeadlessRender, KeptApp, gpu_or_skip};

const SIZE: u32 = 96;
const EYE: Vec3 = Vec3::new(1.0, 3.2, 5.0);
const TARGET: Vec3 = Vec3::new(0.0, 0.3, -0.5);
const SUN: Vec3 = Vec3::new(-0.45, 0.6, -0.65);
const LAMP: Vec3 = Vec3::new(0.8, 2.2, 0.6);
const SUN_DEGREES: f32 = 5.0;
const LAMP_RADIUS: f32 = 0.2;
const SPOT_TARGET: Vec3 = Vec3::new(-0.6, 0.0, -1.2);

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Light {
    Sun,
    Lamp,
    /// A spot light at the lamp's place, aimed past the casters.
    Spot,
    /// The sun, traced at half resolution.
    HalfResolutionSun,
}

/// How the sphere takes part.
#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Sphere {
    Visible,
    /// `Visibility::Hidden`: no shadow (as Bevy hides a hidden mesh's shadow).
    Hidden,
    /// Hidden, with `cast_hidden_shadow`: a shadow proxy.
    HiddenProxy,
    /// Visible, casting through a volume of its exact distances placed as sparse bricks
    /// (`true`) or dense.
    Volume {
        bricked: bool,
    },
}

fn settings(light: Light) -> DistanceFieldShadows {
    DistanceFieldShadows {
        angular_diameter: SUN_DEGREES.to_radians(),
        max_distance: 30.0,
        half_resolution: light == Light::HalfResolutionSun,
        ..default()
    }
}

/// The scene lit by one light, with distance-field shadows or with none.
fn render(light: Light, shadows: bool, sphere: Sphere) -> (Vec<[f32; 4]>, KeptApp) {
    let harness = HeadlessRender::new(SIZE, SIZE)
        .format(CaptureFormat::LinearF16)
        .frames(8);
    let mut app = harness.app();
    app.add_plugins((
        SdfAssetPlugin,
        DistanceFieldScenePlugin,
        PenumbraLightingPlugin::default(),
        DistanceFieldShadowsPlugin,
    ))
    .insert_resource(bevy::pbr::DefaultOpaqueRendererMethod::deferred())
    .insert_resource(GlobalAmbientLight {
        brightness: 0.0,
        ..default()
    })
    .insert_resource(DistanceFieldSceneSettings {
        sparse_min_bytes: if sphere == (Sphere::Volume { bricked: true }) {
            0
        } else {
            u64::MAX
        },
        ..default()
    });
    app.add_systems(
        Startup,
        move |mut commands: Commands,
              mut meshes: ResMut<Assets<Mesh>>,
              mut materials: ResMut<Assets<StandardMaterial>>,
              mut sdfs: ResMut<Assets<SdfVolumeAsset>>| {
            let matte = materials.add(StandardMaterial {
                base_color: Color::srgb(0.7, 0.7, 0.7),
                perceptual_roughness: 1.0,
                ..default()
            });
            let caster = |source| DistanceFieldCaster {
                source,
                ..default()
            };
            commands.spawn((
                Mesh3d(meshes.add(Plane3d::default().mesh().size(30.0, 30.0))),
                MeshMaterial3d(matte.clone()),
                caster(CasterSource::Plane),
            ));
            commands.spawn((
                Mesh3d(meshes.add(bevy::math::primitives::Sphere::new(0.5).mesh().uv(48, 24))),
                MeshMaterial3d(matte.clone()),
                Transform::from_xyz(-0.6, 0.8, -0.4),
                DistanceFieldCaster {
                    cast_hidden_shadow: sphere == Sphere::HiddenProxy,
                    ..caster(match sphere {
                        Sphere::Volume { .. } => CasterSource::Sdf(sdfs.add(SdfVolumeAsset {
                            volume: analytic_volume::sphere_for_bricks(0.5),
                        })),
                        _ => CasterSource::Sphere { radius: 0.5 },
                    })
                },
                if matches!(sphere, Sphere::Visible | Sphere::Volume { .. }) {
                    Visibility::Inherited
                } else {
                    Visibility::Hidden
                },
            ));
            commands.spawn((
                Mesh3d(meshes.add(Cuboid::new(0.6, 1.2, 0.6))),
                MeshMaterial3d(matte),
                Transform::from_xyz(0.9, 0.6, -0.9).with_rotation(Quat::from_rotation_y(0.5)),
                caster(CasterSource::Cuboid {
                    half_size: Vec3::new(0.3, 0.6, 0.3),
                }),
            ));
            let mut light_entity = match light {
                Light::Sun | Light::HalfResolutionSun => commands.spawn((
                    DirectionalLight {
                        illuminance: 2000.0,
                        shadow_maps_enabled: false,
                        ..default()
                    },
                    Transform::from_translation(SUN).looking_at(Vec3::ZERO, Vec3::Y),
                )),
                Light::Spot => commands.spawn((
                    SpotLight {
                        intensity: 200_000.0,
                        range: 20.0,
                        radius: LAMP_RADIUS,
                        shadow_maps_enabled: false,
                        inner_angle: 0.8,
                        outer_angle: 1.1,
                        ..default()
                    },
                    Transform::from_translation(LAMP).looking_at(SPOT_TARGET, Vec3::Y),
                )),
                Light::Lamp => commands.spawn((
                    PointLight {
                        intensity: 200_000.0,
                        range: 20.0,
                        radius: LAMP_RADIUS,
                        shadow_maps_enabled: false,
                        ..default()
                    },
                    Transform::from_translation(LAMP),
                )),
            };
            if shadows {
                light_entity.insert(settings(light));
            }
            commands.spawn((
                Camera3d::default(),
                PenumbraLighting,
                Msaa::Off,
                Hdr,
                Tonemapping::None,
                Transform::from_translation(EYE).looking_at(TARGET, Vec3::Y),
            ));
        },
    );
    let (capture, app) = harness.run_keeping_app(app).expect("renders");
    (capture.to_linear(), app)
}

fn check(light: Light, name: &str) {
    if !gpu_or_skip(name) {
        return;
    }
    check_with(light, name, Sphere::Visible);
}

/// Compares the image's visibility with the CPU model on the plugin's own records;
/// returns the number of ground pixels in shadow (visibility < ½) in the image.
fn check_with(light: Light, name: &str, sphere: Sphere) -> usize {
    let (lit, _) = render(light, false, sphere);
    let (shadowed, app) = render(light, true, sphere);
    let scene = app.world().resource::<DistanceFieldScene>();
    let records = scene.records().to_vec();
    assert_eq!(records.iter().filter(|r| r.flags() != 0).count(), 3);
    let atlas = Atlas::new(UVec3::ONE);
    let camera = CameraOrigin::at(EYE).expect("finite");
    let s = settings(light);
    let model = ShadowLight {
        kind: match light {
            Light::Sun | Light::HalfResolutionSun => ShadowLightKind::Directional(SUN.normalize()),
            Light::Lamp | Light::Spot => ShadowLightKind::Positional(LAMP - EYE),
        },
        source: match light {
            Light::Sun | Light::HalfResolutionSun => (0.5 * s.angular_diameter).tan(),
            Light::Lamp | Light::Spot => LAMP_RADIUS,
        },
        max_distance: s.max_distance,
        bias: s.bias,
        shaping: s.shaping,
        range: 20.0,
        max_steps: s.max_steps,
        max_view_distance: s.max_view_distance,
        // The spot light's cone, as the plugin passes it (outside it, no trace).
        spot: (light == Light::Spot).then(|| ((SPOT_TARGET - LAMP).normalize(), 1.1f32.cos())),
    };
    let view = PerspectiveCamera::looking_at(EYE, TARGET, std::f32::consts::FRAC_PI_4, SIZE, SIZE);
    // The first surface along a pixel's ray: `Some(point)` if it is the ground, away
    // from other objects' silhouettes (all four pixel corners also hit the ground).
    let ground = |px: f32, py: f32| -> Option<Vec3> {
        let hit = |x: f32, y: f32| -> Option<Vec3> {
            let ray = view.ray(x, y);
            let t_plane = -ray.origin.y / ray.dir.y;
            if t_plane.is_nan() || t_plane <= 0.0 {
                return None;
            }
            let mut t = 0.0;
            for _ in 0..200 {
                let p = ray.origin + ray.dir * t;
                let d = records
                    .iter()
                    .filter(|r| r.flags() != 0 && r.kind() != 4)
                    .map(|r| object_distance(r, p - EYE, &camera, &atlas))
                    .fold(f32::INFINITY, f32::min);
                if d < 2e-3 || t >= t_plane {
                    break;
                }
                t += d;
            }
            (t >= t_plane).then(|| ray.origin + ray.dir * t_plane)
        };
        let corners = [(-0.6, -0.6), (0.6, -0.6), (-0.6, 0.6), (0.6, 0.6)];
        corners
            .iter()
            .all(|&(dx, dy)| hit(px + dx, py + dy).is_some())
            .then(|| hit(px, py))?
    };
    let (mut diffs, mut shadowed_px, mut penumbra_px, mut gpu_shadowed) = (Vec::new(), 0, 0, 0);
    for y in 0..SIZE {
        for x in 0..SIZE {
            let i = (y * SIZE + x) as usize;
            let unshadowed = lit[i][1];
            if unshadowed < 1e-3 {
                continue; // unlit ground (a spot's outside, a back face)
            }
            let Some(p) = ground(x as f32 + 0.5, y as f32 + 0.5) else {
                continue;
            };
            let gpu = (shadowed[i][1] / unshadowed).clamp(0.0, 1.0);
            let cpu = pixel_visibility(&records, &atlas, &camera, p - EYE, Vec3::Y, &model);
            shadowed_px += usize::from(cpu < 0.5);
            gpu_shadowed += usize::from(gpu < 0.5);
            penumbra_px += usize::from(cpu > 0.05 && cpu < 0.95);
            diffs.push((gpu - cpu).abs());
        }
    }
    diffs.sort_by(f32::total_cmp);
    let n = diffs.len();
    let mean = diffs.iter().sum::<f32>() / n as f32;
    let p99 = diffs[n * 99 / 100];
    println!(
        "{name}: {n} ground pixels ({shadowed_px} shadowed, {penumbra_px} penumbra): \
         |image visibility − CPU model| mean {mean:.4}, p99 {p99:.4}, max {:.4}",
        diffs[n - 1]
    );
    assert!(
        n > 2000 && shadowed_px > 200 && penumbra_px > 50,
        "scene too unshadowed"
    );
    // Half resolution: the upsample's own error (bilinear across penumbrae).
    let (max_mean, max_p99) = if light == Light::HalfResolutionSun {
        (0.03, 0.3)
    } else {
        (0.01, 0.06)
    };
    assert!(mean < max_mean && p99 < max_p99, "mean {mean}, p99 {p99}");
    gpu_shadowed
}

/// A hidden caster casts no shadow; a hidden one with `cast_hidden_shadow` casts the
/// same shadow as a visible one (image = CPU model in each case).
#[test]
fn hidden_casters_cast_no_shadow_unless_they_are_proxies() {
    let name = "hidden_casters_cast_no_shadow_unless_they_are_proxies";
    if !gpu_or_skip(name) {
        return;
    }
    let visible = check_with(Light::Sun, name, Sphere::Visible);
    let hidden = check_with(Light::Sun, name, Sphere::Hidden);
    let proxy = check_with(Light::Sun, name, Sphere::HiddenProxy);
    println!("shadowed ground pixels: visible {visible}, hidden {hidden}, proxy {proxy}");
    assert!(hidden + 100 < visible, "the hidden sphere still shadows");
    assert_eq!(proxy, visible, "the proxy's shadow differs");
}

#[test]
fn half_resolution_visibility_stays_close_to_the_cpu_model() {
    check(
        Light::HalfResolutionSun,
        "half_resolution_visibility_stays_close_to_the_cpu_model",
    );
}

#[test]
fn directional_light_visibility_is_the_cpu_model() {
    check(Light::Sun, "directional_light_visibility_is_the_cpu_model");
}

#[test]
fn point_light_visibility_is_the_cpu_model() {
    check(Light::Lamp, "point_light_visibility_is_the_cpu_model");
}

#[test]
fn spot_light_visibility_is_the_cpu_model() {
    check(Light::Spot, "spot_light_visibility_is_the_cpu_model");
}

/// The sphere as a volume placed as sparse bricks shadows as the same volume placed
/// dense, for the sun and the lamp (the shadow pass binds the scene's brick table and
/// reads through it).
#[test]
fn a_bricked_volume_shadows_as_a_dense_one() {
    if !gpu_or_skip("a_bricked_volume_shadows_as_a_dense_one") {
        return;
    }
    for light in [Light::Sun, Light::Lamp] {
        let (lit, _) = render(light, false, Sphere::Visible);
        let image = |bricked| {
            let (image, app) = render(light, true, Sphere::Volume { bricked });
            let stats = app.world().resource::<DistanceFieldUploadStats>().clone();
            (image, (stats.atlas_volumes, stats.atlas_bricked))
        };
        let (dense, dense_counts) = image(false);
        let (bricked, bricked_counts) = image(true);
        assert_eq!((dense_counts, bricked_counts), ((1, 0), (1, 1)));
        // Visibility (the ratio to the unshadowed render) where the unshadowed render is
        // lit.
        let (mut diffs, mut shadowed) = (Vec::new(), 0);
        for ((d, b), l) in dense.iter().zip(&bricked).zip(&lit) {
            let l = l[0] + l[1] + l[2];
            if l > 1e-3 {
                let (d, b) = ((d[0] + d[1] + d[2]) / l, (b[0] + b[1] + b[2]) / l);
                shadowed += usize::from(d < 0.5);
                diffs.push((d - b).abs());
            }
        }
        let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
        let max = diffs.iter().copied().fold(0.0, f32::max);
        println!(
            "{light:?}: {} lit pixels, {shadowed} shadowed: |bricked − dense| visibility mean \
             {mean:.2e}, max {max:.2e}",
            diffs.len()
        );
        assert!(shadowed > 100, "{light:?}: {shadowed}");
        assert!(
            mean < 2e-3 && max < 0.1,
            "{light:?}: mean {mean}, max {max}"
        );
    }
}
