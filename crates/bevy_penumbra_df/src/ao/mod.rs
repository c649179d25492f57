//! Distance-field ambient occlusion (DFAO): a [`PenumbraLighting`] camera with
//! [`DistanceFieldAmbientOcclusion`] occludes Bevy's indirect light — environment map,
//! irradiance volumes, `AmbientLight` — with medium-range sky occlusion traced through
//! the distance-field scene, and shades it along the **bent normal**. Off-screen
//! occluders count and nothing fades at the frame's edge: there is no screen-space
//! step.
//!
//! # The technique
//!
//! Unreal 4's DFAO (Wright, "Dynamic Occlusion with Signed Distance Fields", SIGGRAPH
//! 2015): from each traced pixel, `cone_count` cones cover the normal's hemisphere
//! with equal cosine weight. Every occluding caster within reach is marched along each
//! cone; at a sample the caster leaves `d / r` of the cone open (`d` its distance, `r`
//! the cone's radius there: the approximate cone intersection, penumbra only), never
//! less than `1 − (R / r)²` for a caster of bounding radius `R` (small objects on the
//! axis dim a cone rather than shut it); the smallest value over samples and casters is
//! the cone's visibility. The AO is the mean of the cones' visibilities, the bent
//! normal their centres weighted by visibility. Two details of Penumbra's: a cone's
//! radius is capped by the sample's height above the receiver's tangent plane (the
//! receiver's own flat surface never occludes, with no cones tilted away from the
//! horizon), and each cone's visibility is raised to [`CONE_SHAPING`] (0.25): the
//! penumbra-only intersection reports a cone beside an edge as nearly shut when about
//! half of it is open, and the exponent was fitted against ray-traced truth.
//!
//! **Foliage** ([`DistanceFieldCaster::ao_transmission`](crate::DistanceFieldCaster),
//! set by [`DistanceFieldCaster::foliage`](crate::DistanceFieldCaster::foliage) and for
//! alpha-masked scene meshes): a two-sided caster's field fills its leaf cards in, while
//! their alpha lets light through. Such a caster leaves `τ + (1 − τ) v` of a cone it
//! would leave `v` of, so it dims a cone to its transmission `τ` and never shuts it —
//! Unreal's softened occlusion of two-sided distance fields, made a setting. Checked
//! against the analytic occlusion of a sphere that lets `τ` through
//! (`1 − (1 − τ)(R/D)²`). Opaque open sheets (walls) are two-sided too, and stay solid.
//!
//! # Passes (per camera, `Core3d` `MainPass`, before Penumbra's lighting pass)
//!
//! 1. Trace (compute, 8×8 tiles of traced pixels, at `1 / trace_resolution_divisor` of
//!    the view per axis): each tile splits its pixels into two ranges of distance from
//!    the camera, bounds each by a ball, and keeps a caster for a range when the
//!    caster's ball grown by the influence distance meets it and one distance sample at
//!    its centre is within reach (64 casters at a time in workgroup memory); each pixel
//!    marches its range's casters, then every terrain
//!    ([`DistanceFieldHeightfield`](crate::DistanceFieldHeightfield)) within reach
//!    (its conservative heightfield distance; no small-object floor). Output
//!    `Rgba16Float`: AO and bent normal.
//! 2. Upsample (compute, when the divisor is above 1): depth- and normal-aware to the
//!    view's size.
//! 3. Temporal filter (compute, full size, `temporal_filter`): each frame the trace takes
//!    another of four pixels of its `divisor × divisor` cell (jitter); the result is
//!    blended with the previous frame's, reprojected with Bevy's motion vectors (hence
//!    the required [`MotionVectorPrepass`]), rejected where the previous frame saw
//!    another surface (depth), with a confidence that flushes ghosting when a caster
//!    moves and a spatial fill shown on pixels with little history (display only: the
//!    history keeps each pixel's own value, so a still view converges to its own trace
//!    whatever history it started from)
//!    (`penumbra_reference::dfao::temporal_step` documents each step and its figures).
//! 4. Penumbra's lighting pass reads the result: contrast, min occlusion and tint are
//!    applied there.
//!
//! Every pass has a CPU model in `penumbra_reference::dfao`, equal on lavapipe
//! (`tests/dfao_gpu.rs`); the model is checked against ray-traced truth on triangles.
//!
//! # How it shades
//!
//! - Diffuse indirect light — the environment map's and irradiance volumes' (both
//!   sampled along the bent normal) and `AmbientLight`'s — is multiplied by the AO;
//!   `occlusion_tint` fills the occluded part.
//! - Specular indirect light by [`DistanceFieldSpecularOcclusion`].
//! - Direct lights are untouched (their shadows are theirs).
//! - With Bevy's `ScreenSpaceAmbientOcclusion` on the same camera, each term takes the
//!   **smaller** occlusion of the two (SSAO's multi-bounce diffuse occlusion and its
//!   specular occlusion against DFAO's): SSAO adds contact detail finer than the
//!   distance fields' voxels, DFAO the medium range SSAO cannot see, and an occluder
//!   both see darkens once, not twice.
//!
//! # Limits
//!
//! - Only casters with `casts_occlusion` (the default) occlude; meshes without a
//!   `DistanceFieldCaster` do not.
//! - Few cones are coarse under a caster nearly touching the surface (the analytic
//!   sphere-over-plane test: mean error 0.08, worst 0.13); the AO is darker than truth
//!   right beside edges.
//! - The temporal filter trades ghosting for stability: after a caster moves, its old
//!   occlusion fades over about ten frames (the confidence flushes large changes at
//!   once); a camera cut or a resize starts from a single frame.
//! - Under deferred MSAA the temporal filter reads the multisampled motion vectors at
//!   sample 0 (an edge pixel's history is kept or rejected by its representative depth);
//!   the pixels shaded per sample get a per-sample upsample of the trace
//!   ([`DeferredMsaa::sample_occlusion`](crate::DeferredMsaa::sample_occlusion), 32 more
//!   bytes per pixel), which separates a sample's surface from its neighbours' only as
//!   far as the upsample's depth and normal weights do.
//!
//! Cost: nothing without the component. Per camera: one trace over
//! `(w / divisor) × (h / divisor)` pixels, each marching `cone_count × steps_per_cone`
//! samples per caster within reach; an upsample; the temporal pass (one history read,
//! a 5×5 fill on unstable pixels); 8 bytes per pixel (full-size result) plus 8 per
//! traced pixel, plus 40 per pixel for the temporal filter (two history pairs and the
//! filtered result). Diagnostics: the time span `penumbra_dfao` (all passes; per-pass
//! spans read wrongly on lavapipe — inside the compute passes, and also as encoder spans
//! around each pass, whose sum was a sixth of the total — so there are none;
//! `tests/dfao_pass_times.rs`, ignored, times each pass through wgpu instead: at 512² on
//! lavapipe the trace takes 34 / 68 / 386 ms for 10 / 100 / 1,000 casters with the
//! defaults, the upsample and the temporal pass about 14–22 ms each).

