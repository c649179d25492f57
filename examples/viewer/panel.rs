//! The viewer's egui panel (`bevy_egui`): every public Penumbra setting, live — the
//! camera's `PenumbraLighting` (off: plain Bevy with shadow maps) and
//! `DistanceFieldDebugView`, its `BokehDepthOfField`, each light's
//! `DistanceFieldShadows`, the scene's `DistanceFieldSceneCasters` — and Penumbra's
//! diagnostics and pass times.

use super::ViewerCamera;
use super::camera::UiHasInput;
use bevy::diagnostic::DiagnosticsStore;
use bevy::prelude::*;
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};
use penumbra::df::{
    DistanceFieldDebugMode, DistanceFieldDebugView, DistanceFieldSceneCasters, SceneCasterCounts,
    SceneTwoSided, SkinnedCasters,
};
use penumbra::prelude::*;

/// The panel (windowed).
pub fn add_panel(app: &mut App) {
    app.add_plugins(EguiPlugin::default())
        .add_systems(EguiPrimaryContextPass, panel);
}

/// Settings of lights whose distance-field shadows are switched off, to restore.
#[derive(Component, Clone)]
struct StashedShadows(DistanceFieldShadows);

#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
#[allow(clippy::type_complexity)]
fn panel(
    mut contexts: EguiContexts,
    mut commands: Commands,
    mut ui_input: ResMut<UiHasInput>,
    camera: Single<
        (
            Entity,
            Has<PenumbraLighting>,
            Option<&mut DistanceFieldDebugView>,
            Option<&mut BokehDepthOfField>,
        ),
        With<ViewerCamera>,
    >,
    mut lights: Query<
        (
            Entity,
            Option<&Name>,
            Option<&mut DistanceFieldShadows>,
            Option<&StashedShadows>,
            Has<DirectionalLight>,
        ),
        Or<(With<DirectionalLight>, With<PointLight>, With<SpotLight>)>,
    >,
    mut scene: Query<(&mut DistanceFieldSceneCasters, Option<&SceneCasterCounts>)>,
    root: Single<Entity, With<super::ViewerScene>>,
    diagnostics: Res<DiagnosticsStore>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    let (camera, lit, debug, bokeh) = camera.into_inner();
    egui::Window::new("Penumbra")
        .default_width(340.0)
        .show(ctx, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                ui.heading("Penumbra");
                let mut on = lit;
                if ui
                    .checkbox(&mut on, "Penumbra lighting (off: plain Bevy)")
                    .changed()
                {
                    if on {
                        commands.entity(camera).insert(PenumbraLighting);
                    } else {
                        commands.entity(camera).remove::<PenumbraLighting>();
                    }
                }
                debug_view(ui, &mut commands, camera, debug);
                bokeh_ui(ui, &mut commands, camera, bokeh);
                ui.separator();
                ui.heading("Lights");
                for (entity, name, shadows, stash, directional) in &mut lights {
                    let label = name.map_or_else(|| entity.to_string(), |n| n.to_string());
                    light_ui(
                        ui,
                        &mut commands,
                        entity,
                        &label,
                        shadows,
                        stash,
                        directional,
                    );
                }
                ui.separator();
                ui.heading("Casters");
                if scene.is_empty() && ui.button("Make the scene's meshes casters").clicked() {
                    commands
                        .entity(*root)
                        .insert(DistanceFieldSceneCasters::default());
                }
                for (mut casters, counts) in &mut scene {
                    casters_ui(ui, &mut casters, counts);
                }
                ui.separator();
                ui.heading("Diagnostics");
                for d in diagnostics.iter() {
                    let path = d.path().as_str();
                    if path.contains("penumbra")
                        && let Some(v) = d.smoothed()
                    {
                        ui.label(format!("{path}: {v:.3}{}", d.suffix));
                    }
                }
            });
        });
    ui_input.pointer = ctx.egui_wants_pointer_input() || ctx.is_pointer_over_egui();
    ui_input.keyboard = ctx.egui_wants_keyboard_input();
    Ok(())
}

fn debug_view(
    ui: &mut egui::Ui,
    commands: &mut Commands,
    camera: Entity,
    debug: Option<Mut<DistanceFieldDebugView>>,
) {
    let mut on = debug.is_some();
    if ui.checkbox(&mut on, "Distance-field debug view").changed() {
        if on {
            commands
                .entity(camera)
                .insert(DistanceFieldDebugView::default());
        } else {
            commands.entity(camera).remove::<DistanceFieldDebugView>();
        }
    }
    if let Some(mut d) = debug {
        ui.horizontal(|ui| {
            ui.radio_value(&mut d.mode, DistanceFieldDebugMode::StepCount, "step count");
            ui.radio_value(&mut d.mode, DistanceFieldDebugMode::Shaded, "shaded");
        });
        ui.add(egui::Slider::new(&mut d.max_steps, 8..=512).text("max steps"));
        ui.add(
            egui::Slider::new(&mut d.max_distance, 1.0..=10_000.0)
                .logarithmic(true)
                .text("max distance (m)"),
        );
    }
}

