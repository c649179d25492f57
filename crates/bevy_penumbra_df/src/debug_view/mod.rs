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
//! and, on a camera that also has a
//! [`GlobalDistanceField`](crate::GlobalDistanceField), views of its clipmaps instead
//! of the objects (drawn by the global-field module; CPU model
//! `penumbra_reference::field_debug`): the ray sphere-traced through the finest valid
//! clipmap, the surface shaded by the field's gradient
//! ([`DistanceFieldDebugMode::GlobalField`]), tinted by the clipmap that answered —
//! red, orange, yellow, green, cyan, blue, violet, magenta from the finest
//! ([`DistanceFieldDebugMode::ClipmapLevels`]: where each texel size is used) — or
//! orange where its brick was composed this frame
//! ([`DistanceFieldDebugMode::GlobalFieldUpdates`]: scrolling slabs, dirty regions,
//! a teleport's backlog). Without a `GlobalDistanceField` these modes warn once and
//! leave the image as it is.
//!
//! Cost: one fullscreen pass looping over every culled object at every step; meant for
//! inspection, not shipping. Perspective cameras only (an orthographic one gets a
//! one-time warning). The CPU model is `penumbra_reference::df::debug_pixel`.

pub(crate) mod render;

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
    /// The camera's global distance field, sphere-traced and shaded.
    GlobalField,
    /// The global field tinted by the clipmap (texel size) that answered.
    ClipmapLevels,
    /// The global field, bricks composed this frame in orange.
    GlobalFieldUpdates,
}

impl DistanceFieldDebugMode {
    /// Whether the mode shows the camera's global distance field (not the objects).
    pub fn is_global_field(self) -> bool {
        matches!(
            self,
            Self::GlobalField | Self::ClipmapLevels | Self::GlobalFieldUpdates
        )
    }
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
