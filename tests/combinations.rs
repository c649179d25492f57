//! The combination matrix (#46): Penumbra's camera features in every pair on one camera,
//! and each with Bevy's bloom, distance fog, SSR, SSAO, `DepthOfField`, TAA, HDR off and
//! an orthographic projection. One app renders them all: each configuration's components go
//! on the camera (distance-field shadows on the sun), a few frames render, the image is
//! read back.
//!
//! For every configuration and every Penumbra feature in it, against the same
//! configuration without that feature:
//! - its contribution is still there: at least `min_changed` pixels differ (the floor's
//!   shadow, the occlusion at the box's foot, the sphere's skin, the edges, the sign's
//!   streak on the floor, the blurred background);
//! - where it does not act it changes nothing: the sky band at the top is equal;
//! - no warning is logged but the documented ones (`DOCUMENTED`: the combinations that
//!   cannot work, ARCHITECTURE.md's table), and no wgpu error.
//!
//! Bevy's TAA (`TemporalAntiAliasing`) is a context like the others; it is removed with
//! the jitter and mip bias it requires so that the next configuration does not inherit
//! them (its motion-vector prepass stays, as DFAO's does).
//!
//! `cargo test --test combinations -- --nocapture` prints each configuration's figures.

use bevy::anti_alias::taa::TemporalAntiAliasing;
use bevy::camera::{Hdr, ScalingMode};
use bevy::core_pipeline::tonemapping::DebandDither;
use bevy::light::GlobalAmbientLight;
use bevy::pbr::{
    DefaultOpaqueRendererMethod, DistanceFog, FogFalloff, ScreenSpaceAmbientOcclusion,
    ScreenSpaceReflections,
};
use bevy::post_process::bloom::Bloom;
use bevy::post_process::dof::DepthOfField;
use bevy::prelude::*;
use bevy::render::camera::{MipBias, TemporalJitter};
use penumbra::prelude::*;
use penumbra_test::{
    HeadlessRender, gpu_or_skip, image::RgbaImage, output_dir, take_render_errors, take_warnings,
};
use std::collections::{BTreeSet, HashMap};

const WIDTH: u32 = 96;
const HEIGHT: u32 = 72;
/// Rows at the top that show only sky.
const SKY_ROWS: u32 = 4;
/// Updates after a configuration changes, before the read-back.
const FRAMES: u32 = 5;
/// The sphere's distance from the camera (the depth of field's focus).
const FOCUS: f32 = 3.4;

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Feature {
    Shadows,
    Dfao,
    Msaa,
    Sss,
    Reflections,
    Bokeh,
}

impl Feature {
    const ALL: [Feature; 6] = [
        Feature::Shadows,
        Feature::Dfao,
        Feature::Msaa,
        Feature::Sss,
        Feature::Reflections,
        Feature::Bokeh,
    ];

