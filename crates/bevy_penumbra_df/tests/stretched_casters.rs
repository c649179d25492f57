//! Non-uniformly scaled mesh casters bake their stretch (`CasterStretch`): a unit cube
//! scaled 1.6 × 1 × 1 — plain, mirrored, turned — answers `DistanceFieldQuery` with the
//! distances of the 1.6 m block it is, at every side. Read through the conservative
//! bound instead (the smallest scale times the cube's own distance), a point 10 cm past
//! a block's end reads 6.25 cm. A cube made a floor (8 × 0.2 × 8) keeps the bound, exact
//! across its thin axis.

use bevy::prelude::*;
use bevy_penumbra_df::{
    CasterStretch, DistanceFieldCaster, DistanceFieldQuery, DistanceFieldScenePlugin,
    SdfAssetPlugin, SdfBakeCache, SdfBaked,
};

#[derive(Resource, Default)]
struct Probes(Vec<(Vec3, f32)>, Vec<f32>);

fn ask(query: DistanceFieldQuery, mut probes: ResMut<Probes>) {
    let scene = query.scene();
    let answers = probes.0.iter().map(|&(p, _)| scene.distance(p)).collect();
    probes.1 = answers;
}

/// The exact distance from `p` to a box of half extents `h` placed by `t` (rigid part).
fn box_distance(p: Vec3, at: Vec3, rotation: Quat, h: Vec3) -> f32 {
    let q = (rotation.inverse() * (p - at)).abs() - h;
    q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
}

/// A headless app with the scene and SDF-asset plugins (no disk cache) and a unit cube.
fn app_with_a_cube() -> (App, Handle<Mesh>) {
    let mut app = App::new();
    app.add_plugins((
        MinimalPlugins,
        TransformPlugin,
        AssetPlugin::default(),
        SdfAssetPlugin,
        DistanceFieldScenePlugin,
    ))
    .init_asset::<Mesh>()
    .init_asset::<StandardMaterial>()
    .insert_resource(SdfBakeCache::with_directory(None));
    let cube = app
        .world_mut()
        .resource_mut::<Assets<Mesh>>()
        .add(Cuboid::new(1.0, 1.0, 1.0));
    (app, cube)
}

/// Updates `app` until every one of `entities` has its SDF (at most 3,000 frames).
fn bake_all(app: &mut App, entities: &[Entity]) {
    for _ in 0..3000 {
        app.update();
        if entities
            .iter()
            .all(|&e| app.world().get::<SdfBaked>(e).is_some())
        {
            return;
        }
        std::thread::sleep(std::time::Duration::from_millis(2));
    }
}

#[test]
fn a_stretched_cube_is_distance_exact_as_the_block_it_is() {
    let (mut app, cube) = app_with_a_cube();
    app.init_resource::<Probes>().add_systems(Update, ask);
    let blocks = [
        (
            Vec3::new(0.0, 1.0, 0.0),
            Quat::IDENTITY,
            Vec3::new(1.6, 1.0, 1.0),
        ),
        (
            Vec3::new(0.0, 1.0, 5.0),
            Quat::from_rotation_y(0.7),
            Vec3::new(-1.6, 1.0, 1.0),
        ),
        (
            Vec3::new(6.0, 2.0, 0.0),
            Quat::from_euler(EulerRot::XYZ, 0.4, 0.2, 1.1),
            Vec3::new(1.0, 1.8, 0.9),
        ),
    ];
    let mut entities = Vec::new();
    let mut probes = Vec::new();
    for &(at, rotation, scale) in &blocks {
        entities.push(
            app.world_mut()
                .spawn((
                    Mesh3d(cube.clone()),
                    Transform::from_translation(at)
                        .with_rotation(rotation)
                        .with_scale(scale),
                    DistanceFieldCaster::default(),
                ))
                .id(),
        );
        let h = 0.5 * scale.abs();
        // 10 cm off every face's centre and off an edge, in the block's frame.
        for dir in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
            let p = at + rotation * (dir * (h + Vec3::splat(0.1)));
            probes.push((p, box_distance(p, at, rotation, h)));
        }
        let p = at + rotation * Vec3::new(h.x * 0.5, h.y + 0.07, h.z + 0.07);
        probes.push((p, box_distance(p, at, rotation, h)));
    }
    // A floor: the bound, exact across it (10 cm above and below).
    let floor = app
        .world_mut()
        .spawn((
            Mesh3d(cube.clone()),
            Transform::from_xyz(0.0, -3.0, 0.0).with_scale(Vec3::new(8.0, 0.2, 8.0)),
            DistanceFieldCaster::default(),
        ))
        .id();
    for y in [-2.8, -3.2] {
        probes.push((Vec3::new(1.0, y, -2.0), 0.1));
    }
    app.world_mut().resource_mut::<Probes>().0 = probes;
    let mut all = entities.clone();
    all.push(floor);
    bake_all(&mut app, &all);
    app.update();
    for (&e, &(_, _, scale)) in entities.iter().zip(&blocks) {
        let stretch = app.world().get::<CasterStretch>(e).expect("a stretch").0;
        // The exact stretch to within half an eighth of an octave.
        let want = scale.abs() / scale.abs().max_element();
        let off = (stretch / want).to_array().map(|q| q.log2().abs());
        assert!(off.iter().all(|o| *o <= 0.0626), "{scale}: {stretch}");
    }
    assert_eq!(
        app.world().get::<CasterStretch>(floor).map(|s| s.0),
        Some(Vec3::ONE)
    );
    let probes = app.world().resource::<Probes>();
    assert_eq!(probes.1.len(), probes.0.len());
    let mut worst = 0.0_f32;
    for (&(p, exact), &got) in probes.0.iter().zip(&probes.1) {
        worst = worst.max((got - exact).abs());
        assert!((got - exact).abs() < 0.02, "at {p}: {got} for {exact}");
    }
    println!(
        "worst distance error {worst:.4} m over {} probes",
        probes.0.len()
    );
}

/// Instances stretched alike share one bake: a mesh scaled 1 × 1.5 × 1, 2 × 3 × 2 and
/// 1 × 1.53 × 1 rounds to one stretch; unstretched instances share another.
#[test]
fn instances_stretched_alike_share_a_bake() {
    let (mut app, cube) = app_with_a_cube();
    let scales = [
        Vec3::new(1.0, 1.5, 1.0),
        Vec3::new(2.0, 3.0, 2.0),
        Vec3::new(1.0, 1.53, 1.0),
        Vec3::ONE,
        Vec3::splat(1.7),
    ];
    let entities: Vec<Entity> = scales
        .iter()
        .enumerate()
        .map(|(i, &s)| {
            app.world_mut()
                .spawn((
                    Mesh3d(cube.clone()),
                    Transform::from_xyz(3.0 * i as f32, 0.0, 0.0).with_scale(s),
                    DistanceFieldCaster::default(),
                ))
                .id()
        })
        .collect();
    bake_all(&mut app, &entities);
    let baked: Vec<AssetId<bevy_penumbra_df::SdfVolumeAsset>> = entities
        .iter()
        .map(|&e| app.world().get::<SdfBaked>(e).expect("baked").0.id())
        .collect();
    assert!(
        baked[0] == baked[1] && baked[1] == baked[2],
        "stretched alike"
    );
    assert!(baked[3] == baked[4] && baked[0] != baked[3], "unstretched");
}
