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
//! # What reaches the pass: materials rendered deferred, chosen by the app
//!
//! Penumbra changes nothing global: every material keeps the render method the app gave
//! it, and a camera without a Penumbra component renders exactly as it would without the
//! plugins (tested bit for bit, forward and deferred cameras). Bevy decides per
//! *material*, not per camera, whether an opaque material is drawn to the G-buffer
//! (deferred) or shaded in the forward pass, so the app makes that choice, as Bevy's own
//! deferred renderer asks it to — one line:
//!
//! ```no_run
//! # use bevy::prelude::*;
//! # use bevy::pbr::DefaultOpaqueRendererMethod;
//! App::new().insert_resource(DefaultOpaqueRendererMethod::deferred());
//! ```
//!
//! or per material (`StandardMaterial::opaque_render_method`). Materials left forward,
//! and alpha-blended or transmissive ones, are drawn by Bevy's forward pass on the
//! Penumbra camera too, lit by Bevy with shadow maps (the `shadows` module keeps a
//! distance-field-shadowed light's shadow map while such a material is in view).
//!
//! A `PenumbraLighting` camera in an app whose default opaque render method is forward
//! would shade nothing through Penumbra: that fails at startup, naming the fix
//! ([`PenumbraLightingPlugin::require_deferred_default`] turns the check off for apps that
//! choose per material). Bevy's rules for deferred materials still apply to other
//! cameras: with deferred the default, a 3D camera needs a `DeferredPrepass` to draw
//! them (warned once per camera).
//!
//! MSAA: without more, a `PenumbraLighting` camera renders without MSAA (Bevy's deferred
//! rule); with [`DeferredMsaa`] it is shaded with deferred 4× MSAA: per pixel where its
//! samples agree, per sample on edges ([`msaa`]).
//!
//! Cost: one fullscreen pass per camera, replacing Bevy's; nothing for cameras without
//! the component.

pub mod msaa;
pub(crate) mod msaa_render;
pub(crate) mod render;

use crate::face_normals::FaceNormalPrepass;
use crate::system_times::timed;
use bevy::core_pipeline::prepass::{DeferredPrepass, DepthPrepass};
use bevy::pbr::DefaultOpaqueRendererMethod;
use bevy::pbr::deferred::{PbrDeferredLightingDepthId, SkipDeferredLighting};
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::sync_component::SyncComponent;

pub use msaa::{DeferredMsaa, DeferredMsaaShading, DeferredMsaaSystems};
pub use msaa_render::DeferredMsaaTextures;
pub use render::MsaaShadedLightingIds;
pub use render::ShadowedLightKind;
pub use render::{
    PenumbraAoInput, PenumbraLightingBindGroup, PenumbraLightingPipeline, PenumbraLightingSystems,
    set_lighting_bind_groups, unresolved_color_attachment,
};
#[cfg_attr(
    not(feature = "shadows"),
    allow(
        unused_imports,
        reason = "only distance-field shadows make masks so far"
    )
)]
pub(crate) use render::{PenumbraLightingInputs, PenumbraShadowedLight};

/// Adds [`PenumbraLighting`]. Part of `PenumbraPlugins`. Changes no global setting.
#[derive(Clone, Debug)]
pub struct PenumbraLightingPlugin {
    /// Panic (naming the fix) when a [`PenumbraLighting`] camera appears while Bevy's
    /// `DefaultOpaqueRendererMethod` is forward: Penumbra's pass would then shade only the
    /// materials set to deferred one by one, most likely none. Default true; set false
    /// when the app chooses the deferred method per material. No cost.
    pub require_deferred_default: bool,
}

impl Default for PenumbraLightingPlugin {
    fn default() -> Self {
        Self {
            require_deferred_default: true,
        }
    }
}

/// The plugin's settings, as a resource for its systems.
#[derive(Resource, Clone, Debug)]
struct LightingPluginSettings {
    require_deferred_default: bool,
}

