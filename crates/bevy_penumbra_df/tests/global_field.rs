//! The global distance field's main-world bookkeeping (no GPU): nothing without the
//! component; a new camera composes every brick once, a still scene nothing more; a
//! moving caster dirties the bricks around where it was and is; a moving camera
//! reveals slabs; changed settings start over; bad settings are clamped; removing the
//! component drops the state.

use bevy::prelude::*;
use bevy_penumbra_df::{
    CasterSource, DistanceFieldCaster, DistanceFieldScenePlugin, GlobalDistanceField,
    GlobalDistanceFieldPlugin, GlobalDistanceFieldState, GlobalDistanceFieldStats, SdfAssetPlugin,
};

#[path = "support/main_world.rs"]
mod main_world;

fn app() -> App {
    let mut app = main_world::main_world_app();
    app.add_plugins((
        SdfAssetPlugin,
        DistanceFieldScenePlugin,
        GlobalDistanceFieldPlugin,
    ));
    app.finish();
    app.cleanup();
    app
}

/// Two levels of 32³ texels (64 bricks each), 0.2 and 0.4 m texels.
fn small() -> GlobalDistanceField {
    GlobalDistanceField {
        clipmap_count: 2,
        resolution: 32,
        first_extent: 6.4,
        ..default()
    }
}

fn stats(app: &App) -> GlobalDistanceFieldStats {
    *app.world().resource::<GlobalDistanceFieldStats>()
}

#[test]
fn clipmaps_follow_the_camera_and_the_casters() {
    let mut app = app();
    let ball = app
        .world_mut()
        .spawn((
            DistanceFieldCaster {
                source: CasterSource::Sphere { radius: 0.5 },
                ..default()
            },
            Transform::from_xyz(1.0, 0.5, 0.0),
        ))
        .id();
    app.world_mut().spawn((
        DistanceFieldCaster {
            source: CasterSource::Plane,
            ..default()
        },
        Transform::default(),
    ));
    // No component: nothing.
    for _ in 0..3 {
        app.update();
    }
    assert_eq!(stats(&app), GlobalDistanceFieldStats::default());

    let camera = app
        .world_mut()
        .spawn((Transform::from_xyz(0.0, 1.7, 0.0), small()))
        .id();
    app.update();
    let s = stats(&app);
    assert_eq!(
        (s.cameras, s.bricks, s.texels),
        (1, 128, 128 * 512),
        "{s:?}"
    );
    app.update();
    // A still scene: nothing more, ever.
    for _ in 0..5 {
        app.update();
        let s = stats(&app);
        assert_eq!(
            (s.bricks, s.scrolled, s.dirtied, s.pending, s.dirty_regions),
            (0, 0, 0, 0, 0),
            "{s:?}"
        );
    }

    // The ball moves 1 m: its old and new bounding boxes dirty the bricks around them.
    app.world_mut()
        .get_mut::<Transform>(ball)
        .unwrap()
        .translation
        .x = 2.0;
    app.update();
    let s = stats(&app);
    assert_eq!(s.dirty_regions, 2, "{s:?}");
    assert!(
        s.dirtied > 0 && s.bricks == s.dirtied && s.bricks < 128,
        "{s:?}"
    );
    {
        let state = app.world().get::<GlobalDistanceFieldState>(camera).unwrap();
        let layout = *state.layout();
        // Every brick within the band of the ball (new place) was handed out.
        let near = layout
            .bricks_near(
                0,
                Vec3::new(1.5, 0.0, -0.5),
                Vec3::new(2.5, 1.0, 0.5),
                layout.reach(0),
            )
            .unwrap();
        let window = state.clipmaps().window(0).unwrap();
        for b in near.intersect(&window).iter() {
            assert!(
                state
                    .update
                    .jobs
                    .iter()
                    .any(|j| j.level == 0 && j.brick == b),
                "brick {b} not recomposed"
            );
        }
    }
    app.update();
    assert_eq!(stats(&app).bricks, 0);

    // The camera moves two level-0 bricks (3.2 m) along x: slabs are revealed.
    app.world_mut()
        .get_mut::<Transform>(camera)
        .unwrap()
        .translation
        .x = 3.2;
    app.update();
    let s = stats(&app);
    assert!(s.scrolled >= 2 * 16 && s.bricks == s.scrolled, "{s:?}");

    // New settings: start over.
    app.world_mut()
        .get_mut::<GlobalDistanceField>(camera)
        .unwrap()
        .clipmap_count = 1;
    app.update();
    let s = stats(&app);
    assert_eq!(s.bricks, 64, "{s:?}");

    // Gone: nothing kept.
    app.world_mut()
        .entity_mut(camera)
        .remove::<GlobalDistanceField>();
    app.update();
    app.update();
    assert!(
        app.world()
            .get::<GlobalDistanceFieldState>(camera)
            .is_none()
    );
    assert_eq!(stats(&app), GlobalDistanceFieldStats::default());
}

