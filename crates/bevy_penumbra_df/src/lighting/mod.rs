//! Penumbra's lighting pass: deferred shading of Bevy's G-buffer with Penumbra's own
//! light loop, so that a light's visibility can come from a Penumbra shadow mask
//! (distance-field shadows) instead of Bevy's shadow map.
//!
//! # How it plugs into Bevy
//!
//! Bevy's `StandardMaterial` fetches shadow maps inside `apply_pbr_lighting`, with no
//! hook to substitute a visibility. Bevy's deferred renderer, though, lets a camera skip
//! its lighting pass (`SkipDeferredLighting`) to run a custom one. A camera with
//! [`PenumbraLighting`] therefore renders its opaque deferred materials to Bevy's G-buffer
//! (the component requires `DeferredPrepass` and `DepthPrepass`), and Penumbra's pass —
//! a fullscreen triangle, depth-tested against Bevy's lighting-id texture exactly like
//! Bevy's pass, with Bevy's own view bind groups — shades every G-buffer sample:
//! point, spot, directional (and rect) lights with Bevy's BRDF functions, shadow maps
//! (PCF, cascades) or Penumbra masks, contact shadows, SSAO, irradiance volumes,
//! environment maps (SSR-aware), ambient light, emissive, fog and tonemapping. With no
//! mask in use the image equals Bevy's deferred rendering (tested).
//!
//! The plugin makes deferred the default opaque render method
//! (`DefaultOpaqueRendererMethod::deferred()`), so scenes and `StandardMaterial`s stay as
//! they are. Limits (as for Bevy's deferred renderer): forward-only and transparent
//! materials are lit by Bevy's forward path (their lights keep shadow maps); MSAA is not
//! supported on deferred cameras (Bevy switches it off with a warning; until it has, the
//! camera is left to Bevy, with one warning of Penumbra's); a 3D camera without a
//! `DeferredPrepass` does not show deferred materials (warned once).
//!
//! Cost: one fullscreen pass per camera, replacing Bevy's; nothing for cameras without
//! the component.

pub(crate) mod render;

use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::pbr::deferred::{PbrDeferredLightingDepthId, SkipDeferredLighting};
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::sync_component::SyncComponent;

pub use render::{PenumbraLightingInputs, PenumbraShadowedLight, ShadowedLightKind};

/// Adds [`PenumbraLighting`] and makes deferred the default opaque render method. Part
/// of `PenumbraPlugins`.
#[derive(Default)]
pub struct PenumbraLightingPlugin;

/// Renders a camera's deferred opaque materials through Penumbra's lighting pass
/// (module docs). Needed by every Penumbra lighting feature (distance-field shadows,
/// later occlusion); on its own it reproduces Bevy's deferred lighting.
#[derive(Component, Reflect, Clone, Debug, Default)]
#[reflect(Component, Clone, Default)]
#[require(Camera3d, DeferredPrepass, DepthPrepass)]
pub struct PenumbraLighting;

/// Render-world marker of a camera served by Penumbra's lighting pass, with the
/// G-buffer's material pass id.
#[derive(Component, Clone, Copy, Debug)]
pub struct PenumbraLightingView {
    /// Bevy's deferred lighting pass id (`PbrDeferredLightingDepthId`).
    pub depth_id: u32,
}

impl SyncComponent for PenumbraLighting {
    type Target = (PenumbraLightingView, SkipDeferredLighting);
}

impl ExtractComponent for PenumbraLighting {
    type QueryData = (
        Entity,
        Option<&'static PbrDeferredLightingDepthId>,
        Option<&'static Msaa>,
    );
    // Bevy's extraction queries `QueryData` with this filter only: without it, every
    // render-synced entity (lights, other cameras) got the marker and
    // `SkipDeferredLighting`.
    type QueryFilter = With<PenumbraLighting>;
    type Out = (PenumbraLightingView, SkipDeferredLighting);

    fn extract_component(
        (entity, depth_id, msaa): (Entity, Option<&PbrDeferredLightingDepthId>, Option<&Msaa>),
    ) -> Option<Self::Out> {
        if msaa.is_some_and(|m| *m != Msaa::Off) {
            warn_once_per_camera(entity);
            return None; // Bevy's own deferred pass (or its MSAA warning) takes over
        }
        let depth_id = depth_id.copied().unwrap_or_default().get() as u32;
        Some((PenumbraLightingView { depth_id }, SkipDeferredLighting))
    }
}

fn warn_once_per_camera(entity: Entity) {
    use std::sync::Mutex;
    static WARNED: Mutex<Vec<Entity>> = Mutex::new(Vec::new());
    let mut warned = WARNED.lock().unwrap_or_else(|e| e.into_inner());
    if !warned.contains(&entity) {
        warned.push(entity);
        warn!(
            "Penumbra: camera {entity} has PenumbraLighting and MSAA; deferred lighting needs \
             `Msaa::Off`: Penumbra's lighting (and its distance-field shadows) is off for it"
        );
    }
}

impl Plugin for PenumbraLightingPlugin {
    fn build(&self, app: &mut App) {
        crate::shader_library::register_shader_library(app);
        app.register_type::<PenumbraLighting>()
            .insert_resource(DefaultOpaqueRendererMethod::deferred())
            .add_plugins(ExtractComponentPlugin::<PenumbraLighting>::default())
            .add_systems(PostUpdate, warn_forward_cameras);
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

/// Whether the default opaque render method is deferred (the field is private: read
/// through reflection).
fn is_deferred(method: &DefaultOpaqueRendererMethod) -> bool {
    use bevy::material::OpaqueRendererMethod;
    use bevy::reflect::ReflectRef;
    match method.reflect_ref() {
        ReflectRef::TupleStruct(t) => t
            .field(0)
            .and_then(|f| f.try_downcast_ref::<OpaqueRendererMethod>())
            .is_some_and(|m| *m == OpaqueRendererMethod::Deferred),
        _ => false,
    }
}

/// 3D cameras without a deferred G-buffer.
type ForwardCameras = (With<Camera3d>, Without<DeferredPrepass>);

/// With deferred the default render method, a 3D camera without a deferred prepass
/// does not show opaque `StandardMaterial`s: say so once per camera.
fn warn_forward_cameras(
    cameras: Query<(Entity, &Camera), ForwardCameras>,
    method: Res<DefaultOpaqueRendererMethod>,
    mut warned: Local<Vec<Entity>>,
) {
    if !is_deferred(&method) {
        return;
    }
    for (entity, camera) in &cameras {
        if camera.is_active && !warned.contains(&entity) {
            warned.push(entity);
            warn!(
                "Penumbra: 3D camera {entity} has no DeferredPrepass, but Penumbra made deferred \
                 the default opaque render method: add `PenumbraLighting` (or `DeferredPrepass`) \
                 to it, or set `DefaultOpaqueRendererMethod::forward()` after adding the plugins"
            );
        }
    }
}