    /// Pixels (of 6,912) that must change with the feature: its smallest footprint in
    /// this scene over the configurations (measured: shadows 86 px, DFAO 216, MSAA 207,
    /// SSS 108, reflections 227, bokeh 72) with a margin; a feature that is off, or acts
    /// on a wrong texture, changes none.
    fn min_changed(self) -> usize {
        match self {
            Feature::Shadows | Feature::Msaa => 60,
            Feature::Dfao => 100,
            Feature::Sss | Feature::Bokeh => 40,
            Feature::Reflections => 80,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
enum Context {
    None,
    Bloom,
    Fog,
    Ssr,
    Ssao,
    BevyDof,
    Taa,
    HdrOff,
    Ortho,
}

impl Context {
    const ALL: [Context; 9] = [
        Context::None,
        Context::Bloom,
        Context::Fog,
        Context::Ssr,
        Context::Ssao,
        Context::BevyDof,
        Context::Taa,
        Context::HdrOff,
        Context::Ortho,
    ];
}

/// The combinations that cannot work as asked: the feature is off there, with exactly one
/// warning (a substring of it here) and the reason (ARCHITECTURE.md's table). Any other
/// warning fails the test.
const DOCUMENTED: &[(Feature, Context, &str, &str)] = &[
    (
        Feature::Msaa,
        Context::Ssr,
        "has DeferredMsaa and Bevy's ScreenSpaceReflections",
        "Bevy's SSR reads single-sample depth and normals: MSAA is off while it is on",
    ),
    (
        Feature::Msaa,
        Context::Ssao,
        "has DeferredMsaa and Bevy's ScreenSpaceAmbientOcclusion",
        "Bevy's SSAO reads single-sample depth and normals: MSAA is off while it is on",
    ),
    (
        Feature::Msaa,
        Context::Taa,
        "has DeferredMsaa and a TemporalJitter",
        "Bevy's TAA pass skips a camera whose MSAA is on: MSAA is off while TAA is on",
    ),
    (
        Feature::Bokeh,
        Context::BevyDof,
        "also has Bevy's DepthOfField",
        "two lens blurs: Penumbra's is off while Bevy's is there",
    ),
    (
        Feature::Bokeh,
        Context::Ortho,
        "projection is not perspective",
        "a thin lens needs a perspective projection",
    ),
];

/// The documented warning of `feature` in `context`, if the pair cannot work.
fn documented(feature: Feature, context: Context) -> Option<&'static str> {
    DOCUMENTED
        .iter()
        .find(|(f, c, ..)| *f == feature && *c == context)
        .map(|(_, _, text, _)| *text)
}

#[derive(Component)]
struct TestCamera;

#[derive(Component)]
struct Sun;

fn scene(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    mut images: ResMut<Assets<Image>>,
    mut profiles: ResMut<SubsurfaceProfiles>,
) {
    // A glossy dark floor (it occludes and reflects).
    commands.spawn((
        Mesh3d(meshes.add(Plane3d::default().mesh().size(12.0, 12.0))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.12, 0.12, 0.13),
            perceptual_roughness: 0.15,
            ..default()
        })),
        DistanceFieldCaster {
            source: CasterSource::Plane,
            casts_shadows: false,
            ..default()
        },
    ));
    // A box casting the sun's shadow and occluding the floor at its foot.
    commands.spawn((
        Mesh3d(meshes.add(Cuboid::from_length(0.6))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.7, 0.7, 0.68),
            perceptual_roughness: 0.8,
            ..default()
        })),
        Transform::from_xyz(-0.8, 0.3, 0.0),
        DistanceFieldCaster {
            source: CasterSource::Cuboid {
                half_size: Vec3::splat(0.3),
            },
            ..default()
        },
    ));
    // A sphere of wax-like skin (a wide profile: visible at this size).
    let profile = profiles
        .add(SubsurfaceProfile {
            scatter_color: Color::srgb(0.95, 0.5, 0.35),
            radius: 0.05,
        })
        .expect("the first profile");
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(0.35).mesh().uv(32, 16))),
        MeshMaterial3d(materials.add(profile.apply(StandardMaterial {
            base_color: Color::srgb(0.85, 0.62, 0.52),
            perceptual_roughness: 0.5,
            ..default()
        }))),
        Transform::from_xyz(0.6, 0.35, 0.3),
        DistanceFieldCaster {
            source: CasterSource::Sphere { radius: 0.35 },
            ..default()
        },
    ));
    // A lit sign far behind: reflected on the floor, blurred by the depth of field.
    let texels: Vec<u8> = (0..16 * 8)
        .flat_map(|i| {
            let stripe = (i % 16) / 4 % 2 == 0;
            if stripe {
                [255, 200, 60, 255]
            } else {
                [60, 200, 255, 255]
            }
        })
        .collect();
    let image = images.add(Image::new(
        bevy::render::render_resource::Extent3d {
            width: 16,
            height: 8,
            depth_or_array_layers: 1,
        },
        bevy::render::render_resource::TextureDimension::D2,
        texels,
        bevy::render::render_resource::TextureFormat::Rgba8UnormSrgb,
        default(),
    ));
    let size = Vec2::new(1.6, 0.8);
    commands.spawn((
        ReflectionBillboard {
            image: image.clone(),
            size,
            emissive: 2000.0,
        },
        Mesh3d(meshes.add(Rectangle::from_size(size))),
        // Bevy's G-buffer keeps emissive light unexposed: the exposed luminance.
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::BLACK,
            emissive: LinearRgba::rgb(2.0, 2.0, 2.0),
            emissive_texture: Some(image),
            ..default()
        })),
        Transform::from_xyz(0.0, 0.9, -3.0),
    ));
    commands.spawn((
        Sun,
        DirectionalLight {
            illuminance: 10_000.0,
            shadow_maps_enabled: false,
            ..default()
        },
        Transform::default().looking_to(Vec3::new(0.8, -0.7, -0.3), Vec3::Y),
    ));
    commands.spawn((
        TestCamera,
        Camera3d::default(),
        PenumbraLighting,
        Msaa::Off,
        DebandDither::Disabled,
        Transform::from_xyz(0.3, 1.0, 3.6).looking_at(Vec3::new(0.0, 0.45, 0.0), Vec3::Y),
    ));
}

