//! The distance-field debug view: what the distance-field scene looks like to the
//! lighting passes.
//!
//! Add [`DistanceFieldDebugView`] to a 3D camera: after Bevy's post-processing, each
//! pixel's camera ray is sphere-traced through the objects that survive the view's GPU
//! culling (atlas volumes sampled with exact trilinear texel loads, analytic shapes
//! evaluated directly), and the image is replaced by
//!
//! - [`DistanceFieldDebugMode::StepCount`]: a heat map of tracing steps (black → red →
//!   yellow → white as steps grow) — where tracing is expensive: grazing rays, thin
//!   gaps, many overlapping objects;
//! - [`DistanceFieldDebugMode::Shaded`]: the traced surfaces, Lambert-shaded with a fixed
//!   light — what the distance fields *are* (compare with the rasterised meshes).
//!
//! Cost: one fullscreen pass looping over every culled object at every step; meant for
//! inspection, not shipping. Perspective cameras only (an orthographic one gets a
//! one-time warning). The CPU model is `penumbra_reference::df::debug_pixel`.

mod render;

use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};

/// Adds [`DistanceFieldDebugView`]. Part of `PenumbraPlugins`.
#[derive(Default)]
pub struct DistanceFieldDebugPlugin;

/// What the debug view shows.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DistanceFieldDebugMode {
    /// Heat map of sphere-tracing steps (white: `max_steps`).
    #[default]
    StepCount,
    /// Lambert-shaded traced surfaces.
    Shaded,
}

/// Replaces a camera's image with a view of the distance-field scene.
#[derive(Component, Reflect, Clone, Debug, ExtractComponent)]
#[reflect(Component, Clone, Default)]
#[require(Camera3d)]
pub struct DistanceFieldDebugView {
    /// What to show. Default [`DistanceFieldDebugMode::StepCount`].
    pub mode: DistanceFieldDebugMode,
    /// Sphere-tracing step limit (the heat map's white). Default 128; cost is linear.
    pub max_steps: u32,
    /// Trace length, metres. Default 100.
    pub max_distance: f32,
}

impl Default for DistanceFieldDebugView {
    fn default() -> Self {
        Self {
            mode: DistanceFieldDebugMode::StepCount,
            max_steps: 128,
            max_distance: 100.0,
        }
    }
}

impl Plugin for DistanceFieldDebugPlugin {
    fn build(&self, app: &mut App) {
        crate::require_plugin::<crate::DistanceFieldScenePlugin>(
            app,
            "DistanceFieldDebugPlugin",
            "DistanceFieldScenePlugin",
        );
        app.register_type::<DistanceFieldDebugView>()
            .add_plugins(ExtractComponentPlugin::<DistanceFieldDebugView>::default());
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app);
        }
    }

    fn finish(&self, app: &mut App) {
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::finish(render_app);
        }
    }
}
