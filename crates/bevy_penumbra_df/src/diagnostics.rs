//! Penumbra's figures in Bevy's `DiagnosticsStore`, so `LogDiagnosticsPlugin`, the scene
//! viewer's panel and any tool that reads diagnostics show them.
//!
//! GPU pass times: every Penumbra pass records a time span through Bevy's render
//! diagnostics (add Bevy's `RenderDiagnosticsPlugin`: GPU timestamps where the adapter
//! has them, CPU spans otherwise), under `render/<span>/elapsed_gpu` and
//! `render/<span>/elapsed_cpu` (milliseconds), with the spans `penumbra_df_apply_deltas`,
//! `penumbra_df_shadows`, `penumbra_lighting`, `penumbra_df_debug_view` and
//! `penumbra_buffer_dump`. One span per pass, none nested: Bevy 0.19's recorder keeps
//! the open spans of all render threads in one list and closes with `swap_remove`, so
//! a span nested in another on one thread, while other threads open and close theirs,
//! is sometimes closed in its parent's place — stage spans tried inside DF shadows and
//! DFAO (#44) came back as `penumbra_df_shadows/cull/grid` and gave `cull` the whole
//! pass's time at p95 on lavapipe.
//!
//! Scene figures ([`PenumbraDiagnosticsPlugin`], one value per frame):
//!
//! | path | meaning |
//! |---|---|
//! | `penumbra/df/objects` | casters in the object buffer |
//! | `penumbra/df/visible_objects` | of those, inside the first Penumbra camera's frustum (the culling pass's test, `penumbra_df_core::cull`, run on the CPU) |
//! | `penumbra/df/culled_objects` | objects minus visible objects |
//! | `penumbra/df/skipped_objects` | casters over the object buffer's cap, plus SDFs that found no atlas space |
//! | `penumbra/df/atlas_used_bytes` | atlas bytes holding SDFs |
//! | `penumbra/df/atlas_bytes` | the atlas texture's size |
//! | `penumbra/df/atlas_budget_bytes` | `DistanceFieldSceneSettings::atlas_budget_bytes` |
//! | `penumbra/df/uploaded_bytes` | object-buffer and atlas bytes uploaded this frame |
//! | `penumbra/df/bakes_pending` | mesh casters waiting for their SDF |
//!
//! Cost: a few counters per frame, plus one frustum test per caster for the visible count
//! (only with this plugin).

use crate::scene::{DistanceFieldScene, DistanceFieldSceneSettings, DistanceFieldUploadStats};
use crate::sdf_asset::{SdfBakeFailed, SdfBaked};
use crate::system_times::timed;
use crate::{CasterSource, DistanceFieldCaster, PenumbraLighting};
use bevy::diagnostic::{Diagnostic, DiagnosticPath, Diagnostics, RegisterDiagnostic};
use bevy::prelude::*;
use penumbra_df_core::cull::{CameraOrigin, Frustum, is_visible};

/// Casters in the object buffer.
pub const OBJECTS: DiagnosticPath = DiagnosticPath::const_new("penumbra/df/objects");
/// Casters inside the first Penumbra camera's frustum.
pub const VISIBLE_OBJECTS: DiagnosticPath =
    DiagnosticPath::const_new("penumbra/df/visible_objects");
/// Casters outside it.
pub const CULLED_OBJECTS: DiagnosticPath = DiagnosticPath::const_new("penumbra/df/culled_objects");
/// Casters skipped (object buffer full, no atlas space).
pub const SKIPPED_OBJECTS: DiagnosticPath =
    DiagnosticPath::const_new("penumbra/df/skipped_objects");
/// Atlas bytes holding SDFs.
pub const ATLAS_USED_BYTES: DiagnosticPath =
    DiagnosticPath::const_new("penumbra/df/atlas_used_bytes");
/// The atlas texture's size, bytes.
pub const ATLAS_BYTES: DiagnosticPath = DiagnosticPath::const_new("penumbra/df/atlas_bytes");
/// The atlas budget, bytes.
pub const ATLAS_BUDGET_BYTES: DiagnosticPath =
    DiagnosticPath::const_new("penumbra/df/atlas_budget_bytes");
