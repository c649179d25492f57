//! Distance-field soft shadows: a light with [`DistanceFieldShadows`] takes its
//! visibility from the scene's distance fields instead of a shadow map, on every camera
//! with [`PenumbraLighting`](crate::lighting::PenumbraLighting).
//!
//! # The technique
//!
//! Unreal 4's distance-field shadows (Wright, "Dynamic Occlusion with Signed Distance
//! Fields", SIGGRAPH 2015): from each pixel's world position, sphere-trace every nearby
//! caster's distance field toward the light. Along the ray, a caster at distance `d`
//! leaves about `d / r(t)` of the light's cone open, `r(t) = t · tan θ` being the cone's
//! radius (θ from the light's source size: [`DistanceFieldShadows::angular_diameter`]
//! for directional lights, `PointLight::radius` / `SpotLight::radius` for the others).
//! The smallest value wins: contacts are sharp, far penumbrae soft, there is no shadow
//! map to alias or bias by texels, and the cost does not depend on triangle counts.
//! The penumbra is two-sided (Quílez's improved soft shadow): the march goes on through
//! a caster, keeping the least `d / r` down to −1, and the light left open is its
//! smoothstep from −1 to 1 — half where the cone's axis grazes a silhouette, as a disc
//! half covered (`penumbra_df_core::shadow::PENUMBRA_MIN_STEP`). Stopping at the first
//! surface with nothing from there, as the one-sided form does, darkens every
//! penumbra's inner half: on the shadow bench the Cornell box's error went 0.0387 →
//! 0.0113 and the bunny's 0.0447 → 0.0322 with it. A bounded caster of radius `R`
//! darkens at most `(R / r)²` of the cone (tiny casters on the cone's axis dim the
//! light rather than black it out).
//!
//! A surface's own shadow is not left to the march, which starts a bias away from the
//! surface and sees a coarse field there: the pixel's G-buffer normal gives the fraction
//! of the light's disc above its tangent plane (0 on back faces, a smooth ramp across the
//! terminator, exact for a plane), and the mask is the smaller of the two. Pixels whose
//! plane hides the whole light are not marched. On the shadow bench this halves the
//! bunny's error (0.111 → 0.059 mean over its shadowed pixels, same settings). A normal
//! that faces away from the eye is turned to face it first
//! (`penumbra_reference::shadow_mask::facing_the_eye`: an inverted normal negated, a
//! smooth one past a silhouette reflected), as the surface the camera sees faces it.
//!
//! Where the camera has the face-normal prepass
//! ([`FaceNormalPrepass`](crate::face_normals::FaceNormalPrepass), required by
//! `PenumbraLighting`), the triangle at the pixel centre replaces the G-buffer normal for
//! all of this: its plane, turned to face the eye, gives the own shadow and the side the
//! march leaves from, as a ray tracer's triangle does (the scene corpus's terrain 0.240 →
//! 0.088 over shadowed pixels against ray tracing, the flight helmet 0.068 → 0.033;
//! `README.md`, "Facets"). The rules below are what a pixel without it gets (an
//! alpha-masked cut-out, a culled back face, deferred MSAA's per-sample trace).
//!
//! A receiver on a two-sided caster (a terrain sheet, a floor, foliage) sits inside its
//! own field's shell, about √3/2 voxel thick: the march through that field starts where
//! the ray has risen past the shell and half a voxel more above the receiver's tangent
//! plane, at most 4 voxels farther along the ray (Unreal's self-shadow bias;
//! `penumbra_df_core::shadow::self_shadow_start`). Solid fields get none (their surface
//! is the zero crossing; half a voxel more cost the bunny's creases 0.03 of accuracy).
//! On the Bevy terrain example asset the mean error against ray-traced truth went from
//! 0.238 to 0.063 over all pixels.
//!
//! The light's bias is a world distance chosen for metre-scale fields; a field finer than
//! half of it (a small prop) starts its march after two of its own voxels instead
//! (`penumbra_df_core::shadow::march_start`), so its contact shadows survive: on the
//! scene corpus the barn lamp's error over shadowed pixels went 0.393 → 0.261, the
//! cake's 0.075 → 0.047, and the shadow bench's defaults 0.0429 → 0.0401.
//!
//! # Passes (per camera, per light)
//!
//! 1. Light culling (compute): positional lights keep casters within their range,
//!    directional lights the casters whose sphere, swept back along the light, meets the
//!    view frustum within [`DistanceFieldShadows::max_view_distance`] of the camera
//!    (farther pixels are not traced). Directional lights then bin the survivors into a
//!    32 × 32 light-space grid (their spheres projected along the light; casters covering over 64 cells, and
//!    unbounded ones, in a separate list), and record the casters' height along the light.
//! 2. The mask (compute, 8×8 tiles): each tile gathers candidates — the light's list, or
//!    for directional lights the grid cells under the tile's own projected cone (cut at
//!    the casters' height) — and culls them against the round cone from its pixels to the
//!    light, 64 at a time in workgroup memory; each pixel marches the tile's list, then
//!    every terrain ([`DistanceFieldHeightfield`](crate::DistanceFieldHeightfield))
//!    whose box its ray's meets, at least half a terrain cell per step (a ray along a
//!    slope, where the conservative bound is small, would otherwise spend its steps and
//!    leak). One `R32Float` layer per light, at the view's size.
//! 3. Penumbra's lighting pass multiplies the light's contribution by the mask.
//!
//! 4. Optionally ([`DistanceFieldShadows::half_resolution`]) step 2 traces one pixel in
//!    four and a bilateral, depth-aware upsample fills the layer.
//!
//! Every culling step is conservative: the mask equals the CPU model marching all casters
//! (`penumbra_reference::shadow_mask`, tested on lavapipe).
//!
//! Which casters, which pixels: casters shadow while visible, as Bevy hides a hidden
//! mesh's shadow (`DistanceFieldCaster::cast_hidden_shadow` makes a shadow proxy); point
//! and spot lights trace only the pixels they light at all — within their `range`, inside
//! a spot's outer cone — so a tile outside gathers no caster (8 small point lights: 44×
//! fewer distance evaluations per pixel on `benches/df_shadow_lights.rs`).
//!
//! GPU resources are pooled per view (`resources.rs`): created with the view's first
//! shadowed light, grown with the object buffer, uniforms rewritten, counters cleared on
//! the GPU, bind groups remade only when a bound resource changes.
//!
//! # Limits
//!
//! - Only deferred materials on cameras with `PenumbraLighting` see distance-field
//!   shadows. Everything else Bevy lights — other cameras, forward, alpha-blended and
//!   transmissive materials, volumetric fog — keeps the light's shadow map, which is
//!   rendered only while such a consumer exists (`consumers.rs`): with none, the light
//!   costs no shadow map at all.
//! - Shadows come from `DistanceFieldCaster`s only: meshes without one cast none.
//! - Directional lights shadow only within `max_view_distance` of the camera; beyond it
//!   there is no fallback to shadow maps (Unreal hands over to cascades there).
//! - Accuracy: the cone heuristic, not ray-traced area lights — see
//!   `penumbra_reference::df_shadow` for its measured error against Monte Carlo truth.
//!
//! Cost: nothing without the component; per light and camera, one culling dispatch
//! over the object buffer and one pass over the view's pixels (march cost ∝ casters per
//! tile × `max_steps`); 4 bytes per pixel per light of mask memory. Under deferred MSAA
//! ([`DeferredMsaa::sample_occlusion`](crate::DeferredMsaa::sample_occlusion)) the
//! pixels shaded per sample are traced again per sample (`msaa.rs`): 16 more bytes per
//! pixel per light.

