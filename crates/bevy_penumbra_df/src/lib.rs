//! Penumbra's distance-field features for Bevy.
//!
//! - [`sdf_asset`]: signed distance fields as Bevy assets — the `.psdf` loader, runtime
//!   baking of `Mesh`es on the async compute pool with observable progress, and a
//!   content-keyed disk cache so a mesh is baked once, ever.
//! - [`scene`]: distance-field casters, the SDF atlas and the GPU object buffer kept in
//!   sync by per-frame deltas, GPU culling.
//! - [`debug_view`]: a camera component that ray-marches the scene (step-count heat map,
//!   shaded surfaces).
//! - [`lighting`]: Penumbra's lighting pass — deferred shading with Penumbra's light loop,
//!   where lights can take their visibility from Penumbra's shadow masks.
//! - [`shadows`]: distance-field soft shadows for directional, point and spot lights
//!   (`DistanceFieldShadows`), through the lighting pass.
//! - [`buffer_dump`]: the buffers Penumbra's passes read (depth, normals, shadow masks),
//!   read back to the CPU for checking against ground truth.
//! - [`diagnostics`]: Penumbra's figures and pass times in Bevy's `DiagnosticsStore`.
//! - [`shader_library`]: Penumbra's WGSL modules as Bevy shader assets.
//! - [`global_field`]: the global distance field's clipmaps around a camera
//!   (`GlobalDistanceField`), composed on the GPU; DFAO's far field, terrains,
//!   particles and debug views read it.
//! - [`particles`]: GPU particles colliding with the global field
//!   (`DistanceFieldParticles`).
//! - [`gpu_allocations`]: counts of the GPU resources Penumbra creates (pooled: a steady
//!   frame creates none).
//!
//! # Cargo features
//!
//! All on by default; a game that ships pre-baked `.psdf` files and no debug view can
//! turn off what it does not use:
//!
//! - `bake`: runtime baking of `Mesh`es (rayon, the BVH baker, OBJ/glTF readers of
//!   `penumbra_sdf`), the bake cache. Without it `.psdf` assets and analytic casters
//!   still work; mesh casters need an SDF given to them.
//! - `shadows`: distance-field soft shadows (`DistanceFieldShadows`).
//! - `debug_view`: the distance-field debug view (`DistanceFieldDebugView`).

#[cfg(feature = "ao")]
pub mod ao;
pub mod buffer_dump;
#[cfg(feature = "debug_view")]
pub mod debug_view;
pub mod diagnostics;
pub mod face_normals;
pub mod global_field;
pub mod gpu_allocations;
pub mod lighting;
pub mod particles;
pub mod scene;
pub mod sdf_asset;
pub mod shader_library;
#[cfg(feature = "shadows")]
pub mod shadows;
pub mod system_times;

#[cfg(feature = "ao")]
pub use ao::{
    DistanceFieldAmbientOcclusion, DistanceFieldAmbientOcclusionPlugin, DistanceFieldAoDebugView,
    DistanceFieldSpecularOcclusion,
};
pub use buffer_dump::{
    DumpedBuffer, PenumbraBufferDump, PenumbraBufferDumpPlugin, PenumbraBuffers,
};
#[cfg(feature = "debug_view")]
pub use debug_view::{DistanceFieldDebugMode, DistanceFieldDebugPlugin, DistanceFieldDebugView};
pub use diagnostics::PenumbraDiagnosticsPlugin;
pub use face_normals::{FaceNormalPrepass, FaceNormalPrepassPlugin};
pub use global_field::{
    GlobalDistanceField, GlobalDistanceFieldPlugin, GlobalDistanceFieldState,
    GlobalDistanceFieldStats,
};
pub use gpu_allocations::{GpuAllocationCounts, PenumbraGpuAllocations};
pub use lighting::{DeferredMsaa, DeferredMsaaShading, PenumbraLighting, PenumbraLightingPlugin};
pub use particles::{
    DistanceFieldParticleMaterial, DistanceFieldParticles, DistanceFieldParticlesPlugin,
    DistanceFieldParticlesState,
};
pub use scene::{
    CasterMesh, CasterShading, CasterSource, CasterStretch, DistanceFieldCaster,
    DistanceFieldHeightfield, DistanceFieldQuery, DistanceFieldRebake, DistanceFieldRebakeStats,
    DistanceFieldScene, DistanceFieldSceneCaster, DistanceFieldSceneCasters,
    DistanceFieldScenePlugin, DistanceFieldSceneSettings, DistanceFieldUploadStats,
    FOLIAGE_AO_TRANSMISSION, HeightfieldTerrain, MergeDistanceFieldCasters, RebakeCaster,
    RebakedFrom, SceneCasterCounts, SceneHeightfields, SceneTwoSided, SkinCapsule, SkinCapsuleFit,
    SkinCapsules, SkinnedCasters, SphereHit, mesh_shading_apart,
};
pub use sdf_asset::{SdfAssetPlugin, SdfBakeFailed, SdfBaked, SdfVolumeAsset, SdfVolumeLoader};
#[cfg(feature = "bake")]
pub use sdf_asset::{
    SdfBakeCache, SdfBakeRequest, SdfBakeStats, SdfBakeTask, SdfBakeWaiting, mesh_to_tri_mesh,
};
pub use shader_library::{PenumbraShaderLibrary, register_shader_library};
#[cfg(feature = "shadows")]
pub use shadows::{DistanceFieldShadows, DistanceFieldShadowsPlugin, ReadsNoShadowMaps};

/// Panics, naming the missing plugin, when `P` has not been added before `plugin`: as
/// Bevy's own plugins do, prerequisites are checked in `build`, not discovered later as
/// a missing resource. `PenumbraPlugins` adds Penumbra's plugins in order, after
/// `DefaultPlugins`.
pub(crate) fn require_plugin<P: bevy::app::Plugin>(
    app: &bevy::app::App,
    plugin: &str,
    needed: &str,
) {
    assert!(
        app.is_plugin_added::<P>(),
        "Penumbra: {plugin} needs {needed}, which has not been added. Add it first, or add \
         `PenumbraPlugins` (all of Penumbra, in order) after `DefaultPlugins`"
    );
}