mod pipeline;
mod render;

use crate::lighting::{PenumbraAoInput, PenumbraLighting};
use crate::system_times::timed;
use bevy::core_pipeline::prepass::MotionVectorPrepass;
use bevy::prelude::*;
use bevy::render::RenderApp;
use bevy::render::extract_component::{ExtractComponent, ExtractComponentPlugin};
use bevy::render::sync_component::SyncComponent;
pub use penumbra_df_core::ao::CONE_SHAPING;
use penumbra_df_core::ao::{AoTrace, MAX_CONES, MAX_STEPS};

/// Adds [`DistanceFieldAmbientOcclusion`]. Part of `PenumbraPlugins`.
#[derive(Default)]
pub struct DistanceFieldAmbientOcclusionPlugin;

/// How DFAO occludes the environment's specular light (Unreal's "occlusion
/// combine mode" for the sky light's reflections).
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DistanceFieldSpecularOcclusion {
    /// Specular indirect light is not occluded by DFAO.
    None,
    /// From the AO alone (Lagarde and de Rousiers 2014, as Bevy's SSAO does).
    NonDirectional,
    /// The overlap of the reflection cone (its width from roughness) with the cone of
    /// unoccluded directions around the bent normal (its width from the AO): a
    /// reflection pointing into the open side keeps its light. Unreal's default.
    #[default]
    ConeCone,
}

