//! The **global distance field**: the whole scene's distance in camera-centred
//! clipmaps, composited from the casters' distance fields and updated incrementally
//! (Wright, *Dynamic Occlusion with Signed Distance Fields*, SIGGRAPH 2015; UE4's global
//! distance field) — what lets cone traces go far without visiting every object.
//!
//! Put [`GlobalDistanceField`] on a camera: `clipmap_count` cubes of `resolution³`
//! texels centred on it, the first `first_extent` metres across, each `growth` times
//! the last. The books are `penumbra_df_core::clipmap`'s (its module docs: toroidal
//! addressing, windows moved in 8³ bricks, dirty regions, the per-frame brick budget,
//! which bricks are valid); the composition and its bounds are
//! `penumbra_reference::global_sdf`'s (each texel the nearest surface's distance less
//! half a texel diagonal, clamped to ± 8 texels, 8 bits, never above the true distance
//! plus a texel diagonal); `shaders/df/global_compose.wgsl` composes on the GPU.
//!
//! Per frame, in `PostUpdate` after the scene's records: the records that changed give
//! dirty regions (their bounding balls before and after), each camera's clipmaps move
//! with it, and at most `brick_budget` pending bricks are handed out for composition,
//! finest level and nearest first ([`GlobalDistanceFieldStats`] counts them). What is
//! shown meanwhile: a pending brick is invalid, and samplers read the next coarser level
//! there (or treat the far field as open where none is valid: the frames after a
//! teleport); nothing stale is ever read.
//!
//! # Limits
//!
//! - Transmissive casters (foliage) stay out: they occlude only within the objects'
//!   own near-field trace.
//! - Walls: 2 cm walls stay opaque to far-field cones through level 2 (0.8 m texels);
//!   the dilation that ensures it darkens open scenes a little (about 0.05 AO).
//!
//! Cost: nothing without the component. Per camera: `clipmap_count × resolution³`
//! bytes (8 MiB by default) and the composition of the handed-out bricks — none for a
//! still camera in a still scene.
//!
//! On the GPU (`render.rs`): per camera, the clipmaps in pooled buffers, composed in the
//! `RenderGraph` schedule after the object deltas; DFAO's trace reads them beyond
//! `DistanceFieldAmbientOcclusion::global_field_start`, and `DistanceFieldParticles`
//! collide with them. (Distance-field shadows trace the objects' own fields: their
//! rays are short and need the objects' detail.)
//!
//! Terrains (`DistanceFieldHeightfield`) are composed like objects; a terrain that
//! appears, changes or goes dirties its bounds.
//!
//! Debug views (`debug.rs`): a `DistanceFieldDebugView` in mode
//! `GlobalField`, `ClipmapLevels` or `GlobalFieldUpdates` on the same camera shows the
//! clipmaps sphere-traced and shaded, tinted by the level that answered, or with the
//! bricks composed this frame in orange (`debug_view` module docs).

#[cfg(feature = "debug_view")]
mod debug;
pub(crate) mod render;

use crate::scene::{
    DistanceFieldFrame, DistanceFieldScene, DistanceFieldSystems, SceneHeightfields,
};
use crate::system_times::timed;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::sync_component::SyncComponent;
use penumbra_df_core::clipmap::{
    ClipmapLayout, ClipmapState, DEFAULT_BRICK_BUDGET, DirtyBox, record_dirty_box,
};
use penumbra_df_core::object::ObjectRecord;
pub use render::{ExtractedGlobalField, ViewGlobalField};
// The field's readers: DFAO's trace and the particles' step.
pub(crate) use render::{compose_global_fields, empty_read_group, read_layout};

/// Adds the global distance field to cameras with [`GlobalDistanceField`]. Part of
/// `PenumbraPlugins`; needs `DistanceFieldScenePlugin`.
#[derive(Default)]
pub struct GlobalDistanceFieldPlugin;

