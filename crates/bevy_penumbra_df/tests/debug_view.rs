//! The distance-field debug view rendered by Bevy on lavapipe equals the CPU reference
//! (`penumbra_reference::df::debug_pixel`) of the same scene — analytic casters, a
//! baked SDF volume in the atlas, rotation and non-uniform scale — in both modes, for
//! LDR and HDR cameras, for a baked `Mesh3d` caster, and 10⁵ m from the origin; a volume
//! placed as sparse bricks is traced as the same volume placed dense.

use bevy::prelude::*;
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldDebugMode, DistanceFieldDebugPlugin,
    DistanceFieldDebugView, DistanceFieldScene, DistanceFieldScenePlugin, DistanceFieldUploadStats,
    SdfAssetPlugin, SdfVolumeAsset,
};
use penumbra_df_core::cull::{self, CameraOrigin, Frustum};
use penumbra_df_core::object::{ShapeKind, unpack_10_10_12};
use penumbra_reference::analytic_volume;
use penumbra_reference::df::{Atlas, DebugMode, DebugScene, debug_pixel};
use penumbra_sdf::{BakeSettings, bake, shapes};
use penumbra_test::{HeadlessRender, gpu_or_skip};

const SIZE: u32 = 96;
const EYE: Vec3 = Vec3::new(0.5, 2.2, 6.5);

fn camera_transform(offset: Vec3) -> Transform {
    Transform::from_translation(EYE + offset).looking_at(Vec3::new(0.0, 0.6, 0.0) + offset, Vec3::Y)
}

fn torus_volume() -> SdfVolumeAsset {
    let mesh = shapes::torus(0.6, 0.22, 48, 24);
    SdfVolumeAsset {
        volume: bake(&mesh, &BakeSettings::longest_axis(40), None)
            .expect("torus bakes")
            .volume,
    }
}

/// The debug view's camera, looking at the scene shifted by `offset` (world metres).
fn debug_camera(mode: DistanceFieldDebugMode, offset: Vec3) -> impl Bundle {
    (
        Camera3d::default(),
        camera_transform(offset),
        DistanceFieldDebugView {
            mode,
            max_steps: 64,
            max_distance: 40.0,
        },
    )
}

/// An app with the plugins the debug view needs.
fn debug_app(render: &HeadlessRender) -> App {
    let mut app = render.app();
    app.add_plugins((
        SdfAssetPlugin,
        DistanceFieldScenePlugin,
        DistanceFieldDebugPlugin,
    ));
    app
}

/// The test scene, everything shifted by `offset` (world metres).
fn scene_app(render: &HeadlessRender, mode: DistanceFieldDebugMode, offset: Vec3) -> App {
    let mut app = debug_app(render);
    app.add_systems(
        Startup,
        move |mut commands: Commands, mut sdfs: ResMut<Assets<SdfVolumeAsset>>| {
            commands.spawn(debug_camera(mode, offset));
            let caster = |source| DistanceFieldCaster {
                source,
                ..default()
            };
            let at =
                |x: f32, y: f32, z: f32| Transform::from_translation(Vec3::new(x, y, z) + offset);
            commands.spawn((caster(CasterSource::Plane), at(0.0, 0.0, 0.0)));
            commands.spawn((
                caster(CasterSource::Sphere { radius: 0.7 }),
                at(-1.6, 0.7, -0.5),
            ));
            commands.spawn((
                caster(CasterSource::Cuboid {
                    half_size: Vec3::new(0.5, 0.5, 0.5),
                }),
                at(1.5, 0.6, -0.3)
                    .with_rotation(Quat::from_rotation_y(0.6) * Quat::from_rotation_x(0.3))
                    .with_scale(Vec3::new(1.4, 0.8, 1.0)),
            ));
            commands.spawn((
                caster(CasterSource::Capsule {
                    radius: 0.25,
                    half_length: 0.6,
                }),
                at(0.3, 0.85, -1.8).with_rotation(Quat::from_rotation_z(0.9)),
            ));
            let torus = sdfs.add(torus_volume());
            commands.spawn((
                caster(CasterSource::Sdf(torus)),
                at(0.1, 0.45, 0.9)
                    .with_rotation(Quat::from_rotation_x(1.2))
                    .with_scale(Vec3::new(1.3, 1.0, 0.9)),
            ));
        },
    );
    app
}