/// Puts a configuration's components on the camera and the sun (and takes the others
/// off).
fn apply(world: &mut World, features: &BTreeSet<Feature>, context: Context) {
    let camera = world
        .query_filtered::<Entity, With<TestCamera>>()
        .single(world)
        .expect("one camera");
    let sun = world
        .query_filtered::<Entity, With<Sun>>()
        .single(world)
        .expect("one sun");
    let mut c = world.entity_mut(camera);
    c.remove::<(
        DistanceFieldAmbientOcclusion,
        DeferredMsaa,
        SubsurfaceScattering,
        BillboardReflections,
        BokehDepthOfField,
    )>()
    .remove::<(
        Bloom,
        DistanceFog,
        ScreenSpaceReflections,
        ScreenSpaceAmbientOcclusion,
        DepthOfField,
        Hdr,
    )>()
    // Not `MotionVectorPrepass`: Bevy 0.19 keeps a camera's background motion-vector
    // pipeline after the prepass is removed (a wgpu error); DFAO adds it anyway.
    .remove::<(TemporalAntiAliasing, TemporalJitter, MipBias)>()
    .insert((Msaa::Off, Projection::Perspective(default())));
    for feature in features {
        match feature {
            Feature::Shadows => {}
            Feature::Dfao => {
                c.insert(DistanceFieldAmbientOcclusion {
                    max_occlusion_distance: 1.5,
                    ..default()
                });
            }
            Feature::Msaa => {
                c.insert((DeferredMsaa::default(), Msaa::Sample4));
            }
            Feature::Sss => {
                c.insert(SubsurfaceScattering::default());
            }
            Feature::Reflections => {
                c.insert(BillboardReflections::default());
            }
            Feature::Bokeh => {
                c.insert(BokehDepthOfField {
                    focal_distance: FOCUS,
                    aperture_f_stops: 0.25,
                    ..default()
                });
            }
        }
    }
    if context != Context::HdrOff {
        c.insert(Hdr);
    }
    match context {
        Context::None | Context::HdrOff => {}
        Context::Bloom => {
            c.insert(Bloom::NATURAL);
        }
        Context::Fog => {
            c.insert(DistanceFog {
                color: Color::srgb(0.35, 0.4, 0.5),
                falloff: FogFalloff::Linear {
                    start: 2.0,
                    end: 14.0,
                },
                ..default()
            });
        }
        Context::Ssr => {
            c.insert(ScreenSpaceReflections::default());
        }
        Context::Ssao => {
            c.insert(ScreenSpaceAmbientOcclusion::default());
        }
        Context::BevyDof => {
            c.insert(DepthOfField {
                focal_distance: FOCUS,
                aperture_f_stops: 0.25,
                ..default()
            });
        }
        Context::Taa => {
            c.insert(TemporalAntiAliasing::default());
        }
        Context::Ortho => {
            c.insert(Projection::Orthographic(OrthographicProjection {
                scaling_mode: ScalingMode::FixedVertical {
                    viewport_height: 3.0,
                },
                ..OrthographicProjection::default_3d()
            }));
        }
    }
    let mut s = world.entity_mut(sun);
    if features.contains(&Feature::Shadows) {
        s.insert(DistanceFieldShadows::default());
    } else {
        s.remove::<DistanceFieldShadows>();
    }
}

/// A configuration's name, for messages and file names.
fn name(features: &BTreeSet<Feature>, context: Context) -> String {
    let mut parts: Vec<String> = features.iter().map(|f| format!("{f:?}")).collect();
    if parts.is_empty() {
        parts.push("nothing".into());
    }
    format!("{}+{context:?}", parts.join("+"))
}

