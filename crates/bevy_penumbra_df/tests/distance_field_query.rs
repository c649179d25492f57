//! `DistanceFieldQuery` in a system: distances, normals and sphere casts against an
//! analytic scene (a floor plane, a ball, a rotated box and a baked-SDF ball loaded as
//! an asset) equal the analytic values; a hidden caster counts, an entity without a
//! caster does not.

use bevy::prelude::*;
use bevy_penumbra_df::{CasterSource, DistanceFieldCaster, DistanceFieldQuery, SdfVolumeAsset};
use penumbra_sdf::{BakeSettings, bake, shapes};

#[derive(Resource, Default)]
struct Answers(Vec<f32>, Option<(f32, Vec3)>, Vec3);

fn ask(query: DistanceFieldQuery, mut answers: ResMut<Answers>) {
    let points = [
        Vec3::new(0.0, 5.0, -6.0),
        Vec3::new(3.0, 1.0, 0.0),
        Vec3::new(-3.0, 1.5, 0.0),
        Vec3::new(0.0, 1.0, 5.2),
        Vec3::new(0.0, 1.0, -3.0),
    ];
    let scene = query.scene();
    answers.0 = points.iter().map(|&p| scene.distance(p)).collect();
    answers.1 = query
        .sphere_cast(Vec3::new(-10.0, 1.0, 0.0), Vec3::X, 0.25, 20.0)
        .map(|h| (h.distance, h.normal));
    answers.2 = query.gradient(Vec3::new(0.0, 1.0, 5.5));
}

#[test]
fn queries_in_a_system_match_the_analytic_scene() {
    let mut app = App::new();
    app.add_plugins((MinimalPlugins, TransformPlugin, AssetPlugin::default()))
        .init_asset::<SdfVolumeAsset>()
        .init_resource::<Answers>()
        .add_systems(Update, ask);
    let ball = bake(
        &shapes::sphere(1.0, 96, 48),
        &BakeSettings::longest_axis(48),
        None,
    )
    .expect("bakes")
    .volume;
    let sdf = app
        .world_mut()
        .resource_mut::<Assets<SdfVolumeAsset>>()
        .add(SdfVolumeAsset { volume: ball });
    let caster = |source| DistanceFieldCaster {
        source,
        ..default()
    };
    app.world_mut().spawn(caster(CasterSource::Plane));
    app.world_mut().spawn((
        caster(CasterSource::Sphere { radius: 0.5 }),
        Transform::from_xyz(2.0, 1.0, 0.0),
    ));
    app.world_mut().spawn((
        caster(CasterSource::Cuboid {
            half_size: Vec3::new(0.5, 1.0, 0.5),
        }),
        Transform::from_xyz(-2.0, 1.0, 0.0).with_rotation(Quat::from_rotation_y(0.5)),
        Visibility::Hidden,
    ));
    // A baked ball of radius 1 at (0, 1, 4), scaled 1.5×: radius 1.5.
    app.world_mut().spawn((
        caster(CasterSource::Sdf(sdf)),
        Transform::from_xyz(0.0, 1.0, 4.0).with_scale(Vec3::splat(1.5)),
    ));
    // Not a caster.
    app.world_mut().spawn(Transform::from_xyz(0.0, 1.0, -3.0));
    app.update();
    app.update();
    let answers = app.world().resource::<Answers>();
    let d = &answers.0;
    // Above the floor 5 m (the baked ball 9 m away: its bound outside its box is loose,
    // but not that loose); 0.5 m from the ball's surface; the hidden box (analytic, in
    // its frame); 0.3 inside the baked ball; 1 m over the floor where the
    // entity without a caster stands.
    let rot = Quat::from_rotation_y(0.5);
    let q = rot.inverse() * (Vec3::new(-3.0, 1.5, 0.0) - Vec3::new(-2.0, 1.0, 0.0));
    let a = q.abs() - Vec3::new(0.5, 1.0, 0.5);
    let box_distance = a.max(Vec3::ZERO).length() + a.max_element().min(0.0);
    let want = [5.0, 0.5, box_distance.min(1.5), -0.3, 1.0];
    for (i, (got, want)) in d.iter().zip(want).enumerate() {
        // The baked ball: within a tenth of its (scaled) voxel.
        let tolerance = if i == 3 { 0.01 } else { 1e-4 };
        assert!(
            (got - want).abs() < tolerance,
            "point {i}: {got} want {want}"
        );
    }
    // The sphere of radius 0.25 from x = −10 along +x at y = 1 meets the hidden box.
    let (hit, normal) = answers.1.expect("hits the box");
    let mut t = 0.0f32;
    while t < 20.0 {
        let c = Vec3::new(-10.0 + t, 1.0, 0.0);
        let q = rot.inverse() * (c - Vec3::new(-2.0, 1.0, 0.0));
        let a = q.abs() - Vec3::new(0.5, 1.0, 0.5);
        if a.max(Vec3::ZERO).length() + a.max_element().min(0.0) <= 0.25 {
            break;
        }
        t += 1e-4;
    }
    assert!((hit - t).abs() < 2e-3, "{hit} want {t}");
    assert!(normal.x < -0.5, "{normal}");
    // Beside the baked ball: the normal points away from its centre.
    let g = answers.2;
    assert!(g.angle_between(Vec3::Z) < 0.05, "{g}");
}