/// Renders a camera's deferred opaque materials through Penumbra's lighting pass
/// (module docs). Needed by every Penumbra lighting feature (distance-field shadows,
/// later occlusion); on its own it reproduces Bevy's deferred lighting.
///
/// Requires [`FaceNormalPrepass`]: while a light has `DistanceFieldShadows`, the camera
/// draws each pixel's triangle normal for the shadow masks' own-shadow term (on the scene
/// corpus the shadows' error over shadowed pixels fell 0.240 → 0.088 on the terrain,
/// 0.068 → 0.033 on the flight helmet). Remove it from the camera to save that pass
/// (one draw of the visible meshes, positions only) at that cost in accuracy.
#[derive(Component, Reflect, Clone, Debug, Default)]
#[reflect(Component, Clone, Default)]
#[require(Camera3d, DeferredPrepass, DepthPrepass, Msaa::Off, FaceNormalPrepass)]
pub struct PenumbraLighting;

/// A view's specular layer, inserted on the render-world view by a feature that traces
/// reflections of its own (billboard reflections): the lighting pass adds it as
/// specular light, weighted by Bevy's environment BRDF, over the environment map's
/// specular, which it covers by its coverage (`alpha`). Single-sample views only.
#[derive(Component, Clone)]
pub struct PenumbraSpecularLayer {
    /// `Rgba16Float`: premultiplied reflected radiance (cd/m², before exposure) and
    /// coverage in `[0, 1]`.
    pub texture: bevy::render::render_resource::TextureView,
    /// The texture is half the view's size, each texel holding the top-left pixel of
    /// its 2 × 2 block: the lighting pass upsamples it with depth weights.
    pub half_resolution: bool,
    /// Show the layer (radiance and coverage as the lighting pass reads it, unexposed)
    /// instead of the lighting.
    pub debug_view: bool,
}

impl PenumbraSpecularLayer {
    /// `PenumbraLightingUniform::specular_layer`.
    fn mode(&self) -> u32 {
        (if self.half_resolution { 2 } else { 1 }) + if self.debug_view { 4 } else { 0 }
    }
}

/// Render-world marker of a camera served by Penumbra's lighting pass, with the
/// G-buffer's material pass id.
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone)]
pub struct PenumbraLightingView {
    /// Bevy's deferred lighting pass id (`PbrDeferredLightingDepthId`).
    pub depth_id: u32,
    /// Deferred 4× MSAA's settings, when the camera has `Msaa::Sample4`.
    pub msaa: Option<DeferredMsaa>,
}

impl SyncComponent for PenumbraLighting {
    type Target = (PenumbraLightingView, SkipDeferredLighting);
}

impl ExtractComponent for PenumbraLighting {
    type QueryData = (
        Entity,
        Option<&'static PbrDeferredLightingDepthId>,
        Option<&'static Msaa>,
        Option<&'static DeferredMsaa>,
    );
    // Bevy's extraction queries `QueryData` with this filter only: without it, every
    // render-synced entity (lights, other cameras) got the marker and
    // `SkipDeferredLighting`.
    type QueryFilter = With<PenumbraLighting>;
    type Out = (PenumbraLightingView, SkipDeferredLighting);

    /// `Msaa` other than `Off` reaches here only as `Sample4` on a `DeferredMsaa` camera
    /// whose renderer multisamples the G-buffer (`msaa::hold_deferred_msaa`; otherwise
    /// Bevy's `check_msaa` turned it off).
    fn extract_component(
        (_, depth_id, msaa, settings): (
            Entity,
            Option<&PbrDeferredLightingDepthId>,
            Option<&Msaa>,
            Option<&DeferredMsaa>,
        ),
    ) -> Option<Self::Out> {
        let depth_id = depth_id.copied().unwrap_or_default().get() as u32;
        let msaa = settings
            .filter(|_| msaa.is_some_and(|m| *m != Msaa::Off))
            .cloned();
        Some((
            PenumbraLightingView { depth_id, msaa },
            SkipDeferredLighting,
        ))
    }
}

