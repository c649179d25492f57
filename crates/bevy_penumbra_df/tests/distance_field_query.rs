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