#[test]
fn every_pair_of_features_and_each_with_bevys_keeps_its_contribution() {
    if !gpu_or_skip("every_pair_of_features_and_each_with_bevys_keeps_its_contribution") {
        return;
    }
    let harness = HeadlessRender::new(WIDTH, HEIGHT).frames(FRAMES);
    let mut app = harness.app();
    app.add_plugins(PenumbraPlugins)
        .insert_resource(DefaultOpaqueRendererMethod::deferred())
        .insert_resource(ClearColor(Color::srgb(0.4, 0.55, 0.8)))
        .insert_resource(GlobalAmbientLight {
            color: Color::srgb(0.8, 0.85, 1.0),
            brightness: 400.0,
            ..default()
        })
        .add_systems(Startup, scene);
    let (_, mut app) = harness.run_keeping_app(app).expect("the scene renders");
    let _ = take_warnings();

    // The configurations: every pair in the plain context, each feature alone in every
    // context; with what they are compared against.
    let mut wanted: Vec<(BTreeSet<Feature>, Context)> = Vec::new();
    for (i, a) in Feature::ALL.iter().enumerate() {
        for b in &Feature::ALL[i + 1..] {
            wanted.push(([*a, *b].into(), Context::None));
        }
    }
    for context in Context::ALL {
        for f in Feature::ALL {
            wanted.push(([f].into(), context));
        }
    }
    let mut images: HashMap<(BTreeSet<Feature>, Context), RgbaImage> = HashMap::new();
    let mut render = |app: &mut App, features: &BTreeSet<Feature>, context: Context| {
        let key = (features.clone(), context);
        if let Some(image) = images.get(&key) {
            return (image.clone(), Vec::new());
        }
        apply(app.world_mut(), features, context);
        for _ in 0..FRAMES {
            app.update();
        }
        let capture = harness.read_target(app);
        let errors = take_render_errors();
        assert!(
            errors.is_empty(),
            "{}: wgpu errors {errors:?}",
            name(features, context)
        );
        let image = capture.expect("read back").to_rgba8();
        let _ =
            image.save(output_dir().join(format!("combination_{}.png", name(features, context))));
        images.insert(key, image.clone());
        (image, take_warnings())
    };
    let _ = std::fs::create_dir_all(output_dir());
    let mut failures = Vec::new();
    for (features, context) in &wanted {
        let (image, warnings) = render(&mut app, features, *context);
        let label = name(features, *context);
        let expected: Vec<&str> = features
            .iter()
            .filter_map(|f| documented(*f, *context))
            .collect();
        let undocumented: Vec<&String> = warnings
            .iter()
            .filter(|w| !expected.iter().any(|text| w.contains(text)))
            .collect();
        if !undocumented.is_empty() {
            failures.push(format!("{label}: warnings {undocumented:?}"));
        }
        for text in &expected {
            let n = warnings.iter().filter(|w| w.contains(text)).count();
            if n != 1 {
                failures.push(format!("{label}: {n} warnings {text:?} (one expected)"));
            }
        }
        for feature in features {
            if documented(*feature, *context).is_some() {
                continue; // off, with its warning
            }
            let mut without = features.clone();
            without.remove(feature);
            let (other, _) = render(&mut app, &without, *context);
            let differ = |x: u32, y: u32| {
                let (a, b) = (image.get_pixel(x, y), other.get_pixel(x, y));
                (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0)
            };
            let changed = (0..HEIGHT)
                .flat_map(|y| (0..WIDTH).map(move |x| (x, y)))
                .filter(|&(x, y)| differ(x, y) > 3)
                .count();
            let sky = (0..SKY_ROWS)
                .flat_map(|y| (0..WIDTH).map(move |x| (x, y)))
                .map(|(x, y)| differ(x, y))
                .max()
                .unwrap_or(0);
            println!("{label}: {feature:?} changes {changed} pixels; in the sky at most {sky}");
            if changed < feature.min_changed() {
                failures.push(format!(
                    "{label}: {feature:?} changes only {changed} pixels (at least {})",
                    feature.min_changed()
                ));
            }
            if sky > 2 {
                failures.push(format!("{label}: {feature:?} changes the sky by {sky}"));
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