/// Bytes uploaded this frame.
pub const UPLOADED_BYTES: DiagnosticPath = DiagnosticPath::const_new("penumbra/df/uploaded_bytes");
/// Mesh casters waiting for their SDF.
pub const BAKES_PENDING: DiagnosticPath = DiagnosticPath::const_new("penumbra/df/bakes_pending");

/// Adds Penumbra's scene figures to Bevy's diagnostics (see the [module docs](self)).
/// Not part of `PenumbraPlugins`: add it with Bevy's diagnostics plugins.
#[derive(Default)]
pub struct PenumbraDiagnosticsPlugin;

impl Plugin for PenumbraDiagnosticsPlugin {
    fn build(&self, app: &mut App) {
        crate::require_plugin::<crate::DistanceFieldScenePlugin>(
            app,
            "PenumbraDiagnosticsPlugin",
            "DistanceFieldScenePlugin",
        );
        for path in [
            OBJECTS,
            VISIBLE_OBJECTS,
            CULLED_OBJECTS,
            SKIPPED_OBJECTS,
            BAKES_PENDING,
        ] {
            app.register_diagnostic(Diagnostic::new(path));
        }
        for path in [
            ATLAS_USED_BYTES,
            ATLAS_BYTES,
            ATLAS_BUDGET_BYTES,
            UPLOADED_BYTES,
        ] {
            app.register_diagnostic(Diagnostic::new(path).with_suffix(" B"));
        }
        app.add_systems(
            PostUpdate,
            timed(measure).after(crate::scene::DistanceFieldSystems::UpdateObjects),
        );
    }
}

#[allow(clippy::type_complexity)]
fn measure(
    mut diagnostics: Diagnostics,
    stats: Res<DistanceFieldUploadStats>,
    settings: Res<DistanceFieldSceneSettings>,
    scene: Res<DistanceFieldScene>,
    cameras: Query<(&Camera, &GlobalTransform), With<PenumbraLighting>>,
    pending: Query<&DistanceFieldCaster, (Without<SdfBaked>, Without<SdfBakeFailed>)>,
) {
    let objects = stats.objects as f64;
    diagnostics.add_measurement(&OBJECTS, || objects);
    let visible = cameras
        .iter()
        .find(|(c, _)| c.is_active)
        .and_then(|(camera, transform)| {
            let origin = CameraOrigin::at(transform.translation())?;
            let rotation = Mat3::from(transform.affine().matrix3);
            let clip_from_relative = camera.clip_from_view() * Mat4::from_mat3(rotation).inverse();
            let frustum = Frustum::from_clip_from_relative(clip_from_relative);
            Some(
                scene
                    .records()
                    .iter()
                    .filter(|r| is_visible(r, &origin, &frustum))
                    .count() as f64,
            )
        });
    if let Some(visible) = visible {
        diagnostics.add_measurement(&VISIBLE_OBJECTS, || visible);
        diagnostics.add_measurement(&CULLED_OBJECTS, || (objects - visible).max(0.0));
    }
    diagnostics.add_measurement(&SKIPPED_OBJECTS, || {
        (stats.over_cap + stats.atlas_skipped) as f64
    });
    diagnostics.add_measurement(&ATLAS_USED_BYTES, || stats.atlas_used_bytes as f64);
    diagnostics.add_measurement(&ATLAS_BYTES, || stats.atlas_bytes as f64);
    diagnostics.add_measurement(&ATLAS_BUDGET_BYTES, || settings.atlas_budget_bytes as f64);
    diagnostics.add_measurement(&UPLOADED_BYTES, || {
        (stats.frame_object_bytes + stats.frame_atlas_bytes) as f64
    });
    let bakes = pending
        .iter()
        .filter(|c| c.source == CasterSource::Mesh)
        .count() as f64;
    diagnostics.add_measurement(&BAKES_PENDING, || bakes);
}