/// The CPU reference image (linear RGB) of the scene in `app`'s main world.
fn reference(app: &App, mode: DebugMode, sdf: &SdfVolumeAsset, objects: usize) -> Vec<Vec3> {
    let scene = app.world().resource::<DistanceFieldScene>();
    let size = scene.atlas_size().expect("the torus made an atlas");
    let mut atlas = Atlas::new(size);
    for r in scene.records() {
        if r.flags() != 0 && r.kind() == ShapeKind::Volume as u32 {
            let [origin, dims_minus_one, _] = r.params();
            let dims = unpack_10_10_12(dims_minus_one) + UVec3::ONE;
            assert_eq!(dims, sdf.volume.dims);
            let bits: Vec<u16> = sdf.volume.data.iter().map(|h| h.to_bits()).collect();
            atlas.write(unpack_10_10_12(origin), dims, &bits);
        }
    }
    let t = camera_transform(Vec3::ZERO).compute_affine();
    let proj = Mat4::perspective_infinite_reverse_rh(std::f32::consts::FRAC_PI_4, 1.0, 0.1);
    let clip_from_relative = proj * Mat4::from_mat3a(t.matrix3).inverse();
    let camera = CameraOrigin::at(EYE).unwrap();
    let frustum = Frustum::from_clip_from_relative(clip_from_relative);
    let culled = cull::cull(scene.records(), &camera, &frustum);
    assert!(culled.len() == objects, "culled {culled:?}");
    let debug = DebugScene {
        objects: culled
            .iter()
            .map(|&s| &scene.records()[s as usize])
            .collect(),
        atlas: &atlas,
        camera,
        relative_from_clip: clip_from_relative.inverse(),
        max_steps: 64,
        max_distance: 40.0,
    };
    (0..SIZE * SIZE)
        .map(|i| {
            let uv = Vec2::new(
                ((i % SIZE) as f32 + 0.5) / SIZE as f32,
                ((i / SIZE) as f32 + 0.5) / SIZE as f32,
            );
            debug_pixel(&debug, mode, uv)
        })
        .collect()
}