/// Put on a camera: the scene's distance in clipmaps around it (module docs).
#[derive(Component, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Clone, Default)]
pub struct GlobalDistanceField {
    /// Number of clipmaps. Default 4 (Unreal's). Memory and a teleport's work are
    /// linear in it. Clamped to `1..=8` with a warning.
    pub clipmap_count: u32,
    /// Texels per side of every clipmap. Default 128 (Unreal's). Memory and a
    /// teleport's work grow with its cube. Rounded to a multiple of 8 in `16..=256`
    /// with a warning.
    pub resolution: u32,
    /// Side of the first (finest) clipmap, metres. Default 25.6 (0.2 m texels). Must
    /// be finite and positive (a warning and the default otherwise); texels below
    /// 1 cm are raised to it.
    pub first_extent: f32,
    /// Each clipmap's side over the previous one's. Default 2 (the largest of four:
    /// 204.8 m). At least 1, finite.
    pub growth: f32,
    /// Bricks (8³ texels) composed per frame at most. Default 4,096 (2²¹ texels): a
    /// flight at 30 m/s or 100 one-metre casters moving near the camera fit; a teleport
    /// takes a few frames. At least 1.
    pub brick_budget: u32,
}

impl Default for GlobalDistanceField {
    fn default() -> Self {
        let d = ClipmapLayout::DEFAULT;
        Self {
            clipmap_count: d.levels,
            resolution: d.resolution,
            first_extent: d.first_extent,
            growth: d.growth,
            brick_budget: DEFAULT_BRICK_BUDGET as u32,
        }
    }
}

impl GlobalDistanceField {
    /// The layout and budget the settings give, and what had to be clamped (one line
    /// per setting).
    pub fn resolve(&self) -> (ClipmapLayout, usize, Vec<String>) {
        let (layout, mut problems) = ClipmapLayout::new(
            self.clipmap_count,
            self.resolution,
            self.first_extent,
            self.growth,
        );
        let budget = if self.brick_budget == 0 {
            problems.push("brick_budget = 0: using 1".into());
            1
        } else {
            self.brick_budget as usize
        };
        (layout, budget, problems)
    }
}

/// A camera's clipmaps as the main world keeps them, and this frame's update.
#[derive(Component, Debug)]
pub struct GlobalDistanceFieldState {
    settings: GlobalDistanceField,
    layout: ClipmapLayout,
    budget: usize,
    state: ClipmapState,
    /// This frame's update: the bricks to compose, and the counts.
    pub update: penumbra_df_core::clipmap::ClipmapUpdate,
}

impl GlobalDistanceFieldState {
    /// The resolved layout.
    pub fn layout(&self) -> &ClipmapLayout {
        &self.layout
    }

    /// The clipmaps' books (windows, pending bricks, validity).
    pub fn clipmaps(&self) -> &ClipmapState {
        &self.state
    }
}

impl SyncComponent for GlobalDistanceField {
    /// The render world's clipmaps go with the component.
    type Target = (ExtractedGlobalField, ViewGlobalField);
}

impl ExtractComponent for GlobalDistanceField {
    type QueryData = (&'static GlobalDistanceFieldState, &'static GlobalTransform);
    type QueryFilter = ();
    type Out = ExtractedGlobalField;

    fn extract_component(
        (state, transform): (&GlobalDistanceFieldState, &GlobalTransform),
    ) -> Option<ExtractedGlobalField> {
        Some(ExtractedGlobalField::new(state, transform.translation()))
    }
}

/// This frame's global-field work, summed over the cameras.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GlobalDistanceFieldStats {
    /// Cameras with clipmaps.
    pub cameras: usize,
    /// Bricks handed out for composition.
    pub bricks: usize,
    /// Texels in them.
    pub texels: usize,
    /// Bricks newly revealed by moving windows.
    pub scrolled: usize,
    /// Bricks newly marked by dirty regions.
    pub dirtied: usize,
    /// Bricks still pending after this frame.
    pub pending: usize,
    /// Dirty regions from changed records, terrains and re-baked fields.
    pub dirty_regions: usize,
}

/// The object records as the field last saw them (to know where a changed record was);
/// kept only while a camera has clipmaps.
#[derive(Resource, Default)]
struct SeenRecords(Option<Vec<ObjectRecord>>);

impl Plugin for GlobalDistanceFieldPlugin {
    fn build(&self, app: &mut App) {
        crate::require_plugin::<crate::DistanceFieldScenePlugin>(
            app,
            "GlobalDistanceFieldPlugin",
            "DistanceFieldScenePlugin",
        );
        crate::shader_library::register_shader_library(app);
        app.register_type::<GlobalDistanceField>()
            .init_resource::<GlobalDistanceFieldStats>()
            .init_resource::<SeenRecords>()
            .add_systems(
                PostUpdate,
                (
                    timed(warn_bad_settings),
                    timed(update_global_distance_fields),
                )
                    .chain()
                    .after(DistanceFieldSystems::UpdateObjects),
            );
        // Headless apps without a renderer (servers asking `DistanceFieldQuery`) keep
        // the main-world books only.
        if app.get_sub_app(RenderApp).is_some() {
            app.add_plugins(ExtractComponentPlugin::<GlobalDistanceField>::default());
            render::build(app.sub_app_mut(RenderApp));
            #[cfg(feature = "debug_view")]
            debug::build(app.sub_app_mut(RenderApp));
        }
    }