fn height_image(
    width: u32,
    height: u32,
    format: bevy::render::render_resource::TextureFormat,
    data: Vec<u8>,
) -> Image {
    use bevy::asset::RenderAssetUsages;
    use bevy::render::render_resource::{Extent3d, TextureDimension};
    Image::new(
        Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        TextureDimension::D2,
        data,
        format,
        RenderAssetUsages::MAIN_WORLD,
    )
}

#[path = "support/main_world.rs"]
mod main_world;

#[derive(Resource, Default)]
struct TerrainAnswer(f32);

fn ask_terrain(query: DistanceFieldQuery, mut answer: ResMut<TerrainAnswer>) {
    answer.0 = query.distance(Vec3::new(20.0, 3.0, 1.0));
}

/// A `DistanceFieldHeightfield` from an image: queries see the terrain (a ramp rising
/// along x, 10 m across, centred on the entity); a wrong format, a 1 × 1 image or a NaN
/// height scale are refused with a reason and give no terrain.
#[test]
fn heightfields_from_images_answer_queries_and_bad_images_are_refused() {
    use bevy::render::render_resource::TextureFormat;
    use bevy_penumbra_df::{DistanceFieldHeightfield, HeightfieldTerrain};
    let mut app = main_world::main_world_app();
    app.init_asset::<Image>()
        .add_plugins((
            bevy_penumbra_df::SdfAssetPlugin,
            bevy_penumbra_df::DistanceFieldScenePlugin,
        ))
        .init_resource::<TerrainAnswer>()
        .add_systems(Update, ask_terrain);
    // 3 × 3 R32Float heights 0, 0.5, 1 along x (scaled ×2: 0, 1, 2 m).
    let ramp: Vec<u8> = (0..9)
        .flat_map(|i| (0.5 * (i % 3) as f32).to_le_bytes())
        .collect();
    let mut images = app.world_mut().resource_mut::<Assets<Image>>();
    let good = images.add(height_image(3, 3, TextureFormat::R32Float, ramp));
    // Two 8-bit channels: not a format heights come in (8-bit PNGs, grey ones too,
    // load as RGBA and are read).
    let rg = images.add(height_image(2, 2, TextureFormat::Rg8Unorm, vec![0; 8]));
    let tiny = images.add(height_image(1, 1, TextureFormat::R8Unorm, vec![7]));
    let terrain = |heights, height_scale| {
        (
            DistanceFieldHeightfield {
                heights,
                size: Vec2::splat(10.0),
                height_scale,
            },
            Transform::from_xyz(20.0, 0.0, 0.0),
        )
    };
    let ok = app.world_mut().spawn(terrain(good.clone(), 2.0)).id();
    let refused = [
        (app.world_mut().spawn(terrain(rg, 1.0)).id(), "Rg8Unorm"),
        (app.world_mut().spawn(terrain(tiny, 1.0)).id(), "2 × 2"),
        (
            app.world_mut().spawn(terrain(good, f32::NAN)).id(),
            "height_scale",
        ),
    ];
    app.update();
    app.update();
    assert!(matches!(
        app.world().get::<HeightfieldTerrain>(ok),
        Some(HeightfieldTerrain::Ready(_))
    ));
    for (entity, why) in refused {
        match app.world().get::<HeightfieldTerrain>(entity) {
            Some(HeightfieldTerrain::Refused(reason)) => assert!(reason.contains(why), "{reason}"),
            other => panic!("{why}: {other:?}"),
        }
    }
    // Over the ramp's middle (height 1 m at x = 20) at y = 3: 2 m above it, less by the
    // slope (0.2 m per m: √(1 + 0.04)).
    let d = app.world().resource::<TerrainAnswer>().0;
    let want = 2.0 / (1.0f32 + 0.04).sqrt();
    assert!((d - want).abs() < 0.02, "{d} want {want}");
}