fn srgb8(linear: f32) -> u8 {
    let c = linear.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// Per-pixel max channel difference (0–255) between the GPU image and the reference.
fn differences(gpu: &image::RgbaImage, reference: &[Vec3]) -> Vec<u8> {
    gpu.pixels()
        .zip(reference)
        .map(|(p, r)| {
            let want = [srgb8(r.x), srgb8(r.y), srgb8(r.z)];
            (0..3).map(|c| p.0[c].abs_diff(want[c])).max().unwrap_or(0)
        })
        .collect()
}

fn check(mode: DistanceFieldDebugMode, reference_mode: DebugMode, name: &str) {
    if !gpu_or_skip(name) {
        return;
    }
    let render = HeadlessRender::new(SIZE, SIZE).frames(4);
    let app = scene_app(&render, mode, Vec3::ZERO);
    let (capture, app) = render.run_keeping_app(app).expect("render");
    let image = capture.to_rgba8();
    let want = reference(&app, reference_mode, &torus_volume(), 5);
    assert_matches_reference(&image, &want, name);
}

/// Compares with tolerances (mean ≤ 0.2/255, ≤ 0.3 % of pixels over 8/255), writing the
/// actual and expected PNGs on failure (or always with `PENUMBRA_SAVE_IMAGES`).
fn assert_matches_reference(image: &image::RgbaImage, want: &[Vec3], name: &str) {
    let diff = differences(image, want);
    let mean = diff.iter().map(|&d| d as f64).sum::<f64>() / diff.len() as f64;
    let over = diff.iter().filter(|&&d| d > 8).count() as f64 / diff.len() as f64;
    let mut sorted = diff.clone();
    sorted.sort_unstable();
    let p99 = sorted[sorted.len() * 99 / 100];
    println!(
        "{name}: mean {mean:.3}, p99 {p99}, {:.3} % of pixels over 8/255",
        over * 100.0
    );
    // Distinct content: the image is not flat.
    let distinct: std::collections::HashSet<[u8; 4]> = image.pixels().map(|p| p.0).collect();
    assert!(
        distinct.len() > 16,
        "{name}: {} distinct colours",
        distinct.len()
    );
    if mean > 0.2 || over > 0.003 || std::env::var_os("PENUMBRA_SAVE_IMAGES").is_some() {
        let dir = penumbra_test::output_dir();
        image.save(dir.join(format!("{name}.actual.png"))).ok();
        let expected = image::RgbaImage::from_fn(SIZE, SIZE, |x, y| {
            let r = want[(x + SIZE * y) as usize];
            image::Rgba([srgb8(r.x), srgb8(r.y), srgb8(r.z), 255])
        });
        expected.save(dir.join(format!("{name}.expected.png"))).ok();
        panic!(
            "{name}: GPU differs from the CPU reference: mean {mean:.3}, {:.3} % over 8/255",
            over * 100.0
        );
    }
}

#[test]
fn shaded_debug_view_matches_the_cpu_reference() {
    check(
        DistanceFieldDebugMode::Shaded,
        DebugMode::Shaded,
        "df_debug_view_shaded",
    );
}

#[test]
fn step_count_debug_view_matches_the_cpu_reference() {
    check(
        DistanceFieldDebugMode::StepCount,
        DebugMode::Steps,
        "df_debug_view_steps",
    );
}

/// An `Hdr` camera (`Rgba16Float` target) gets the same image, in linear values.
#[test]
fn hdr_cameras_get_the_same_linear_image() {
    if !gpu_or_skip("hdr_cameras_get_the_same_linear_image") {
        return;
    }
    let render = HeadlessRender::new(SIZE, SIZE)
        .frames(4)
        .format(penumbra_test::CaptureFormat::LinearF16);
    let mut app = scene_app(&render, DistanceFieldDebugMode::Shaded, Vec3::ZERO);
    app.add_systems(
        PostStartup,
        |mut commands: Commands, cameras: Query<Entity, With<DistanceFieldDebugView>>| {
            for camera in &cameras {
                commands.entity(camera).insert(bevy::camera::Hdr);
            }
        },
    );
    let (capture, app) = render.run_keeping_app(app).expect("render");
    let want = reference(&app, DebugMode::Shaded, &torus_volume(), 5);
    let got = capture.to_linear();
    let mut errors: Vec<f32> = got
        .iter()
        .zip(&want)
        .map(|(g, w)| (0..3).map(|c| (g[c] - w[c]).abs()).fold(0.0, f32::max))
        .collect();
    errors.sort_by(f32::total_cmp);
    let mean = errors.iter().sum::<f32>() / errors.len() as f32;
    let over = errors.iter().filter(|&&e| e > 0.02).count() as f32 / errors.len() as f32;
    println!(
        "hdr: mean {mean:.5}, median {:.5}, {:.3} % over 0.02",
        errors[errors.len() / 2],
        over * 100.0
    );
    if !(mean < 2e-3 && over < 0.003) {
        let to8 = |v: f32| (v.clamp(0.0, 1.0) * 255.0) as u8;
        let img = image::RgbaImage::from_fn(SIZE, SIZE, |x, y| {
            let p = got[(x + SIZE * y) as usize];
            image::Rgba([to8(p[0]), to8(p[1]), to8(p[2]), 255])
        });
        img.save(penumbra_test::output_dir().join("df_debug_view_hdr.actual.png"))
            .ok();
        panic!("mean {mean}, {over} over 0.02");
    }
}

/// A `Mesh3d` caster goes the whole way: baked in the background, placed in the atlas,
/// uploaded, culled and traced — the image equals the CPU reference of the baked SDF.
#[test]
fn mesh_casters_are_baked_and_traced() {
    if !gpu_or_skip("mesh_casters_are_baked_and_traced") {
        return;
    }
    // Enough frames for the background bake (≈ 0.2 s) with a wide margin.
    let render = HeadlessRender::new(SIZE, SIZE).frames(80);
    let mut app = render.app();
    app.insert_resource(bevy_penumbra_df::SdfBakeCache::with_directory(None))
        .add_plugins((
            SdfAssetPlugin,
            DistanceFieldScenePlugin,
            DistanceFieldDebugPlugin,
        ))
        .add_systems(
            Startup,
            |mut commands: Commands, mut meshes: ResMut<Assets<Mesh>>| {
                commands.spawn(debug_camera(DistanceFieldDebugMode::Shaded, Vec3::ZERO));
                commands.spawn((
                    DistanceFieldCaster {
                        source: CasterSource::Plane,
                        ..default()
                    },
                    Transform::default(),
                ));
                commands.spawn((
                    Mesh3d(meshes.add(Torus::new(0.4, 0.9))),
                    DistanceFieldCaster::default(),
                    Transform::from_xyz(0.0, 0.6, 0.0).with_rotation(Quat::from_rotation_x(0.8)),
                ));
            },
        );
    let (capture, mut app) = render.run_keeping_app(app).expect("render");
    let stats = app.world().resource::<DistanceFieldUploadStats>().clone();
    assert_eq!((stats.objects, stats.atlas_volumes), (2, 1), "{stats:?}");
    let baked = app
        .world_mut()
        .query::<&bevy_penumbra_df::SdfBaked>()
        .single(app.world())
        .expect("one baked caster")
        .0
        .clone();
    let sdf = app
        .world()
        .resource::<Assets<SdfVolumeAsset>>()
        .get(&baked)
        .expect("baked asset")
        .clone();
    let want = reference(&app, DebugMode::Shaded, &sdf, 2);
    assert_matches_reference(&capture.to_rgba8(), &want, "df_debug_view_mesh_caster");
}

/// The same scene 10⁵ m from the origin renders the same image: records keep positions
/// in 512 m tiles and the shaders work camera-relative. (Without that, f32 world
/// positions there are only 8 mm apart and the image breaks up.)
#[test]
fn far_from_the_origin_the_image_is_unchanged() {
    if !gpu_or_skip("far_from_the_origin_the_image_is_unchanged") {
        return;
    }
    let render = HeadlessRender::new(SIZE, SIZE).frames(4);
    let near = render
        .run(scene_app(
            &render,
            DistanceFieldDebugMode::Shaded,
            Vec3::ZERO,
        ))
        .expect("render")
        .to_rgba8();
    let far = render
        .run(scene_app(
            &render,
            DistanceFieldDebugMode::Shaded,
            Vec3::new(1e5, 0.0, -1e5),
        ))
        .expect("render")
        .to_rgba8();
    let tolerance = penumbra_test::Tolerance {
        per_pixel: 8,
        max_differing_fraction: 0.005,
        max_mean: 0.5,
        max_p99: 8.0,
    };
    let c = penumbra_test::compare_rgba8(&far, &near, &tolerance);
    println!("far vs near: {c:?}");
    assert!(c.passed, "{c:?}");
}

/// A sphere's volume placed as sparse bricks is traced as the same volume placed dense:
/// the view binds the scene's brick table and reads through it.
#[test]
fn bricked_volumes_are_traced_as_dense_ones() {
    if !gpu_or_skip("bricked_volumes_are_traced_as_dense_ones") {
        return;
    }
    let render = HeadlessRender::new(SIZE, SIZE).frames(4);
    let image = |sparse_min_bytes: u64| {
        let mut app = debug_app(&render);
        app.insert_resource(bevy_penumbra_df::DistanceFieldSceneSettings {
            sparse_min_bytes,
            ..default()
        })
        .add_systems(
            Startup,
            |mut commands: Commands, mut sdfs: ResMut<Assets<SdfVolumeAsset>>| {
                commands.spawn(debug_camera(DistanceFieldDebugMode::Shaded, Vec3::ZERO));
                let caster = |source| DistanceFieldCaster {
                    source,
                    ..default()
                };
                commands.spawn((caster(CasterSource::Plane), Transform::default()));
                commands.spawn((
                    caster(CasterSource::Sdf(sdfs.add(SdfVolumeAsset {
                        volume: analytic_volume::sphere_for_bricks(0.8),
                    }))),
                    Transform::from_xyz(0.2, 0.8, 0.0),
                ));
            },
        );
        let (capture, app) = render.run_keeping_app(app).expect("render");
        let stats = app.world().resource::<DistanceFieldUploadStats>().clone();
        (
            capture.to_rgba8(),
            (stats.atlas_volumes, stats.atlas_bricked),
        )
    };
    let (dense, dense_counts) = image(u64::MAX);
    let (bricked, bricked_counts) = image(0);
    assert_eq!((dense_counts, bricked_counts), ((1, 0), (1, 1)));
    let tolerance = penumbra_test::Tolerance {
        per_pixel: 8,
        max_differing_fraction: 0.003,
        max_mean: 0.2,
        max_p99: 8.0,
    };
    let c = penumbra_test::compare_rgba8(&bricked, &dense, &tolerance);
    println!("bricked vs dense: {c:?}");
    if !c.passed {
        let dir = penumbra_test::output_dir();
        bricked
            .save(dir.join("df_debug_view_bricked.actual.png"))
            .ok();
        dense
            .save(dir.join("df_debug_view_bricked.expected.png"))
            .ok();
    }
    assert!(c.passed, "{c:?}");
}
