//! Deferred shading with 4× MSAA (Samaritan, GDC 2011; Lauritzen, *Deferred Rendering
//! for Current and Future Rendering Pipelines*, 2010).
//!
//! A [`PenumbraLighting`] camera with [`DeferredMsaa`] (and `Msaa::Sample4`, which the
//! component brings) keeps its MSAA: Bevy's deferred
//! prepass renders into a **multisampled G-buffer** (Bevy's own layout: `Rgba32Uint`
//! words plus the `R8Uint` lighting pass id, 17 bytes per sample, plus the 4-byte depth
//! sample), a classification pass marks each pixel in a multisampled stencil — **once**
//! where its samples agree, **per sample** where they differ in depth beyond the
//! surface's own slope, in normal beyond a cone or in material, or where only some hold
//! the deferred material — and the lighting pass draws twice, stencil-tested: per pixel
//! at the pixel centre, then per sample (`@builtin(sample_index)`) on the edges. The
//! hardware resolve at the end of Bevy's main pass is the box filter over the samples
//! (the lighting pass stores its samples unresolved: that resolve is the only one).
//! Forward materials, the sky and transparent meshes draw into the same multisampled
//! target afterwards, as on a forward MSAA camera. The CPU model is
//! `penumbra_reference::msaa`; the thresholds `penumbra_df_core::msaa::EdgeParams`.
//!
//! Opt-in: `Msaa::Sample4` is Bevy's default on every camera (a `Camera3d` spawned with
//! `PenumbraLighting` has it unless the app says otherwise), so it cannot tell a user's
//! choice apart; the explicit `DeferredMsaa` is what asks for deferred MSAA and its
//! memory (about 5× the G-buffer's). Without it a `PenumbraLighting` camera renders
//! without MSAA as before (Bevy's `check_msaa` warns; Penumbra adds, once, that
//! `DeferredMsaa` keeps it); `Msaa::Off` on a `DeferredMsaa` camera turns it off.
//!
//! How Bevy is brought along: Bevy 0.19 turns MSAA off on deferred cameras
//! (`check_msaa`); Penumbra keeps a supported camera's `Msaa` across that system, makes
//! the deferred prepass render into its multisampled G-buffer (swapped into Bevy's
//! `ViewPrepassTextures` for the prepass only: Bevy's view bind group keeps the
//! single-sample texture it was made with), and skips Bevy's lighting-id copy, which
//! the classification replaces.
//!
//! The G-buffer format: Bevy's `Rgba32Uint` multisamples only with
//! `TEXTURE_ADAPTER_SPECIFIC_FORMAT_FEATURES` (lavapipe, Vulkan, D3D12 and Metal
//! desktop GPUs; not WebGPU): checked in `Plugin::finish`; without it the camera falls
//! back to Bevy's rule (MSAA off, warned once). A portable layout (two `Rgba16Uint`
//! targets, also 16 bytes per sample, guaranteed multisampled) would need Penumbra's
//! own G-buffer encoding in every deferred material's shader.
//!
//! Distance-field shadows and DFAO trace once per pixel, from a representative sample
//! (the samples' mean depth where they agree, the first covered sample on edges) that
//! the classification pass writes. On the pixels shaded per sample they are redone per
//! sample ([`DeferredMsaa::sample_occlusion`]): a second shadow trace whose threads are
//! the samples of those pixels (the others exit at once) and a per-sample AO upsample
//! from the per-pixel trace, each into a texture at twice the view's size (a 2×2 block
//! of texels per pixel), which the per-sample lighting reads. Only 4× is served: `Sample2` and `Sample8` are set to `Sample4` (warned
//! once). SSR, Bevy's SSAO and its TAA stay unavailable with MSAA, as on any Bevy
//! camera: a `DeferredMsaa` camera with any of them (TAA: a `TemporalJitter`) renders
//! without MSAA while it has them (one warning) and gets its `Msaa` back when they go.
//!
//! Cost: the multisampled G-buffer (4 × 17 bytes) plus the stencil (4 × 1), the class
//! (1) and the representative G-buffer and depth (16 + 4) per pixel; one
//! classification pass; lighting once per pixel plus three more times on edge pixels.

use super::PenumbraLighting;
use bevy::prelude::*;

pub use penumbra_df_core::msaa::EdgeParams;