    fn finish(&self, app: &mut App) {
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::finish(render_app);
            #[cfg(feature = "debug_view")]
            debug::finish(render_app);
        }
    }
}

fn warn_bad_settings(cameras: Query<(Entity, &GlobalDistanceField), Changed<GlobalDistanceField>>) {
    for (entity, settings) in &cameras {
        let (_, _, problems) = settings.resolve();
        if !problems.is_empty() {
            warn!(
                "Penumbra: GlobalDistanceField on {entity}: {}; clamped",
                problems.join(", ")
            );
        }
    }
}

/// The dirty regions of this frame's record writes (where each written slot's record
/// was, and where it is now), updating the seen records.
fn dirty_regions(seen: &mut Vec<ObjectRecord>, frame: &DistanceFieldFrame) -> Vec<DirtyBox> {
    let deltas = &frame.deltas;
    if seen.len() < deltas.slot_count as usize {
        seen.resize(deltas.slot_count as usize, ObjectRecord::EMPTY);
    }
    let mut dirty = Vec::new();
    for w in &deltas.writes {
        let Some(old) = seen.get_mut(w.slot as usize) else {
            continue;
        };
        dirty.extend(record_dirty_box(old));
        dirty.extend(record_dirty_box(&w.record));
        *old = w.record;
    }
    dirty
}

#[allow(clippy::too_many_arguments, reason = "a Bevy system")]
fn update_global_distance_fields(
    mut commands: Commands,
    scene: Res<DistanceFieldScene>,
    frame: Res<DistanceFieldFrame>,
    terrains: Res<SceneHeightfields>,
    rebakes: Res<crate::scene::RebakeJobs>,
    mut seen: ResMut<SeenRecords>,
    mut stats: ResMut<GlobalDistanceFieldStats>,
    mut cameras: Query<(
        Entity,
        &GlobalDistanceField,
        &GlobalTransform,
        Option<&mut GlobalDistanceFieldState>,
    )>,
    removed: Query<Entity, (With<GlobalDistanceFieldState>, Without<GlobalDistanceField>)>,
) {
    // Without the component: nothing kept.
    for entity in &removed {
        commands.entity(entity).remove::<GlobalDistanceFieldState>();
    }
    *stats = GlobalDistanceFieldStats::default();
    if cameras.is_empty() {
        // Nothing followed, nothing kept.
        seen.0 = None;
        return;
    }
    // The records are followed while a camera has clipmaps; from the current ones when
    // the first appears (every camera is then new and composes everything).
    let mut dirty = match &mut seen.0 {
        Some(records) => dirty_regions(records, &frame),
        None => {
            seen.0 = Some(scene.records().to_vec());
            Vec::new()
        }
    };
    dirty.extend(
        terrains
            .dirty()
            .iter()
            .copied()
            .chain(rebakes.dirty_boxes())
            .map(|(min, max)| DirtyBox { min, max }),
    );
    stats.dirty_regions = dirty.len();
    for (entity, settings, transform, state) in &mut cameras {
        let camera = transform.translation();
        match state {
            Some(mut state) if state.settings == *settings => {
                let budget = state.budget;
                state.update = state.state.update(camera, &dirty, budget);
                count(&mut stats, &state.update);
            }
            _ => {
                // New, or its settings changed: start over.
                let (layout, budget, _) = settings.resolve();
                let mut clipmaps = ClipmapState::new(layout);
                let update = clipmaps.update(camera, &[], budget);
                count(&mut stats, &update);
                commands.entity(entity).insert(GlobalDistanceFieldState {
                    settings: settings.clone(),
                    layout,
                    budget,
                    state: clipmaps,
                    update,
                });
            }
        }
    }
}

fn count(stats: &mut GlobalDistanceFieldStats, update: &penumbra_df_core::clipmap::ClipmapUpdate) {
    stats.cameras += 1;
    stats.bricks += update.jobs.len();
    stats.texels += update.jobs.len() * (penumbra_df_core::clipmap::BRICK as usize).pow(3);
    stats.scrolled += update.scrolled;
    stats.dirtied += update.dirtied;
    stats.pending += update.pending;
}