/// What Penumbra's lighting pass shows on a DFAO camera.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DistanceFieldAoDebugView {
    /// Normal shading.
    #[default]
    None,
    /// The AO (contrast and min occlusion applied) as grey.
    AmbientOcclusion,
    /// The bent normal, `0.5 + 0.5 · n` as colour.
    BentNormal,
    /// How many objects each 8×8 tile of trace texels keeps for the pixel's distance
    /// range (what its pixels march), as a heat map: black 0, then blue, cyan, green,
    /// yellow and red, each colour step about 2.5× the count before (red: ≥ 255). The
    /// temporal filter is off in this view.
    ObjectsPerTile,
}

/// Put on a [`PenumbraLighting`] camera: distance-field ambient occlusion of its
/// indirect light (module docs).
#[derive(Component, Reflect, Clone, Debug, PartialEq)]
#[reflect(Component, Clone, Default)]
#[require(PenumbraLighting, MotionVectorPrepass)]
pub struct DistanceFieldAmbientOcclusion {
    /// How far an occluder can be and still occlude, metres. Default 10 (Unreal's
    /// "Max Occlusion Distance"). Cost grows with it: more casters are within reach of
    /// each pixel. At least 0.01 (a smaller positive value is raised to it) and finite;
    /// zero, negative, NaN or infinite takes the default, 10. Both with a warning.
    pub max_occlusion_distance: f32,
    /// Contrast of the AO, 0 (none) to 1 (strong): an S-curve through ½. Default 0
    /// (Unreal's "Occlusion Contrast"). No cost. Clamped to `[0, 1]` with a warning.
    pub occlusion_contrast: f32,
    /// The darkest the AO may get, 0 to 1: the AO is lifted to `[min, 1]`. Default 0
    /// (Unreal's "Min Occlusion"). No cost. Clamped to `[0, 1]` with a warning.
    pub min_occlusion: f32,
    /// Light filling the occluded part of the diffuse indirect light, in the units of
    /// `AmbientLight` (colour × cd/m²): `diffuse colour × tint × (1 − AO)` is added.
    /// Default black (Unreal's "Occlusion Tint"). No cost.
    pub occlusion_tint: Color,
    /// Cones per pixel, oriented in the normal's hemisphere with equal cosine weight.
    /// Default 9 (Unreal's). Cost is linear in it; 16 cones have about a quarter less AO
    /// error against ray-traced truth for 1.7× the trace (`benches/dfao.rs`). Clamped
    /// to `1..=16` with a warning.
    pub cone_count: u32,
    /// March steps per cone and caster. Default 8: more add work and, on the bench's
    /// scenes, no accuracy (a cone's steps grow with its radius; at a 10 m reach 16
    /// steps gain about 1 % of AO error for 14 % more work). Cost is at most linear in
    /// it. Clamped to `1..=64` with a warning.
    pub steps_per_cone: u32,
    /// The trace runs on one pixel in `divisor × divisor`, upsampled with depth and
    /// normal weights, the temporal filter cycling the traced pixel. Default 4 (one
    /// pixel in 16; Unreal traces one in 4). 1 traces every pixel. Cost
    /// is about `1 / divisor²` of the trace. Clamped to `1..=8` with a warning.
    pub trace_resolution_divisor: u32,
    /// The fewest rows of traced pixels a view keeps: a view shorter than
    /// `trace_resolution_divisor × min_trace_rows` pixels traces at the largest divisor
    /// that keeps them, or every pixel (`penumbra_df_core::ao::view_divisor`). Default
    /// 96 ([`penumbra_df_core::ao::MIN_TRACE_ROWS`]): views 384 pixels tall or more keep
    /// the divisor; a small view (a picture-in-picture, a minimap, a thumbnail) traces
    /// more densely at no more cost than a 384-pixel one. 0 keeps the divisor whatever
    /// the size. One texel per 4 × 4 pixels of a 128 × 96 view lost the scene corpus's
    /// contact occlusion (mean error against ray tracing: the ship 0.089 → 0.059).
    pub min_trace_rows: u32,
    /// Temporal filtering: the trace jitters over four positions and the result is
    /// blended with the reprojected previous frames (module docs). Default on (Unreal
    /// always filters). Off: every frame stands alone, with the divisor's blockiness and
    /// no history memory. Cost: one full-size pass and 40 bytes per pixel.
    pub temporal_filter: bool,
    /// The cones start this far from the surface along its normal, metres. Default
    /// 0.02. Too small: the distance fields' error near surfaces occludes; too large:
    /// contact occlusion detaches. Clamped to `≥ 0`, and to a quarter of
    /// `max_occlusion_distance` when at least half of it, with a warning.
    pub surface_bias: f32,
    /// With a [`GlobalDistanceField`](crate::GlobalDistanceField) on the camera: each
    /// cone marches the casters' own distance fields up to this far, metres, and the
    /// global field from there to `max_occlusion_distance` (Wright 2015; Unreal's
    /// `r.AOGlobalDFStartDistance`, 1 m). Default 3: on 1,000 casters at a 10 m reach
    /// (`tests/dfao_pass_times.rs`, `dfao_far_field_figures_at_512`) the trace takes
    /// 0.37× the objects-only time with mean |AO − truth| 0.057 (objects only 0.044);
    /// from 1 m 0.34× and 0.118 (the field's grown surfaces over-occlude near small
    /// casters). Shorter: fewer casters per pixel, more over-occlusion. Ignored without
    /// a global field, or when at least `max_occlusion_distance`. Must be ≥ 0 (the
    /// default otherwise, with a warning).
    pub global_field_start: f32,
    /// How specular indirect light is occluded. Default
    /// [`DistanceFieldSpecularOcclusion::ConeCone`]. No cost to speak of.
    pub specular_occlusion: DistanceFieldSpecularOcclusion,
    /// Debug output instead of shading. Default none.
    pub debug_view: DistanceFieldAoDebugView,
}