/// How the pixels of a deferred MSAA camera are shaded.
#[derive(Reflect, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DeferredMsaaShading {
    /// Once per pixel where the samples agree, per sample on edges (Samaritan's).
    #[default]
    Classified,
    /// Every covered sample shaded: the reference the classifier is measured against
    /// (up to 4× the lighting cost).
    EverySample,
}

/// Deferred 4× MSAA on a [`PenumbraLighting`] camera, and its settings (module docs):
/// the opt-in. Requires `Msaa::Sample4` (filled in only where the camera has no `Msaa`
/// yet); `Msaa::Off` on the camera turns deferred MSAA off while the component stays.
#[derive(Component, Reflect, Clone, Debug)]
#[reflect(Component, Clone, Default)]
#[require(PenumbraLighting, Msaa::Sample4)]
pub struct DeferredMsaa {
    /// Samples may differ in view depth by this many times the pixel's depth slope
    /// (`|∂z/∂x| + |∂z/∂y|` of sample 0's tangent plane). Default 1. Lower finds more
    /// edges (more per-sample shading); no other cost.
    pub depth_slope_scale: f32,
    /// …plus this fraction of the view depth. Default 10⁻³.
    pub relative_depth: f32,
    /// Samples whose normals' cosine falls below this differ. Default 0.98 (11.5°).
    pub normal_cos: f32,
    /// Classified (default) or every sample.
    pub shading: DeferredMsaaShading,
    /// Distance-field shadows and DFAO per sample on the pixels shaded per sample: each
    /// sample takes the visibility and AO of its own surface (a lit wire in front of a
    /// shadowed wall stays lit). Default true. Costs, with it: a second shadow trace per
    /// light over the edge pixels' samples and a per-sample AO upsample over them, and
    /// 16 bytes per pixel per shadowed light plus 32 with DFAO (textures at twice the
    /// view's size). False: every sample of a pixel takes the pixel's (its first covered
    /// sample's).
    pub sample_occlusion: bool,
    /// Debug view: tint the per-sample-shaded samples magenta. Default false.
    pub show_edges: bool,
}

impl Default for DeferredMsaa {
    fn default() -> Self {
        let edge = EdgeParams::default();
        Self {
            depth_slope_scale: edge.slope_scale,
            relative_depth: edge.relative_depth,
            normal_cos: edge.normal_cos,
            shading: DeferredMsaaShading::Classified,
            sample_occlusion: true,
            show_edges: false,
        }
    }
}

impl DeferredMsaa {
    /// The edge test's uniform.
    pub fn edge_params(&self) -> EdgeParams {
        EdgeParams {
            slope_scale: self.depth_slope_scale,
            relative_depth: self.relative_depth,
            normal_cos: self.normal_cos,
            sample_count: 4,
        }
    }
}

/// Whether this renderer multisamples Bevy's G-buffer (set in `Plugin::finish`).
#[derive(Resource, Clone, Debug)]
pub(crate) struct DeferredMsaaSupport {
    /// `None`: supported; otherwise why not.
    pub unsupported: Option<String>,
}

/// `Msaa` of the Penumbra cameras kept across Bevy's `check_msaa` this frame.
#[derive(Resource, Default)]
pub(crate) struct HeldMsaa(Vec<(Entity, Msaa)>);

/// `DeferredMsaa` cameras whose MSAA is off while they have Bevy's SSR or SSAO, and
/// the `Msaa` they had.
#[derive(Default)]
pub(crate) struct SuspendedMsaa(Vec<(Entity, Msaa)>);

/// A camera's `DeferredMsaa`, whether it has Bevy's SSR or SSAO (which read
/// single-sample depth and normals: not served under deferred MSAA), and whether its
/// projection is jittered for temporal anti-aliasing (Bevy's `TemporalAntiAliasing`
/// requires `TemporalJitter`, and its pass skips a camera whose MSAA is on).
type HoldItem = (
    Entity,
    &'static mut Msaa,
    Has<DeferredMsaa>,
    Has<bevy::pbr::ScreenSpaceReflections>,
    Has<bevy::pbr::ScreenSpaceAmbientOcclusion>,
    Has<bevy::render::camera::TemporalJitter>,
);