/// Scatter bokeh depth of field: on/off, focus, aperture and its shape.
fn bokeh_ui(
    ui: &mut egui::Ui,
    commands: &mut Commands,
    camera: Entity,
    bokeh: Option<Mut<BokehDepthOfField>>,
) {
    let mut on = bokeh.is_some();
    if ui.checkbox(&mut on, "Bokeh depth of field").changed() {
        if on {
            commands.entity(camera).insert(BokehDepthOfField::default());
        } else {
            commands.entity(camera).remove::<BokehDepthOfField>();
        }
    }
    if let Some(mut b) = bokeh {
        ui.add(
            egui::Slider::new(&mut b.focal_distance, 0.1..=1_000.0)
                .logarithmic(true)
                .text("focal distance (m)"),
        );
        ui.add(
            egui::Slider::new(&mut b.aperture_f_stops, 0.01..=22.0)
                .logarithmic(true)
                .text("f-stops"),
        );
        ui.add(
            egui::Slider::new(&mut b.max_circle_of_confusion_diameter, 1.0..=256.0)
                .text("max CoC (px)"),
        );
        ui.horizontal(|ui| {
            ui.radio_value(&mut b.aperture, BokehAperture::Hexagon, "hexagon");
            ui.radio_value(&mut b.aperture, BokehAperture::Circle, "circle");
        });
        ui.checkbox(&mut b.merge_blocks, "1-or-4 sprites per block");
        ui.add_enabled(
            b.merge_blocks,
            egui::Checkbox::new(&mut b.merge_groups, "one sprite per agreeing 4×4 group"),
        );
    }
}

fn light_ui(
    ui: &mut egui::Ui,
    commands: &mut Commands,
    entity: Entity,
    label: &str,
    shadows: Option<Mut<DistanceFieldShadows>>,
    stash: Option<&StashedShadows>,
    directional: bool,
) {
    ui.collapsing(label, |ui| {
        let mut on = shadows.is_some();
        if ui
            .checkbox(&mut on, "distance-field shadows (off: shadow map)")
            .changed()
        {
            let mut e = commands.entity(entity);
            match (&shadows, on) {
                (Some(s), false) => {
                    e.insert(StashedShadows((**s).clone()))
                        .remove::<DistanceFieldShadows>();
                }
                (None, true) => {
                    e.insert(stash.map(|s| s.0.clone()).unwrap_or_default());
                }
                _ => {}
            }
        }
        let Some(mut s) = shadows else { return };
        if directional {
            let mut deg = s.angular_diameter.to_degrees();
            if ui
                .add(egui::Slider::new(&mut deg, 0.0..=20.0).text("angular diameter (°)"))
                .changed()
            {
                s.angular_diameter = deg.to_radians();
            }
            ui.add(
                egui::Slider::new(&mut s.max_distance, 0.1..=100_000.0)
                    .logarithmic(true)
                    .text("max distance (m)"),
            );
            ui.add(
                egui::Slider::new(&mut s.max_view_distance, 0.1..=100_000.0)
                    .logarithmic(true)
                    .text("max view distance (m)"),
            );
        }
        ui.add(egui::Slider::new(&mut s.max_steps, 1..=256).text("max steps"));
        ui.add(
            egui::Slider::new(&mut s.bias, 0.0..=100.0)
                .logarithmic(true)
                .text("bias (m)"),
        );
        ui.add(egui::Slider::new(&mut s.shaping, 0.05..=2.0).text("shaping"));
        ui.checkbox(&mut s.half_resolution, "half resolution");
    });
}

fn casters_ui(
    ui: &mut egui::Ui,
    casters: &mut Mut<DistanceFieldSceneCasters>,
    counts: Option<&SceneCasterCounts>,
) {
    if let Some(c) = counts {
        ui.label(format!(
            "{} casters ({} two-sided, {} ground, {} double-sided but closed: solid, {} shaded \
             apart from their faces, {} primitives merged into them); {} skinned meshes \
             cast through {} capsules; skipped: {} skinned, {} small, {} blended or glass, {} \
             other",
            c.casters,
            c.two_sided,
            c.ground,
            c.solid_double_sided,
            c.shaded_apart,
            c.merged,
            c.capsule_meshes,
            c.capsules,
            c.skinned,
            c.small,
            c.blended,
            c.unsupported
        ));
    }
    // Edit a copy: writing through `Mut` every frame would re-tag the scene every frame.
    let mut edit = (**casters).clone();
    ui.horizontal(|ui| {
        ui.label("skinned:");
        ui.radio_value(&mut edit.skinned, SkinnedCasters::Skip, "skip");
        ui.radio_value(&mut edit.skinned, SkinnedCasters::BindPose, "bind pose");
        ui.radio_value(&mut edit.skinned, SkinnedCasters::Capsules, "capsules");
    });
    ui.horizontal(|ui| {
        ui.label("two-sided:");
        ui.radio_value(&mut edit.two_sided, SceneTwoSided::Never, "never");
        ui.radio_value(
            &mut edit.two_sided,
            SceneTwoSided::FromMaterial,
            "from material",
        );
        ui.radio_value(&mut edit.two_sided, SceneTwoSided::Always, "always");
    });
    ui.add(
        egui::Slider::new(&mut edit.min_size, 0.0..=100.0)
            .logarithmic(true)
            .text("min size (m)"),
    );
    ui.add(
        egui::Slider::new(&mut edit.caster.resolution_scale, 0.125..=4.0)
            .logarithmic(true)
            .text("resolution scale"),
    );
    ui.checkbox(&mut edit.caster.casts_shadows, "cast shadows");
    ui.checkbox(&mut edit.caster.cast_hidden_shadow, "cast hidden shadow");
    if edit.skinned != casters.skinned
        || edit.two_sided != casters.two_sided
        || edit.min_size != casters.min_size
        || edit.caster.resolution_scale != casters.caster.resolution_scale
        || edit.caster.casts_shadows != casters.caster.casts_shadows
        || edit.caster.cast_hidden_shadow != casters.caster.cast_hidden_shadow
    {
        **casters = edit;
    }
}
