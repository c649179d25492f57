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
//! - [`shader_library`]: Penumbra's WGSL modules as Bevy shader assets.
//! - [`gpu_allocations`]: counts of the GPU resources Penumbra creates (pooled: a steady
//!   frame creates none).

pub mod debug_view;
pub mod gpu_allocations;
pub mod lighting;
pub mod scene;
pub mod sdf_asset;
pub mod shader_library;
pub mod shadows;

pub use debug_view::{DistanceFieldDebugMode, DistanceFieldDebugPlugin, DistanceFieldDebugView};
pub use gpu_allocations::{GpuAllocationCounts, PenumbraGpuAllocations};
pub use lighting::{PenumbraLighting, PenumbraLightingPlugin};
pub use scene::{
    CasterSource, DistanceFieldCaster, DistanceFieldScene, DistanceFieldScenePlugin,
    DistanceFieldSceneSettings, DistanceFieldUploadStats,
};
pub use sdf_asset::{
    SdfAssetPlugin, SdfBakeCache, SdfBakeFailed, SdfBakeRequest, SdfBakeStats, SdfBakeTask,
    SdfBakeWaiting, SdfBaked, SdfVolumeAsset, SdfVolumeLoader, mesh_to_tri_mesh,
};
pub use shader_library::{PenumbraShaderLibrary, register_shader_library};
pub use shadows::{DistanceFieldShadows, DistanceFieldShadowsPlugin};

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
