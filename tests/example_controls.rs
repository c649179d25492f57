//! The examples' keyboard toggles (`examples/common/controls.rs`), driven without a
//! window: `Space` stashes and restores the lights' distance-field shadows, `H` sets half
//! resolution, `D` cycles the debug view on the cameras, and the window title says so.

#[path = "../examples/common/controls.rs"]
mod controls;

use bevy::input::ButtonInput;
use bevy::prelude::*;
use penumbra::prelude::*;

fn press(app: &mut App, key: KeyCode) {
    let mut keys = app.world_mut().resource_mut::<ButtonInput<KeyCode>>();
    keys.clear();
    keys.press(key);
    app.update();
    let mut keys = app.world_mut().resource_mut::<ButtonInput<KeyCode>>();
    keys.release(key);
    keys.clear();
}

#[test]
fn keys_toggle_shadows_half_resolution_and_debug_view() {
    let mut app = App::new();
    app.add_plugins(MinimalPlugins)
        .init_resource::<ButtonInput<KeyCode>>();
    controls::add_controls(&mut app, "test");
    let light = app
        .world_mut()
        .spawn((DirectionalLight::default(), DistanceFieldShadows::default()))
        .id();
    let camera = app.world_mut().spawn(Camera3d::default()).id();
    let window = app.world_mut().spawn(Window::default()).id();
    app.update();
    let title = |app: &App| app.world().get::<Window>(window).unwrap().title.clone();
    assert!(title(&app).contains("DF shadows: on"), "{}", title(&app));

    press(&mut app, KeyCode::Space);
    assert!(app.world().get::<DistanceFieldShadows>(light).is_none());
    assert!(title(&app).contains("DF shadows: off"));
    press(&mut app, KeyCode::KeyH);
    press(&mut app, KeyCode::Space);
    let shadows = app
        .world()
        .get::<DistanceFieldShadows>(light)
        .expect("restored");
    assert!(
        !shadows.half_resolution,
        "stashed before H: restored as it was"
    );
    press(&mut app, KeyCode::KeyH);
    press(&mut app, KeyCode::KeyH);
    assert!(
        app.world()
            .get::<DistanceFieldShadows>(light)
            .unwrap()
            .half_resolution
    );
    assert!(title(&app).contains("half-res: on"));

    press(&mut app, KeyCode::KeyD);
    let view = app
        .world()
        .get::<DistanceFieldDebugView>(camera)
        .expect("debug view");
    assert_eq!(view.mode, DistanceFieldDebugMode::StepCount);
    press(&mut app, KeyCode::KeyD);
    assert_eq!(
        app.world()
            .get::<DistanceFieldDebugView>(camera)
            .unwrap()
            .mode,
        DistanceFieldDebugMode::Shaded
    );
    press(&mut app, KeyCode::KeyD);
    assert!(app.world().get::<DistanceFieldDebugView>(camera).is_none());
    assert!(title(&app).contains("debug view: off"));
}

#[test]
fn keys_toggle_dfao_and_its_debug_view() {
    let mut app = App::new();
    app.add_plugins(MinimalPlugins)
        .init_resource::<ButtonInput<KeyCode>>();
    controls::add_controls(&mut app, "test");
    let camera = app
        .world_mut()
        .spawn((
            Camera3d::default(),
            DistanceFieldAmbientOcclusion {
                max_occlusion_distance: 3.0,
                ..default()
            },
        ))
        .id();
    let window = app.world_mut().spawn(Window::default()).id();
    app.update();
    let title = |app: &App| app.world().get::<Window>(window).unwrap().title.clone();
    assert!(title(&app).contains("DFAO: on"), "{}", title(&app));
    let ao = |app: &App| {
        app.world()
            .get::<DistanceFieldAmbientOcclusion>(camera)
            .cloned()
    };

    press(&mut app, KeyCode::KeyV);
    assert_eq!(
        ao(&app).unwrap().debug_view,
        DistanceFieldAoDebugView::AmbientOcclusion
    );
    press(&mut app, KeyCode::KeyA);
    assert!(ao(&app).is_none(), "A removes DFAO");
    assert!(title(&app).contains("DFAO: off"));
    press(&mut app, KeyCode::KeyA);
    let restored = ao(&app).expect("A restores it");
    assert_eq!(restored.max_occlusion_distance, 3.0, "as it was");
    for want in [
        DistanceFieldAoDebugView::BentNormal,
        DistanceFieldAoDebugView::ObjectsPerTile,
        DistanceFieldAoDebugView::None,
    ] {
        press(&mut app, KeyCode::KeyV);
        assert_eq!(ao(&app).unwrap().debug_view, want);
    }
    assert!(title(&app).contains("AO view: off"), "{}", title(&app));
}

/// On a camera with a `GlobalDistanceField`, `D` goes on from the shaded view to the
/// field's three views before turning off.
#[test]
fn d_cycles_through_the_global_field_views_on_a_field_camera() {
    let mut app = App::new();
    app.add_plugins(MinimalPlugins)
        .init_resource::<ButtonInput<KeyCode>>();
    controls::add_controls(&mut app, "test");
    let camera = app
        .world_mut()
        .spawn((Camera3d::default(), GlobalDistanceField::default()))
        .id();
    let mut modes = Vec::new();
    for _ in 0..6 {
        press(&mut app, KeyCode::KeyD);
        modes.push(
            app.world()
                .get::<DistanceFieldDebugView>(camera)
                .map(|v| v.mode),
        );
    }
    use DistanceFieldDebugMode as M;
    assert_eq!(
        modes,
        [
            Some(M::StepCount),
            Some(M::Shaded),
            Some(M::GlobalField),
            Some(M::ClipmapLevels),
            Some(M::GlobalFieldUpdates),
            None
        ]
    );
}