impl Plugin for PenumbraLightingPlugin {
    fn build(&self, app: &mut App) {
        crate::require_plugin::<bevy::pbr::PbrPlugin>(
            app,
            "PenumbraLightingPlugin",
            "PbrPlugin (in DefaultPlugins)",
        );
        crate::shader_library::register_shader_library(app);
        app.register_type::<PenumbraLighting>()
            .register_type::<PenumbraLightingView>()
            .register_type::<DeferredMsaa>()
            .init_resource::<msaa::HeldMsaa>()
            .insert_resource(LightingPluginSettings {
                require_deferred_default: self.require_deferred_default,
            })
            .add_plugins(ExtractComponentPlugin::<PenumbraLighting>::default())
            .add_systems(
                PostUpdate,
                (
                    timed(check_render_method),
                    timed(warn_forward_cameras).after(bevy::camera::CameraUpdateSystems),
                ),
            )
            .add_systems(
                PostUpdate,
                (
                    timed(msaa::hold_deferred_msaa)
                        .in_set(DeferredMsaaSystems::Hold)
                        .before(bevy::core_pipeline::core_3d::check_msaa),
                    timed(msaa::restore_deferred_msaa)
                        .in_set(DeferredMsaaSystems::Restore)
                        .after(bevy::core_pipeline::core_3d::check_msaa),
                ),
            );
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::build(render_app);
        }
    }

    fn finish(&self, app: &mut App) {
        let mut support = None;
        if let Some(render_app) = app.get_sub_app_mut(RenderApp) {
            render::finish(render_app);
            support = Some(msaa_render::support(render_app.world()));
        }
        app.insert_resource(msaa::DeferredMsaaSupport {
            unsupported: support.unwrap_or_else(|| Some("there is no renderer".into())),
        });
    }
}

/// The main-world entities of the meshes a render-world view sees, whether Bevy culled
/// them on the CPU or leaves them to the GPU (for deciding per view what its visible
/// materials need: shadow maps, subsurface scattering).
pub fn visible_meshes(
    visible: &bevy::render::view::RenderVisibleEntities,
) -> impl Iterator<Item = bevy::render::sync_world::MainEntity> + '_ {
    visible.get::<Mesh3d>().into_iter().flat_map(|meshes| {
        let cpu_culled = meshes.entities_cpu_culling.iter().map(|(_, main)| *main);
        cpu_culled.chain(meshes.entities_gpu_culling.keys().copied())
    })
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

/// The fix named when a `PenumbraLighting` camera has no deferred materials to shade.
const DEFERRED_FIX: &str = "add `.insert_resource(DefaultOpaqueRendererMethod::deferred())` \
    to the app (Bevy's deferred renderer needs the same), or, if the app sets \
    `opaque_render_method` per material, add the plugins with \
    `PenumbraPlugins.set(PenumbraLightingPlugin { require_deferred_default: false })`";

/// A `PenumbraLighting` camera while opaque materials render forward by default:
/// Penumbra's pass would shade nothing. Fails loudly, once, when the camera appears.
fn check_render_method(
    cameras: Query<Entity, Added<PenumbraLighting>>,
    method: Res<DefaultOpaqueRendererMethod>,
    settings: Res<LightingPluginSettings>,
) {
    if !settings.require_deferred_default || is_deferred(&method) {
        return;
    }
    if let Some(camera) = cameras.iter().next() {
        panic!(
            "Penumbra: camera {camera} has `PenumbraLighting`, but opaque materials render \
             forward (Bevy's default), so Penumbra's lighting pass (and its distance-field \
             shadows) would shade nothing. Fix: {DEFERRED_FIX}"
        );
    }
}

/// 3D cameras without a deferred G-buffer.
type ForwardCameras = (With<Camera3d>, Without<DeferredPrepass>);

/// With deferred the app's default render method, a 3D camera without a deferred
/// prepass does not show opaque `StandardMaterial`s (Bevy's rule): say so once per
/// camera, since Penumbra's docs asked for the setting.
fn warn_forward_cameras(
    cameras: Query<(Entity, &Camera), ForwardCameras>,
    penumbra_cameras: Query<(), With<PenumbraLighting>>,
    method: Res<DefaultOpaqueRendererMethod>,
    mut warned: Local<Vec<Entity>>,
) {
    if penumbra_cameras.is_empty() || !is_deferred(&method) {
        return;
    }
    for (entity, camera) in &cameras {
        if camera.is_active && !warned.contains(&entity) {
            warned.push(entity);
            warn!(
                "3D camera {entity} has no DeferredPrepass while deferred is the default opaque \
                 render method: Bevy does not draw deferred materials on it. Add \
                 `PenumbraLighting` (or `DeferredPrepass`) to it"
            );
        }
    }
}