impl Default for DistanceFieldAmbientOcclusion {
    fn default() -> Self {
        Self {
            max_occlusion_distance: 10.0,
            occlusion_contrast: 0.0,
            min_occlusion: 0.0,
            occlusion_tint: Color::BLACK,
            cone_count: 9,
            steps_per_cone: 8,
            trace_resolution_divisor: 4,
            temporal_filter: true,
            min_trace_rows: penumbra_df_core::ao::MIN_TRACE_ROWS,
            surface_bias: 0.02,
            global_field_start: 3.0,
            specular_occlusion: DistanceFieldSpecularOcclusion::ConeCone,
            debug_view: DistanceFieldAoDebugView::None,
        }
    }
}

/// A DFAO camera's settings in the render world, resolved once per frame at extraction.
#[derive(Component, Clone, Copy, Debug)]
pub struct ExtractedDfao(pub(crate) ResolvedAo);

impl SyncComponent for DistanceFieldAmbientOcclusion {
    /// Everything the render world keeps for a DFAO camera goes with the component (or
    /// with its `PenumbraLighting`): no texture, bind group or pass is left behind.
    type Target = (
        ExtractedDfao,
        PenumbraAoInput,
        render::ViewAoTextures,
        render::ViewAoBindGroups,
    );
}

impl ExtractComponent for DistanceFieldAmbientOcclusion {
    type QueryData = (&'static Self, Has<PenumbraLighting>);
    type QueryFilter = ();
    type Out = ExtractedDfao;

    fn extract_component((settings, lit): (&Self, bool)) -> Option<ExtractedDfao> {
        lit.then(|| ExtractedDfao(settings.resolve().0))
    }
}

/// Settings as the passes use them: every value in range, finite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ResolvedAo {
    pub(crate) trace: AoTrace,
    pub(crate) divisor: u32,
    /// [`DistanceFieldAmbientOcclusion::min_trace_rows`].
    pub(crate) min_trace_rows: u32,
    pub(crate) temporal: bool,
    /// Where the cones switch to the global field, metres.
    pub(crate) global_field_start: f32,
    pub(crate) contrast: f32,
    pub(crate) min_occlusion: f32,
    pub(crate) tint: LinearRgba,
    pub(crate) specular: DistanceFieldSpecularOcclusion,
    pub(crate) debug: DistanceFieldAoDebugView,
}