mod consumers;
mod msaa;
mod render;
mod resources;

pub use consumers::{ReadsNoShadowMaps, ShadowMapConsumers};
pub use render::{DistanceFieldShadowedLight, DistanceFieldShadowedLights};

use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};

/// Adds [`DistanceFieldShadows`]. Part of `PenumbraPlugins`.
#[derive(Default)]
pub struct DistanceFieldShadowsPlugin;

/// Put next to a `DirectionalLight`, `PointLight` or `SpotLight`: on `PenumbraLighting`
/// cameras the light's shadows come from the distance-field scene; its shadow map is
/// rendered only for what else needs it (module docs, Limits).
#[derive(Component, Reflect, Clone, Debug, PartialEq, ExtractComponent)]
#[reflect(Component, Clone, Default)]
pub struct DistanceFieldShadows {
    /// Directional lights: the angular diameter of the source, radians; the penumbra
    /// widens with it. Default 0.0093 (the sun). Point and spot lights use their
    /// `radius` instead. No cost.
    pub angular_diameter: f32,
    /// Directional lights: the shadow ray's length, metres (casters farther along the
    /// ray cast nothing). Default 100. Longer rays keep more casters per tile.
    pub max_distance: f32,
    /// Directional lights: the farthest shadowed pixel from the camera, metres. Pixels
    /// beyond are not traced and get no shadow from this light (Penumbra cameras do not
    /// fall back to its shadow map there), and the light cull drops casters that could
    /// shadow only them. Default 150,
    /// the reach of Bevy's default shadow cascades. The smaller, the fewer casters kept.
    /// Point and spot lights ignore it (their range bounds them).
    pub max_view_distance: f32,
    /// Sphere-tracing steps per caster. Default 64; cost is at most linear in it.
    pub max_steps: u32,
    /// World-space bias: the ray starts this far from the surface, metres. Default 0.04
    /// (the bench's choice: 0.02 costs 9 % more distance evaluations for 8 %
    /// more error, 0.06 saves 6 % for 12 % more). Too small: self-shadowing where SDFs
    /// are coarse; too large: detached contacts. The surface's own shadow (back faces,
    /// the terminator) comes from the G-buffer normal instead, whatever the bias. A
    /// distance field with voxels under half the bias starts two of its voxels out
    /// instead (module docs).
    pub bias: f32,
    /// Penumbra shaping: visibility `v` becomes `v^shaping` (clamped to `[0.05, 20]`).
    /// The march's penumbra is two-sided (half the light at a silhouette,
    /// `penumbra_df_core::shadow::PENUMBRA_MIN_STEP`); its smoothstep is a little
    /// wider than a disc's coverage, and an exponent a little above 1 narrows it.
    /// Default 1.25: the lowest error of `cargo bench -p penumbra_reference --bench
    /// df_shadows`'s sweep (mean error against ray-traced ground truth over shadowed
    /// pixels: the Cornell box 0.0113, the bunny 0.0322; 1.2: 0.0114 / 0.0321; 1.0:
    /// 0.0163 / 0.0357; 1.5: 0.0168 / 0.0342). No cost.
    pub shaping: f32,
    /// Trace at half resolution (one ray per 2×2 pixels) and upsample bilaterally
    /// (depth-aware). Default false. About a quarter of the tracing cost; see the bench
    /// for the error it adds.
    pub half_resolution: bool,
}

