//! Penumbra's distance-field features for Bevy.
//!
//! - [`sdf_asset`]: signed distance fields as Bevy assets — the `.psdf` loader, runtime
//!   baking of `Mesh`es on the async compute pool with observable progress, and a
//!   content-keyed disk cache so a mesh is baked once, ever.

pub mod sdf_asset;

pub use sdf_asset::{
    SdfAssetPlugin, SdfBakeCache, SdfBakeFailed, SdfBakeRequest, SdfBakeStats, SdfBakeTask,
    SdfBakeWaiting, SdfBaked, SdfVolumeAsset, SdfVolumeLoader, mesh_to_tri_mesh,
};