impl DistanceFieldAmbientOcclusion {
    /// What is out of range, one message per setting naming the value used instead
    /// (empty when nothing is).
    pub fn problems(&self) -> Vec<String> {
        self.resolve().1
    }

    pub(crate) fn resolve(&self) -> (ResolvedAo, Vec<String>) {
        let mut problems = Vec::new();
        let mut positive = |name: &str, v: f32, min: f32, fallback: f32| {
            if v.is_finite() && v >= min {
                v
            } else {
                problems.push(format!("{name} = {v} (must be ≥ {min}; using {fallback})"));
                fallback
            }
        };
        let max_distance = positive(
            "max_occlusion_distance",
            self.max_occlusion_distance,
            0.01,
            // Positive but under the minimum: the minimum; zero, negative, NaN or
            // infinite (an unbounded reach would put every caster within reach of
            // every pixel): the default.
            if self.max_occlusion_distance.is_finite() && self.max_occlusion_distance > 0.0 {
                0.01
            } else {
                10.0
            },
        );
        let mut bias = positive("surface_bias", self.surface_bias, 0.0, 0.0);
        let global_field_start = positive("global_field_start", self.global_field_start, 0.0, 3.0);
        if bias >= 0.5 * max_distance {
            // The cones would start (nearly) beyond their reach: no occlusion at all.
            let c = 0.25 * max_distance;
            problems.push(format!(
                "surface_bias = {bias} is at least half of max_occlusion_distance \
                 ({max_distance}): the cones would start out of reach (using {c})"
            ));
            bias = c;
        }
        let mut unit = |name: &str, v: f32| {
            if (0.0..=1.0).contains(&v) {
                v
            } else {
                let c = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
                problems.push(format!("{name} = {v} (must be in [0, 1]; using {c})"));
                c
            }
        };
        let contrast = unit("occlusion_contrast", self.occlusion_contrast);
        let min_occlusion = unit("min_occlusion", self.min_occlusion);
        let mut count = |name: &str, v: u32, max: u32| {
            if (1..=max).contains(&v) {
                v
            } else {
                let c = v.clamp(1, max);
                problems.push(format!("{name} = {v} (must be in 1..={max}; using {c})"));
                c
            }
        };
        let cone_count = count("cone_count", self.cone_count, MAX_CONES);
        let steps = count("steps_per_cone", self.steps_per_cone, MAX_STEPS);
        let divisor = count("trace_resolution_divisor", self.trace_resolution_divisor, 8);
        let tint = self.occlusion_tint.to_linear();
        let tint = if [tint.red, tint.green, tint.blue]
            .iter()
            .all(|c| c.is_finite())
        {
            tint
        } else {
            problems.push("occlusion_tint is not finite (using black)".into());
            LinearRgba::BLACK
        };
        (
            ResolvedAo {
                trace: AoTrace {
                    max_distance,
                    cone_count,
                    steps_per_cone: steps,
                    bias,
                    shaping: CONE_SHAPING,
                },
                divisor,
                min_trace_rows: self.min_trace_rows,
                temporal: self.temporal_filter,
                global_field_start,
                contrast,
                min_occlusion,
                tint,
                specular: self.specular_occlusion,
                debug: self.debug_view,
            },
            problems,
        )
    }
}