/// Before `check_msaa`: a supported `DeferredMsaa` camera's MSAA is set aside (and
/// non-4× counts become 4×, warned once per camera); other `PenumbraLighting` cameras
/// with MSAA are told, once, how to keep it. A `DeferredMsaa` camera with Bevy's SSR,
/// SSAO or temporal anti-aliasing renders without MSAA while it has them (warned once),
/// and gets its `Msaa` back when they are gone.
pub(crate) fn hold_deferred_msaa(
    mut cameras: Query<HoldItem, With<PenumbraLighting>>,
    support: Option<Res<DeferredMsaaSupport>>,
    mut held: ResMut<HeldMsaa>,
    mut warned: Local<Vec<Entity>>,
    mut suspended: Local<SuspendedMsaa>,
) {
    held.0.clear();
    suspended.0.retain(|(e, _)| cameras.contains(*e));
    for (entity, mut msaa, deferred_msaa, ssr, ssao, jitter) in &mut cameras {
        // Bevy's passes that cannot work on a multisampled camera.
        let single_sample = deferred_msaa && (ssr || ssao || jitter);
        if let Some(i) = suspended.0.iter().position(|(e, _)| *e == entity) {
            if single_sample {
                continue;
            }
            let (_, kept) = suspended.0.swap_remove(i);
            // Back, unless the app has since set its own or dropped `DeferredMsaa`.
            if deferred_msaa && *msaa == Msaa::Off {
                *msaa = kept;
            }
        }
        if *msaa == Msaa::Off {
            continue;
        }
        if single_sample {
            if ssr || ssao {
                warn!(
                    "Penumbra: camera {entity} has DeferredMsaa and Bevy's {}, which reads \
                     single-sample depth and normals: it renders without MSAA while it has it",
                    if ssr {
                        "ScreenSpaceReflections"
                    } else {
                        "ScreenSpaceAmbientOcclusion"
                    }
                );
            } else {
                warn!(
                    "Penumbra: camera {entity} has DeferredMsaa and a TemporalJitter (Bevy's \
                     TemporalAntiAliasing), which resolves edges over frames and needs MSAA \
                     off: it renders without MSAA while it has it"
                );
            }
            suspended.0.push((entity, *msaa));
            *msaa = Msaa::Off;
            continue;
        }
        if !deferred_msaa {
            if !warned.contains(&entity) {
                warned.push(entity);
                info!(
                    "Penumbra: camera {entity} has PenumbraLighting and {:?} (Bevy's default): \
                     it renders without MSAA; add `DeferredMsaa` for deferred 4× MSAA",
                    *msaa
                );
            }
            continue;
        }
        if let Some(reason) = support.as_ref().and_then(|s| s.unsupported.as_ref()) {
            if !warned.contains(&entity) {
                warned.push(entity);
                warn!(
                    "Penumbra: camera {entity} asks for MSAA with PenumbraLighting, but {reason}: \
                     it renders without MSAA"
                );
            }
            continue;
        }
        let served = Msaa::Sample4;
        if *msaa != served && !warned.contains(&entity) {
            warned.push(entity);
            warn!(
                "Penumbra: camera {entity} has {:?}; Penumbra's deferred MSAA serves 4× only: \
                 it is set to Msaa::Sample4",
                *msaa
            );
        }
        held.0.push((entity, served));
        *msaa.bypass_change_detection() = Msaa::Off;
    }
}

/// Where `DeferredMsaa` cameras' `Msaa` is set aside around Bevy's `check_msaa` in
/// `PostUpdate` (which would turn it off on deferred cameras) and put back: a system
/// reading a camera's `Msaa` there runs after [`DeferredMsaaSystems::Restore`] to see
/// the camera's own.
#[derive(bevy::ecs::schedule::SystemSet, Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DeferredMsaaSystems {
    /// Before `check_msaa`: the MSAA of `DeferredMsaa` cameras is held.
    Hold,
    /// After `check_msaa`: it is put back.
    Restore,
}

/// After `check_msaa`: the held MSAA is put back (what the render world extracts).
pub(crate) fn restore_deferred_msaa(mut cameras: Query<&mut Msaa>, held: Res<HeldMsaa>) {
    for (entity, msaa) in &held.0 {
        if let Ok(mut current) = cameras.get_mut(*entity) {
            let changed = *current != *msaa;
            *current.bypass_change_detection() = *msaa;
            if changed {
                current.set_changed();
            }
        }
    }
}
