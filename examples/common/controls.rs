//! Keyboard toggles shared by the examples, shown in the window title (on-screen, with
//! no UI dependency) and printed once at start:
//!
//! - `Space`: distance-field shadows on/off. Off, the lights fall back to Bevy's shadow
//!   maps (the examples' lights keep `shadow_maps_enabled`): compare the two.
//! - `H`: half-resolution shadow tracing on/off.
//! - `D`: the distance-field debug view: off → step-count heat map → shaded → off; with
//!   a `GlobalDistanceField` on a camera (`dfao --global-field`), also its clipmaps
//!   (shaded → tinted by clipmap level → bricks updated this frame) before off.
//! - `A`: distance-field ambient occlusion on/off (cameras that have it).
//! - `V`: the DFAO debug view: off → AO → bent normal → objects per tile → off.
//!
//! Windowed runs only: headless captures are not affected.

use bevy::prelude::*;
use penumbra::prelude::*;

/// The toggles as text, printed at start.
pub const HELP: &str = "keys: [Space] distance-field shadows on/off (off: Bevy's shadow maps) · \
    [H] half-resolution shadows · [D] debug view (off / step count / shaded / \
    global field / clipmap levels / field updates) · \
    [A] distance-field AO on/off · [V] AO view (off / AO / bent normal / objects per tile)";

/// Adds the toggles to a windowed example app.
pub fn add_controls(app: &mut App, name: &str) {
    println!("{name}: {HELP}");
    app.insert_resource(Controls {
        name: name.to_string(),
        ..default()
    })
    .add_systems(Update, (toggle, show_in_title).chain());
}

/// What the toggles have set.
#[derive(Resource, Clone, Debug, Default)]
struct Controls {
    name: String,
    shadows_off: bool,
    half_resolution: bool,
    debug: Option<DistanceFieldDebugMode>,
    ao_off: bool,
    ao_view: DistanceFieldAoDebugView,
}

/// A light's distance-field shadows while they are toggled off.
#[derive(Component, Clone)]
struct StashedShadows(DistanceFieldShadows);

/// A camera's distance-field AO while it is toggled off.
#[derive(Component, Clone)]
struct StashedAo(DistanceFieldAmbientOcclusion);

/// The cameras with DFAO on, and those with it stashed.
type AoCameras<'w, 's> = (
    Query<'w, 's, (Entity, &'static mut DistanceFieldAmbientOcclusion)>,
    Query<'w, 's, (Entity, &'static StashedAo)>,
);

fn toggle(
    mut commands: Commands,
    keys: Res<ButtonInput<KeyCode>>,
    mut controls: ResMut<Controls>,
    mut lit: Query<(Entity, &mut DistanceFieldShadows)>,
    stashed: Query<(Entity, &StashedShadows)>,
    cameras: Query<(Entity, Has<GlobalDistanceField>), With<Camera3d>>,
    ao: AoCameras,
) {
    toggle_ao(&mut commands, &keys, &mut controls, ao);
    if keys.just_pressed(KeyCode::Space) {
        controls.shadows_off = !controls.shadows_off;
        if controls.shadows_off {
            for (entity, shadows) in &lit {
                commands
                    .entity(entity)
                    .insert(StashedShadows(shadows.clone()))
                    .remove::<DistanceFieldShadows>();
            }
        } else {
            for (entity, StashedShadows(shadows)) in &stashed {
                commands
                    .entity(entity)
                    .insert(shadows.clone())
                    .remove::<StashedShadows>();
            }
        }
    }
    if keys.just_pressed(KeyCode::KeyH) {
        controls.half_resolution = !controls.half_resolution;
        for (_, mut shadows) in &mut lit {
            shadows.half_resolution = controls.half_resolution;
        }
    }
    if keys.just_pressed(KeyCode::KeyD) {
        controls.debug = match controls.debug {
            None => Some(DistanceFieldDebugMode::StepCount),
            Some(DistanceFieldDebugMode::StepCount) => Some(DistanceFieldDebugMode::Shaded),
            Some(DistanceFieldDebugMode::Shaded) if cameras.iter().any(|(_, field)| field) => {
                Some(DistanceFieldDebugMode::GlobalField)
            }
            Some(DistanceFieldDebugMode::GlobalField) => {
                Some(DistanceFieldDebugMode::ClipmapLevels)
            }
            Some(DistanceFieldDebugMode::ClipmapLevels) => {
                Some(DistanceFieldDebugMode::GlobalFieldUpdates)
            }
            Some(_) => None,
        };
        for (camera, _) in &cameras {
            match controls.debug {
                Some(mode) => commands
                    .entity(camera)
                    .insert(DistanceFieldDebugView { mode, ..default() }),
                None => commands.entity(camera).remove::<DistanceFieldDebugView>(),
            };
        }
    }
}

/// `A` and `V`.
fn toggle_ao(
    commands: &mut Commands,
    keys: &ButtonInput<KeyCode>,
    controls: &mut Controls,
    (mut on, stashed): AoCameras,
) {
    if keys.just_pressed(KeyCode::KeyA) {
        controls.ao_off = !controls.ao_off;
        if controls.ao_off {
            for (entity, ao) in &on {
                commands
                    .entity(entity)
                    .insert(StashedAo(ao.clone()))
                    .remove::<DistanceFieldAmbientOcclusion>();
            }
        } else {
            for (entity, StashedAo(ao)) in &stashed {
                commands
                    .entity(entity)
                    .insert(ao.clone())
                    .remove::<StashedAo>();
            }
        }
    }
    if keys.just_pressed(KeyCode::KeyV) {
        controls.ao_view = match controls.ao_view {
            DistanceFieldAoDebugView::None => DistanceFieldAoDebugView::AmbientOcclusion,
            DistanceFieldAoDebugView::AmbientOcclusion => DistanceFieldAoDebugView::BentNormal,
            DistanceFieldAoDebugView::BentNormal => DistanceFieldAoDebugView::ObjectsPerTile,
            DistanceFieldAoDebugView::ObjectsPerTile => DistanceFieldAoDebugView::None,
        };
        for (_, mut ao) in &mut on {
            ao.debug_view = controls.ao_view;
        }
    }
}

fn show_in_title(controls: Res<Controls>, mut windows: Query<&mut Window>) {
    if !controls.is_changed() {
        return;
    }
    let on_off = |on: bool| if on { "on" } else { "off" };
    let debug = match controls.debug {
        None => "off",
        Some(DistanceFieldDebugMode::StepCount) => "step count",
        Some(DistanceFieldDebugMode::Shaded) => "shaded",
        Some(DistanceFieldDebugMode::GlobalField) => "global field",
        Some(DistanceFieldDebugMode::ClipmapLevels) => "clipmap levels",
        Some(DistanceFieldDebugMode::GlobalFieldUpdates) => "field updates",
    };
    let ao_view = match controls.ao_view {
        DistanceFieldAoDebugView::None => "off",
        DistanceFieldAoDebugView::AmbientOcclusion => "AO",
        DistanceFieldAoDebugView::BentNormal => "bent normal",
        DistanceFieldAoDebugView::ObjectsPerTile => "objects per tile",
    };
    let title = format!(
        "Penumbra {} — [Space] DF shadows: {} · [H] half-res: {} · [D] debug view: {} · \
         [A] DFAO: {} · [V] AO view: {}",
        controls.name,
        on_off(!controls.shadows_off),
        on_off(controls.half_resolution),
        debug,
        on_off(!controls.ao_off),
        ao_view
    );
    for mut window in &mut windows {
        window.title = title.clone();
    }
}