#[test]
fn bad_settings_are_clamped_and_named() {
    let nan = f32::NAN;
    let table: [(GlobalDistanceField, usize); 5] = [
        (GlobalDistanceField::default(), 0),
        (
            GlobalDistanceField {
                clipmap_count: 0,
                ..default()
            },
            1,
        ),
        (
            GlobalDistanceField {
                resolution: 100_000,
                ..default()
            },
            1,
        ),
        (
            GlobalDistanceField {
                first_extent: nan,
                growth: -1.0,
                ..default()
            },
            2,
        ),
        (
            GlobalDistanceField {
                brick_budget: 0,
                first_extent: -2.0,
                ..default()
            },
            2,
        ),
    ];
    for (settings, n) in table {
        let (layout, budget, problems) = settings.resolve();
        assert_eq!(problems.len(), n, "{settings:?}: {problems:?}");
        assert!(budget >= 1 && layout.levels >= 1 && layout.first_extent > 0.0);
        assert!(layout.extent(layout.levels - 1).is_finite());
    }
}

/// Terrains are casters of the field: a `DistanceFieldHeightfield` appearing, changing
/// (its height scale) and going dirties the bricks around its bounds (before and after)
/// and bumps `SceneHeightfields`' generation; a still terrain dirties nothing.
#[test]
fn terrains_dirty_the_field_when_they_appear_change_and_go() {
    use bevy::asset::RenderAssetUsages;
    use bevy::render::render_resource::{Extent3d, TextureDimension, TextureFormat};
    use bevy_penumbra_df::{DistanceFieldHeightfield, SceneHeightfields};
    let mut app = main_world::main_world_app();
    app.init_asset::<Image>().add_plugins((
        SdfAssetPlugin,
        DistanceFieldScenePlugin,
        GlobalDistanceFieldPlugin,
    ));
    app.finish();
    app.cleanup();
    app.world_mut()
        .spawn((Transform::from_xyz(0.0, 1.7, 0.0), small()));
    app.update();
    app.update();
    assert_eq!(stats(&app).bricks, 0);
    // 3 × 3 heights over 4 × 4 m around (1, 0, 1): a bump of 0.5 m in the middle.
    let heights: Vec<u8> = [0.0f32, 0.0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0, 0.0]
        .iter()
        .flat_map(|h| h.to_le_bytes())
        .collect();
    let image = app
        .world_mut()
        .resource_mut::<Assets<Image>>()
        .add(Image::new(
            Extent3d {
                width: 3,
                height: 3,
                depth_or_array_layers: 1,
            },
            TextureDimension::D2,
            heights,
            TextureFormat::R32Float,
            RenderAssetUsages::MAIN_WORLD,
        ));
    let generation = |app: &App| app.world().resource::<SceneHeightfields>().generation();
    let terrain = app
        .world_mut()
        .spawn((
            DistanceFieldHeightfield {
                heights: image,
                size: Vec2::splat(4.0),
                height_scale: 1.0,
            },
            Transform::from_xyz(1.0, 0.0, 1.0),
        ))
        .id();
    app.update();
    let s = stats(&app);
    assert!(s.dirty_regions == 1 && s.dirtied > 0, "{s:?}");
    assert_eq!(generation(&app), 1);
    assert_eq!(
        app.world()
            .resource::<SceneHeightfields>()
            .terrains()
            .count(),
        1
    );
    for _ in 0..3 {
        app.update();
        let s = stats(&app);
        assert_eq!((s.dirty_regions, s.bricks), (0, 0), "{s:?}");
    }
    app.world_mut()
        .get_mut::<DistanceFieldHeightfield>(terrain)
        .unwrap()
        .height_scale = 3.0;
    app.update();
    let s = stats(&app);
    assert!(s.dirty_regions == 2 && s.dirtied > 0, "{s:?}");
    assert_eq!(generation(&app), 2);
    app.world_mut()
        .entity_mut(terrain)
        .remove::<DistanceFieldHeightfield>();
    app.update();
    let s = stats(&app);
    assert!(s.dirty_regions == 1 && s.dirtied > 0, "{s:?}");
    app.update();
    let scene = app.world().resource::<SceneHeightfields>();
    assert_eq!((scene.terrains().count(), scene.generation()), (0, 3));
    assert!(
        app.world()
            .get::<bevy_penumbra_df::HeightfieldTerrain>(terrain)
            .is_none()
    );
}