/// Warns once per change of a camera's settings when some are out of range.
fn warn_bad_settings(
    cameras: Query<
        (Entity, &DistanceFieldAmbientOcclusion),
        Changed<DistanceFieldAmbientOcclusion>,
    >,
) {
    for (entity, settings) in &cameras {
        let problems = settings.problems();
        if !problems.is_empty() {
            warn!(
                "Penumbra: DistanceFieldAmbientOcclusion on {entity}: {}; clamped",
                problems.join(", ")
            );
        }
    }
}

impl Plugin for DistanceFieldAmbientOcclusionPlugin {
    fn build(&self, app: &mut App) {
        crate::require_plugin::<crate::DistanceFieldScenePlugin>(
            app,
            "DistanceFieldAmbientOcclusionPlugin",
            "DistanceFieldScenePlugin",
        );
        crate::require_plugin::<crate::PenumbraLightingPlugin>(
            app,
            "DistanceFieldAmbientOcclusionPlugin",
            "PenumbraLightingPlugin",
        );
        crate::shader_library::register_shader_library(app);
        app.register_type::<DistanceFieldAmbientOcclusion>()
            .add_plugins(ExtractComponentPlugin::<DistanceFieldAmbientOcclusion>::default())
            .add_systems(PostUpdate, timed(warn_bad_settings));
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_settings_are_clamped_and_named() {
        assert!(
            DistanceFieldAmbientOcclusion::default()
                .problems()
                .is_empty()
        );
        let bad = DistanceFieldAmbientOcclusion {
            max_occlusion_distance: f32::NAN,
            occlusion_contrast: 3.0,
            cone_count: 0,
            ..default()
        };
        let (resolved, problems) = bad.resolve();
        assert_eq!(problems.len(), 3, "{problems:?}");
        assert_eq!(resolved.trace.max_distance, 10.0);
        assert_eq!(resolved.contrast, 1.0);
        assert_eq!(resolved.trace.cone_count, 1);
        let negative = DistanceFieldAmbientOcclusion {
            max_occlusion_distance: -1.0,
            ..default()
        };
        assert_eq!(negative.resolve().0.trace.max_distance, 10.0);
        assert!(problems[0].contains("max_occlusion_distance"));
        // An unbounded reach takes the default (it took the minimum, 0.01 m: #46), a
        // tiny one the minimum.
        for (v, want) in [
            (f32::INFINITY, 10.0),
            (f32::NEG_INFINITY, 10.0),
            (1e-4, 0.01),
        ] {
            let (resolved, problems) = DistanceFieldAmbientOcclusion {
                max_occlusion_distance: v,
                ..default()
            }
            .resolve();
            assert_eq!(resolved.trace.max_distance, want, "{v}");
            assert!(
                problems[0].contains("max_occlusion_distance"),
                "{v}: {problems:?}"
            );
        }
        // A bias beyond half the reach would leave every cone open.
        let far_bias = DistanceFieldAmbientOcclusion {
            max_occlusion_distance: 2.0,
            surface_bias: 3.0,
            ..default()
        };
        let (resolved, problems) = far_bias.resolve();
        assert_eq!(resolved.trace.bias, 0.5);
        assert!(problems[0].contains("surface_bias"), "{problems:?}");
    }
}