impl DistanceFieldShadows {
    /// Largest [`max_steps`](Self::max_steps).
    pub const MAX_STEPS: u32 = 4096;

    /// The settings the passes use, and a note for each value changed: the angular
    /// diameter in `[0, 3]` radians (NaN: the default), distances and the bias `≥ 0` and
    /// finite (NaN or infinite: the default), steps in `1..=4096`, shaping in
    /// `[0.05, 20]` (NaN: the default).
    pub fn resolve(&self) -> (DistanceFieldShadows, Vec<String>) {
        let d = DistanceFieldShadows::default();
        let mut s = self.clone();
        let mut notes = Vec::new();
        let mut fix = |name: &str, value: f32, fixed: &mut f32, clean: f32| {
            if clean.to_bits() != value.to_bits() {
                *fixed = clean;
                notes.push(format!("{name} {value} → {clean}"));
            }
        };
        let clamp_or = |v: f32, lo: f32, hi: f32, default: f32| {
            if v.is_nan() { default } else { v.clamp(lo, hi) }
        };
        let length = |v: f32, default: f32| {
            if v.is_finite() { v.max(0.0) } else { default }
        };
        let v = self.angular_diameter;
        fix(
            "angular_diameter",
            v,
            &mut s.angular_diameter,
            clamp_or(v, 0.0, 3.0, d.angular_diameter),
        );
        let v = self.max_distance;
        fix(
            "max_distance",
            v,
            &mut s.max_distance,
            length(v, d.max_distance),
        );
        let v = self.max_view_distance;
        fix(
            "max_view_distance",
            v,
            &mut s.max_view_distance,
            length(v, d.max_view_distance),
        );
        let v = self.bias;
        fix("bias", v, &mut s.bias, length(v, d.bias));
        let v = self.shaping;
        fix(
            "shaping",
            v,
            &mut s.shaping,
            clamp_or(v, 0.05, 20.0, d.shaping),
        );
        if !(1..=Self::MAX_STEPS).contains(&self.max_steps) {
            s.max_steps = self.max_steps.clamp(1, Self::MAX_STEPS);
            notes.push(format!("max_steps {} → {}", self.max_steps, s.max_steps));
        }
        (s, notes)
    }
}

/// One warning per change of a light's settings that are out of range.
fn warn_bad_settings(
    lights: Query<(Entity, &DistanceFieldShadows), Changed<DistanceFieldShadows>>,
) {
    for (entity, settings) in &lights {
        let (_, notes) = settings.resolve();
        if !notes.is_empty() {
            warn!(
                "Penumbra: DistanceFieldShadows on {entity}: {}",
                notes.join(", ")
            );
        }
    }
}

impl Default for DistanceFieldShadows {
    fn default() -> Self {
        Self {
            angular_diameter: 0.0093,
            max_distance: 100.0,
            max_view_distance: 150.0,
            max_steps: 64,
            bias: 0.04,
            shaping: 1.25,
            half_resolution: false,
        }
    }
}

impl Plugin for DistanceFieldShadowsPlugin {
    fn build(&self, app: &mut App) {
        app.add_systems(PostUpdate, warn_bad_settings);
        crate::require_plugin::<crate::DistanceFieldScenePlugin>(
            app,
            "DistanceFieldShadowsPlugin",
            "DistanceFieldScenePlugin",
        );
        crate::require_plugin::<crate::PenumbraLightingPlugin>(
            app,
            "DistanceFieldShadowsPlugin",
            "PenumbraLightingPlugin",
        );
        crate::shader_library::register_shader_library(app);
        if !app.is_plugin_added::<crate::FaceNormalPrepassPlugin>() {
            app.add_plugins(crate::FaceNormalPrepassPlugin);
        }
        app.register_type::<DistanceFieldShadows>()
            .register_type::<ShadowMapConsumers>()
            .register_type::<ReadsNoShadowMaps>()
            .add_plugins(ExtractComponentPlugin::<DistanceFieldShadows>::default());
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
